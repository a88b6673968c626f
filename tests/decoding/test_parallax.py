"""Decoded views keep the parallax of a plane at a known disparity (issue 22: where H lost 0.1-0.3 %).

A raw whose radiance is a sinusoid of the plane at disparity ``d`` (px per view step, the generator's
contract: the pixel at lattice offset ``o`` from the centre of the lens at decoded ``(y, x)`` sees
``T(x + d o_b)``, :func:`plenodecode.synthetic.assign_pixels`) is decoded; the phase of each view's
sinusoid against the centre view's gives the view's shift, and ``s = sum(shift . nominal) / sum(nominal^2)``
over the views of one ring ``max(|v - vc|, |u - uc|) = r`` is the parallax scale of that ring.

A linear ramp cannot see this bias (a least-squares plane extrapolates it exactly, ``test_slice.py``); a
sinusoid of period 4-8 decoded px at ``d = 1`` has curvature across the micro-image, as a checkerboard's
edges do.  Measured (F01, bilinear demosaic, ``view_edges='extrapolate'``): rings 1-3 within 2.4e-3 of 1
(colour and monochrome, periods 4 and 8), while renormalising compresses ring 3 by 17e-3 (colour).  Ring 4
(the views on the disk's soft edge, relative weight 0.02-0.6, every colour sample extrapolated) stays
compressed (colour 50-99e-3, monochrome 18-34e-3) and is not judged.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from plenodecode import synthetic
from plenodecode.decoding import decode
from plenodecode.synthetic.presets import get_preset
from plenodecode.types import LensletGrid, RawCapture

#: Largest |s - 1| allowed on rings 1-3 (measured at most 2.4e-3; renormalising: 17e-3 on ring 3).
MAX_SCALE_ERROR = 5e-3
DISPARITY = 1.0


def sine_raw(white: RawCapture, grid: LensletGrid, axis: int, period: float) -> RawCapture:
    """Noise-free raw of ``0.5 + 0.25 sin(2 pi (p + d o) / period)`` along decoded ``p`` = y (axis 0) or x (1):
    the white's signal times the radiance, so ``raw / white`` is the radiance (up to rounding)."""
    h, w = white.shape
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    lens = synthetic.assign_pixels(grid, rows, cols)
    pos, o = (lens.y, lens.oa) if axis == 0 else (lens.x, lens.ob)
    black = np.tile(np.asarray(white.black, np.float64), (h // 2, w // 2))
    signal = (white.mosaic - black) * (0.5 + 0.25 * np.sin(2 * math.pi * (pos + DISPARITY * o) / period))
    return dataclasses.replace(white, mosaic=np.clip(np.rint(black + signal), 0, np.max(white.white)).astype(np.uint16))


def ring_scales(white: RawCapture, grid: LensletGrid, period: float, view_edges: str) -> np.ndarray:
    """Parallax scale ``s`` of rings 1 .. V // 2 (both axes pooled)."""
    num, den = 0.0, 0.0
    for axis in (0, 1):
        lf = decode(sine_raw(white, grid, axis, period), grid, white=white, demosaic="bilinear", colour="camera",
                    view_edges=view_edges)
        lum = lf.data.mean(axis=-1)[:, :, 2:-2, 2:-2]
        n_v, n = lum.shape[0], lum.shape[2 + axis]
        pos = np.arange(2, 2 + n, dtype=np.float64)
        basis = np.column_stack([np.ones(n), np.sin(2 * math.pi * pos / period), np.cos(2 * math.pi * pos / period)])
        profiles = lum.mean(axis=3 - axis).reshape(n_v * n_v, n)
        coef = np.linalg.lstsq(basis, profiles.T, rcond=None)[0]
        phase = np.arctan2(coef[2], coef[1]).reshape(n_v, n_v)
        k = np.arange(n_v) - n_v // 2
        nominal = (k[:, None] if axis == 0 else k[None, :]) * np.ones((n_v, n_v))
        c = n_v // 2
        # the view's error, wrapped to half a period, in view steps
        err = np.angle(np.exp(1j * (phase - phase[c, c] - 2 * math.pi * DISPARITY * nominal / period)))
        err *= period / (2 * math.pi * DISPARITY)
        ring = np.maximum(np.abs(k)[:, None], np.abs(k)[None, :])
        rings = np.arange(1, c + 1)
        num = num + np.array([(err * nominal)[ring == r].sum() for r in rings])
        den = den + np.array([(nominal ** 2)[ring == r].sum() for r in rings])
    return 1.0 + num / den


@pytest.fixture(scope="module", params=["BGGR", None], ids=["colour", "mono"])
def f01_white(request):
    p = get_preset("f01")
    if request.param is None:
        p = dataclasses.replace(p, cfa=None, wb_gains=None, ccm=None)
    return synthetic.simulate_white(p, noise=False, shape=(240, 264))


@pytest.mark.parametrize("period", [4.0, 8.0])
def test_inner_rings_keep_their_parallax(f01_white, period):
    white, grid = f01_white
    s = ring_scales(white, grid, period, "extrapolate")
    print(f"\nperiod {period}: s - 1 per ring (1e-3) {np.round((s - 1) * 1e3, 1)}")
    assert s.size == 4
    assert np.all(np.abs(s[:3] - 1) < MAX_SCALE_ERROR)


@pytest.mark.parametrize("f01_white", ["BGGR"], ids=["colour"], indirect=True)
def test_renormalised_edges_compress_ring_3(f01_white):
    """The measurement has the power to see the bias it guards against: renormalising the cut footprints
    (the decoder's default) compresses ring 3 of a colour decode (measured -17e-3; a monochrome decode's
    ring 3 is hardly cut, -1e-3)."""
    white, grid = f01_white
    s = ring_scales(white, grid, 8.0, "renormalise")
    assert s[2] < 1 - 2 * MAX_SCALE_ERROR
