"""Disk rims (self-calibration from scene raws, :mod:`plenodecode.calib.selfcal`).

A scene's brightness moves intensity peaks, but not the dark gap around each disk: the disks are
located by their rims instead -- :func:`rim_gradients`, :func:`rim_votes` (fixed-radius Hough
transform [4]_) and :func:`refine_rims` (circle of known radius fitted to the lit part of each rim).

References
----------
.. [4] C. Kimme, D. Ballard, J. Sklansky, "Finding circles by an array of accumulators",
   Communications of the ACM 18(2), 1975 (votes along the gradient direction).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..._numba import njit, run_in_blocks
from .contrast import devignette


#: Half-width (px) of the band about the rim radius whose pixels a rim fit uses.
RIM_BAND = 2.5
#: Over-relaxation of the rim fit's Gauss-Newton steps (the band taper makes plain steps too short).
RIM_RELAX = 1.7


def rim_gradients(img: np.ndarray, pitch: float, *, sigma: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Gradient of the lenslet contrast image, the input of the disk-rim estimators.

    ``grad( G_sigma * (I / L - 1) )`` with ``I / L - 1`` from :func:`devignette` (scene brightness
    divided out at the lens scale, so dim and bright micro-images weigh alike; dark regions are 0)
    and 3x3 Sobel derivatives.

    Parameters
    ----------
    img : ndarray (H, W) float32
        Flattened image.
    pitch : float
        Lattice pitch, px.
    sigma : float
        Gaussian pre-smoothing, px.

    Returns
    -------
    gy, gx : ndarray (H, W) float32
        d/drow and d/dcol, per px.
    """
    cs = cv2.GaussianBlur(devignette(img, pitch), (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(cs, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8, borderType=cv2.BORDER_REFLECT)
    gx = cv2.Sobel(cs, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8, borderType=cv2.BORDER_REFLECT)
    return gy, gx


@njit(cache=True)
def _splat_votes(gy, gx, radius, threshold):  # pragma: no cover - compiled
    h, w = gy.shape
    acc = np.zeros((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            vy = gy[i, j]
            vx = gx[i, j]
            m = math.sqrt(vy * vy + vx * vx)
            if m <= threshold:
                continue
            y = i + radius * vy / m
            x = j + radius * vx / m
            y0 = int(math.floor(y))
            x0 = int(math.floor(x))
            if y0 < 0 or x0 < 0 or y0 + 1 >= h or x0 + 1 >= w:
                continue
            fy = y - y0
            fx = x - x0
            acc[y0, x0] += m * (1 - fy) * (1 - fx)
            acc[y0, x0 + 1] += m * (1 - fy) * fx
            acc[y0 + 1, x0] += m * fy * (1 - fx)
            acc[y0 + 1, x0 + 1] += m * fy * fx
    return acc


def rim_votes(gy: np.ndarray, gx: np.ndarray, radius: float, *, min_gradient: float = 0.1) -> np.ndarray:
    """Fixed-radius Hough transform for disk centres, using the gradient direction.

    A disk is brighter than the dark gap around it whatever the scene, so the gradient on its
    rim points to its centre: every pixel ``p`` whose gradient ``g`` exceeds ``min_gradient``
    times the 99th percentile of ``|g|`` votes ``|g|`` at ``p + radius * g / |g|`` (bilinear
    splat).  Edges of the scene inside a micro-image scatter their votes; the rim's votes meet at
    the centre (Kimme, Ballard & Sklansky 1975 [4]_).

    Returns
    -------
    ndarray (H, W) float32
        The vote accumulator.
    """
    mag = np.hypot(gy[::3, ::3], gx[::3, ::3])
    thr = float(min_gradient * np.percentile(mag, 99))
    return _splat_votes(np.ascontiguousarray(gy), np.ascontiguousarray(gx), float(radius), thr)


@njit(cache=True, nogil=True, fastmath=True)
def _rim_fit(gy, gx, start, radius, band, n_iter, relax, tol, out, ok, k0, k1):  # pragma: no cover - compiled
    """Disks ``k0 .. k1`` of :func:`refine_rims` into ``out`` (N, 2) and ``ok`` (N,) (see there)."""
    h, w = gy.shape
    half = int(math.ceil(radius + band + 1.0))
    for k in range(k0, k1):
        cy = start[k, 0]
        cx = start[k, 1]
        for _ in range(n_iter):
            iy = int(math.floor(cy + 0.5))
            ix = int(math.floor(cx + 0.5))
            if iy - half < 0 or ix - half < 0 or iy + half >= h or ix + half >= w:
                ok[k] = False
                break
            a11 = 0.0
            a12 = 0.0
            a22 = 0.0
            b1 = 0.0
            b2 = 0.0
            r_out = radius + band
            r_in = max(radius - band, 0.0)
            for r in range(iy - half, iy + half + 1):
                dy = cy - r
                q_out = r_out * r_out - dy * dy
                if q_out <= 0.0:
                    continue
                x_out = math.sqrt(q_out)
                q_in = r_in * r_in - dy * dy
                x_in = math.sqrt(q_in) if q_in > 0.0 else 0.0
                # the columns of this row inside the annulus: two runs, cx - x_out..cx - x_in and cx + x_in..cx + x_out
                for side in range(2):
                    if side == 0:
                        c0 = int(math.ceil(cx - x_out))
                        c1 = int(math.floor(cx - x_in))
                    else:
                        c0 = max(int(math.ceil(cx + x_in)), int(math.floor(cx - x_in)) + 1)
                        c1 = int(math.floor(cx + x_out))
                    for c in range(max(c0, ix - half), min(c1, ix + half) + 1):
                        dx = cx - c
                        d = math.sqrt(dy * dy + dx * dx)
                        res = d - radius
                        if abs(res) >= band or d < 1e-9:
                            continue
                        uy = dy / d
                        ux = dx / d
                        gi = gy[r, c] * uy + gx[r, c] * ux  # gradient towards the centre
                        if gi <= 0.0:
                            continue
                        t = res / band
                        wgt = gi * (1.0 - t * t)
                        a11 += wgt * uy * uy
                        a12 += wgt * uy * ux
                        a22 += wgt * ux * ux
                        b1 -= wgt * res * uy
                        b2 -= wgt * res * ux
            # the normal matrix must constrain both axes: the lit rim spans enough angle
            tr = a11 + a22
            det = a11 * a22 - a12 * a12
            if tr <= 0.0 or det <= 0.04 * tr * tr:
                ok[k] = False
                break
            sy = (a22 * b1 - a12 * b2) / det
            sx = (a11 * b2 - a12 * b1) / det
            nrm = math.sqrt(sy * sy + sx * sx)
            if nrm > 1.0:
                sy /= nrm
                sx /= nrm
            cy += relax * sy
            cx += relax * sx
            if nrm < tol:
                break
        if abs(cy - start[k, 0]) > band + 1.0 or abs(cx - start[k, 1]) > band + 1.0:
            ok[k] = False
        out[k, 0] = cy
        out[k, 1] = cx


def refine_rims(gy: np.ndarray, gx: np.ndarray, start: np.ndarray, radius: float, *, band: float = RIM_BAND,
                n_iter: int = 20, tol: float = 2e-3) -> tuple[np.ndarray, np.ndarray]:
    """Disk centres as the centres of circles of known radius fitted to the lit part of each rim.

    For each disk, Gauss-Newton minimises ``sum_p w_p (|p - c| - radius)^2`` over the pixels
    within ``band`` of the circle whose gradient points towards ``c``, with weight
    ``w_p = (g_p . u_p) (1 - (res / band)^2)`` (``u_p`` the unit vector to ``c``; the steps are
    over-relaxed by :data:`RIM_RELAX`, as the taper makes each step fall short).  Only
    positions enter the residuals -- not the gradient directions, which scene texture tilts --
    and a rim profile symmetric about ``radius`` pulls equally from both sides, so a half-lit
    disk is centred as well as a fully lit one.  A disk whose lit rim spans too small an angle
    (normal matrix with ``det < 0.04 trace^2``) is dropped.

    Parameters
    ----------
    gy, gx : ndarray (H, W) float32
        :func:`rim_gradients`.
    start : ndarray (N, 2)
        Initial centres (within ~``band`` px).
    radius : float
        Rim radius, px.
    band : float
        Half-width of the band of pixels used, px.
    n_iter : int
        Largest number of Gauss-Newton steps.
    tol : float
        Stop once a step is shorter than this, px.

    Returns
    -------
    centres : ndarray (N, 2) float64
    ok : ndarray (N,) bool
    """
    if len(start) == 0:
        return np.zeros((0, 2)), np.zeros(0, bool)
    gy, gx = np.ascontiguousarray(gy, np.float32), np.ascontiguousarray(gx, np.float32)
    start = np.ascontiguousarray(start, np.float64)
    out = np.empty((len(start), 2))
    ok = np.ones(len(start), bool)
    run_in_blocks(lambda k0, k1: _rim_fit(gy, gx, start, float(radius), float(band), int(n_iter), float(RIM_RELAX),
                                          float(tol), out, ok, k0, k1), len(start))
    return out, ok
