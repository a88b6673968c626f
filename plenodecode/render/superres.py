"""Refocused photographs above the lenslet resolution: the views' samples fused onto a finer grid.

For a surface at disparity ``d``, pixel ``(y, x)`` of view ``(v, u)`` sees the point that the photograph refocused
at slope ``s = d`` shows at ``P = (y + s a, x + s b)``, ``a = v - vc``, ``b = u - uc`` (design.md).  The views are
copies of one image sampled on integer grids shifted by ``s (a, b)``: together they sample it at the sub-pixel
phases ``frac(s a)`` along y and ``frac(s b)`` along x, finer than one lenslet.  :func:`fuse_views` places every
sample at its true position ``P`` and reconstructs the photograph on the ``k``-times finer grid by normalised
convolution (Knutsson & Westin, "Normalized and differential convolution", CVPR 1993)::

    F(q) = sum_n K_h(q - P_n) c_n L_n / sum_n K_h(q - P_n) c_n,      K_h(t) = k(t_y / h) k(t_x / h)

with ``q = (j / k, i / k)`` the output sample ``(j, i)``, ``c_n = m_vu w_vu(y, x)`` the aperture mask times the
decoder's weight (1 without one) and ``k`` Keys' cubic kernel (Keys, IEEE TASSP 1981, eq. (15)) with OpenCV's
``a = -0.75``.  The kernel's scale ``h`` (lenslet pixels) is the largest gap between the sample phases of the
views in use, bounded to ``[1 / k, 1]``: at ``h = 1`` (slope 0, where every view samples the same points) the
result is the mean of the views interpolated by that kernel, i.e. OpenCV's bicubic upsampling of the 1x
photograph (``a = -0.75`` is sharper than -0.5 on the generator's detailed scenes, 43.0 against 42.1 dB); when the phases fill the pixel
(``|s|`` of a few tenths of a pixel per view or more) ``h = 1 / k`` and each output sample is made from the views
that sampled the scene next to it, so detail that a single view aliases comes back.  ``K_h`` is separable and its
y factor depends only on ``v``, its x factor only on ``u``, so the sums are the compiled shift-and-add of
:mod:`plenodecode.render.shiftsum` with these taps, once per output phase ``(j mod k, i mod k)``.

Only surfaces near the refocus slope gain.  Away from it each output phase averages a different subset of views,
and their disagreement would show as a pattern of period ``k`` in the blur.  So the fused detail is kept only where
the views agree with it (:func:`in_focus_gain`, photo-consistency)::

    out = B + g (F - B),     B = Keys upsampling of the 1x photograph,  g in [0, 1]

``g`` compares how well the fused photograph ``F`` and the 1x photograph predict every view's samples at their
own positions: 1 where ``F`` explains them much better (in focus, detail the views alias), 0 where neither does
(out of focus: the views disagree by their parallax).  A linear fix cannot do this: giving every phase the same
views with the same weight is interpolating each view (``shift_sum(upsample=k)``), which loses most of the gain.
The gain over bicubic upsampling and the pattern's energy, measured against exact ground truth, are in
``bench/bench_superres.py`` and the README (refocus section).
"""

from __future__ import annotations

import logging
from typing import Callable

import cv2
import numpy as np

from ..types import LightField
from ._common import aperture_mask, check_lightfield, check_slopes, check_upsample
from .shiftsum import shift_sum, sum_shifted_views

log = logging.getLogger(__name__)

#: Views whose mean weight (aperture mask times decoder weight) is below this fraction of the largest one do not
#: count when the sample phases are gathered (their samples are still fused with their weight).
_VIEW_FLOOR = 0.05
#: Largest phase gap (lenslet px) below which fusion resolves finer than bicubic upsampling at ``k = 2``.
_GAIN_GAP = 0.75
#: Keys' free parameter of the fusion kernel: OpenCV's (and Photoshop's) bicubic value, so that where the views
#: sample the same points (h = 1) the result is OpenCV's bicubic upsampling of the 1x photograph.
KEYS_A = -0.75
#: Gaussian window (lenslet px) over which the views' agreement with a photograph is averaged.
_CONSISTENCY_SIGMA = 1.0
#: Residual ratio ``R_F / R_B`` below which the fused detail is kept whole, above which it is dropped.
_RHO = (0.5, 0.85)


def _keys(t: np.ndarray, a: float = KEYS_A) -> np.ndarray:
    """Keys' cubic convolution kernel with free parameter ``a`` at ``t`` (float64), 0 for ``|t| >= 2``:
    ``(a + 2) s^3 - (a + 3) s^2 + 1`` for ``s = |t| <= 1``, ``a s^3 - 5 a s^2 + 8 a s - 4 a`` for ``1 < s < 2``."""
    s = np.abs(t)
    inner = (a + 2) * s**3 - (a + 3) * s**2 + 1
    outer = a * s**3 - 5 * a * s**2 + 8 * a * s - 4 * a
    return np.where(s <= 1, inner, np.where(s < 2, outer, 0.0))


def scaled_keys_taps(t: np.ndarray, h: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Four taps of Keys' kernel stretched to ``h`` (``0 < h <= 1``) for a sample at ``x + t``.

    Tap ``r`` (0..3) reads ``x + first + r`` with weight ``k((t - first - r) / h)``; the kernel's support
    ``|t| < 2 h <= 2`` lies inside them.  The weights sum to 1 only when ``h = 1`` (interpolation by Keys' kernel
    with ``a =`` :data:`KEYS_A`).

    Parameters
    ----------
    t : ndarray (...) float64
    h : float or ndarray broadcastable to ``t``

    Returns
    -------
    first : ndarray (...) int64
    weights : ndarray (..., 4) float32
    """
    t = np.asarray(t, np.float64)
    first = np.floor(t) - 1
    dist = t[..., None] - (first[..., None] + np.arange(4))
    w = _keys(dist / np.asarray(h, np.float64)[..., None])
    return first.astype(np.int64), w.astype(np.float32)


def phase_gap(offsets: np.ndarray) -> float:
    """Largest gap between the sub-pixel phases ``frac(offsets)`` on the unit circle (1 for a single phase).

    Parameters
    ----------
    offsets : ndarray (N,) float64
        Sample offsets in lenslet pixels (``s a`` of the views in use).
    """
    ph = np.unique(np.round(np.mod(np.asarray(offsets, np.float64), 1.0), 6) % 1.0)
    if ph.size < 2:
        return 1.0
    gaps = np.diff(np.concatenate([ph, [ph[0] + 1.0]]))
    return float(gaps.max())


def _view_use(lf: LightField, vmask: np.ndarray) -> np.ndarray:
    """Views (V, U) bool whose mean weight counts when the phases are gathered."""
    w = vmask.astype(np.float64)
    if lf.weight is not None:
        w = w * lf.weight.mean(axis=(2, 3), dtype=np.float64)
    return w > _VIEW_FLOOR * w.max()


def kernel_scales(lf: LightField, slopes: np.ndarray, k: int, aperture: float | np.ndarray = 1.0) -> np.ndarray:
    """Scale ``h`` (S, 2) of the fusion kernel along y and x for each slope (see the module docstring)."""
    vmask = aperture_mask(lf.shape[:2], aperture)
    use = _view_use(lf, vmask)
    vc, uc = lf.centre_index
    a = np.flatnonzero(use.any(axis=1)) - vc
    b = np.flatnonzero(use.any(axis=0)) - uc
    h = [[phase_gap(s * a), phase_gap(s * b)] for s in slopes]
    return np.clip(np.asarray(h, np.float64), 1.0 / k, 1.0)


def _unweighted_taps(vmask: np.ndarray, wy: np.ndarray, wx: np.ndarray, view_weight: np.ndarray) -> np.ndarray:
    """``wx`` scaled so that the kernel's ``1 / sum(m)`` normalises an unweighted sum: the denominator
    ``D_s = sum_vu m_vu W_vu Sy_sv Sx_su`` (``S`` the tap sums, ``W`` a weight per view) does not depend on the
    pixel (edges are replicated), so it is folded into the x taps as ``sum(m) / D_s``."""
    den = np.einsum("vu,sv,su->s", vmask * view_weight, wy.sum(-1, dtype=np.float64), wx.sum(-1, dtype=np.float64))
    return (wx * (float(vmask.sum()) / den)[:, None, None]).astype(np.float32)


def _fuse_phase(lf: LightField, vmask: np.ndarray, taps_y: tuple[np.ndarray, np.ndarray],
                taps_x: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """One output phase of :func:`fuse_views`: (S, Y, X, C) float32.

    With a weight, Keys' negative lobes can make the per-pixel denominator ``sum K m w`` small where the weights
    vary from pixel to pixel (missing samples); where it is below a quarter of its value for each view's mean
    weight, the photograph fused without the weight is used there.
    """
    (by, wy), (bx, wx) = taps_y, taps_x
    if lf.weight is None:
        return sum_shifted_views(lf, vmask, (by, wy), (bx, _unweighted_taps(vmask, wy, wx, np.ones_like(vmask))))
    fused = sum_shifted_views(lf, vmask, (by, wy), (bx, wx))
    weight = LightField(np.ascontiguousarray(lf.weight[..., None], np.float32))
    view_weight = lf.weight.mean(axis=(2, 3), dtype=np.float64)
    # sum K m w / sum K m W (W the view's mean weight): 1 where the weight is constant in each view
    relative = sum_shifted_views(weight, vmask, (by, wy), (bx, _unweighted_taps(vmask, wy, wx, view_weight)))
    bad = relative[..., 0] < 0.25
    if bad.any():
        log.debug("upsample: %d output samples with a small weight sum fused without the weight", int(bad.sum()))
        plain = _fuse_phase(lf.replace(weight=None), vmask, taps_y, taps_x)
        fused[bad] = plain[bad]
    return fused


def _resample_rows(img: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """``img`` (N, ...) sampled at the rows ``positions`` (M,) float64 by Keys' kernel (:data:`KEYS_A`), rows
    outside taking the edge value: (M, ...) float32."""
    first, w = scaled_keys_taps(positions, 1.0)
    out = np.zeros((len(positions),) + img.shape[1:], np.float32)
    for r in range(4):
        rows = np.clip(first + r, 0, img.shape[0] - 1)
        out += w[:, r].reshape((-1,) + (1,) * (img.ndim - 1)) * img[rows]
    return out


def keys_upsample(img: np.ndarray, k: int) -> np.ndarray:
    """Keys (OpenCV bicubic, ``a =`` :data:`KEYS_A`) interpolation of ``img`` (Y, X, C) at ``(j / k, i / k)``,
    edges replicated: (k Y, k X, C) float32."""
    ny, nx = img.shape[:2]
    rows = _resample_rows(np.asarray(img, np.float32), np.arange(k * ny) / k)
    return _resample_rows(rows.swapaxes(0, 1), np.arange(k * nx) / k).swapaxes(0, 1)


def _view_residuals(lf: LightField, s: float, images: list[tuple[np.ndarray, int]]) -> np.ndarray:
    """Squared differences between every view and each image sampled at the view's positions.

    ``r[v, u, y, x, n] = sum_c (L_vu(y, x, c) - I_n(k_n (y + s a), k_n (x + s b), c))^2`` with ``I_n`` sampled by
    Keys' kernel on its grid of ``k_n`` samples per lenslet pixel.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C).
    s : float
        Refocus slope.
    images : list of (ndarray (k Y, k X, C) float32, int k)

    Returns
    -------
    ndarray, shape (V, U, Y, X, len(images)), float32
    """
    nv, nu, ny, nx, _ = lf.shape
    vc, uc = lf.centre_index
    out = np.empty((nv, nu, ny, nx, len(images)), np.float32)
    for n, (img, k) in enumerate(images):
        for v in range(nv):
            rows = _resample_rows(img, k * (np.arange(ny) + s * (v - vc)))                 # (Y, k X, C)
            for u in range(nu):
                pred = _resample_rows(rows.swapaxes(0, 1), k * (np.arange(nx) + s * (u - uc))).swapaxes(0, 1)
                out[v, u, ..., n] = np.square(lf.data[v, u] - pred).sum(axis=-1)
    return out


def in_focus_gain(lf: LightField, s: float, fused: np.ndarray, photo: np.ndarray, vmask: np.ndarray) -> np.ndarray:
    """Where the fused detail is real: 1 where the views agree with the fused photograph much better than with the
    1x photograph, 0 where both explain them equally (out of focus), on the 1x grid.

    Every view's sample is compared with both photographs at its own position ``P = (y + s a, x + s b)``
    (:func:`_view_residuals`); the squared residuals are gathered at ``P`` like a refocused photograph (weighted
    by ``m w``, bilinear) and averaged over a Gaussian window of :data:`_CONSISTENCY_SIGMA` px::

        R_F = G * E_s[(L - F(P))^2],   R_B = G * E_s[(L - E(P))^2],   rho = R_F / R_B
        g = 1 for rho <= rho_0,  0 for rho >= rho_1,  smoothstep between  (:data:`_RHO`)

    In focus the fused photograph ``F`` predicts every view up to the noise while the 1x photograph ``E`` misses
    the detail the views alias (``rho`` small; with noise ``rho ~ noise / (noise + detail)``, a Wiener-like
    test).  Out of focus the views disagree by their parallax and neither explains them (``rho`` near 1): the
    fused detail there is the difference between the subsets of views each output phase averages, and is dropped.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32, optional ``weight`` (V, U, Y, X).
    s : float
        Refocus slope.
    fused : ndarray (k Y, k X, C) float32
        Normalised-convolution photograph.
    photo : ndarray (Y, X, C) float32
        Photograph refocused at ``s`` on the lenslet grid.
    vmask : ndarray (V, U) float32
        Aperture weights.

    Returns
    -------
    ndarray, shape (Y, X), float32, in [0, 1]
    """
    k = fused.shape[0] // photo.shape[0]
    res = _view_residuals(lf, s, [(fused, k), (photo, 1)])
    r = np.concatenate([shift_sum(LightField(res[..., n:n + 1], lf.weight), s, aperture=vmask, interp="linear")[0]
                        for n in range(2)], axis=-1).astype(np.float64)
    r = cv2.GaussianBlur(r, (0, 0), _CONSISTENCY_SIGMA, borderType=cv2.BORDER_REPLICATE)
    rho = r[..., 0] / np.maximum(r[..., 1], 1e-20)
    t = np.clip((_RHO[1] - rho) / (_RHO[1] - _RHO[0]), 0.0, 1.0)
    return (t * t * (3 - 2 * t)).astype(np.float32)


def _fuse_samples(lf: LightField, s: np.ndarray, k: int, vmask: np.ndarray, h: np.ndarray,
                  progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """The normalised convolution of every view's samples on the ``k``-times finer grid with kernel scales
    ``h`` (S, 2): (S, k Y, k X, C)."""
    nv, nu, ny, nx, nc = lf.shape
    vc, uc = lf.centre_index
    a = np.arange(nv, dtype=np.float64) - vc
    b = np.arange(nu, dtype=np.float64) - uc
    if k > 1 and np.any(h.max(axis=1) >= _GAIN_GAP):
        log.info("upsample: at slope(s) %s the views sample nearly the same points (phase gap >= %.2f px), so the "
                 "%dx photograph is close to bicubic upsampling there", np.round(s[h.max(axis=1) >= _GAIN_GAP], 3),
                 _GAIN_GAP, k)
    out = np.empty((len(s), k * ny, k * nx, nc), np.float32)
    for py in range(k):
        by, wy = scaled_keys_taps(py / k - s[:, None] * a[None, :], h[:, :1])      # (S, V), (S, V, 4)
        for px in range(k):
            bx, wx = scaled_keys_taps(px / k - s[:, None] * b[None, :], h[:, 1:])  # (S, U), (S, U, 4)
            out[:, py::k, px::k] = _fuse_phase(lf, vmask, (by, wy), (bx, wx))
            if progress is not None:
                progress(py * k + px + 1, k * k + 1)
    return out


def fuse_views(lf: LightField, slopes: float | np.ndarray, *, upsample: int = 2,
               aperture: float | np.ndarray = 1.0,
               progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Refocused photographs on a ``k``-times finer grid, fused from every view's samples at their true positions.

    Normalised convolution of the samples ``L_vu(y, x)`` placed at ``(y + s a, x + s b)`` with Keys' kernel
    stretched to the phase gap ``h`` of the views, kept where the views agree with it (module docstring)::

        F_s(j / k, i / k) = sum K_h(q - P) m w L / sum K_h(q - P) m w
        out = B + g (F - B),      B = Keys upsampling of the 1x photograph,  g = :func:`in_focus_gain`

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32, optional ``weight`` (V, U, Y, X).
    slopes : float or array_like (S,)
        Refocus slopes, spatial samples per view step.
    upsample : int
        ``k >= 1``; output sample ``(j, i)`` is the photograph at ``(j / k, i / k)``.
    aperture : float or ndarray (V, U)
        See :func:`plenodecode.render.aperture_mask`.
    progress : callable(done, total), optional
        Called after each of the ``k * k`` output phases and after the blend.

    Returns
    -------
    ndarray, shape (S, k Y, k X, C), float32
    """
    check_lightfield(lf)
    s = check_slopes(slopes)
    k = check_upsample(upsample)
    vmask = aperture_mask(lf.shape[:2], aperture)
    h = kernel_scales(lf, s, k, vmask)
    out = _fuse_samples(lf, s, k, vmask, h, progress)
    sharp = np.flatnonzero(h.min(axis=1) < 1.0)           # h = 1 on both axes: the fusion is the bicubic
    if k > 1 and sharp.size:
        photos = shift_sum(lf, s[sharp], aperture=vmask)
        for n, i in enumerate(sharp):
            base = keys_upsample(photos[n], k)
            gain = keys_upsample(in_focus_gain(lf, float(s[i]), out[i], photos[n], vmask)[..., None], k)
            out[i] = base + np.clip(gain, 0.0, 1.0) * (out[i] - base)
    if progress is not None:
        progress(k * k + 1, k * k + 1)
    return out


__all__ = ["fuse_views", "in_focus_gain", "keys_upsample", "kernel_scales", "phase_gap", "scaled_keys_taps"]
