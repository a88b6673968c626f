"""Synthetic plenoptic raws with exact ground truth (a physical forward model).

The model is the unfocused plenoptic camera of Ng et al. (2005) and Ng (2006, thesis,
ch. 3): a micro-lens array (MLA) one focal length in front of the sensor, so the pixels
under one lenslet sample the directions of the rays through that lenslet.  The lattice is
:class:`~plenodecode.types.LensletGrid`; the mapping from sensor pixels to light-field
coordinates is the *decoded sampling contract* of :mod:`plenodecode.types`:

* a sensor pixel ``q`` belongs to the lens ``k`` whose centre is nearest (the hexagonal
  or square Voronoi cell), and ``o = (o_a, o_b)`` is its lattice-frame offset from that
  centre in px (= view units, the view step is one sensor pixel);
* lens ``k`` at lattice position ``(A_k, B_k)`` has decoded spatial coordinate
  ``y = (A_k - a0) / step``, ``x = (B_k - b0) / step`` (:meth:`LensletGrid.decoded_sampling`);
* the radiance of that ray is ``L(o, y, x) = T((y + d * o_a, x + d * o_b))`` for the
  front-most scene plane (texture ``T``, disparity ``d`` in decoded px per view step, HCI
  convention) whose support contains the hit point.

A pixel records the mean of ``L`` over its 1 x 1 px box in ``o`` (2 x 2 Gauss-Legendre rule),
times the lenslet's disk response (also box-averaged), the sensor vignetting
(``cos^4`` law) and an exposure scale.  The white image is the same with ``T = 1`` in every
camera channel, so ``(raw - black) / (white - black)`` is the camera-RGB radiance exactly
(noise-free).  Camera RGB is ``diag(1 / wb) @ inv(ccm) @ srgb``, so a decoder applying
``ccm @ diag(wb)`` recovers linear sRGB.  Then Bayer sampling, Poisson-Gaussian noise
(full well, read noise), hot pixels, quantisation and clipping.

The 'raytrix' preset is a focused plenoptic camera (Lumsdaine & Georgiev 2009; Perwass &
Wietzke 2012): each micro-image is a small inverted image of the main lens's virtual
image; see :func:`simulate`.
"""

from __future__ import annotations

import json
import logging
import math
import os
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import FormatError
from ..types import CameraMetadata, LensletGrid, LightField, RawCapture, cfa_channel_map
from .atomic import atomic_output, refuse_existing, write_text_atomic

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Rows processed at a time (bounds memory on full-size sensors).  Part of the RNG
#: contract: the noise of a given seed depends on it.
BAND_ROWS = 256
#: Shot noise is drawn exactly (Poisson) below this many electrons, normal above.
POISSON_EXACT_BELOW = 100.0
#: Sub-sample offsets (px, in the lattice frame) of the rule that averages over a pixel box:
#: 2 x 2 Gauss-Legendre points, exact for polynomials up to degree 3 per axis.
SUBSAMPLES = np.array([-0.5 / math.sqrt(3.0), 0.5 / math.sqrt(3.0)])


# ---------------------------------------------------------------------------------------
# presets
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Preset:
    """A simulated camera: sensor, MLA, optics, levels, colour and noise.

    Lengths in metres unless the name says px; angles in radians.
    """

    name: str
    sensor_shape: tuple[int, int]          # (H, W)
    pitch_px: float                        # lens pitch along a lens row
    lattice: str = "hex"                   # 'hex' or 'square'
    rotation: float = 0.0
    offset: tuple[float, float] = (0.0, 0.0)   # lattice anchor shift from the sensor centre (row, col) px
    cfa: str | None = "GRBG"
    bits: int = 10                         # bits of the data
    black: float = 64.0
    white: float = 1023.0
    radius_frac: float = 0.46              # disk radius / pitch
    edge_px: float = 1.5                   # width of the soft disk edge
    disk_falloff: float = 0.12             # relative loss at the disk radius (mild radial falloff)
    vignette_corner: float = 0.5           # sensor vignetting at the corners
    exposure: float = 0.8                  # white-image signal at the sensor centre, fraction of range
    full_well: float = 4000.0              # electrons at the white level
    read_noise_dn: float = 2.0
    hot_fraction: float = 2e-5
    focused: bool = False                  # focused plenoptic (Raytrix)
    type_focus: tuple[float, ...] = (1.5, 3.3, 7.3)   # focused: virtual depth each lens type images sharply
    texel_px: float = 4.0                  # focused: sensor px per scene-texture unit in the virtual image
    make: str = "Lytro"
    model: str = "ILLUM"
    serial: str = "B5143909630"
    pixel_pitch_m: float = 1.4e-6
    lens_pitch_m: float = 2.0e-5
    mla_gap_m: float = 3.9e-5
    zoom_step: float | None = None
    focus_step: float | None = None
    focal_length_m: float | None = None
    f_number: float | None = None
    exposure_s: float = 1.0 / 125.0
    iso: float = 100.0
    wb_gains: tuple[float, float, float, float] | None = None    # (r, gr, gb, b)
    ccm: tuple[tuple[float, float, float], ...] | None = None   # camera RGB -> linear sRGB, rows sum to 1

    @property
    def mono(self) -> bool:
        """True for a sensor without a colour filter array."""
        return self.cfa is None

    def camera_matrix(self) -> np.ndarray:
        """``M = diag(1 / wb) @ inv(ccm)``: linear sRGB -> camera RGB, (3, 3) float64 (identity if mono)."""
        if self.ccm is None or self.wb_gains is None:
            return np.eye(3)
        r, gr, gb, b = self.wb_gains
        return np.diag([1.0 / r, 2.0 / (gr + gb), 1.0 / b]) @ np.linalg.inv(np.asarray(self.ccm, np.float64))


_ILLUM_CCM = ((1.6182, -0.5113, -0.1069), (-0.2261, 1.4870, -0.2609), (0.0452, -0.6216, 1.5764))
_F01_CCM = ((1.7013, -0.5646, -0.1367), (-0.2994, 1.5633, -0.2639), (-0.0139, -0.6742, 1.6881))

_ILLUM = Preset(
    name="illum", sensor_shape=(5368, 7728), pitch_px=2.0e-5 / 1.4e-6, rotation=6e-4, offset=(0.37, -0.21),
    cfa="GRBG", bits=10, black=64.0, white=1023.0, make="Lytro", model="ILLUM", serial="B5143909630",
    pixel_pitch_m=1.4e-6, lens_pitch_m=2.0e-5, mla_gap_m=3.9e-5, zoom_step=-312.0, focus_step=417.0,
    focal_length_m=0.0301, f_number=2.0, exposure_s=1.0 / 125.0, iso=200.0,
    wb_gains=(1.379, 1.0, 1.0, 1.148), ccm=_ILLUM_CCM)

_F01 = Preset(
    name="f01", sensor_shape=(3280, 3280), pitch_px=1.38986e-5 / 1.4e-6, rotation=0.00193, offset=(0.4, -1.94),
    cfa="BGGR", bits=12, black=168.0, white=4095.0, make="Lytro", model="F01", serial="A000424242",
    pixel_pitch_m=1.4e-6, lens_pitch_m=1.38986e-5, mla_gap_m=2.5e-5, zoom_step=981.0, focus_step=582.0,
    focal_length_m=0.00645, f_number=2.0, exposure_s=1.0 / 60.0, iso=100.0,
    wb_gains=(1.0, 1.117, 1.117, 1.723), ccm=_F01_CCM)

#: Simulated cameras by name.  ``pitch``, ``rotation``, ``offset`` and ``shape`` can be
#: overridden per call.
PRESETS: dict[str, Preset] = {
    "illum": _ILLUM,
    "illum-mini": replace(_ILLUM, name="illum-mini", sensor_shape=(1072, 1544)),
    "f01": _F01,
    "f01-mini": replace(_F01, name="f01-mini", sensor_shape=(656, 656)),
    "square": Preset(
        name="square", sensor_shape=(1100, 1100), pitch_px=27.5, lattice="square", rotation=0.0015,
        offset=(0.23, -0.31), cfa=None, bits=12, black=100.0, white=4095.0, radius_frac=0.47,
        make="plenodecode", model="LFM-synthetic", serial="LFM-0001", pixel_pitch_m=4.55e-6,
        lens_pitch_m=1.25e-4, mla_gap_m=2.5e-3, focal_length_m=None, f_number=None,
        exposure_s=0.05, iso=None, full_well=8000.0),
    "raytrix": Preset(
        name="raytrix", sensor_shape=(700, 1000), pitch_px=34.86, lattice="hex", rotation=0.0008,
        offset=(0.31, 0.12), cfa=None, bits=12, black=0.0, white=4095.0, radius_frac=0.47, focused=True,
        make="Raytrix", model="R42-synthetic", serial="RX-0042", pixel_pitch_m=5.5e-6,
        lens_pitch_m=34.86 * 5.5e-6, mla_gap_m=2.0e-4, focal_length_m=0.035, f_number=2.4,
        exposure_s=0.01, iso=None, full_well=10000.0),
}


def get_preset(preset: str | Preset) -> Preset:
    """Look up a preset by name (ValueError listing the names) or pass a Preset through."""
    if isinstance(preset, Preset):
        return preset
    try:
        return PRESETS[preset]
    except (KeyError, TypeError):
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}") from None


# ---------------------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------------------
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
    from ._focused import lens_types_at

    i, j = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
    return lens_types_at(grid, i, j).astype(np.int8)


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


def disk_profile(r: np.ndarray, radius: float, *, edge_px: float = 1.5, falloff: float = 0.12) -> np.ndarray:
    """Lenslet disk response at distance ``r`` (px) from the lens centre.

    ``(1 - falloff * (r / radius)^2)`` inside, times a raised-cosine edge that falls from 1
    at ``radius - edge_px / 2`` to 0 at ``radius + edge_px / 2``.

    Returns
    -------
    ndarray, same shape as r, float64, in [0, 1]
    """
    r = np.asarray(r, np.float64)
    t = np.clip((r - (radius - edge_px / 2.0)) / edge_px, 0.0, 1.0)
    edge = 0.5 * (1.0 + np.cos(np.pi * t))
    return np.maximum(1.0 - falloff * (r / radius) ** 2, 0.0) * edge


def disk_response(oa: np.ndarray, ob: np.ndarray, radius: float, *, edge_px: float = 1.5,
                  falloff: float = 0.12) -> np.ndarray:
    """Disk response averaged over the 1 x 1 px box centred at lattice offset ``(oa, ob)``.

    The 2 x 2 Gauss-Legendre rule of :data:`SUBSAMPLES`, the same rule as the radiance, so the
    white image and the ground-truth ``weight`` agree exactly.

    Returns
    -------
    ndarray, same shape as oa, float64
    """
    acc = np.zeros(np.broadcast(oa, ob).shape)
    for da in SUBSAMPLES:
        for db in SUBSAMPLES:
            acc += disk_profile(np.hypot(oa + da, ob + db), radius, edge_px=edge_px, falloff=falloff)
    return acc / SUBSAMPLES.size ** 2


def vignetting(rows: np.ndarray, cols: np.ndarray, sensor_shape: tuple[int, int], corner: float,
               nominal_shape: tuple[int, int] | None = None) -> np.ndarray:
    """Main-lens ``cos^4`` falloff ``1 / (1 + (rho / f)^2)^2`` about the sensor centre.

    ``f`` is set so the corners of ``nominal_shape`` (the preset's sensor; default
    ``sensor_shape``) get ``corner``: a smaller ``shape`` override crops the same optics.

    Returns
    -------
    ndarray, broadcast shape of rows and cols, float64
    """
    h, w = sensor_shape
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    nh, nw = nominal_shape if nominal_shape is not None else sensor_shape
    rho_c2 = ((nh - 1) / 2.0) ** 2 + ((nw - 1) / 2.0) ** 2
    if not 0.0 < corner <= 1.0:
        raise ValueError(f"vignette_corner must be in (0, 1], got {corner}")
    k = (1.0 / math.sqrt(corner) - 1.0) / rho_c2       # (rho/f)^2 = k * rho^2
    rho2 = (np.asarray(rows, np.float64) - cy) ** 2 + (np.asarray(cols, np.float64) - cx) ** 2
    return 1.0 / (1.0 + k * rho2) ** 2


# ---------------------------------------------------------------------------------------
# sensor: signal -> DN
# ---------------------------------------------------------------------------------------
def _levels(p: Preset) -> tuple[np.ndarray, np.ndarray]:
    return np.full((2, 2), p.black), np.full((2, 2), p.white)


def _to_dn(signal: np.ndarray, p: Preset, rng: np.random.Generator | None) -> np.ndarray:
    """Signal (fraction of the black..white range, float) -> uint16 DN with noise.

    Shot noise on ``signal * full_well`` electrons plus Gaussian read noise (DN), then
    rounding and clipping to ``[0, 2^bits - 1]``.  Shot noise is drawn from the Poisson law
    below :data:`POISSON_EXACT_BELOW` electrons and from its normal approximation (same mean
    and variance) above, where the two are indistinguishable at DN resolution.
    ``rng=None``: noise-free.
    """
    span = p.white - p.black
    if rng is not None:
        lam = np.clip(signal, 0.0, None) * p.full_well
        z = rng.standard_normal(lam.shape, dtype=np.float32)
        electrons = lam + np.sqrt(lam) * z
        small = lam < POISSON_EXACT_BELOW
        electrons[small] = rng.poisson(lam[small])
        dn = p.black + electrons * (span / p.full_well) + rng.normal(0.0, p.read_noise_dn, signal.shape)
    else:
        dn = p.black + signal * span
    top = float(2 ** p.bits - 1)
    return np.clip(np.rint(dn), 0.0, top).astype(np.uint16)


def _hot_pixels(p: Preset, shape: tuple[int, int], rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices and DN of the hot pixels (``hot_fraction`` of the sensor)."""
    n = int(round(p.hot_fraction * shape[0] * shape[1]))
    idx = np.unique(rng.integers(0, shape[0] * shape[1], n))
    span = p.white - p.black
    val = np.rint(p.black + span * rng.uniform(0.3, 1.0, idx.size))
    return idx, np.clip(val, 0, 2 ** p.bits - 1).astype(np.uint16)


def _vignette_k(p: Preset) -> float:
    """``k`` of ``vignetting = 1 / (1 + k * rho^2)^2`` (see :func:`vignetting`)."""
    nh, nw = p.sensor_shape
    return (1.0 / math.sqrt(p.vignette_corner) - 1.0) / (((nh - 1) / 2.0) ** 2 + ((nw - 1) / 2.0) ** 2)


def _empty_textures():
    """A tiny placeholder scene: the kernel's texture arguments when rendering a white image."""
    from ._scene import Plane, Scene, build_textures

    return build_textures(Scene((Plane(0.0, colour=(1.0, 1.0, 1.0)),)), 2, 2, mono=True, cam_matrix=np.eye(3))


def _render_sensor(grid: LensletGrid, p: Preset, textures, rng: np.random.Generator | None,
                   progress: Progress = None, gain: np.ndarray | None = None) -> np.ndarray:
    """Render the whole mosaic band by band (compiled kernel ``_scene._sensor_band``).

    ``textures`` (a ``_scene.Textures``) gives the scene in camera RGB; None renders the
    white image (radiance 1 in every channel).  ``gain`` (H, W), if given, multiplies the
    signal (the focused model passes its per-pixel radiance this way).
    """
    from ._scene import SUPPORT_EDGE, _sensor_band

    h, w = grid.sensor_shape
    out = np.empty((h, w), np.uint16)
    smp = grid.decoded_sampling()
    tex = _empty_textures() if textures is None else textures
    chmap = cfa_channel_map(p.cfa).astype(np.int64)
    if textures is not None and tex.camera.shape[1] == 1:
        chmap = np.zeros((2, 2), np.int64)
    n_bands = (h + BAND_ROWS - 1) // BAND_ROWS
    for k in range(n_bands):
        r0, r1 = k * BAND_ROWS, min(h, (k + 1) * BAND_ROWS)
        sig = np.empty((r1 - r0, w))
        _sensor_band(r0, sig, grid.origin[0], grid.origin[1], math.cos(grid.rotation), math.sin(grid.rotation),
                     grid.pitch, grid.row_spacing, grid.odd_row_shift, grid.lattice == "hex",
                     smp["a0"], smp["b0"], smp["step"], grid.radius, p.edge_px, p.disk_falloff, SUBSAMPLES,
                     (h - 1) / 2.0, (w - 1) / 2.0, _vignette_k(p), p.exposure, chmap,
                     textures is not None, tex.camera, tex.y0, tex.x0, tex.scale, tex.d0, tex.gy, tex.gx,
                     tex.kind, tex.prm, SUPPORT_EDGE)
        if gain is not None:
            sig *= gain[r0:r1]
        out[r0:r1] = _to_dn(sig, p, rng)
        if progress is not None:
            progress(k + 1, n_bands)
    if rng is not None:
        idx, val = _hot_pixels(p, (h, w), rng)
        out.reshape(-1)[idx] = val
    return out


def _metadata(p: Preset, grid: LensletGrid, *, white: bool, seed: int, offset: tuple[float, float]) -> CameraMetadata:
    wb = None
    if p.wb_gains is not None:
        gains = (1.0, 1.0, 1.0, 1.0) if white else p.wb_gains
        wb = dict(zip(("r", "gr", "gb", "b"), (float(g) for g in gains)))
    return CameraMetadata(
        make=p.make, model=p.model, serial=p.serial, zoom_step=p.zoom_step, focus_step=p.focus_step,
        exposure_s=p.exposure_s, iso=p.iso, wb_gains=wb, ccm=p.ccm,
        pixel_pitch_m=p.pixel_pitch_m, lens_pitch_m=grid.pitch * p.pixel_pitch_m, mla_rotation=grid.rotation,
        mla_offset_m=(offset[1] * p.pixel_pitch_m, offset[0] * p.pixel_pitch_m, p.mla_gap_m),
        mla_scale=(1.0, 1.0), focal_length_m=p.focal_length_m, f_number=p.f_number, is_white_image=white,
        extra={"synthetic": {"preset": p.name, "seed": int(seed), "generator": "plenodecode.io.synthetic"}},
    )


def _resolve(preset: str | Preset, pitch, rotation, offset, shape) -> tuple[Preset, LensletGrid, tuple[float, float]]:
    p = get_preset(preset)
    off = tuple(float(v) for v in (p.offset if offset is None else offset))
    grid = make_grid(p, pitch=pitch, rotation=rotation, offset=off, shape=shape)
    return p, grid, off  # type: ignore[return-value]


def _rngs(seed: int) -> dict[str, np.random.Generator]:
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    names = ("scene", "raw", "white")
    return {n: np.random.default_rng(s) for n, s in zip(names, np.random.SeedSequence(int(seed)).spawn(len(names)))}


def simulate_white(preset: str | Preset, *, seed: int = 0, pitch: float | None = None,
                   rotation: float | None = None, offset: tuple[float, float] | None = None,
                   noise: bool = True, shape: tuple[int, int] | None = None,
                   progress: Progress = None) -> tuple[RawCapture, LensletGrid]:
    """A white (flat-field) image of a preset camera and its true lenslet grid.

    Each pixel is ``black + (white - black) * exposure * vignetting(q) * D(o)`` plus noise,
    where ``D`` is the box-averaged disk response (:func:`disk_response`) at the pixel's
    lattice offset ``o`` from its nearest lens, the same in every CFA channel.

    Parameters
    ----------
    preset : str or Preset
        A key of :data:`PRESETS`.
    seed : int
        Seed of the noise (``np.random.SeedSequence(seed)``); same seed, same image.
    pitch, rotation, offset : optional
        Override the preset's lens pitch (px), grid rotation (rad) and lattice anchor
        shift from the sensor centre ((row, col) px).
    noise : bool
        False: no shot/read noise and no hot pixels (values only rounded).
    shape : (H, W), optional
        Override the sensor size.
    progress : callable(done, total), optional
        Called after each band of rows.

    Returns
    -------
    white : RawCapture
        ``mosaic`` (H, W) uint16, ``metadata.is_white_image`` True, WB gains 1.
    grid : LensletGrid
        The true grid (see :func:`make_grid`).
    """
    p, grid, off = _resolve(preset, pitch, rotation, offset, shape)
    rng = _rngs(seed)["white"] if noise else None
    mosaic = _render_sensor(grid, p, None, rng, progress)
    black, white = _levels(p)
    raw = RawCapture(mosaic=mosaic, cfa=p.cfa, black=black, white=white,
                     metadata=_metadata(p, grid, white=True, seed=seed, offset=off))
    return raw, grid


# ---------------------------------------------------------------------------------------
# scene raws
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Simulation:
    """A synthetic capture and its exact ground truth.

    Attributes
    ----------
    raw : RawCapture
        The scene raw.
    white : RawCapture
        The white image of the same camera (same exposure scale and noise model).
    grid : LensletGrid
        The true lenslet grid.
    disparity : ndarray (Y, X) float32
        Disparity of the centre view at the decoded sampling (px per view step, HCI convention).
    scene : Scene
        The scene description (planes).
    preset : Preset
    seed : int
    truth : dict
        Extra ground truth (focused presets: virtual depth, total-focus image, lens types).
    """

    raw: RawCapture
    white: RawCapture
    grid: LensletGrid
    disparity: np.ndarray
    scene: Any
    preset: Preset
    seed: int = 0
    noise: bool = True
    truth: Mapping[str, Any] = field(default_factory=dict)
    textures: Any = field(default=None, repr=False, compare=False)

    @property
    def disparity_range(self) -> tuple[float, float]:
        """``(min, max)`` disparity over the centre view."""
        d = self.disparity[np.isfinite(self.disparity)]
        return (float(d.min()), float(d.max())) if d.size else (0.0, 0.0)

    def ground_truth_lightfield(self, n_views: int | None = None, *, progress: Progress = None) -> LightField:
        """The ideal decoded light field of the scene, from the continuous model (no lenses).

        ``LF[v, u, y, x, c]`` is the mean over the 1 x 1 px box in ``o`` centred at
        ``o = (v - vc, u - uc)`` (view steps = sensor px) of the linear-sRGB radiance
        ``L(o, y, x)`` (2 x 2 Gauss-Legendre rule, as the raw), for every decoded sample
        ``(y, x)`` of :meth:`LensletGrid.decoded_sampling`.  ``weight`` is the lenslet
        disk response at that ``o`` (what a real decoder sees there).

        Parameters
        ----------
        n_views : int, optional
            Odd number of views per axis; default ``grid.n_views()``.

        Returns
        -------
        LightField
            data (V, U, Y, X, C) float32, C = 3 (1 for monochrome presets), colour 'linear-srgb'.
            15 x 15 views of a full-size Illum is 1.8 GB: use the small presets.
        """
        if self.preset.focused:
            raise ValueError("ground_truth_lightfield is defined for unfocused presets; a focused (Raytrix) "
                             "simulation has truth['total_focus'] and truth['virtual_depth'] instead")
        from ._scene import box_radiance

        n = self.grid.n_views() if n_views is None else int(n_views)
        if n < 1 or n % 2 == 0:
            raise ValueError(f"n_views must be a positive odd number, got {n_views!r}")
        smp = self.grid.decoded_sampling()
        ny, nx = int(smp["Y"]), int(smp["X"])
        c = self.textures.srgb.shape[1]
        half = n // 2
        o = np.arange(n, dtype=np.float64) - half
        yy, xx = np.meshgrid(np.arange(ny, dtype=np.float64), np.arange(nx, dtype=np.float64), indexing="ij")
        data = np.empty((n, n, ny, nx, c), np.float32)
        for v in range(n):
            for ch in range(c):
                data[v, :, :, :, ch] = box_radiance(self.textures, yy[None], xx[None], o[v],
                                                    o[:, None, None], ch, space="srgb")
            if progress is not None:
                progress(v + 1, n)
        weight = disk_response(o[:, None], o[None, :], self.grid.radius, edge_px=self.preset.edge_px,
                               falloff=self.preset.disk_falloff).astype(np.float32)
        weight = np.ascontiguousarray(np.broadcast_to(weight[:, :, None, None], (n, n, ny, nx)))
        meta = {
            "source": "plenodecode.io.synthetic", "preset": self.preset.name, "seed": self.seed,
            "spatial_step_px": float(smp["step"]), "view_step_px": 1.0, "calibration": self.grid.to_dict(),
            "camera": self.raw.metadata.to_dict(), "disparity_range": list(self.disparity_range),
        }
        return LightField(data=data, weight=weight, colour="linear-srgb", metadata=meta)


def simulate(preset: str | Preset, *, seed: int = 0, pitch: float | None = None, rotation: float | None = None,
             offset: tuple[float, float] | None = None, noise: bool = True, scene=None,
             shape: tuple[int, int] | None = None, progress: Progress = None) -> Simulation:
    """Simulate a scene raw, its white image and the ground truth.

    The forward model of the module docstring (Ng et al. 2005): each pixel records the
    box-averaged camera-RGB radiance of its CFA channel along the rays ``(o, y, x)`` of its
    lenslet, times the disk response, the vignetting and the exposure; then noise.

    Parameters
    ----------
    preset : str or Preset
        A key of :data:`PRESETS`.
    seed : int
        Seeds the default scene's textures and the noise.
    pitch, rotation, offset, shape :
        Overrides, as in :func:`simulate_white`.
    noise : bool
        False: no shot/read noise, no hot pixels.
    scene : Scene, list of Plane or list of plane dicts, optional
        Planes in decoded coordinates (see :class:`plenodecode.io._scene.Plane`);
        default :func:`plenodecode.io._scene.default_scene` for the decoded size.
    progress : callable(done, total), optional

    Returns
    -------
    Simulation
    """
    from ._scene import as_scene, build_textures, default_scene, front_disparity

    p, grid, off = _resolve(preset, pitch, rotation, offset, shape)
    rngs = _rngs(seed)
    if p.focused:
        from ._focused import simulate_focused

        return simulate_focused(p, grid, off, seed=seed, rngs=rngs if noise else None, scene=scene,
                                metadata=lambda white: _metadata(p, grid, white=white, seed=seed, offset=off),
                                progress=progress)
    smp = grid.decoded_sampling()
    ny, nx = int(smp["Y"]), int(smp["X"])
    sc = default_scene(ny, nx, seed) if scene is None else as_scene(scene)
    tex = build_textures(sc, ny, nx, mono=p.mono, cam_matrix=p.camera_matrix())
    total = 2 * ((grid.sensor_shape[0] + BAND_ROWS - 1) // BAND_ROWS)
    half = total // 2

    def prog(offset_done: int):
        if progress is None:
            return None
        return lambda d, t: progress(offset_done + d, total)

    mosaic = _render_sensor(grid, p, tex, rngs["raw"] if noise else None, prog(0))
    white_mosaic = _render_sensor(grid, p, None, rngs["white"] if noise else None, prog(half))
    black, white = _levels(p)
    raw = RawCapture(mosaic=mosaic, cfa=p.cfa, black=black, white=white,
                     metadata=_metadata(p, grid, white=False, seed=seed, offset=off))
    wcap = RawCapture(mosaic=white_mosaic, cfa=p.cfa, black=black, white=white,
                      metadata=_metadata(p, grid, white=True, seed=seed, offset=off))
    yy, xx = np.meshgrid(np.arange(ny, dtype=np.float64), np.arange(nx, dtype=np.float64), indexing="ij")
    disp = front_disparity(tex, yy, xx)
    return Simulation(raw=raw, white=wcap, grid=grid, disparity=disp, scene=sc, preset=p, seed=int(seed),
                      noise=bool(noise), textures=tex)


# ---------------------------------------------------------------------------------------
# writing and reading back
# ---------------------------------------------------------------------------------------
TRUTH_FORMAT = "plenodecode.SyntheticTruth"
TRUTH_VERSION = 1
#: Presets whose truth npz holds the ground-truth light field by default (small sensors).
_SMALL_SENSOR_PX = 2_000_000


def simulation_files(preset: str | Preset, name: str = "scene") -> dict[str, str]:
    """File names :func:`write_simulation` writes for a preset: key -> name (sidecars included)."""
    p = get_preset(preset)
    if not name or any(c in name for c in "/\\") or name in (".", ".."):
        raise ValueError(f"name must be a plain file stem, got {name!r}")
    names = _raw_names(p, name)
    names.update({"truth_json": f"{name}.truth.json", "truth_npz": f"{name}.truth.npz"})
    return names


def _raw_names(p: Preset, name: str) -> dict[str, str]:
    if p.model == "ILLUM":
        return {"raw": f"{name}.lfr", "white": "MOD_0000.RAW", "white_txt": "MOD_0000.TXT"}
    if p.model == "F01":
        return {"raw": f"{name}.lfp", "white": "MOD_0000.RAW", "white_txt": "MOD_0000.TXT"}
    if p.focused:
        return {"raw": f"{name}.png", "raw_xml": f"{name}.xml", "raw_json": f"{name}.json",
                "white": f"{name}_white.png", "white_xml": f"{name}_white.xml", "white_json": f"{name}_white.json"}
    return {"raw": f"{name}.png", "raw_json": f"{name}.json", "white": f"{name}_white.png",
            "white_json": f"{name}_white.json"}


def truth_document(sim: Simulation, files: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The JSON ground-truth document of a simulation (see :func:`write_simulation`)."""
    smp = sim.grid.decoded_sampling()
    doc = {
        "format": TRUTH_FORMAT, "version": TRUTH_VERSION, "generator": "plenodecode.io.synthetic",
        "preset": sim.preset.name, "preset_params": json.loads(json.dumps(asdict(sim.preset))),
        "seed": sim.seed, "noise": sim.noise, "grid": sim.grid.to_dict(),
        "decoded_sampling": {k: (float(v) if k in ("step", "a0", "b0") else int(v)) for k, v in smp.items()},
        "scene": sim.scene.to_dict() if hasattr(sim.scene, "to_dict") else None,
        "disparity_range": list(sim.disparity_range),
        "disparity_convention": ("virtual-depth micro-image disparity D / v (px)" if sim.preset.focused else
                                 "HCI: view[v,u](y - d*(v-vc), x - d*(u-uc)) = centre(y, x); px per view step"),
        "camera": sim.raw.metadata.to_dict(), "files": dict(files or {}),
    }
    return doc


def write_simulation(sim: Simulation, out_dir: str | os.PathLike, *, name: str = "scene", overwrite: bool = False,
                     lightfield: bool | None = None) -> dict[str, Path]:
    """Write a simulation in its camera's real file format plus the ground truth.

    * illum / illum-mini: ``<name>.lfr`` (Illum LFR) and the white image ``MOD_0000.RAW`` + ``.TXT``;
    * f01 / f01-mini: ``<name>.lfp`` (F01 raw LFP) and ``MOD_0000.RAW`` + ``.TXT``;
    * square: ``<name>.png`` + ``<name>.json`` (16-bit mosaic + sidecar) and ``<name>_white.png`` + json;
    * raytrix: ``<name>.png`` + RayCalibData ``<name>.xml`` + ``<name>.json``, likewise the white;
    * ``<name>.truth.json``: grid, preset, seed, scene, disparity range, camera metadata;
    * ``<name>.truth.npz``: ``centres`` (N, 2) float64, ``disparity`` (Y, X) float32, for
      focused presets ``lens_type``, ``virtual_depth``, ``total_focus``..., and when
      ``lightfield`` (default: sensors up to 2 Mpx) ``lf_data`` / ``lf_weight``.

    Every file is written to a temporary name and renamed.  Nothing is replaced unless
    ``overwrite``: existing targets raise FileExistsError before anything is written.

    Returns
    -------
    dict
        Key (``raw``, ``white``, ``white_txt``, ``truth_json``, ``truth_npz``, ...) -> Path.
    """
    out = Path(out_dir)
    p = sim.preset
    paths = {k: out / v for k, v in simulation_files(p, name).items()}
    refuse_existing(paths.values(), overwrite)
    out.mkdir(parents=True, exist_ok=True)
    if p.model == "ILLUM" or p.model == "F01":
        from . import lytro

        (lytro.write_lfr if p.model == "ILLUM" else lytro.write_lfp)(paths["raw"], sim.raw, overwrite=overwrite)
        lytro.write_raw_pair(paths["white"], sim.white, overwrite=overwrite)
    elif p.focused:
        from .raytrix import write_raytrix

        write_raytrix(paths["raw"], sim.raw, sim.grid, overwrite=overwrite)
        write_raytrix(paths["white"], sim.white, sim.grid, overwrite=overwrite)
    else:
        from .generic import write_mosaic

        write_mosaic(paths["raw"], sim.raw, overwrite=overwrite)
        write_mosaic(paths["white"], sim.white, overwrite=overwrite)
    arrays: dict[str, np.ndarray] = {"centres": sim.grid.centres(), "disparity": sim.disparity}
    for key, val in sim.truth.items():
        if isinstance(val, np.ndarray):
            arrays[key] = val
    if lightfield is None:
        lightfield = not p.focused and sim.raw.shape[0] * sim.raw.shape[1] <= _SMALL_SENSOR_PX
    if lightfield:
        lf = sim.ground_truth_lightfield()
        arrays["lf_data"] = lf.data
        arrays["lf_weight"] = lf.weight
    with atomic_output(paths["truth_npz"], overwrite=overwrite) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
    doc = truth_document(sim, {k: v.name for k, v in paths.items()})
    doc["npz_arrays"] = sorted(arrays)
    write_text_atomic(paths["truth_json"], json.dumps(doc, indent=1), overwrite=overwrite)
    log.info("wrote synthetic %s capture to %s", p.name, out)
    return paths


@dataclass(frozen=True)
class Truth:
    """Ground truth read back by :func:`load_truth`.

    Attributes
    ----------
    grid : LensletGrid
    preset : str
    seed : int
    scene : Scene or None
    centres : ndarray (N, 2) float64
    disparity : ndarray (Y, X) float32
    disparity_range : (float, float)
    lightfield : LightField or None
        When the npz holds it.
    arrays : dict
        Every array of the npz (focused presets: ``lens_type``, ``virtual_depth``, ``total_focus``...).
    document : dict
        The whole truth JSON.
    """

    grid: LensletGrid
    preset: str
    seed: int
    scene: Any
    centres: np.ndarray
    disparity: np.ndarray
    disparity_range: tuple[float, float]
    lightfield: LightField | None
    arrays: Mapping[str, np.ndarray]
    document: Mapping[str, Any]


def load_truth(path: str | os.PathLike) -> Truth:
    """Read ``<name>.truth.json`` and its ``.truth.npz`` (either path, or a folder holding one).

    Raises
    ------
    FormatError
        Missing files, or not a plenodecode synthetic-truth document.
    """
    from ._scene import Scene

    p = Path(path)
    if p.is_dir():
        found = sorted(p.glob("*.truth.json"))
        if len(found) != 1:
            raise FormatError(f"{p}: expected exactly one *.truth.json, found {len(found)}; pass the file itself")
        p = found[0]
    if p.name.endswith(".truth.npz"):
        p = p.with_name(p.name[: -len(".npz")] + ".json")
    if not p.is_file():
        raise FormatError(f"{p}: no such ground-truth file; pass the .truth.json written by write_simulation")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FormatError(f"{p}: not readable JSON ({exc}); pass a .truth.json written by write_simulation") from exc
    if not isinstance(doc, dict) or doc.get("format") != TRUTH_FORMAT:
        raise FormatError(f"{p}: format is {doc.get('format') if isinstance(doc, dict) else None!r}, expected "
                          f"{TRUTH_FORMAT!r}; pass a .truth.json written by write_simulation")
    if int(doc.get("version", 0)) > TRUTH_VERSION:
        raise FormatError(f"{p}: truth version {doc.get('version')} is newer than {TRUTH_VERSION}; upgrade plenodecode")
    npz = p.with_name(p.name[: -len(".json")] + ".npz")
    if not npz.is_file():
        raise FormatError(f"{npz}: missing; the .truth.json and .truth.npz must stay together")
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    grid = LensletGrid.from_dict(doc["grid"])
    lf = None
    if "lf_data" in arrays:
        smp = doc.get("decoded_sampling", {})
        lf = LightField(data=arrays["lf_data"], weight=arrays.get("lf_weight"), colour="linear-srgb",
                        metadata={"source": str(p), "preset": doc.get("preset"), "seed": doc.get("seed"),
                                  "spatial_step_px": smp.get("step"), "view_step_px": 1.0,
                                  "calibration": doc["grid"], "disparity_range": doc.get("disparity_range"),
                                  "camera": doc.get("camera")})
    scene = Scene.from_dict(doc["scene"]) if doc.get("scene") else None
    dr = doc.get("disparity_range") or (0.0, 0.0)
    return Truth(grid=grid, preset=str(doc.get("preset")), seed=int(doc.get("seed", 0)), scene=scene,
                 centres=arrays["centres"], disparity=arrays["disparity"],
                 disparity_range=(float(dr[0]), float(dr[1])), lightfield=lf, arrays=arrays, document=doc)


__all__ = ["Preset", "PRESETS", "get_preset", "make_grid", "raytrix_lens_types", "assign_pixels", "disk_profile",
           "disk_response", "vignetting", "simulate_white", "Simulation", "simulate", "write_simulation",
           "simulation_files",
           "truth_document", "Truth", "load_truth", "SUBSAMPLES", "BAND_ROWS"]
