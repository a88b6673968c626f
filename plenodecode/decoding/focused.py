"""Focused-plenoptic (plenoptic 2.0, Raytrix) rendering: patches of micro-images, "total focus".

In a focused plenoptic camera the micro-lenses image the main lens's (virtual) image, so every
micro-image is a small sharp picture of part of the scene, inverted in the Keplerian
configuration (Lumsdaine & Georgiev, "The focused plenoptic camera", ICCP 2009).  A point at
virtual depth ``v`` appears in neighbouring micro-images ``D / v`` px apart along the lens baseline
(``D`` = lens pitch in px); a micro-image therefore holds ``P = D / v`` px of new content per lens
step, and the image is rendered by taking a ``P`` x ``P`` patch around each micro-image centre
(flipped for Keplerian) and tiling the patches at a common output spacing.  Using a wrong ``P``
duplicates or drops content; changing ``P`` refocuses.

This module renders with a per-lens ``P`` (an array, or estimated from the data):

* :func:`estimate_patch_sizes` measures, for every lens, the shift ``P`` between its micro-image
  and its six neighbours' (normalised cross-correlation along each baseline, parabolic sub-pixel
  peak): the per-lens depth of Georgiev & Lumsdaine's depth-based rendering ("Reducing plenoptic
  camera artifacts", Computer Graphics Forum 2010), with low-confidence lenses filled from
  their neighbours;
* :func:`render_focused` tiles the patches with feathered blending: every output pixel is the
  weighted mean of the patches of the lenses around it, weights falling linearly to 0 at
  ``feather`` output-lens-spacings from each lens (no seams);
* the micro-image orientation (inverted = Keplerian, upright = Galilean) is detected by matching
  both ways and keeping the better-correlated one (the Raytrix R42 sample is upright);
* :func:`render_total_focus` adds a per-lens focus measure (Tenengrad: mean squared gradient of
  the micro-image centre relative to its brightness) as a weight ``focus ** sharpness`` so that,
  with Raytrix multi-focus MLAs (three interleaved lens types, Perwass & Wietzke, SPIE 2012),
  each region of the image comes from the lens type that is sharp there: "total focus";
* :func:`map_to_render` carries any per-sensor-pixel quantity (e.g. the virtual depth of
  :mod:`plenodecode.depth.focused`) to a rendering's grid through the same mapping and weights.

Geometry: the output pixel ``q`` lies at sensor position ``q / s`` with ``s = spacing / D``; lens
``k`` sits at ``s * c_k`` and shows, at output offset ``delta = q - s * c_k``, its micro-image
pixel ``c_k + flip * delta * P_k / spacing`` (``flip = -1`` Keplerian, ``+1`` Galilean).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._numba import njit
from ..errors import CalibrationError, DecodeError
from ..types import LensletGrid, RawCapture
from .slice import view_offsets

log = logging.getLogger(__name__)

FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


@dataclass(frozen=True)
class FocusedRender:
    """Result of a focused-plenoptic rendering.

    Attributes
    ----------
    image : ndarray, shape (Ho, Wo, C), float32
        The rendered image (linear, devignetted units).
    weight : ndarray, shape (Ho, Wo), float32
        Sum of the blending weights (0 where no lens covers the pixel).
    patch : ndarray, shape (rows, cols), float64
        Patch size ``P`` used per lens, px.
    focus : ndarray, shape (rows, cols), float64
        Focus measure per lens (1 when not used).
    spacing : float
        Output pixels between neighbouring lens centres.
    scale : float
        Output px per sensor px (``spacing / pitch``).
    spread : ndarray, shape (Ho, Wo), float32
        Weighted standard deviation of the lenses' contributions at each pixel: low where the
        overlapping patches agree (right patch size), high where they disagree.
    keplerian : bool
        Orientation used (inverted micro-images).
    """

    image: np.ndarray
    weight: np.ndarray
    patch: np.ndarray
    focus: np.ndarray
    spacing: float
    scale: float
    spread: np.ndarray | None = None
    keplerian: bool = True


# -------------------------------------------------------------------------------------
# input preparation
# -------------------------------------------------------------------------------------
def _prepare_image(raw, grid: LensletGrid, white, demosaic: str) -> np.ndarray:
    """(H, W, C) float32 sensor image, devignetted when a white is given, NaN where unusable."""
    from .demosaic import demosaic as _demosaic
    from .devignette import normalise, repair_hot_pixels
    from .slice import lens_labels

    if isinstance(raw, RawCapture):
        if tuple(grid.sensor_shape) != tuple(raw.shape):
            raise CalibrationError(f"the grid was fitted on a {grid.sensor_shape[1]}x{grid.sensor_shape[0]} sensor but "
                                   f"the raw is {raw.shape[1]}x{raw.shape[0]} (width x height); pass the grid of "
                                   "this camera")
        x = normalise(raw.mosaic, raw.black, raw.white)
        x, _ = repair_hot_pixels(x)
        cfa = raw.cfa
        if white is not None:
            wm = white.mosaic if isinstance(white, RawCapture) else np.asarray(white)
            if wm.shape != raw.shape:
                raise DecodeError(f"white image must be {raw.shape[0]}x{raw.shape[1]}, found "
                                  f"{'x'.join(map(str, wm.shape))}; pass the white image of this camera")
            wb = (white.black, white.white) if isinstance(white, RawCapture) else (raw.black, raw.white)
            wn = wm.astype(np.float32) if wm.dtype.kind == "f" else normalise(wm, *wb)
            x = _devignetted(x, wn, cfa, grid)
        labels, _ = lens_labels(grid.centres_2d(), x.shape, 0.6 * grid.pitch + 1.0)
        img = _demosaic(x, cfa, method=demosaic, labels=labels)
        return img
    arr = np.asarray(raw, np.float32)
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3 or arr.shape[:2] != tuple(grid.sensor_shape):
        raise DecodeError(f"image must be {grid.sensor_shape[0]}x{grid.sensor_shape[1]} (H, W[, C]) like the grid's "
                          f"sensor, found {arr.shape}; pass the raw the grid was calibrated for")
    return np.ascontiguousarray(arr)


def _devignetted(x: np.ndarray, white: np.ndarray, cfa: str | None, grid: LensletGrid) -> np.ndarray:
    """``x / white`` where the white's relative light is usable, NaN elsewhere (both (H, W) float32, normalised;
    :func:`~plenodecode.decoding.devignette.relative_white` over about one lens pitch)."""
    from .devignette import devignette, relative_white

    rel = relative_white(np.ascontiguousarray(white, np.float32), cfa, window=int(round(grid.pitch)) + 2)
    return devignette(x, white, rel)


def _devignetted_image(img: np.ndarray, white, grid: LensletGrid) -> np.ndarray:
    """A prepared (H, W, C) image divided, channel by channel, by a normalised white image (H, W) or (H, W, C)."""
    wn = np.asarray(white, np.float32)
    wn = wn[..., None] if wn.ndim == 2 else wn
    if wn.shape[:2] != img.shape[:2] or wn.shape[2] not in (1, img.shape[2]):
        raise DecodeError(f"white image must be {img.shape[0]}x{img.shape[1]} with 1 or {img.shape[2]} channels "
                          f"like the image, found {wn.shape}; pass the white image of this camera")
    planes = []
    for c in range(img.shape[2]):
        w_c = np.ascontiguousarray(wn[..., min(c, wn.shape[2] - 1)])
        planes.append(_devignetted(np.ascontiguousarray(img[..., c]), w_c, None, grid))
    return np.stack(planes, -1)


def _as_image(image, grid: LensletGrid, white=None, demosaic: str = "bilinear") -> np.ndarray:
    """A prepared (H, W, C) float image as is (shape checked; divided by ``white``, a normalised float image
    (H, W[, C]), when given), anything else through :func:`_prepare_image`."""
    if isinstance(image, np.ndarray) and image.ndim == 3:
        if image.shape[:2] != tuple(grid.sensor_shape):
            raise DecodeError(f"image must be {grid.sensor_shape[0]}x{grid.sensor_shape[1]} like the grid's sensor, "
                              f"found {image.shape[0]}x{image.shape[1]}; pass the raw the grid was calibrated for")
        img = np.ascontiguousarray(image, np.float32)
        return img if white is None else _devignetted_image(img, white, grid)
    return _prepare_image(image, grid, white, demosaic)


def _lens_patches(img: np.ndarray, grid: LensletGrid, half: int) -> tuple[np.ndarray, np.ndarray]:
    """Micro-images sampled on the integer lattice-frame offsets ``-half..half``.

    Returns
    -------
    patches : ndarray (rows, cols, n, n, C) float32 (NaN outside the image or where unknown)
    offsets : ndarray (n, n, 2) sensor offsets
    """
    import cv2

    n = 2 * half + 1
    offs = view_offsets(grid, n)
    cen = grid.centres_2d()
    pos = cen[:, :, None, None, :] + offs[None, None]
    rows, cols = grid.shape
    h, w, c = img.shape
    mx = pos[..., 1].reshape(rows * cols, n * n).astype(np.float32)
    my = pos[..., 0].reshape(rows * cols, n * n).astype(np.float32)
    out = np.empty((rows * cols, n * n, c), np.float32)
    block = 30000                                   # cv2.remap maps must stay below 32767 rows
    for ch in range(c):
        plane = np.ascontiguousarray(img[..., ch])
        for b0 in range(0, rows * cols, block):
            b1 = min(rows * cols, b0 + block)
            out[b0:b1, :, ch] = cv2.remap(plane, mx[b0:b1], my[b0:b1], interpolation=cv2.INTER_LINEAR,
                                          borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    return out.reshape(rows, cols, n, n, c), offs


# -------------------------------------------------------------------------------------
# per-lens patch size from micro-image disparity
# -------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, inline="always")
def _bilin(lum, k, fa, fb, n):  # pragma: no cover - numba
    ya = int(math.floor(fa))
    xb = int(math.floor(fb))
    if ya < 0 or xb < 0 or ya + 1 >= n or xb + 1 >= n:
        return np.nan
    wy = fa - ya
    wx = fb - xb
    return ((1 - wy) * ((1 - wx) * lum[k, ya, xb] + wx * lum[k, ya, xb + 1])
            + wy * ((1 - wx) * lum[k, ya + 1, xb] + wx * lum[k, ya + 1, xb + 1]))


@njit(cache=True, nogil=True, error_model="numpy")
def _match_costs(lum, nbr, dirs, shifts, win, out):  # pragma: no cover - numba
    """Mean NCC between each lens and its neighbours for every candidate shift t along the baseline.

    Lens k is read at ``m - alpha t e`` and its neighbour at ``m + (1 - alpha) t e``, with the smallest
    ``alpha >= 0`` that keeps both windows inside their micro-images: the window stays on lens k's
    centre (its central ray) while it fits, and moves towards the baseline midpoint for large shifts.
    """
    nl, n, _ = lum.shape
    half = n // 2
    lim = half - 1.0
    nn = nbr.shape[1]
    nt = shifts.shape[0]
    for k in range(nl):
        for t in range(nt):
            acc = 0.0
            cnt = 0.0
            at = abs(shifts[t])
            alpha = max(0.0, (win + at - lim) / at) if at > 0 else 0.0
            if alpha > 0.5:
                for tt in range(t, nt):
                    out[k, tt] = np.nan
                break
            for q in range(nn):
                kk = nbr[k, q]
                if kk < 0:
                    continue
                ua = dirs[k, q, 0] * shifts[t]
                ub = dirs[k, q, 1] * shifts[t]
                s1 = 0.0
                s2 = 0.0
                s11 = 0.0
                s22 = 0.0
                s12 = 0.0
                m = 0.0
                for ia in range(-win, win + 1):
                    for ib in range(-win, win + 1):
                        a = _bilin(lum, k, ia - alpha * ua + half, ib - alpha * ub + half, n)
                        if a != a:
                            continue
                        b = _bilin(lum, kk, ia + (1.0 - alpha) * ua + half, ib + (1.0 - alpha) * ub + half, n)
                        if b != b:
                            continue
                        s1 += a
                        s2 += b
                        s11 += a * a
                        s22 += b * b
                        s12 += a * b
                        m += 1.0
                if m < 0.5 * (2 * win + 1) ** 2:
                    continue
                va = s11 - s1 * s1 / m
                vb = s22 - s2 * s2 / m
                if va <= 1e-12 or vb <= 1e-12:
                    continue
                acc += (s12 - s1 * s2 / m) / math.sqrt(va * vb)
                cnt += 1.0
            out[k, t] = acc / cnt if cnt > 0 else np.nan


def _neighbours(grid: LensletGrid) -> tuple[np.ndarray, np.ndarray]:
    """Six (hex) or four (square) lattice neighbours of each lens and the unit baseline to each (lattice frame)."""
    rows, cols = grid.shape
    cen = grid.centres_2d()
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    if grid.lattice == "hex":
        # neighbours in the same row and in the rows above/below; the column step of the next row
        # depends on the row parity and the sign of the odd-row shift
        cand = [(0, 1), (0, -1)]
        par_steps = []
        for di in (-1, 1):
            for dj in (-1, 0, 1):
                par_steps.append((di, dj))
        cand += par_steps
    else:
        cand = [(0, 1), (0, -1), (1, 0), (-1, 0)]
    e_row, e_col = grid.axes()
    nbr, dirs = [], []
    for di, dj in cand:
        ii, jj = i + di, j + dj
        ok = (ii >= 0) & (ii < rows) & (jj >= 0) & (jj < cols)
        iic, jjc = np.clip(ii, 0, rows - 1), np.clip(jj, 0, cols - 1)
        d = cen[iic, jjc] - cen
        dist = np.linalg.norm(d, axis=-1)
        ok &= np.abs(dist - grid.pitch) < 0.25 * grid.pitch          # a true nearest neighbour
        la = d @ e_row
        lb = d @ e_col
        nrm = np.maximum(np.hypot(la, lb), 1e-9)
        nbr.append(np.where(ok, iic * cols + jjc, -1))
        dirs.append(np.stack([la / nrm, lb / nrm], -1))
    return (np.stack(nbr, -1).reshape(rows * cols, -1).astype(np.int64),
            np.stack(dirs, -2).reshape(rows * cols, -1, 2).astype(np.float64))


def _estimate_auto(img, grid, **kw) -> tuple[np.ndarray, np.ndarray, bool]:
    """Try both orientations; keep the one whose matches correlate better (median peak NCC)."""
    best = None
    for kep in (True, False):
        p, score = estimate_patch_sizes(img, grid, keplerian=kep, **kw)
        med = float(np.nanmedian(score)) if np.isfinite(score).any() else -1.0
        if best is None or med > best[3]:
            best = (p, score, kep, med)
    log.info("micro-images look %s (median match correlation %.2f)", "inverted (Keplerian)" if best[2]
             else "upright (Galilean)", best[3])
    return best[0], best[1], best[2]


def estimate_patch_sizes(image, grid: LensletGrid, *, keplerian: bool | None = None,
                         p_range: tuple[float, float] | None = None, step: float = 0.25,
                         min_score: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Per-lens patch size ``P`` (= micro-image disparity ``D / v``) by matching neighbouring micro-images.

    For lens ``k`` and neighbour ``k'`` at unit baseline ``e``, content at offset ``m`` in ``k``
    appears at ``m + sign * P * e`` in ``k'`` (``sign = +1`` Keplerian, ``-1`` Galilean).  The
    normalised cross-correlation of a central window is averaged over the neighbours for every
    candidate ``P`` (step ``step`` px); the peak is refined by a parabola.  Lenses whose peak
    correlation is below ``min_score`` take the median of their confident neighbours.

    Parameters
    ----------
    image : RawCapture or ndarray (H, W[, C])
        Scene raw, or a demosaiced / monochrome sensor image.
    grid : LensletGrid
    keplerian : bool or None
        Micro-images inverted (Keplerian) or upright (Galilean, e.g. the Raytrix R42 sample);
        None tries both and keeps the orientation whose matches correlate better.
    p_range : (float, float), optional
        Candidate patch sizes, px; default ``(0.12, 0.6) * pitch``.
    step : float
        Candidate spacing, px.
    min_score : float
        Minimum peak correlation of a confident lens.

    Returns
    -------
    patch : ndarray (rows, cols) float64
    score : ndarray (rows, cols) float64
        Peak correlation (NaN where no neighbour could be compared).
    """
    img = _as_image(image, grid)
    if keplerian is None:
        return _estimate_auto(img, grid, p_range=p_range, step=step, min_score=min_score)[:2]
    lo, hi = p_range if p_range is not None else (0.12 * grid.pitch, 0.6 * grid.pitch)
    if not 0 < lo < hi:
        raise ValueError(f"p_range must be 0 < lo < hi, got {p_range}")
    half = int(math.floor(grid.radius))
    patches, _ = _lens_patches(img, grid, half)
    lum = patches.mean(axis=-1).reshape(-1, 2 * half + 1, 2 * half + 1).astype(np.float64)
    nbr, dirs = _neighbours(grid)
    sign = 1.0 if keplerian else -1.0
    shifts = sign * np.arange(lo, hi + 1e-9, step)
    win = 2
    costs = np.full((lum.shape[0], shifts.size), np.nan)
    _match_costs(lum, nbr, dirs, shifts, win, costs)
    rows, cols = grid.shape
    filled = np.where(np.isfinite(costs), costs, -np.inf)
    best = np.argmax(filled, axis=1)
    score = filled[np.arange(best.size), best]
    # parabolic sub-step refinement
    b0 = np.clip(best, 1, shifts.size - 2)
    c_m, c_0, c_p = (filled[np.arange(best.size), b0 - 1], filled[np.arange(best.size), b0],
                     filled[np.arange(best.size), b0 + 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        den = c_m - 2 * c_0 + c_p
        frac = np.where(np.isfinite(den) & (den < 0) & (best == b0), 0.5 * (c_m - c_p) / den, 0.0)
    p = np.abs(shifts[best]) + np.clip(frac, -0.5, 0.5) * step
    score = np.where(np.isfinite(score), score, np.nan)
    p = p.reshape(rows, cols)
    score = score.reshape(rows, cols)
    good = np.isfinite(score) & (score >= min_score)
    if not good.any():
        log.warning("no lens matched its neighbours with correlation >= %.2f; using P = %.2f px everywhere",
                    min_score, 0.5 * (lo + hi))
        return np.full((rows, cols), 0.5 * (lo + hi)), score
    out = _fill_from_neighbours(p, good)
    return out, score


def _fill_from_neighbours(p: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Replace unconfident values by the median of confident ones nearby (growing windows)."""
    import warnings

    from scipy import ndimage

    out = np.where(good, p, np.nan)
    fallback = float(np.median(p[good]))
    for size in (3, 5, 9, 17):
        missing = ~np.isfinite(out)
        if not missing.any():
            break
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = ndimage.generic_filter(np.where(good, p, np.nan), np.nanmedian, size=size, mode="nearest")
        out = np.where(missing, med, out)
    return np.where(np.isfinite(out), out, fallback)


def focus_measure(image, grid: LensletGrid) -> np.ndarray:
    """Tenengrad focus measure of every micro-image centre: mean squared gradient / mean brightness^2.

    Returns
    -------
    ndarray (rows, cols) float64 (0 where unknown)
    """
    img = _as_image(image, grid)
    half = max(2, int(math.floor(0.6 * grid.radius)))
    patches, _ = _lens_patches(img, grid, half)
    lum = patches.mean(axis=-1)
    gy = np.diff(lum, axis=2)[:, :, :, :-1]
    gx = np.diff(lum, axis=3)[:, :, :-1, :]
    import warnings

    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        g2 = np.nanmean(gy ** 2 + gx ** 2, axis=(2, 3))
        mean = np.nanmean(lum, axis=(2, 3))
    f = g2 / np.maximum(mean ** 2, 1e-12)
    return np.where(np.isfinite(f), f, 0.0)


# -------------------------------------------------------------------------------------
# rendering
# -------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _render(img, centres, patch, lens_w, scale, spacing, flip, reach, rmax, out, out2, wsum):  # pragma: no cover
    h, w, nch = img.shape
    ho, wo = wsum.shape
    rows, cols = patch.shape
    for i in range(rows):
        for j in range(cols):
            lw = lens_w[i, j]
            if not lw > 0.0:
                continue
            cy = centres[i, j, 0]
            cx = centres[i, j, 1]
            if not (cy == cy and cx == cx):
                continue
            qy = cy * scale
            qx = cx * scale
            k = patch[i, j] / spacing * flip
            y0 = max(0, int(math.ceil(qy - reach)))
            y1 = min(ho - 1, int(math.floor(qy + reach)))
            x0 = max(0, int(math.ceil(qx - reach)))
            x1 = min(wo - 1, int(math.floor(qx + reach)))
            for oy in range(y0, y1 + 1):
                dy = oy - qy
                for ox in range(x0, x1 + 1):
                    dx = ox - qx
                    r = math.sqrt(dy * dy + dx * dx)
                    if r >= reach:
                        continue
                    my = dy * k
                    mx = dx * k
                    if my * my + mx * mx > rmax * rmax:
                        continue
                    py = cy + my
                    px = cx + mx
                    fy0 = math.floor(py)
                    fx0 = math.floor(px)
                    iy = int(fy0)
                    ix = int(fx0)
                    if iy < 0 or ix < 0 or iy + 1 >= h or ix + 1 >= w:
                        continue
                    fy = py - fy0
                    fx = px - fx0
                    bad = False
                    for c in range(nch):
                        if img[iy, ix, c] != img[iy, ix, c] or img[iy, ix + 1, c] != img[iy, ix + 1, c] or \
                                img[iy + 1, ix, c] != img[iy + 1, ix, c] or img[iy + 1, ix + 1, c] != img[iy + 1, ix + 1, c]:
                            bad = True
                    if bad:
                        continue
                    wgt = lw * (1.0 - r / reach)
                    for c in range(nch):
                        val = ((1 - fy) * ((1 - fx) * img[iy, ix, c] + fx * img[iy, ix + 1, c])
                               + fy * ((1 - fx) * img[iy + 1, ix, c] + fx * img[iy + 1, ix + 1, c]))
                        out[oy, ox, c] += wgt * val
                        out2[oy, ox] += wgt * val * val
                    wsum[oy, ox] += wgt


def render_focused(image, grid: LensletGrid, *, patch: float | np.ndarray, keplerian: bool = True,
                   spacing: float | None = None, feather: float = 1.0, lens_weight: np.ndarray | None = None,
                   white=None, demosaic: str = "malvar") -> FocusedRender:
    """Render a focused-plenoptic raw by tiling micro-image patches (Lumsdaine & Georgiev 2009).

    Parameters
    ----------
    image : RawCapture or ndarray (H, W[, C])
        Scene raw (levels, hot pixels, optional white, demosaicing within lenses are applied), or a
        prepared sensor image.
    grid : LensletGrid
    patch : float or ndarray (rows, cols)
        Patch size ``P`` per lens, px (``D / virtual depth``).
    keplerian : bool
        Flip the patches (Keplerian / inverted micro-images, Raytrix).
    spacing : float, optional
        Output px between neighbouring lens centres; default the median patch size.
    feather : float
        Blending radius around each lens in output-lens-spacings (>= 1/sqrt(3) covers a hex
        lattice; 1.0 blends every point from about three lenses).
    lens_weight : ndarray (rows, cols), optional
        Extra weight per lens (0 = unused), e.g. a focus measure.
    white : RawCapture or ndarray, optional
        White image for devignetting: the raw's white (RawCapture or mosaic) for a raw, a normalised float
        image (H, W[, C]) for a prepared image.

    Returns
    -------
    FocusedRender
    """
    rows, cols = grid.shape
    p = np.broadcast_to(np.asarray(patch, np.float64), (rows, cols)).copy()
    if not np.all(np.isfinite(p)) or np.any(p <= 0):
        raise ValueError("patch must be positive and finite")
    if feather <= 0:
        raise ValueError(f"feather must be > 0, got {feather}")
    img = _as_image(image, grid, white, demosaic)
    sp = float(np.median(p)) if spacing is None else float(spacing)
    if not sp > 0:
        raise ValueError(f"spacing must be > 0, got {spacing}")
    scale = sp / grid.pitch
    h, w = grid.sensor_shape
    ho, wo = int(math.ceil(h * scale)), int(math.ceil(w * scale))
    lw = np.ones((rows, cols)) if lens_weight is None else np.asarray(lens_weight, np.float64)
    if lw.shape != (rows, cols):
        raise ValueError(f"lens_weight must have shape {(rows, cols)}, got {lw.shape}")
    out = np.zeros((ho, wo, img.shape[2]), np.float64)
    out2 = np.zeros((ho, wo), np.float64)
    wsum = np.zeros((ho, wo), np.float64)
    rmax = grid.radius - 1.0
    _render(img, grid.centres_2d(), p, lw, scale, sp, -1.0 if keplerian else 1.0, feather * sp, rmax, out, out2, wsum)
    with np.errstate(invalid="ignore", divide="ignore"):
        has = wsum > 1e-9
        res = np.where(has[..., None], out / wsum[..., None], 0.0)
        var = np.where(has, out2 / wsum - np.sum(res ** 2, axis=-1), 0.0) / img.shape[2]
    spread = np.sqrt(np.maximum(var, 0.0)).astype(np.float32)
    return FocusedRender(image=res.astype(np.float32), weight=wsum.astype(np.float32), patch=p, focus=lw,
                         spacing=sp, scale=scale, spread=spread, keplerian=bool(keplerian))


def focus_weights(focus: np.ndarray, sharpness: float = 2.0) -> np.ndarray:
    """Per-lens weight of the total focus: ``(focus / median(focus > 0)) ** sharpness`` (all 1 for
    ``sharpness = 0``).

    Parameters
    ----------
    focus : ndarray (rows, cols) float64
        :func:`focus_measure` (0 = unknown).
    sharpness : float

    Returns
    -------
    ndarray (rows, cols) float64
    """
    f = np.asarray(focus, np.float64)
    if sharpness <= 0:
        return np.ones(f.shape)
    med = float(np.median(f[f > 0])) if np.any(f > 0) else 1.0
    return (np.maximum(f, 0.0) / med) ** sharpness


def map_to_render(planes: np.ndarray, grid: LensletGrid, render: FocusedRender, *,
                  lens_weight: np.ndarray | None = None, feather: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-sensor-pixel quantities carried onto a rendering's output grid by the rendering's own mapping.

    Output pixel ``q`` takes from lens ``k`` (output position ``s c_k``, patch ``P_k``) its sensor pixel
    ``c_k + flip (q - s c_k) P_k / spacing`` (bilinear) with weight ``lens_weight_k (1 - |q - s c_k| / reach)``,
    ``reach = feather * spacing``, as :func:`render_focused` does for the image: a value made from the same
    sensor pixels as the rendered pixel, so the two align pixel for pixel.

    Parameters
    ----------
    planes : ndarray (H, W, K) float32
        Values on the sensor; a sample touching a NaN is skipped (use 0 and a weight plane instead).
    grid : LensletGrid
    render : FocusedRender
        Its ``patch``, ``scale``, ``spacing`` and ``keplerian`` (and output shape) are used.
    lens_weight : ndarray (rows, cols), optional
        Weight per lens (default: the total focus's, :func:`focus_weights` of ``render.focus``).
    feather : float
        Blending radius in output lens spacings (as the rendering).

    Returns
    -------
    sums : ndarray (Ho, Wo, K) float64
        ``sum_k w_k planes_k`` at every output pixel.
    wsum : ndarray (Ho, Wo) float64
        ``sum_k w_k``.
    """
    pl = np.ascontiguousarray(planes, np.float32)
    if pl.ndim != 3 or pl.shape[:2] != tuple(grid.sensor_shape):
        raise ValueError(f"planes must be (H, W, K) with (H, W) = {tuple(grid.sensor_shape)}, got {pl.shape}")
    lw = focus_weights(render.focus) if lens_weight is None else np.asarray(lens_weight, np.float64)
    ho, wo = render.image.shape[:2]
    sums = np.zeros((ho, wo, pl.shape[2]), np.float64)
    sq = np.zeros((ho, wo), np.float64)
    wsum = np.zeros((ho, wo), np.float64)
    _render(pl, grid.centres_2d(), np.asarray(render.patch, np.float64), lw, render.scale, render.spacing,
            -1.0 if render.keplerian else 1.0, feather * render.spacing, grid.radius - 1.0, sums, sq, wsum)
    return sums, wsum


def render_total_focus(raw, grid: LensletGrid, *, patch: float | np.ndarray | None = None, white=None,
                       keplerian: bool | None = None, spacing: float | None = None, sharpness: float = 2.0,
                       feather: float = 1.0, p_range: tuple[float, float] | None = None,
                       demosaic: str = "malvar", progress: Callable[[int, int], None] | None = None) -> FocusedRender:
    """All-in-focus ("total focus") rendering of a focused / multi-focus plenoptic raw.

    Parameters
    ----------
    raw : RawCapture or ndarray (H, W[, C])
        Scene raw (or prepared sensor image).
    grid : LensletGrid
        With ``lens_type`` for Raytrix multi-focus arrays (used through the focus weights).
    patch : float or ndarray (rows, cols), optional
        Patch size per lens; default: estimated per lens (:func:`estimate_patch_sizes`).
    white : optional
        White image for devignetting (as for :func:`render_focused`).
    keplerian : bool or None
        Micro-image orientation; None detects it from the data (:func:`estimate_patch_sizes`).
    spacing : float, optional
        Output px between lens centres (default: median patch).
    sharpness : float
        Exponent of the per-lens focus weight (0 = plain blending of all lenses).
    feather : float
        Blending radius in output lens spacings.
    p_range : (float, float), optional
        Range searched for the patch sizes.
    progress : callable(done, total), optional

    Returns
    -------
    FocusedRender
        ``patch`` holds the per-lens P, ``focus`` the focus measure.
    """
    if sharpness < 0:
        raise ValueError(f"sharpness must be >= 0, got {sharpness}")
    img = _as_image(raw, grid, white, demosaic)
    if progress:
        progress(1, 4)
    if patch is None or keplerian is None:
        if keplerian is None:
            p_est, score, keplerian = _estimate_auto(img, grid, p_range=p_range)
        else:
            p_est, score = estimate_patch_sizes(img, grid, keplerian=keplerian, p_range=p_range)
        log.info("patch sizes: median %.2f px, %.0f%% confident lenses", float(np.median(p_est)),
                 100.0 * float(np.mean(np.nan_to_num(score, nan=0.0) >= 0.5)))
    p = p_est if patch is None else np.broadcast_to(np.asarray(patch, np.float64), grid.shape).copy()
    if progress:
        progress(2, 4)
    f = focus_measure(img, grid)
    if progress:
        progress(3, 4)
    lw = focus_weights(f, sharpness)
    res = render_focused(img, grid, patch=p, keplerian=keplerian, spacing=spacing, feather=feather, lens_weight=lw)
    if progress:
        progress(4, 4)
    return FocusedRender(image=res.image, weight=res.weight, patch=p, focus=f, spacing=res.spacing, scale=res.scale,
                         spread=res.spread, keplerian=res.keplerian)


# -------------------------------------------------------------------------------------
# refocus at a chosen virtual depth
# -------------------------------------------------------------------------------------
#: Weight of a lens whose type is not in focus at the chosen virtual depth (its depth range, RayCalibData).
OUT_OF_RANGE_WEIGHT = 0.05
#: Smallest patch size a virtual depth may ask for when the calibration has no depth ranges, px.
MIN_PATCH_PX = 2.0


def _lens_depth_ranges(grid: LensletGrid) -> dict[int, tuple[float, float]]:
    """Lens type id -> its (min, max) virtual depth, from the RayCalibData the grid came from (may be empty)."""
    types = (grid.info or {}).get("raytrix", {}).get("lens_types", ()) if isinstance(grid.info, dict) else ()
    return {int(t["id"]): (float(t["depth_range"][0]), float(t["depth_range"][1]))
            for t in types if t.get("depth_range") is not None}


def virtual_depth_range(grid: LensletGrid) -> tuple[float, float]:
    """The virtual depths ``v`` a focused-plenoptic raw can be rendered at, ``(lowest, highest)``.

    A point at virtual depth ``v`` repeats every ``P = D / v`` px in neighbouring micro-images (``D`` the lens
    pitch, px); the patch ``P`` is cut from one micro-image, so ``P < 2 r`` (the micro-image diameter), i.e.
    ``v > D / (2 r)``.  Within that, the range is the union of the lens types' depth ranges of the
    RayCalibData (R42: 1..3, 2.8..4, 3.8..100); without them, up to ``D / 2`` (a patch of 2 px).

    Returns
    -------
    (float, float)
        Both ends included.
    """
    geometric = float(grid.pitch) / (2.0 * float(grid.radius)) * (1.0 + 1e-6)
    ranges = list(_lens_depth_ranges(grid).values())
    if not ranges:
        return geometric, float(grid.pitch) / MIN_PATCH_PX
    return max(geometric, min(r[0] for r in ranges)), max(r[1] for r in ranges)


def shown_virtual_depth_range(grid: LensletGrid) -> tuple[float, float]:
    """:func:`virtual_depth_range` to three significant digits, rounded inwards (the R42's 1.0609 .. 100 reads
    1.07 .. 100): every value a message shows is one :func:`check_virtual_depth` accepts."""
    def inward(x: float, up: bool) -> float:
        scale = 10.0 ** (2 - math.floor(math.log10(x)))
        return (math.ceil(x * scale) if up else math.floor(x * scale)) / scale

    lo, hi = virtual_depth_range(grid)
    return max(lo, inward(lo, True)), min(hi, inward(hi, False))


def check_virtual_depth(grid: LensletGrid, virtual_depth: float) -> None:
    """Raise ValueError naming ``virtual_depth`` unless it lies in :func:`virtual_depth_range` (the message shows
    :func:`shown_virtual_depth_range`)."""
    lo, hi = virtual_depth_range(grid)
    if not (math.isfinite(virtual_depth) and lo <= virtual_depth <= hi):
        source = "its lens types' depth ranges" if _lens_depth_ranges(grid) else "its micro-image size"
        lo, hi = shown_virtual_depth_range(grid)
        raise ValueError(f"virtual depth must lie in [{lo:g}, {hi:g}] for this camera ({source}; patch = "
                         f"lens pitch {grid.pitch:.2f} px / virtual depth), got {virtual_depth:g}")


def lens_weights_at(grid: LensletGrid, virtual_depth: float) -> np.ndarray:
    """Per-lens weight for a rendering at ``virtual_depth``: 1 for the lens types whose depth range holds it,
    :data:`OUT_OF_RANGE_WEIGHT` for the others (they still fill gaps); all 1 without lens types or ranges.

    Returns
    -------
    ndarray (rows, cols) float64
    """
    ranges = _lens_depth_ranges(grid)
    if grid.lens_type is None or not ranges:
        return np.ones(grid.shape)
    sharp = [tid for tid, (lo, hi) in ranges.items() if lo <= virtual_depth <= hi]
    if not sharp:
        return np.ones(grid.shape)
    return np.where(np.isin(grid.lens_type, sharp), 1.0, OUT_OF_RANGE_WEIGHT)


def detect_orientation(image, grid: LensletGrid) -> bool:
    """True when the micro-images are inverted (Keplerian), False when upright (Galilean): the orientation whose
    neighbour matches correlate better (:func:`estimate_patch_sizes`)."""
    return _estimate_auto(_as_image(image, grid), grid)[2]


def render_at_virtual_depth(raw, grid: LensletGrid, virtual_depth: float, *, white=None,
                            keplerian: bool | None = None, feather: float = 1.0,
                            demosaic: str = "malvar") -> FocusedRender:
    """A focused-plenoptic raw refocused at one virtual depth: every lens gives a patch of
    ``P = D / virtual_depth`` px (Lumsdaine & Georgiev 2009), the lens types in focus there weigh most
    (:func:`lens_weights_at`), tiled at ``P`` output px per lens (the sampling of that depth).

    Parameters
    ----------
    raw : RawCapture or ndarray (H, W[, C])
        Scene raw, or a prepared sensor image.
    grid : LensletGrid
        The raw's grid; its RayCalibData (``grid.info['raytrix']``) gives the lens types' depth ranges.
    virtual_depth : float
        In :func:`virtual_depth_range`.
    white : optional
        White image for devignetting (as for :func:`render_focused`).
    keplerian : bool or None
        Micro-image orientation; None detects it (:func:`detect_orientation`).

    Returns
    -------
    FocusedRender

    Raises
    ------
    ValueError
        ``virtual_depth`` out of range (:func:`check_virtual_depth`).
    """
    check_virtual_depth(grid, virtual_depth)
    img = _as_image(raw, grid, white, demosaic)
    if keplerian is None:
        keplerian = detect_orientation(img, grid)
    return render_focused(img, grid, patch=float(grid.pitch) / float(virtual_depth), keplerian=keplerian,
                          feather=feather, lens_weight=lens_weights_at(grid, virtual_depth))


__all__ = ["FocusedRender", "estimate_patch_sizes", "focus_measure", "render_focused", "render_total_focus",
           "focus_weights", "map_to_render",
           "virtual_depth_range", "shown_virtual_depth_range", "check_virtual_depth", "lens_weights_at",
           "detect_orientation",
           "render_at_virtual_depth"]
