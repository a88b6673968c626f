"""Virtual depth of a focused-plenoptic (plenoptic 2.0, Raytrix) raw at the total-focus image's resolution.

A focused camera's micro-lenses image the main lens's virtual image (VI): a VI point at virtual depth
``v = a / B`` appears in neighbouring micro-images ``D / v`` px apart along the lens baseline (``D`` the lens
pitch, px; Georgiev & Lumsdaine 2010; Perwass & Wietzke, SPIE 2012).  A raw pixel ``x`` at offset ``m`` from its
lens centre therefore sees the point that lens ``j`` at baseline ``b`` (sensor px, ``|b|`` = D, sqrt(3) D, 2 D)
shows at offset ``m + sign b / v`` (``sign = +1`` Keplerian / inverted micro-images, ``-1`` Galilean), i.e. at
the sensor pixel::

    x + b + sign * b / v        (the same shift for every lens pair of a regular lattice)

so one cost slice of candidate ``P = D / v`` and baseline ``b`` is one translation of the whole raw
(Fleischmann & Koch 2014 match micro-images the same way, per pixel, over several baselines).

Per raw pixel (:func:`sensor_virtual_depth`):

1. luminance, standardised within every micro-image by a local window that never leaves the lens's usable
   disk: ``n = (L - mu_5x5) / (sigma_5x5 + eps)`` (gain and blur-contrast differences between the three lens
   types of a multi-focus array cancel; ``eps`` = the noise level, :func:`relative_noise`), kept only where the
   window lies wholly inside the disk;
2. for every candidate ``P`` (step ``step`` px) and every baseline: the truncated absolute difference
   ``min(|n(x) - n(x + s)|, tau)``, counted only where both ``x`` and ``x + s`` are kept
   (``|m + sign b P / D| < r_kept``); summed over baselines and a ``window`` x ``window`` window, divided by the
   number of valid pairs;
3. the winner, refined by a parabola through its neighbours (sub-label); a winner at the end of a pixel's
   searchable range (its neighbour candidate has no valid pair, e.g. a micro-image centre at v ~ 2 that no
   neighbour sees) is no minimum: confidence 0;
4. confidence = texture ``t^2 / (t^2 + 0.02^2)`` (``t`` the local standard deviation, noise removed, over the
   lens mean brightness; low on featureless micro-images) x ``clip((1 - c1 / c2) / 0.3, 0, 1)`` (``c2`` the
   lowest cost at least 2 px of ``P`` away from the winner; low on ambiguous or flat cost curves) x 0.1 where
   no neighbour's pixel showing the same point found the same ``P`` (:func:`_cross_check`, a left-right check).

The per-pixel depth is then carried to the total-focus image (:func:`estimate_focused_depth`) with the
rendering's own output-pixel -> sensor-pixel mapping (:func:`plenodecode.decoding.focused.map_to_render`),
weighted by the lens's focus weight x the pixel's confidence, so depth and photograph align pixel for pixel.

Virtual depth is Raytrix's own unit; metres need the main lens and the MLA-sensor distance ``B``, which a
RayCalibData XML does not hold.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from ..types import LensletGrid

log = logging.getLogger(__name__)

#: Label and unit of a focused raw's depth map.
VIRTUAL_DEPTH_LABEL = "virtual depth (v = a / B)"
VIRTUAL_DEPTH_UNIT = "virtual depth (a / B)"
#: Smallest candidate micro-image disparity, in lens pitches (0.06 D: v up to ~17).
MIN_P_PITCH = 0.06
#: Largest candidate micro-image disparity, in lens pitches (as :func:`~plenodecode.decoding.focused.
#: estimate_patch_sizes`: v down to ~1.7).
MAX_P_PITCH = 0.6
#: Texture level (local std of the signal, noise removed, / lens mean) at which the texture confidence is 0.5.
TEXTURE_HALF = 0.02
#: Floor of the local standardisation, in noise standard deviations (:func:`relative_noise`), and its minimum
#: (relative to the lens's brightness).
NOISE_EPS = 1.0
MIN_EPS = 0.005
#: Cost ratio margin ``1 - c1 / c2`` that counts as an unambiguous match.
AMBIGUITY_FULL = 0.3
#: Distance (px of P) from the winner beyond which the second minimum is sought.
SECOND_MIN_PX = 2.0
#: A pixel whose estimate no neighbour's match confirms (:func:`_cross_check`) keeps this share of its confidence.
UNCONFIRMED = 0.1
#: Agreement of the cross-check: px of P, and relative.
CHECK_PX = 0.75
CHECK_REL = 0.08
#: Cost-volume budget per band of rows, bytes.
BAND_BYTES = 48 << 20


@dataclass(frozen=True)
class FocusedDepth:
    """Virtual depth of a focused-plenoptic raw.

    Attributes
    ----------
    virtual_depth : ndarray (Ho, Wo) float32
        On the total-focus image's grid (``render.image``); NaN where no lens covers the pixel.
    confidence : ndarray (Ho, Wo) float32 in [0, 1]
    render : FocusedRender
        The total focus whose grid and mapping were used.
    sensor_depth : ndarray (H, W) float32
        Per raw pixel (NaN outside the usable disks or without an estimate).
    sensor_confidence : ndarray (H, W) float32
    params : dict
        Candidate range, step, windows, orientation and ``seconds``.
    """

    virtual_depth: np.ndarray
    confidence: np.ndarray
    render: Any
    sensor_depth: np.ndarray
    sensor_confidence: np.ndarray
    params: Mapping[str, Any] = field(default_factory=dict)


def lattice_baselines(grid: LensletGrid, max_pitches: float = 2.05) -> np.ndarray:
    """Vectors (sensor ``(row, col)``, px) from a lens to its lattice neighbours up to ``max_pitches`` lens
    pitches away: 6 + 6 + 6 on a hex lattice (D, sqrt(3) D, 2 D), 4 + 4 + 4 on a square one.

    Returns
    -------
    ndarray (N, 2) float64
    """
    rs, d = float(grid.row_spacing), float(grid.pitch)
    e_row, e_col = grid.axes()
    out = []
    for di in range(-3, 4):
        for dj in range(-3, 4):
            a = di * rs
            b = dj * d + grid.odd_row_shift * d * (di % 2)
            if 0.9 * d < math.hypot(a, b) < max_pitches * d:
                out.append(a * e_row + b * e_col)
    return np.array(out, np.float64).reshape(-1, 2)


def _box(x: np.ndarray, k: int) -> np.ndarray:
    import cv2

    return cv2.boxFilter(x, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)


def candidate_patches(grid: LensletGrid, p_range: tuple[float, float] | None, step: float) -> np.ndarray:
    """Candidate micro-image disparities ``P = D / v`` (px): ``p_range`` or the camera's virtual depth range
    (:func:`~plenodecode.decoding.focused.virtual_depth_range`) within ``[MIN_P_PITCH, MAX_P_PITCH] * D``."""
    from ..decoding.focused import virtual_depth_range

    d = float(grid.pitch)
    if p_range is None:
        vlo, vhi = virtual_depth_range(grid)
        lo, hi = max(d / vhi, MIN_P_PITCH * d), min(d / vlo, MAX_P_PITCH * d)
    else:
        lo, hi = (float(p_range[0]), float(p_range[1]))
    if not (0 < lo < hi and step > 0):
        raise ValueError(f"p_range must be 0 < lo < hi and step > 0, got {p_range}, {step}")
    return np.arange(lo, hi + 1e-9, step)


def _normalised_luminance(img: np.ndarray, grid: LensletGrid, margin: float, lcn: int):
    """Usable mask, offsets from the lens centre, standardised luminance and texture level (all (H, W))."""
    from ..decoding.slice import lens_labels

    h, w, c = img.shape
    lum = img.mean(axis=-1) if c > 1 else img[..., 0]
    finite = np.isfinite(lum)
    cen = grid.centres_2d()
    lab, dist = lens_labels(cen, (h, w), float(grid.radius))
    usable = (lab >= 0) & (dist < grid.radius - margin) & finite
    flat = cen.reshape(-1, 2)
    k = np.maximum(lab, 0)
    yy, xx = np.mgrid[0:h, 0:w]
    my = np.where(usable, yy - flat[k, 0], 1e4).astype(np.float32)
    mx = np.where(usable, xx - flat[k, 1], 1e4).astype(np.float32)
    uf = usable.astype(np.float32)
    lm = np.where(usable, lum, 0.0).astype(np.float32)
    n0 = np.maximum(_box(uf, lcn), 1.0)
    mu = _box(lm, lcn) / n0
    sd = np.sqrt(np.maximum(_box(lm * lm, lcn) / n0 - mu * mu, 0.0))
    # the lens's mean brightness sets eps and the texture scale (no window crosses a lens border)
    nl = flat.shape[0]
    labc = np.where(usable, lab, nl)
    mean = np.bincount(labc.ravel(), weights=lm.ravel(), minlength=nl + 1) / np.maximum(
        np.bincount(labc.ravel(), minlength=nl + 1), 1)
    lens_mean = np.maximum(mean[labc], 1e-6).astype(np.float32)
    noise = relative_noise(lm, usable, lens_mean)
    eps = np.float32(max(noise * NOISE_EPS, MIN_EPS)) * lens_mean
    n = np.where(usable, (lm - mu) / (sd + eps), 0.0).astype(np.float32)
    signal = np.sqrt(np.maximum((sd / lens_mean) ** 2 - np.float32(noise) ** 2, 0.0))
    texture = np.where(usable, signal, 0.0).astype(np.float32)
    # only pixels whose standardisation window lies wholly in the disk: a clipped window shifts the local mean
    # and scale with the position in the micro-image, which biased P by 1 - 2 % (the exact planes of the tests)
    complete = usable & (n0 >= lcn * lcn - 0.5)
    my[~complete] = 1e4
    mx[~complete] = 1e4
    return complete, my, mx, n, texture, noise


def relative_noise(lum: np.ndarray, usable: np.ndarray, lens_mean: np.ndarray) -> float:
    """Noise standard deviation over brightness, from the median absolute response to the Laplacian-like kernel
    ``[[1, -2, 1], [-2, 4, -2], [1, -2, 1]]`` (std ``6 sigma`` on white noise; Immerkaer 1996) on the pixels whose
    3 x 3 neighbourhood is usable; the median keeps edges out."""
    import cv2

    k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    r = cv2.filter2D(lum.astype(np.float32), -1, k, borderType=cv2.BORDER_CONSTANT)
    inner = cv2.erode(usable.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    if not inner.any():
        return 0.0
    return float(1.4826 * np.median(np.abs(r[inner]) / lens_mean[inner]) / 6.0)


def sensor_virtual_depth(image, grid: LensletGrid, *, keplerian: bool, p_range: tuple[float, float] | None = None,
                         step: float = 0.5, window: int = 9, lcn: int = 5, tau: float = 1.5, margin: float = 1.5,
                         max_baseline: float = 2.05,
                         progress: Callable[[int, int], None] | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Virtual depth of every raw pixel inside a micro-image (see the module docstring for the cost).

    Parameters
    ----------
    image : RawCapture or ndarray (H, W[, C])
        Scene raw or prepared (devignetted, demosaiced) sensor image.
    grid : LensletGrid
    keplerian : bool
        Micro-images inverted (Keplerian) or upright (Galilean).
    p_range : (float, float), optional
        Candidate micro-image disparities ``P = D / v``, px (default :func:`candidate_patches`).
    step : float
        Candidate spacing, px of ``P``.
    window : int
        Aggregation window, px (odd).
    lcn : int
        Window of the local standardisation, px (odd).
    tau : float
        Truncation of the per-pixel cost (standardised units).
    margin : float
        px kept off the usable disk's edge (``grid.radius``); a pixel is compared when its whole ``lcn`` window
        lies within (the match: within ``radius - margin - (lcn // 2) sqrt 2``).
    max_baseline : float
        Farthest neighbour compared, in lens pitches.

    Returns
    -------
    v : ndarray (H, W) float32
        ``D / P`` (NaN outside the usable disks or without a valid candidate).
    confidence : ndarray (H, W) float32 in [0, 1]
    info : dict
        ``'patches'`` (the candidates), ``'usable'`` (H, W) bool.
    """
    import cv2

    from ..decoding.focused import _as_image

    img = _as_image(image, grid)
    h, w = img.shape[:2]
    usable, my, mx, n, texture, noise = _normalised_luminance(img, grid, margin, lcn)
    pitch = float(grid.pitch)
    patches = candidate_patches(grid, p_range, step)
    nt = patches.size
    if nt < 3:
        raise ValueError(f"at least 3 candidate patch sizes are needed, got {nt} in {p_range} (step {step})")
    base = lattice_baselines(grid, max_baseline)
    sign = 1.0 if keplerian else -1.0
    r_use = float(grid.radius) - margin
    r2 = np.float32((r_use - (lcn // 2) * math.sqrt(2.0)) ** 2)
    area = window * window
    pad = window // 2 + 1
    band = int(max(16, min(h, BAND_BYTES // max(1, 4 * nt * w))))
    v_out = np.full((h, w), np.nan, np.float32)
    conf_out = np.zeros((h, w), np.float32)
    ex = max(2, int(math.ceil(SECOND_MIN_PX / step)))
    # a baseline whose match moves farther than 1.7 usable radii leaves too little overlap to compare
    reach = np.hypot(base[:, 0], base[:, 1]) / pitch
    per_t = [base[reach * p < 1.7 * r_use] for p in patches]
    done, total = 0, sum(len(b) for b in per_t) * int(math.ceil(h / band))
    for y0 in range(0, h, band):
        y1 = min(h, y0 + band)
        a0, a1 = max(0, y0 - pad), min(h, y1 + pad)
        bh = a1 - a0
        nb_ref, my_b, mx_b = n[a0:a1], my[a0:a1], mx[a0:a1]
        vol = np.full((nt, y1 - y0, w), np.inf, np.float32)
        moved, diff = np.empty((bh, w), np.float32), np.empty((bh, w), np.float32)
        qy, qx = np.empty((bh, w), np.float32), np.empty((bh, w), np.float32)
        ones = np.ones((bh, w), np.float32)
        for t in range(nt):
            acc = np.zeros((bh, w), np.float32)
            cnt = np.zeros((bh, w), np.float32)
            for b in per_t[t]:
                d = sign * b * patches[t] / pitch          # offset change in the neighbour
                s = b + d                                  # sensor shift of the match
                m = np.float32([[1, 0, s[1]], [0, 1, s[0] + a0]])
                cv2.warpAffine(n, m, (w, bh), dst=moved, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_CONSTANT)
                # the match inside the neighbour's kept disk: |m + d| < r_kept (my, mx huge off the kept pixels)
                np.add(my_b, np.float32(d[0]), out=qy)
                np.multiply(qy, qy, out=qy)
                np.add(mx_b, np.float32(d[1]), out=qx)
                np.multiply(qx, qx, out=qx)
                np.add(qy, qx, out=qy)
                valid = np.less(qy, r2).view(np.uint8)
                cv2.absdiff(nb_ref, moved, dst=diff)
                np.minimum(diff, np.float32(tau), out=diff)
                cv2.accumulate(diff, acc, mask=valid)
                cv2.accumulate(ones, cnt, mask=valid)
                done += 1
            num = _box(cnt, window)[y0 - a0:y1 - a0]
            cost = _box(acc, window)[y0 - a0:y1 - a0] / np.maximum(num, 1.0)
            vol[t] = np.where(num >= 0.5 * area, cost, np.inf)
            if progress:
                progress(done, total)
        v_b, c_b = _winner(vol, patches, step, ex)
        v_out[y0:y1] = v_b
        conf_out[y0:y1] = c_b
    agree = _cross_check(v_out, usable, my, mx, base, sign, pitch, r2)
    conf_out *= np.where(agree, np.float32(1.0), np.float32(UNCONFIRMED))
    v_out = np.where(usable, pitch / v_out, np.nan).astype(np.float32)   # P -> v
    tex = texture ** 2 / (texture ** 2 + TEXTURE_HALF ** 2)
    conf = np.where(usable & np.isfinite(v_out), conf_out * tex, 0.0).astype(np.float32)
    return v_out, conf, {"patches": patches, "usable": usable, "noise": noise}


def _cross_check(p: np.ndarray, usable: np.ndarray, my: np.ndarray, mx: np.ndarray, base: np.ndarray, sign: float,
                 pitch: float, r2: float) -> np.ndarray:
    """True where some neighbour's pixel that shows the same point (``x + b + sign b P / D``, nearest pixel, inside
    its usable disk) found the same ``P`` within ``max(CHECK_PX, CHECK_REL P)``: a left-right check over the
    lattice's baselines.  ``p`` (H, W) float32 micro-image disparity (NaN = none)."""
    import cv2

    h, w = p.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    pf = np.where(np.isfinite(p), p, np.float32(-1e3)).astype(np.float32)
    tol = np.maximum(np.float32(CHECK_PX), np.float32(CHECK_REL) * pf)
    agree = np.zeros((h, w), bool)
    for b in base:
        k = np.float32(sign / pitch)
        dy, dx = np.float32(b[0]) * k * pf, np.float32(b[1]) * k * pf
        inside = usable & ((my + dy) ** 2 + (mx + dx) ** 2 < r2)
        other = cv2.remap(pf, xx + np.float32(b[1]) + dx, yy + np.float32(b[0]) + dy, cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=-1e3)
        agree |= inside & (np.abs(other - pf) <= tol)
    return agree & np.isfinite(p)


def _winner(vol: np.ndarray, patches: np.ndarray, step: float, ex: int) -> tuple[np.ndarray, np.ndarray]:
    """Sub-label winner ``P`` (NaN without one) and ambiguity confidence of a cost volume (T, h, w) (inf =
    no valid pair)."""
    nt = vol.shape[0]
    best = np.zeros(vol.shape[1:], np.int64)
    c1 = vol[0].copy()
    for t in range(1, nt):                        # a loop over planes: argmin over axis 0 strides badly
        better = vol[t] < c1
        best[better] = t
        np.minimum(c1, vol[t], out=c1)
    cm = np.take_along_axis(vol, np.maximum(best - 1, 0)[None], 0)[0]
    cp = np.take_along_axis(vol, np.minimum(best + 1, nt - 1)[None], 0)[0]
    interior = (best > 0) & (best < nt - 1) & np.isfinite(cm) & np.isfinite(cp) & np.isfinite(c1)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        den = cm - 2 * c1 + cp
        frac = np.where(interior & (den > 0), 0.5 * (cm - cp) / den, 0.0)
    p = np.where(np.isfinite(c1), patches[best] + np.clip(frac, -0.5, 0.5) * step, np.nan)
    c2 = np.full(c1.shape, np.inf, np.float32)
    for t in range(nt):
        np.minimum(c2, np.where(np.abs(t - best) >= ex, vol[t], np.inf), out=c2)
    with np.errstate(invalid="ignore", divide="ignore"):
        amb = np.where(interior & np.isfinite(c2) & (c2 > 0), 1.0 - c1 / c2, np.where(interior, 1.0, 0.0))
    conf = np.clip(np.nan_to_num(amb) / AMBIGUITY_FULL, 0.0, 1.0)
    return p.astype(np.float32), conf.astype(np.float32)


def estimate_focused_depth(raw, grid: LensletGrid, *, white=None, render=None, sharpness: float = 2.0,
                           p_range: tuple[float, float] | None = None, demosaic: str = "malvar",
                           progress: Callable[[int, int], None] | None = None, **options: Any) -> FocusedDepth:
    """Virtual depth of a focused-plenoptic raw on its total-focus image's grid.

    Parameters
    ----------
    raw : RawCapture or ndarray (H, W[, C])
        Scene raw, or a prepared sensor image.
    grid : LensletGrid
    white : optional
        White image for devignetting (as :func:`~plenodecode.decoding.focused.render_focused`).
    render : FocusedRender, optional
        The total focus to align with (default: :func:`~plenodecode.decoding.focused.render_total_focus` of
        ``raw`` with ``sharpness``); its orientation, patch sizes and focus weights are used.
    sharpness : float
        Exponent of the focus weights of the mapping (as the total focus).
    p_range : (float, float), optional
        Candidate micro-image disparities, px (default from the camera's virtual depth range).
    progress : callable(done, total), optional
    **options
        Of :func:`sensor_virtual_depth` (``step``, ``window``, ...).

    Returns
    -------
    FocusedDepth
    """
    from ..decoding.focused import _as_image, focus_weights, map_to_render, render_total_focus

    t0 = time.perf_counter()
    img = _as_image(raw, grid, white, demosaic)
    if render is None:
        render = render_total_focus(img, grid, sharpness=sharpness)
    v, conf, info = sensor_virtual_depth(img, grid, keplerian=render.keplerian, p_range=p_range, progress=progress,
                                         **options)
    # weights conf + 1e-3: every covered pixel gets the mean of what it is made of, confident pixels dominate
    wgt = np.where(np.isfinite(v), conf + np.float32(1e-3), 0.0).astype(np.float32)
    planes = np.stack([np.where(wgt > 0, v, 0.0) * wgt, wgt, conf], -1).astype(np.float32)
    sums, wsum = map_to_render(planes, grid, render, lens_weight=focus_weights(render.focus, sharpness))
    with np.errstate(invalid="ignore", divide="ignore"):
        vq = np.where(sums[..., 1] > 0, sums[..., 0] / sums[..., 1], np.nan)
        cq = np.where(wsum > 0, sums[..., 2] / wsum, 0.0)
    seconds = time.perf_counter() - t0
    patches = info["patches"]
    params = {"p_range": (float(patches[0]), float(patches[-1])), "step": float(patches[1] - patches[0]),
              "v_range": (float(grid.pitch / patches[-1]), float(grid.pitch / patches[0])),
              "keplerian": bool(render.keplerian), **options, "seconds": seconds}
    log.info("focused depth: v %.2f .. %.2f searched, %.1f s", *params["v_range"], seconds)
    return FocusedDepth(virtual_depth=vq.astype(np.float32), confidence=np.clip(cq, 0, 1).astype(np.float32),
                        render=render, sensor_depth=v, sensor_confidence=conf, params=params)


__all__ = ["FocusedDepth", "VIRTUAL_DEPTH_LABEL", "VIRTUAL_DEPTH_UNIT", "lattice_baselines", "candidate_patches",
           "sensor_virtual_depth", "estimate_focused_depth"]
