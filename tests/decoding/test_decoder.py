"""decoding.decoder: the output allocation (the decode itself is tested against ground truth in test_synthetic.py)."""

from __future__ import annotations

import gc
from pathlib import Path

import numpy as np
import pytest

from plenodecode.decoding.decoder import SMALL_PAGE_MIN_BYTES, small_page_empty


def _vm_flags(a: np.ndarray) -> list[str] | None:
    """VmFlags of the memory mapping holding the middle of ``a`` (Linux), None without /proc/self/smaps."""
    smaps = Path("/proc/self/smaps")
    if not smaps.exists():
        return None
    addr = a.__array_interface__["data"][0] + a.nbytes // 2
    inside = False
    for line in smaps.read_text().splitlines():
        head = line.split()[0]
        if "-" in head and all(c in "0123456789abcdef-" for c in head):
            lo, hi = (int(x, 16) for x in head.split("-"))
            inside = lo <= addr < hi
        elif inside and head == "VmFlags:":
            return line.split()[1:]
    return None


def test_small_page_empty_is_a_plain_writable_array_without_huge_page_advice():
    shape = (3, SMALL_PAGE_MIN_BYTES // 4 // 3 + 5)
    a = small_page_empty(shape, np.float32)
    assert a.shape == shape and a.dtype == np.float32 and a.flags.c_contiguous and a.flags.writeable
    a[...] = np.arange(a.size, dtype=np.float32).reshape(shape)
    view = a[1]
    del a
    gc.collect()                                   # the mapping lives as long as a view of it
    assert view[0] == shape[1] and view[-1] == 2 * shape[1] - 1
    plain = np.empty(shape, np.float32)
    plain[...] = 0
    if "hg" not in (_vm_flags(plain) or []):
        pytest.skip("numpy advises no huge pages here (or no /proc/self/smaps): nothing to avoid")
    assert "hg" not in _vm_flags(view)             # ours is not advised for transparent huge pages


def test_small_arrays_come_from_numpy():
    a = small_page_empty((4, 5), np.int32)
    assert a.flags.owndata and a.shape == (4, 5) and a.dtype == np.int32


def test_decode_samples_hands_out_what_the_views_are_interpolated_from():
    """decode_samples: the same light field as decode; each lens row of samples, placed at ``position``
    and interpolated linearly, gives that row of a 'linear' decode."""
    from plenodecode.calib import calibrate
    from plenodecode.decoding import decode, decode_samples
    from plenodecode.synthetic.checkerboard import simulate_checkerboard_set

    cset = simulate_checkerboard_set("f01", (7, 5, 0.004), 1, seed=0)
    grid = calibrate(cset.white)
    kw = {"white": cset.white, "demosaic": "bilinear", "view_edges": "extrapolate", "resample": "linear"}
    lf, samples = decode_samples(cset.raws[0], grid, **kw)
    plain = decode(cset.raws[0], grid, **kw)
    np.testing.assert_array_equal(lf.data, plain.data)
    np.testing.assert_array_equal(lf.weight, plain.weight)
    V, U, Y, X, C = lf.shape
    assert samples.data.shape == (V, U, *grid.shape, C) and samples.position.shape == (*grid.shape, 2)
    np.testing.assert_array_equal(samples.position[:, 0, 1], np.arange(Y))
    x = np.arange(X)
    for r in (10, 11, 50):
        for v, u in ((4, 4), (2, 5)):
            row = np.interp(x, samples.position[r, :, 0], samples.data[v, u, r, :, 1])
            np.testing.assert_allclose(row, lf.data[v, u, r, :, 1], atol=2e-6)
