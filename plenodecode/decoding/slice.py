"""Slicing a lenslet image into sub-aperture samples.

A sub-aperture view ``(v, u)`` takes, from every lens ``k``, the value of the micro-image at
``c_k + (v - vc) * e_row + (u - uc) * e_col`` (sensor px; ``c_k`` the lens centre, ``e_row``,
``e_col`` the lattice axes, so the view offset is expressed in the lattice frame, one view step =
one sensor pixel; see the decoded sampling contract in :mod:`plenodecode.types`).

The value is interpolated bilinearly from the pixels of the *same* micro-image only: every pixel
carries the label of the lens whose Voronoi cell contains it (:func:`lens_labels`) and
pixels of other lenses, or pixels without a value (NaN), are left out and the remaining bilinear
weights renormalised (normalised convolution, Knutsson & Westin, CVPR 1993).  So light never
mixes across lenslet borders.

The sensor is processed in bands of lens rows (:func:`plan_bands`) to bound memory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .._numba import njit
from ..types import LensletGrid

#: Half-size (in units of the lens pitch) of the box searched around each lens when labelling
#: pixels: covers the Voronoi cell of a hex (0.577 pitch) and a square (0.707 pitch) lattice.
CELL_REACH = 0.75


def view_offsets(grid: LensletGrid, n_views: int) -> np.ndarray:
    """Sensor offset of every view from its lens centre.

    Parameters
    ----------
    grid : LensletGrid
    n_views : int
        Views per angular axis (odd).

    Returns
    -------
    ndarray, shape (n_views, n_views, 2), float64
        ``(row, col)`` offset ``(v - vc) * e_row + (u - uc) * e_col`` with ``vc = uc = n_views // 2``.
    """
    e_row, e_col = grid.axes()
    k = np.arange(n_views, dtype=np.float64) - n_views // 2
    return k[:, None, None] * e_row + k[None, :, None] * e_col


@dataclass(frozen=True)
class Band:
    """One band of lens rows and the sensor rows it needs.

    ``rows`` = lens rows ``[i0, i1)`` decoded by this band; ``ext`` = lens rows ``[e0, e1)`` labelled
    (one more on each side, so Voronoi cells at the band border are right); ``sensor`` = sensor rows
    ``[r0, r1)`` read (``r0`` even so the CFA phase is kept).
    """

    i0: int
    i1: int
    e0: int
    e1: int
    r0: int
    r1: int


def plan_bands(grid: LensletGrid, *, max_pixels: int = 2_500_000, margin: int = 4) -> list[Band]:
    """Split the lens rows into bands whose sensor footprint has at most about ``max_pixels`` pixels.

    Parameters
    ----------
    grid : LensletGrid
    max_pixels : int
        Target number of sensor pixels per band (memory per worker is about 40 bytes per pixel).
    margin : int
        Extra sensor rows above and below the lens cells (demosaicing and hot-pixel neighbourhoods).

    Returns
    -------
    list of Band
    """
    h, w = grid.sensor_shape
    rows = grid.shape[0]
    centres = grid.centres_2d()
    reach = CELL_REACH * max(grid.pitch, grid.row_spacing) + margin
    # sensor row span of each lens row (its lenses' centres +- reach), robust to NaN
    with np.errstate(all="ignore"):
        lo = np.nanmin(centres[..., 0], axis=1) - reach
        hi = np.nanmax(centres[..., 0], axis=1) + reach
    lo = np.where(np.isfinite(lo), lo, 0.0)
    hi = np.where(np.isfinite(hi), hi, 0.0)
    n_per = max(1, min(rows, int(max_pixels // max(1.0, grid.row_spacing * w))))
    bands = []
    for i0 in range(0, rows, n_per):
        i1 = min(rows, i0 + n_per)
        e0, e1 = max(0, i0 - 1), min(rows, i1 + 1)
        r0 = int(math.floor(lo[e0:e1].min()))
        r1 = int(math.ceil(hi[e0:e1].max())) + 1
        r0 = max(0, min(h, r0))
        r0 -= r0 % 2
        r1 = max(r0, min(h, r1))
        bands.append(Band(i0, i1, e0, e1, r0, r1))
    return bands


@njit(cache=True, nogil=True)
def _label_cells(centres, reach, labels, dist2):  # pragma: no cover - numba
    h, w = labels.shape
    nr, nc = centres.shape[0], centres.shape[1]
    r2 = reach * reach
    for y in range(h):
        for x in range(w):
            labels[y, x] = -1
            dist2[y, x] = r2
    for i in range(nr):
        for j in range(nc):
            cy = centres[i, j, 0]
            cx = centres[i, j, 1]
            if not (cy == cy and cx == cx):
                continue
            y0 = max(0, int(math.floor(cy - reach)))
            y1 = min(h - 1, int(math.ceil(cy + reach)))
            x0 = max(0, int(math.floor(cx - reach)))
            x1 = min(w - 1, int(math.ceil(cx + reach)))
            lab = i * nc + j
            for y in range(y0, y1 + 1):
                dy = y - cy
                for x in range(x0, x1 + 1):
                    dx = x - cx
                    d = dy * dy + dx * dx
                    if d < dist2[y, x]:
                        dist2[y, x] = d
                        labels[y, x] = lab


def lens_labels(centres: np.ndarray, shape: tuple[int, int], reach: float, *,
                out: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Label every pixel with the lens whose centre is nearest (the lens's Voronoi cell).

    Parameters
    ----------
    centres : ndarray, shape (R, C, 2), float64
        Lens centres ``(row, col)`` in the coordinates of the labelled image; NaN = no lens.
    shape : (int, int)
        ``(H, W)`` of the labelled image.
    reach : float
        Pixels farther than ``reach`` px from every lens stay unlabelled.
    out : (ndarray int32, ndarray float32), optional
        Destinations of the labels and distances.

    Returns
    -------
    labels : ndarray, shape (H, W), int32
        ``i * C + j`` for lens ``(i, j)``, -1 where no lens is within ``reach``.
    dist : ndarray, shape (H, W), float32
        Distance to that lens centre, px.
    """
    labels, dist2 = (np.empty(shape, np.int32), np.empty(shape, np.float32)) if out is None else out
    _label_cells(np.ascontiguousarray(centres, np.float64), float(reach), labels, dist2)
    np.sqrt(dist2, out=dist2)
    return labels, dist2


#: LLVM fast-math flags without 'nnan'/'ninf' (NaN marks missing pixels)
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _known(image, labels, usable, lab, y, x):  # pragma: no cover - numba
    """Is pixel ``(y, x)`` (inside the image) one of lens ``lab``'s, usable and with a value?"""
    p0 = image[y, x, 0]
    return labels[y, x] == lab and usable[y, x] and p0 == p0


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _nearest_known_cell(image, labels, usable, lab, y0, x0, fy, fx):  # pragma: no cover - numba
    """The 2 x 2 cell of known pixels of lens ``lab`` nearest to the point ``(y0 + fy, x0 + fx)``.

    Candidates are the bilinear cell ``[y0, y0 + 1] x [x0, x0 + 1]`` moved by ``(sy, sx)`` in
    ``{-1, 0, 1}^2``; the point lies ``fy`` (``sy = -1``), 0 or ``1 - fy`` (``sy = +1``) rows outside
    the moved cell, likewise for columns, and the cell with the smallest squared distance wins.
    Returns ``3 * (sy + 1) + (sx + 1)``, or 9 when no candidate has four known pixels.
    """
    h, w = labels.shape
    best = 9
    best_d = np.float32(3.0)
    for cell in range(9):
        sy = cell // 3 - 1
        sx = cell % 3 - 1
        ey = fy if sy < 0 else (np.float32(1.0) - fy if sy > 0 else np.float32(0.0))
        ex = fx if sx < 0 else (np.float32(1.0) - fx if sx > 0 else np.float32(0.0))
        d = ey * ey + ex * ex
        ya = y0 + sy
        xa = x0 + sx
        if d >= best_d or ya < 0 or ya + 1 >= h or xa < 0 or xa + 1 >= w:
            continue
        if (_known(image, labels, usable, lab, ya, xa) and _known(image, labels, usable, lab, ya, xa + 1)
                and _known(image, labels, usable, lab, ya + 1, xa)
                and _known(image, labels, usable, lab, ya + 1, xa + 1)):
            best = cell
            best_d = d
    return best


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _plane_at(image, labels, usable, lab, y0, x0, fy, fx):  # pragma: no cover - numba
    """Weighted least-squares plane through the known pixels of lens ``lab`` around ``(y0 + fy, x0 + fx)``,
    evaluated there (for a point with no full cell of known pixels nearby, :func:`_nearest_known_cell`).

    Window ``[y0 - 2, y0 + 3] x [x0 - 2, x0 + 3]`` (6 x 6: it reaches the known pixels of a point up to
    two pixels outside them), weights ``(3.5 - |dy|) (3.5 - |dx|)`` with ``(dy, dx)``
    the pixel's offset from the point; minimises ``sum w (f - c0 - c1 dy - c2 dx)^2`` and returns ``c0``:
    the equivalent stencil has unit sum and its centroid at the point, so a linear radiance is exact.
    Returns ``(ok, c0 of channels 0, 1, 2)``; ok is False with fewer than three non-collinear known pixels.
    """
    h, w = labels.shape
    nch = image.shape[2]
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    r0 = r1 = r2 = g0 = g1 = g2 = b0 = b1 = b2 = 0.0
    for yy in range(max(0, y0 - 2), min(h, y0 + 4)):
        dy = yy - y0 - float(fy)
        for xx in range(max(0, x0 - 2), min(w, x0 + 4)):
            if not _known(image, labels, usable, lab, yy, xx):
                continue
            dx = xx - x0 - float(fx)
            wgt = (3.5 - abs(dy)) * (3.5 - abs(dx))
            s00 += wgt
            s01 += wgt * dy
            s02 += wgt * dx
            s11 += wgt * dy * dy
            s12 += wgt * dy * dx
            s22 += wgt * dx * dx
            f = wgt * image[yy, xx, 0]
            r0 += f
            r1 += f * dy
            r2 += f * dx
            if nch == 3:
                f = wgt * image[yy, xx, 1]
                g0 += f
                g1 += f * dy
                g2 += f * dx
                f = wgt * image[yy, xx, 2]
                b0 += f
                b1 += f * dy
                b2 += f * dx
    # c0 = first row of the inverse of the (symmetric) normal matrix times the right-hand side, by cofactors
    c00 = s11 * s22 - s12 * s12
    c01 = s02 * s12 - s01 * s22
    c02 = s01 * s12 - s02 * s11
    det = s00 * c00 + s01 * c01 + s02 * c02
    if not (s00 > 0.0 and det > 1e-3 * s00 * s00 * s00):
        return False, 0.0, 0.0, 0.0
    return (True, (c00 * r0 + c01 * r1 + c02 * r2) / det, (c00 * g0 + c01 * g1 + c02 * g2) / det,
            (c00 * b0 + c01 * b1 + c02 * b2) / det)


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _sample(image, rel, labels, usable, centres, first_label, nc_label, offsets, inner, reach, matrix, out,
            out_w):  # pragma: no cover
    h, w, nch = image.shape
    nr, nc = centres.shape[0], centres.shape[1]
    nv, nu = offsets.shape[0], offsets.shape[1]
    m00, m01, m02 = matrix[0, 0], matrix[0, 1], matrix[0, 2]
    m10, m11, m12 = matrix[1, 0], matrix[1, 1], matrix[1, 2]
    m20, m21, m22 = matrix[2, 0], matrix[2, 1], matrix[2, 2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    for i in range(nr):
        for j in range(nc):
            cy = centres[i, j, 0]
            cx = centres[i, j, 1]
            lab = first_label + i * nc_label + j
            if not (cy == cy and cx == cx):
                for v in range(nv):
                    for u in range(nu):
                        out_w[v, u, i, j] = zero
                        for c in range(nch):
                            out[v, u, i, j, c] = zero
                continue
            interior = cy - reach >= 0.0 and cy + reach < h - 1 and cx - reach >= 0.0 and cx + reach < w - 1
            for v in range(nv):
                for u in range(nu):
                    py = cy + offsets[v, u, 0]
                    px = cx + offsets[v, u, 1]
                    fy0 = math.floor(py)
                    fx0 = math.floor(px)
                    y0 = int(fy0)
                    x0 = int(fx0)
                    fy = np.float32(py - fy0)
                    fx = np.float32(px - fx0)
                    a0 = zero
                    a1 = zero
                    a2 = zero
                    wsum = zero
                    wrel = zero
                    # near the lens centre and away from the image border every tap is this lens's own
                    fast = interior and inner[v, u]
                    if fast and nch == 3:
                        gx = one - fx
                        gy = one - fy
                        w00 = gy * gx
                        w01 = gy * fx
                        w10 = fy * gx
                        w11 = fy * fx
                        q00 = image[y0, x0, 0]
                        q01 = image[y0, x0 + 1, 0]
                        q10 = image[y0 + 1, x0, 0]
                        q11 = image[y0 + 1, x0 + 1, 0]
                        if (q00 == q00 and q01 == q01 and q10 == q10 and q11 == q11 and usable[y0, x0]
                                and usable[y0, x0 + 1] and usable[y0 + 1, x0] and usable[y0 + 1, x0 + 1]):
                            r = w00 * q00 + w01 * q01 + w10 * q10 + w11 * q11
                            g = (w00 * image[y0, x0, 1] + w01 * image[y0, x0 + 1, 1]
                                 + w10 * image[y0 + 1, x0, 1] + w11 * image[y0 + 1, x0 + 1, 1])
                            b = (w00 * image[y0, x0, 2] + w01 * image[y0, x0 + 1, 2]
                                 + w10 * image[y0 + 1, x0, 2] + w11 * image[y0 + 1, x0 + 1, 2])
                            wrel = (w00 * rel[y0, x0] + w01 * rel[y0, x0 + 1]
                                    + w10 * rel[y0 + 1, x0] + w11 * rel[y0 + 1, x0 + 1])
                            out[v, u, i, j, 0] = m00 * r + m01 * g + m02 * b
                            out[v, u, i, j, 1] = m10 * r + m11 * g + m12 * b
                            out[v, u, i, j, 2] = m20 * r + m21 * g + m22 * b
                            out_w[v, u, i, j] = min(one, max(zero, wrel))
                            continue
                    # the bilinear footprint: the weight is the white's share of it inside this lens
                    n_known = 0
                    for t in range(4):
                        dy = t >> 1
                        dx = t & 1
                        yy = y0 + dy
                        xx = x0 + dx
                        if not fast and (yy < 0 or yy >= h or xx < 0 or xx >= w or labels[yy, xx] != lab):
                            continue
                        wgt = (fy if dy == 1 else one - fy) * (fx if dx == 1 else one - fx)
                        wrel += wgt * rel[yy, xx]
                        p0 = image[yy, xx, 0]
                        if p0 != p0:
                            continue
                        wsum += wgt
                        a0 += wgt * p0
                        if nch == 3:
                            a1 += wgt * image[yy, xx, 1]
                            a2 += wgt * image[yy, xx, 2]
                        if usable[yy, xx]:
                            n_known += 1
                    if wsum > 1e-4 and n_known < 4:
                        # the footprint is cut by the micro-image's edge: rather than renormalising what
                        # is left (which moves the sample inwards), extrapolate linearly from known pixels
                        cell = _nearest_known_cell(image, labels, usable, lab, y0, x0, fy, fx)
                        if cell < 9:
                            sy = cell // 3 - 1
                            sx = cell % 3 - 1
                            ty = fy - np.float32(sy)
                            tx = fx - np.float32(sx)
                            a0 = zero
                            a1 = zero
                            a2 = zero
                            for t in range(4):
                                dy = t >> 1
                                dx = t & 1
                                wgt = (ty if dy == 1 else one - ty) * (tx if dx == 1 else one - tx)
                                yy = y0 + sy + dy
                                xx = x0 + sx + dx
                                a0 += wgt * image[yy, xx, 0]
                                if nch == 3:
                                    a1 += wgt * image[yy, xx, 1]
                                    a2 += wgt * image[yy, xx, 2]
                            wsum = one
                        else:
                            ok, pr, pg, pb = _plane_at(image, labels, usable, lab, y0, x0, fy, fx)
                            if ok:
                                a0 = np.float32(pr)
                                a1 = np.float32(pg)
                                a2 = np.float32(pb)
                                wsum = one
                    if wsum > 1e-4:
                        inv = one / wsum
                        if nch == 3:
                            r = a0 * inv
                            g = a1 * inv
                            b = a2 * inv
                            out[v, u, i, j, 0] = m00 * r + m01 * g + m02 * b
                            out[v, u, i, j, 1] = m10 * r + m11 * g + m12 * b
                            out[v, u, i, j, 2] = m20 * r + m21 * g + m22 * b
                        else:
                            out[v, u, i, j, 0] = a0 * inv
                        out_w[v, u, i, j] = min(one, max(zero, wrel))
                    else:
                        for c in range(nch):
                            out[v, u, i, j, c] = zero
                        out_w[v, u, i, j] = zero


def safe_radius(grid: LensletGrid) -> float:
    """Radius around every lens centre inside which all pixels belong to that lens's Voronoi cell.

    Half the nearest-neighbour distance of the lattice, less the largest deviation of a refined
    centre from the lattice (twice: both lenses of a pair may move towards each other).
    """
    nn = grid.pitch if grid.shape[0] < 2 else min(grid.pitch, math.hypot(grid.row_spacing, grid.odd_row_shift * grid.pitch))
    dev = 0.0
    if grid.refined is not None:
        d = np.linalg.norm(grid.centres_2d() - grid.lattice_centres(), axis=-1)
        dev = float(np.nanmax(d)) if d.size else 0.0
    return max(0.0, 0.5 * nn - 2.0 * dev)


def usable_pixels(labels: np.ndarray, measured: np.ndarray, *, demosaiced: bool,
                  out: np.ndarray | None = None) -> np.ndarray:
    """Pixels whose decoded value is centred on the pixel: the ones :func:`sample_lenses` interpolates from.

    A pixel the sensor did not measure (NaN in the mosaic: below the white's floor, or off a lens) is
    filled by the demosaic from one side, and so is a channel of a pixel whose 3 x 3 neighbourhood
    (the bilinear demosaic's stencil; Malvar's 5 x 5 falls back to it) is cut by the edge of its
    micro-image: normalised convolution over what is left moves the estimate inwards (up to a pixel).
    Such values are left out and the slice extrapolates from the pixels inside instead.

    Parameters
    ----------
    labels : ndarray, shape (H, W), int32
        Lens label of every pixel (:func:`lens_labels`), below 2**24.
    measured : ndarray, shape (H, W), bool
        The mosaic has a value there (``~isnan`` of the normalised, devignetted mosaic).
    demosaiced : bool
        A colour mosaic (the 3 x 3 neighbourhood must be the pixel's own and measured); False for a
        monochrome sensor (only the pixel itself must be measured).
    out : ndarray, shape (H, W), bool, optional
        Destination.

    Returns
    -------
    ndarray, shape (H, W), bool
    """
    out = np.empty(labels.shape, np.bool_) if out is None else out
    if not demosaiced:
        np.copyto(out, measured)
        return out
    box = np.ones((3, 3), np.uint8)
    lab = labels.astype(np.float32)
    # one label over the 3 x 3 box: its minimum equals its maximum; measured over the whole box
    same = cv2.erode(lab, box) == cv2.dilate(lab, box)
    full = cv2.erode(measured.view(np.uint8), box, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    np.logical_and(same, full.view(np.bool_), out=out)
    return out


def sample_lenses(image: np.ndarray, rel: np.ndarray, labels: np.ndarray, centres: np.ndarray,
                  offsets: np.ndarray, *, first_label: int = 0, label_cols: int | None = None,
                  matrix: np.ndarray | None = None, safe_radius: float = 0.0, usable: np.ndarray | None = None,
                  out: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sample every view offset under every lens, from that lens's own pixels only.

    Parameters
    ----------
    image : ndarray, shape (H, W, C), float32
        Demosaiced micro-images; a pixel is known in all channels or NaN in all (left out).
    rel : ndarray, shape (H, W), float32
        Relative white (fraction of the lens's peak light) per pixel, gives the weight.
    labels : ndarray, shape (H, W), int32
        Lens label of every pixel (:func:`lens_labels`).
    centres : ndarray, shape (R, K, 2), float64
        Centres (image coordinates) of the lenses to sample; lens ``(i, j)`` has label
        ``first_label + i * label_cols + j``.
    offsets : ndarray, shape (V, U, 2), float64
        View offsets (:func:`view_offsets`).
    matrix : ndarray (3, 3) or None
        Colour matrix applied to each 3-channel sample (identity when None).
    safe_radius : float
        Pixels closer than this to a lens centre are known to carry its label (a speed-up;
        :func:`safe_radius`); 0 checks every label.
    usable : ndarray, shape (H, W), bool, optional
        Pixels to interpolate from (:func:`usable_pixels`); default every pixel with a value.
    out : (ndarray, ndarray), optional
        Destinations of the samples and weights.

    Returns
    -------
    samples : ndarray, shape (V, U, R, K, C), float32
        Value at ``p = centre + offset``: bilinear from the 2 x 2 pixels around ``p``; where some of
        them are not this lens's usable pixels, bilinear *extrapolation* from the nearest 2 x 2 cell of
        usable ones (the cell moved by up to one pixel per axis), else the weighted least-squares plane
        through the usable pixels of the 6 x 6 window around ``p`` evaluated at ``p``.  Either stencil
        sums to one and has its centroid at ``p`` (``sum w_q = 1``, ``sum w_q q = p``), so the sample
        sits where the view says, up to the micro-image's edge; only without three usable pixels
        around ``p`` the bilinear weights are renormalised over the lens's pixels with a value.
        0 where the lens has no pixel with a value there.
    weight : ndarray, shape (V, U, R, K), float32
        Bilinear interpolation of ``rel`` over the lens's own pixels, clipped to [0, 1].
    """
    h, w, nch = image.shape
    nr, nc = centres.shape[:2]
    nv, nu = offsets.shape[:2]
    if out is None:
        out, out_w = np.empty((nv, nu, nr, nc, nch), np.float32), np.empty((nv, nu, nr, nc), np.float32)
    else:
        out, out_w = out
    m = np.eye(3, dtype=np.float32) if matrix is None else np.asarray(matrix, np.float32)
    offsets = np.ascontiguousarray(offsets, np.float64)
    inner = np.hypot(offsets[..., 0], offsets[..., 1]) + 1.5 < safe_radius
    reach = float(np.abs(offsets).max()) + 2.0
    if usable is None:
        usable = ~np.isnan(image[..., 0])
    elif usable.shape != (h, w) or usable.dtype != np.bool_:
        raise ValueError(f"usable must be a bool array of shape {(h, w)}, got {usable.dtype} {usable.shape}")
    _sample(image, np.ascontiguousarray(rel, np.float32), labels, np.ascontiguousarray(usable),
            np.ascontiguousarray(centres, np.float64),
            int(first_label), int(nc if label_cols is None else label_cols), offsets, inner, reach, m, out, out_w)
    return out, out_w


__all__ = ["view_offsets", "plan_bands", "Band", "lens_labels", "sample_lenses", "safe_radius", "usable_pixels", "CELL_REACH"]
