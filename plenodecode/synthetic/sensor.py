"""The sensor model of the synthetic generator: what a pixel records, and how it becomes a DN.

A pixel at lattice offset ``o`` from its lens centre (:func:`~plenodecode.synthetic.lattice.assign_pixels`)
records ``exposure * vignetting(q) * D(o)`` times the radiance of its CFA channel, as a fraction
of the black..white range: ``D`` is the lenslet disk response averaged over the pixel's box
(:func:`disk_response`), ``vignetting`` the main lens's ``cos^4`` falloff (:func:`vignetting`).
Then Poisson-Gaussian noise (full well, read noise), hot pixels, rounding and clipping
(:func:`render_sensor`, band by band in the compiled kernel
:func:`~plenodecode.synthetic.kernels.sensor_band_kernel`).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..types import LensletGrid, cfa_channel_map
from .kernels import SUBSAMPLES, sensor_band_kernel
from .presets import Preset
from .scene import Plane, Scene, Textures, build_textures

#: Progress callback ``progress(done, total)``, or None.
Progress = Callable[[int, int], None] | None

#: Rows processed at a time (bounds memory on full-size sensors).  Part of the RNG
#: contract: the noise of a given seed depends on it.
BAND_ROWS = 256
#: Shot noise is drawn exactly (Poisson) below this many electrons, normal above.
POISSON_EXACT_BELOW = 100.0


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


def levels(p: Preset) -> tuple[np.ndarray, np.ndarray]:
    """Black and white levels of a preset's raws: two (2, 2) float64 arrays, one value per CFA site."""
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
    return build_textures(Scene((Plane(0.0, colour=(1.0, 1.0, 1.0)),)), 2, 2, mono=True, cam_matrix=np.eye(3))


def render_sensor(grid: LensletGrid, p: Preset, textures: Textures | None, rng: np.random.Generator | None,
                  progress: Progress = None, gain: np.ndarray | None = None) -> np.ndarray:
    """Render the whole mosaic band by band (:data:`BAND_ROWS` rows per call of the compiled kernel).

    Parameters
    ----------
    grid : LensletGrid
        The true lattice; its ``sensor_shape`` (H, W) is the mosaic's.
    p : Preset
        Levels, bits, disk edge and falloff, vignetting, exposure and noise of the camera.
    textures : Textures or None
        The scene in camera RGB; None renders the white image (radiance 1 in every channel).
    rng : numpy.random.Generator or None
        Noise source (shot and read noise, hot pixels); None: noise-free, values only rounded.
    progress : callable(done, total), optional
        Called after each band.
    gain : ndarray (H, W) float64, optional
        Multiplies the signal (the focused model passes its per-pixel radiance this way).

    Returns
    -------
    ndarray (H, W) uint16
        ``black + (white - black) * signal`` with noise, rounded and clipped to ``[0, 2^bits - 1]``.
    """
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
        sensor_band_kernel(r0, sig, grid.origin[0], grid.origin[1], math.cos(grid.rotation), math.sin(grid.rotation),
                           grid.pitch, grid.row_spacing, grid.odd_row_shift, grid.lattice == "hex",
                           smp["a0"], smp["b0"], smp["step"], grid.radius, p.edge_px, p.disk_falloff, SUBSAMPLES,
                           (h - 1) / 2.0, (w - 1) / 2.0, _vignette_k(p), p.exposure, chmap,
                           textures is not None, tex.camera, tex.y0, tex.x0, tex.scale, tex.d0, tex.gy, tex.gx,
                           tex.kind, tex.prm, tex.rim)
        if gain is not None:
            sig *= gain[r0:r1]
        out[r0:r1] = _to_dn(sig, p, rng)
        if progress is not None:
            progress(k + 1, n_bands)
    if rng is not None:
        idx, val = _hot_pixels(p, (h, w), rng)
        out.reshape(-1)[idx] = val
    return out


__all__ = ["Progress", "BAND_ROWS", "POISSON_EXACT_BELOW", "disk_profile", "disk_response", "vignetting", "levels",
           "render_sensor"]
