"""The true lenslet lattice of a preset camera, and which lens every sensor pixel belongs to.

:func:`make_grid` places the lattice on the sensor (a :class:`~plenodecode.types.LensletGrid`);
:func:`assign_pixels` finds each sensor position's nearest lens (its hexagonal or square Voronoi
cell) and the position's offset from that lens's centre; :func:`raytrix_lens_types` and
:func:`lens_types_at` give the three interleaved lens types of a multi-focus (Raytrix) array.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..types import LensletGrid
from .presets import Preset, get_preset


def make_grid(preset: str | Preset, *, pitch: float | None = None, rotation: float | None = None,
              offset: tuple[float, float] | None = None, shape: tuple[int, int] | None = None) -> LensletGrid:
    """The true lenslet grid of a preset camera.

    An infinite lattice is anchored at the sensor centre ``((H-1)/2, (W-1)/2) + offset``
    (anchor lens on an even row, odd rows shifted by +pitch/2 for hex).  The returned grid
    is the smallest (rows, cols) block of it that contains every lens whose centre lies on
    the sensor (``-0.5 <= row <= H - 0.5`` and likewise for col); its lens (0, 0) may lie
    just off the sensor when the grid is rotated.  If the first row of that block is odd in
    the infinite lattice, ``odd_row_shift`` is -0.5.

    Returns
    -------
    LensletGrid
        With ``radius = radius_frac * pitch`` and, for a focused (Raytrix) preset,
        ``lens_type`` (see :func:`raytrix_lens_types`).
    """
    p = get_preset(preset)
    pitch = float(p.pitch_px if pitch is None else pitch)
    rotation = float(p.rotation if rotation is None else rotation)
    offset = tuple(float(v) for v in (p.offset if offset is None else offset))
    h, w = _check_shape(p.sensor_shape if shape is None else shape)
    if not pitch > 2.0:
        raise ValueError(f"pitch must be > 2 px, got {pitch}")
    if not abs(rotation) < 0.5:
        raise ValueError(f"rotation must be within +-0.5 rad, got {rotation}")
    if len(offset) != 2:
        raise ValueError(f"offset must be (row, col), got {offset!r}")
    hexagonal = p.lattice == "hex"
    rs = pitch * math.sqrt(3.0) / 2.0 if hexagonal else pitch
    shift = 0.5 if hexagonal else 0.0
    anchor = np.array([(h - 1) / 2.0 + offset[0], (w - 1) / 2.0 + offset[1]])
    s, c = math.sin(rotation), math.cos(rotation)
    e_row, e_col = np.array([c, -s]), np.array([s, c])
    corners = np.array([[-0.5, -0.5], [-0.5, w - 0.5], [h - 0.5, -0.5], [h - 0.5, w - 0.5]]) - anchor
    a_c, b_c = corners @ e_row, corners @ e_col
    i_lo, i_hi = int(math.floor(a_c.min() / rs)) - 1, int(math.ceil(a_c.max() / rs)) + 1
    j_lo, j_hi = int(math.floor(b_c.min() / pitch)) - 1, int(math.ceil(b_c.max() / pitch)) + 1
    ii, jj = np.meshgrid(np.arange(i_lo, i_hi + 1), np.arange(j_lo, j_hi + 1), indexing="ij")
    a = ii * rs
    b = (jj + shift * np.mod(ii, 2)) * pitch
    pos = anchor + a[..., None] * e_row + b[..., None] * e_col
    on = ((pos[..., 0] >= -0.5) & (pos[..., 0] <= h - 0.5) & (pos[..., 1] >= -0.5) & (pos[..., 1] <= w - 0.5))
    i0, i1 = int(ii[on].min()), int(ii[on].max())
    j0, j1 = int(jj[on].min()), int(jj[on].max())
    first_odd = i0 % 2 == 1
    odd_row_shift = -shift if first_odd else shift
    a0 = i0 * rs
    b0 = (j0 + (shift if first_odd else 0.0)) * pitch
    origin = anchor + a0 * e_row + b0 * e_col
    grid = LensletGrid(
        lattice="hex" if hexagonal else "square", pitch=pitch, row_spacing=rs, rotation=rotation,
        origin=(float(origin[0]), float(origin[1])), shape=(i1 - i0 + 1, j1 - j0 + 1),
        odd_row_shift=odd_row_shift, sensor_shape=(h, w), radius=p.radius_frac * pitch,
        info={"source": "plenodecode.io.synthetic", "preset": p.name, "truth": True},
    )
    if p.focused:
        grid = grid.replace(lens_type=raytrix_lens_types(grid))
    return grid


def raytrix_lens_types(grid: LensletGrid) -> np.ndarray:
    """Lens type (0, 1, 2) of every lens of a hex grid: the 3-colouring of the hex lattice.

    With axial coordinates ``q = j + odd_row_shift * (i mod 2) - i / 2`` (an integer) and
    ``r = i``, ``type = (q - r) mod 3``.  The six neighbours of a lens all have other types
    and lenses of one type form a hex lattice of spacing ``sqrt(3) * pitch`` (Raytrix
    ``sub_grid_base`` = (3, 1.732) lens units, Perwass & Wietzke 2012).

    Returns
    -------
    ndarray, shape grid.shape, int8
    """
    i, j = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
    return lens_types_at(grid, i, j).astype(np.int8)


def lens_types_at(grid: LensletGrid, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Lens type of lens indices (i, j), also beyond the grid's block.

    ``type = (q - i) mod 3`` with the axial coordinate ``q = j + odd_row_shift * (i mod 2) - i / 2``
    (see :func:`raytrix_lens_types`).
    """
    q = np.rint(j + grid.odd_row_shift * np.mod(i, 2) - 0.5 * i).astype(np.int64)
    return np.mod(q - i, 3).astype(np.int64)


def _check_shape(shape: Any) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in shape)
    except (TypeError, ValueError):
        raise ValueError(f"shape must be (H, W), got {shape!r}") from None
    if h < 16 or w < 16:
        raise ValueError(f"shape must be at least (16, 16), got {(h, w)}")
    return h, w


@dataclass(frozen=True)
class _PixelLens:
    """Per-pixel lens assignment of a band of sensor rows (all arrays (h, W))."""

    oa: np.ndarray       # lattice-frame offset from the lens centre, across rows, px (float64)
    ob: np.ndarray       # ... along rows
    y: np.ndarray        # decoded spatial coordinate of the lens (float64)
    x: np.ndarray
    i: np.ndarray        # lens row / col index in the grid (int64, may be outside the grid)
    j: np.ndarray


def assign_pixels(grid: LensletGrid, rows: np.ndarray, cols: np.ndarray) -> _PixelLens:
    """Nearest lens of every sensor position (hex or square Voronoi cell), vectorised.

    Parameters
    ----------
    grid : LensletGrid
        Lattice only (refined centres are ignored: the truth is the ideal lattice).
    rows, cols : ndarray, same shape S, float
        Sensor positions.

    Returns
    -------
    _PixelLens
        Offsets ``o`` (lattice frame), decoded coordinates ``(y, x)`` and indices ``(i, j)``
        of the nearest lens; lenses beyond the grid's block are extrapolated from the lattice.
    """
    e_row, e_col = grid.axes()
    pr = np.asarray(rows, np.float64) - grid.origin[0]
    pc = np.asarray(cols, np.float64) - grid.origin[1]
    a = pr * e_row[0] + pc * e_row[1]
    b = pr * e_col[0] + pc * e_col[1]
    p, rs, sh = grid.pitch, grid.row_spacing, grid.odd_row_shift
    if grid.lattice == "square":
        i = np.rint(a / rs)
        j = np.rint(b / p)
        oa = a - i * rs
        ob = b - j * p
    else:
        # the nearest lens lies in one of the two lens rows bracketing a (hex cells reach
        # at most pitch / sqrt(3) < row_spacing from their row)
        i = np.floor(a / rs)
        best = None
        for di in (0.0, 1.0):
            ic = i + di
            bs = sh * p * np.mod(ic, 2.0)
            jc = np.rint((b - bs) / p)
            oac = a - ic * rs
            obc = b - jc * p - bs
            d2 = oac * oac + obc * obc
            if best is None:
                best = [d2, ic, jc, oac, obc]
            else:
                take = d2 < best[0]
                for k, v in enumerate((d2, ic, jc, oac, obc)):
                    best[k] = np.where(take, v, best[k])
        _, i, j, oa, ob = best
    smp = grid.decoded_sampling()
    a_k = i * rs
    b_k = j * p + sh * p * np.mod(i, 2.0)
    return _PixelLens(oa=oa, ob=ob, y=(a_k - smp["a0"]) / smp["step"], x=(b_k - smp["b0"]) / smp["step"],
                      i=i.astype(np.int64), j=j.astype(np.int64))


__all__ = ["make_grid", "raytrix_lens_types", "lens_types_at", "assign_pixels"]
