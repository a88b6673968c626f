"""Perspective views at fractional view positions, and parallax sequences (a circle of viewpoints).

A view at a fractional position ``(v, u)`` (absolute view indices, ``0 <= v <= V - 1``) is interpolated across
the neighbouring views with no disparity compensation (the light field is treated as a function of the
aperture position, sampled on the view grid): bilinear over the 4 neighbours, or Keys' bicubic convolution
(Keys 1981, a = -0.5) over 4 x 4 neighbours with edge views repeated.  Both are exact at integer positions.
With the light field's weight ``w`` the interpolation is weighted, ``sum t w L / sum t w`` (``t`` the taps),
and a pixel with ``sum t w`` below :data:`~plenodecode.imaging.MIN_DATA_WEIGHT` (no lens sample: the frame's
edge gaps a decode leaves) takes its nearest neighbour with data (:func:`~plenodecode.imaging.fill_gaps`).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..imaging import INTERPOLATION_TAPS, MIN_DATA_WEIGHT, fill_gaps, interpolation_taps
from ..types import LightField
from ._common import check_lightfield

#: Angular interpolation kernels of :func:`perspective`.
PERSPECTIVE_INTERPOLATIONS = tuple(INTERPOLATION_TAPS)


def _axis_taps(p: float, n: int, interp: str) -> list[tuple[int, float]]:
    """(index, weight) pairs interpolating position ``p`` on ``n`` samples (indices clamped)."""
    base, w = interpolation_taps(np.array([p], np.float64), interp)
    taps: dict[int, float] = {}
    for k in range(w.shape[1]):
        if w[0, k] != 0.0:
            i = min(max(int(base[0]) + k, 0), n - 1)
            taps[i] = taps.get(i, 0.0) + float(w[0, k])
    return list(taps.items())


def perspective(lf: LightField, v: float, u: float, *, interp: str = "linear") -> np.ndarray:
    """The view seen from fractional view position ``(v, u)``.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32.
    v, u : float
        Absolute view indices, ``0 <= v <= V - 1``, ``0 <= u <= U - 1``; the centre view is ``(V // 2, U // 2)``.
    interp : 'linear' or 'cubic'
        Bilinear over the 4 neighbouring views, or bicubic (Keys) over 4 x 4.

    Returns
    -------
    ndarray, shape (Y, X, C), float32
        ``lf.data[v, u]`` exactly (a copy) at integer positions, where it has data (module docstring).
    """
    check_lightfield(lf)
    nv, nu = lf.shape[:2]
    if interp not in PERSPECTIVE_INTERPOLATIONS:
        raise ValueError(f"interp must be one of {', '.join(PERSPECTIVE_INTERPOLATIONS)}, got {interp!r}")
    for name, p, n in (("v", v, nv), ("u", u, nu)):
        if not (math.isfinite(p) and 0 <= p <= n - 1):
            raise ValueError(f"{name} must be within [0, {n - 1}] (view index), got {p}")
    taps = [(i, j, np.float32(wi * wj)) for i, wi in _axis_taps(float(v), nv, interp)
            for j, wj in _axis_taps(float(u), nu, interp)]
    if len(taps) == 1:
        out = lf.data[taps[0][0], taps[0][1]].copy()
    else:
        out = np.zeros(lf.shape[2:], np.float32)
        for i, j, t in taps:
            out += t * lf.data[i, j]
    if lf.weight is None:
        return out
    if len(taps) == 1:
        return fill_gaps(out, lf.weight[taps[0][0], taps[0][1]] >= MIN_DATA_WEIGHT)
    num = np.zeros(lf.shape[2:], np.float32)
    den = np.zeros(lf.shape[2:4], np.float32)
    for i, j, t in taps:
        tw = t * lf.weight[i, j]
        num += tw[..., None] * lf.data[i, j]
        den += tw
    known = den >= MIN_DATA_WEIGHT
    out[known] = num[known] / den[known, None]
    return fill_gaps(out, known)


def parallax_path(lf: LightField, n_frames: int = 24, radius: float | None = None) -> list[tuple[float, float]]:
    """A circle of viewpoints around the centre view.

    Parameters
    ----------
    lf : LightField
    n_frames : int
        Number of viewpoints (>= 1).
    radius : float, optional
        In view steps; default 3/4 of the largest radius inside the view grid.

    Returns
    -------
    list of (v, u)
        ``(vc + r sin t, uc + r cos t)`` for ``t = 2 pi i / n_frames``.
    """
    check_lightfield(lf)
    nv, nu = lf.shape[:2]
    vc, uc = lf.centre_index
    rmax = float(min(vc, uc, nv - 1 - vc, nu - 1 - uc))
    if int(n_frames) != n_frames or n_frames < 1:
        raise ValueError(f"n_frames must be a positive integer, got {n_frames}")
    r = 0.75 * rmax if radius is None else float(radius)
    if not (0 <= r <= rmax + 1e-9):
        raise ValueError(f"radius must be within [0, {rmax:g}] view steps for a {nv}x{nu} light field, got {radius}")
    t = 2 * np.pi * np.arange(int(n_frames)) / int(n_frames)
    return [(float(min(max(vc + r * np.sin(a), 0), nv - 1)), float(min(max(uc + r * np.cos(a), 0), nu - 1)))
            for a in t]


def render_parallax(lf: LightField, n_frames: int = 24, radius: float | None = None, *, interp: str = "linear",
                    progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """The perspective views along :func:`parallax_path`.

    Returns
    -------
    ndarray, shape (n_frames, Y, X, C), float32
    """
    path = parallax_path(lf, n_frames, radius)
    out = np.empty((len(path), *lf.shape[2:]), np.float32)
    for i, (v, u) in enumerate(path):
        out[i] = perspective(lf, v, u, interp=interp)
        if progress is not None:
            progress(i + 1, len(path))
    return out
