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
