"""The lenslet contrast image ``I / L - 1``: brightness divided out at the lens scale.

:func:`local_mean` is a Gaussian-weighted local *linear* regression (normalised convolution,
Knutsson & Westin 1993), which, unlike a plain blur, keeps a vignetting slope up to the border;
:func:`devignette` divides by it, so brightness gradients do not bias the centres.
"""

from __future__ import annotations

import math

import cv2
import numpy as np


def _blur_1d_moments(n: int, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Zero-padded 1-D Gaussian blurs of ``1``, ``t``, ``t^2`` over ``t = 0..n-1`` (centred), and ``t``."""
    t = np.arange(n, dtype=np.float64) - n / 2
    half = int(math.ceil(4 * sigma))
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    k /= k.sum()
    conv = [np.convolve(v, k, mode="same") if n >= len(k) else np.convolve(v, k, mode="full")[half:half + n]
            for v in (np.ones(n), t, t * t)]
    return conv[0], conv[1], conv[2], t


def _local_linear_level(r1: np.ndarray, ry: np.ndarray, ryy: np.ndarray, ty: np.ndarray, c1: np.ndarray,
                        cx: np.ndarray, cxx: np.ndarray, tx: np.ndarray, s0: np.ndarray, sy: np.ndarray,
                        sx: np.ndarray) -> np.ndarray:
    """``beta0`` of the 3x3 normal equations of :func:`local_mean` per pixel (Cramer's rule), float32 (hs, ws).

    The geometric moments are separable: with ``a_y = G*(y' - y)``, ``a_yy = G*(y' - y)^2`` along the rows
    (from the 1-D blurs ``r1, ry, ryy`` of ``1, t, t^2`` and ``ty``; likewise ``a_x, a_xx`` along the columns),
    ``g1 = r1 c1``, ``m0y = a_y c1``, ``m0x = r1 a_x``, ``myy = a_yy c1``, ``mxx = r1 a_xx``, ``mxy = a_y a_x``
    (outer products, float64).  ``s0, sy, sx`` (hs, ws) are the Gaussian blurs of ``I``, ``I t_y`` and
    ``I t_x``.  A determinant tiny against the largest (a degenerate fit) falls back to the plain mean.
    """
    ay, ayy = ry - ty * r1, ryy - 2 * ty * ry + ty * ty * r1
    ax, axx = cx - tx * c1, cxx - 2 * tx * cx + tx * tx * c1
    col = (slice(None), None)
    g1, m0y, m0x = r1[col] * c1, ay[col] * c1, r1[col] * ax
    myy, mxx, mxy = ayy[col] * c1, r1[col] * axx, ay[col] * ax
    c00 = myy * mxx - mxy * mxy                 # cofactors of the first row of [[g1, m0y, m0x], ...]
    c01 = m0x * mxy - m0y * mxx
    c02 = m0y * mxy - m0x * myy
    det = g1 * c00 + m0y * c01 + m0x * c02
    v0 = s0.astype(np.float64)
    by = sy - ty[col] * v0
    bx = sx - tx * v0
    fit = np.abs(det) > 1e-9 * np.abs(det).max()
    with np.errstate(divide="ignore", invalid="ignore"):
        level = np.where(fit, (c00 * v0 + c01 * by + c02 * bx) / det, v0 / np.maximum(g1, 1e-12))
    return level.astype(np.float32)


def local_mean(img: np.ndarray, sigma: float) -> np.ndarray:
    """Local brightness level: Gaussian-weighted local *linear* regression of ``img``.

    At each pixel ``x`` the plane ``beta0 + beta . (x' - x)`` minimising
    ``sum_x' G_sigma(x' - x) (img(x') - beta0 - beta . (x' - x))^2`` is fitted and ``beta0``
    returned (normalised convolution with a first-order model, Knutsson & Westin 1993).  Inside
    the image this equals the Gaussian mean; near the borders, where a plain blur flattens a
    vignetting slope and so tilts every disk there, a linear trend is still reproduced.
    The geometric moments are separable 1-D blurs; the data moments are three 2-D blurs of an
    image area-reduced by ``f = max(1, round(sigma / 4))``, enlarged back bilinearly (cv2's
    pixel-centre conventions keep it aligned).

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
    sigma : float
        Gaussian sigma, px.

    Returns
    -------
    ndarray, shape (H, W), float32
    """
    h, w = img.shape
    f = max(1, int(round(sigma / 4)))
    hs, ws = max(1, h // f), max(1, w // f)
    small = img[:hs * f, :ws * f]
    if f > 1:
        small = cv2.resize(small, (ws, hs), interpolation=cv2.INTER_AREA)
    small = np.ascontiguousarray(small, np.float32)
    sg = sigma / f
    r1, ry, ryy, ty = _blur_1d_moments(hs, sg)
    c1, cx, cxx, tx = _blur_1d_moments(ws, sg)

    def blur(a: np.ndarray) -> np.ndarray:
        return cv2.GaussianBlur(a, (0, 0), sg, borderType=cv2.BORDER_CONSTANT)
    s0 = blur(small)
    sy = blur(small * ty[:, None].astype(np.float32))
    sx = blur(small * tx[None, :].astype(np.float32))
    lvl = _local_linear_level(r1, ry, ryy, ty, c1, cx, cxx, tx, s0, sy, sx)
    if f == 1:
        return lvl
    # pad one small pixel on every side by linear extrapolation, so the bilinear enlargement keeps
    # a linear trend up to the border instead of clamping it; then crop the aligned view
    padded = np.empty((hs + 2, ws + 2), np.float32)
    padded[1:-1, 1:-1] = lvl
    if hs > 1:
        padded[0, 1:-1] = 2 * lvl[0] - lvl[1]
        padded[-1, 1:-1] = 2 * lvl[-1] - lvl[-2]
    else:
        padded[0, 1:-1] = padded[-1, 1:-1] = lvl[0]
    if ws > 1:
        padded[:, 0] = 2 * padded[:, 1] - padded[:, 2]
        padded[:, -1] = 2 * padded[:, -2] - padded[:, -3]
    else:
        padded[:, 0] = padded[:, -1] = padded[:, 1]
    big = cv2.resize(padded, ((ws + 2) * f, (hs + 2) * f), interpolation=cv2.INTER_LINEAR)
    return big[f:f + h, f:f + w]


def devignette(img: np.ndarray, pitch: float, *, floor: float = 0.02) -> np.ndarray:
    """Zero-mean lenslet contrast image ``I / L - 1`` with ``L`` the local mean over ~one pitch.

    Dividing by the local mean (a Gaussian of sigma = pitch, which removes the lattice's
    fundamental frequency entirely) flattens sensor vignetting or scene brightness, and removing
    the mean leaves only the lenslet pattern; without it a brightness gradient across a window
    shifts a peak of the weakly modulated, nearly touching disks by tenths of a pixel.

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
    pitch : float
        Lattice pitch, px.
    floor : float
        ``L`` is clamped to at least ``floor`` times its 99th percentile (dark regions stay ~0).

    Returns
    -------
    ndarray, shape (H, W), float32
    """
    lm = local_mean(img, 1.5 * float(pitch))
    top = float(np.percentile(lm[::4, ::4], 99))
    lo = np.float32(max(floor * top, 1e-6))
    # I / L - 1 where L >= lo, else 0 (cv2.divide gives 0 where L is 0; those pixels are cleared anyway)
    out = cv2.divide(np.ascontiguousarray(img, np.float32), lm)
    np.subtract(out, np.float32(1.0), out=out)
    out[~(lm >= lo)] = 0.0
    return out
