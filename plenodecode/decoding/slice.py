"""Slicing a lenslet image into sub-aperture samples.

A sub-aperture view ``(v, u)`` takes, from every lens ``k``, the value of the micro-image at
``c_k + (v - vc) * e_row + (u - uc) * e_col`` (sensor px; ``c_k`` the lens centre, ``e_row``,
``e_col`` the lattice axes, so the view offset is expressed in the lattice frame, one view step =
one sensor pixel; see the decoded sampling contract in :mod:`plenodecode.types`).

The value is interpolated from the pixels of the *same* micro-image only: every pixel carries the
label of the lens whose Voronoi cell contains it (:func:`lens_labels`), so light never mixes across
lenslet borders.  Inside the micro-image it is bilinear.  Where the bilinear footprint is cut by the
micro-image's edge (pixels of another lens, unmeasured pixels, or demosaiced channels whose stencil
was cut, :func:`usable_pixels`), it is, with ``view_edges='extrapolate'`` (:data:`VIEW_EDGES`),
*extrapolated*: the weighted least-squares plane through the usable pixels around the sample, whose
stencil has its centroid at the sample.  Renormalising the bilinear weights over the pixels left
(normalised convolution, Knutsson & Westin, CVPR 1993) moves the centroid inwards: it pulls the outer
views of an F01 decode 0.2-0.35 view steps towards the centre, which biased a geometric calibration's view
terms.  It stays the default ('renormalise'): on a full Illum decode extrapolation costs about 6x the CPU of
this step (1.1 -> 6.7 s; 2.4x the whole decode's), and a picture does not need the outer views within a
tenth of a step; geometric calibration extrapolates.  The weight of a sample stays the white's share of its
bilinear footprint inside the lens.

The sensor is processed in bands of lens rows (:func:`plan_bands`) to bound memory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._numba import njit
from ..registry import lookup
from ..types import LensletGrid, cfa_channel_map

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


def plan_bands(grid: LensletGrid, *, max_pixels: int = 2_500_000, margin: int = 4, context: int = 0) -> list[Band]:
    """Split the lens rows into bands whose sensor footprint has at most about ``max_pixels`` pixels.

    Parameters
    ----------
    grid : LensletGrid
    max_pixels : int
        Target number of sensor pixels per band (memory per worker is about 40 bytes per pixel).
    margin : int
        Extra sensor rows above and below the lens cells (demosaicing and hot-pixel neighbourhoods).
    context : int
        Lens rows above and below ``[i0, i1)`` that are sampled too (a 2-D resampling kernel reads them):
        ``ext`` widens by as many.

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
        e0, e1 = max(0, i0 - 1 - context), min(rows, i1 + 1 + context)
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
def _add_moments(moments, k, wgt, dy, dx):  # pragma: no cover - numba
    """Add a pixel's terms ``w (1, dy, dx, dy^2, dy dx, dx^2)`` to the normal equations ``moments[k, :6]``."""
    moments[k, 0] += wgt
    moments[k, 1] += wgt * dy
    moments[k, 2] += wgt * dx
    moments[k, 3] += wgt * dy * dy
    moments[k, 4] += wgt * dy * dx
    moments[k, 5] += wgt * dx * dx


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _extrapolate(image, labels, usable, lab, need, y0, x0, fy, fx, moments, values):  # pragma: no cover - numba
    """Channels ``need`` (bit ``c`` = channel ``c``) at ``p = (y0 + fy, x0 + fx)`` from the weighted
    least-squares plane through the usable values of lens ``lab`` around ``p``: a linear extrapolation.

    Window ``[y0 - 2, y0 + 3] x [x0 - 2, x0 + 3]``, weights ``w_q = (3 - |dy|)+ (3 - |dx|)+`` with ``(dy, dx)``
    the pixel's offset from ``p``; for each channel, over the pixels where it is usable
    (:func:`usable_pixels`), minimises ``sum w_q (f_q - c0 - c1 dy - c2 dx)^2`` and returns ``c0``.
    The equivalent stencil ``c0 = sum a_q f_q`` has ``sum a_q = 1`` and ``sum a_q (dy, dx) = 0``: its
    centroid is ``p``, so a linear radiance is exact and the sample is not pulled towards the pixels it
    has.  The tent is wider than the bilinear footprint (a point up to two pixels outside the usable
    pixels still has some) and averages more pixels than a 2 x 2 extrapolation would, which keeps the
    noise of an extrapolated sample near that of an interpolated one.

    One pass over the window: the normal equations of pixels usable in every channel are summed once
    (``moments[3]``), those usable in channel ``c`` only in ``moments[c]``.  Writes ``values[c]`` and
    returns the bits of the channels solved (a channel with fewer than three non-collinear usable
    pixels is not).
    """
    h, w = labels.shape
    nch = image.shape[2]
    moments[:, :] = 0.0
    for yy in range(max(0, y0 - 2), min(h, y0 + 4)):
        dy = yy - y0 - float(fy)
        wy = 3.0 - abs(dy)
        if wy <= 0.0:
            continue
        for xx in range(max(0, x0 - 2), min(w, x0 + 4)):
            bits = usable[yy, xx] & need
            if bits == 0 or labels[yy, xx] != lab or image[yy, xx, 0] != image[yy, xx, 0]:
                continue
            dx = xx - x0 - float(fx)
            wgt = wy * (3.0 - abs(dx))
            if wgt <= 0.0:
                continue
            shared = bits == need
            for c in range(nch):
                if bits & (1 << c) == 0:
                    continue
                f = wgt * image[yy, xx, c]
                moments[c, 6] += f
                moments[c, 7] += f * dy
                moments[c, 8] += f * dx
                if not shared:
                    _add_moments(moments, c, wgt, dy, dx)
            if shared:
                _add_moments(moments, 3, wgt, dy, dx)
    solved = 0
    for c in range(nch):
        if need & (1 << c) == 0:
            continue
        s00 = moments[3, 0] + moments[c, 0]
        s01 = moments[3, 1] + moments[c, 1]
        s02 = moments[3, 2] + moments[c, 2]
        s11 = moments[3, 3] + moments[c, 3]
        s12 = moments[3, 4] + moments[c, 4]
        s22 = moments[3, 5] + moments[c, 5]
        # c0 = first row of the inverse of the (symmetric) normal matrix times the right-hand side, by cofactors
        c00 = s11 * s22 - s12 * s12
        c01 = s02 * s12 - s01 * s22
        c02 = s01 * s12 - s02 * s11
        det = s00 * c00 + s01 * c01 + s02 * c02
        if s00 > 0.0 and det > 1e-3 * s00 * s00 * s00:
            values[c] = (c00 * moments[c, 6] + c01 * moments[c, 7] + c02 * moments[c, 8]) / det
            solved |= 1 << c
    return solved


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _sample(image, rel, labels, usable, centres, first_label, nc_label, offsets, inner, reach, matrix, moments,
            out, out_w):  # pragma: no cover
    # ``moments``: None renormalises cut footprints; a (4, 9) float64 work array extrapolates them.  With None
    # numba prunes the ``moments is not None`` branch before typing it, so a decode that does not extrapolate
    # never compiles :func:`_extrapolate` (about 1.5 CPU s on a cold start).
    h, w, nch = image.shape
    nr, nc = centres.shape[0], centres.shape[1]
    nv, nu = offsets.shape[0], offsets.shape[1]
    m00, m01, m02 = matrix[0, 0], matrix[0, 1], matrix[0, 2]
    m10, m11, m12 = matrix[1, 0], matrix[1, 1], matrix[1, 2]
    m20, m21, m22 = matrix[2, 0], matrix[2, 1], matrix[2, 2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    every = (1 << nch) - 1
    values = np.empty(3)
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
                    wsum = zero
                    wrel = zero
                    # near the lens centre and away from the image border every tap is this lens's own
                    fast = interior and inner[v, u] and nch == 3
                    if fast:
                        if moments is None:      # renormalising: the four taps have a value
                            fast = (image[y0, x0, 0] == image[y0, x0, 0]
                                    and image[y0, x0 + 1, 0] == image[y0, x0 + 1, 0]
                                    and image[y0 + 1, x0, 0] == image[y0 + 1, x0, 0]
                                    and image[y0 + 1, x0 + 1, 0] == image[y0 + 1, x0 + 1, 0])
                        else:                    # extrapolating: every channel of the four taps is usable
                            fast = (usable[y0, x0] == every and usable[y0, x0 + 1] == every
                                    and usable[y0 + 1, x0] == every and usable[y0 + 1, x0 + 1] == every)
                    if fast:
                        gx = one - fx
                        gy = one - fy
                        w00 = gy * gx
                        w01 = gy * fx
                        w10 = fy * gx
                        w11 = fy * fx
                        r = (w00 * image[y0, x0, 0] + w01 * image[y0, x0 + 1, 0]
                             + w10 * image[y0 + 1, x0, 0] + w11 * image[y0 + 1, x0 + 1, 0])
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
                    inner_taps = interior and inner[v, u]
                    a0 = zero
                    a1 = zero
                    a2 = zero
                    cut = 0                       # channels with a footprint pixel not usable
                    for t in range(4):
                        dy = t >> 1
                        dx = t & 1
                        yy = y0 + dy
                        xx = x0 + dx
                        if not inner_taps and (yy < 0 or yy >= h or xx < 0 or xx >= w or labels[yy, xx] != lab):
                            cut = every
                            continue
                        wgt = (fy if dy == 1 else one - fy) * (fx if dx == 1 else one - fx)
                        wrel += wgt * rel[yy, xx]
                        p0 = image[yy, xx, 0]
                        if p0 != p0:
                            cut = every
                            continue
                        wsum += wgt
                        a0 += wgt * p0
                        if nch == 3:
                            a1 += wgt * image[yy, xx, 1]
                            a2 += wgt * image[yy, xx, 2]
                        if moments is not None:
                            cut |= every & ~usable[yy, xx]
                    if wsum <= 1e-4:
                        for c in range(nch):
                            out[v, u, i, j, c] = zero
                        out_w[v, u, i, j] = zero
                        continue
                    inv = one / wsum
                    a0 *= inv
                    a1 *= inv
                    a2 *= inv
                    if moments is not None:
                        if cut != 0:
                            # the footprint is cut by the micro-image's edge: rather than renormalising what
                            # is left (which moves the sample inwards), extrapolate from the usable values
                            solved = _extrapolate(image, labels, usable, lab, cut, y0, x0, fy, fx, moments, values)
                            if solved & 1:
                                a0 = np.float32(values[0])
                            if solved & 2:
                                a1 = np.float32(values[1])
                            if solved & 4:
                                a2 = np.float32(values[2])
                    if nch == 3:
                        out[v, u, i, j, 0] = m00 * a0 + m01 * a1 + m02 * a2
                        out[v, u, i, j, 1] = m10 * a0 + m11 * a1 + m12 * a2
                        out[v, u, i, j, 2] = m20 * a0 + m21 * a1 + m22 * a2
                    else:
                        out[v, u, i, j, 0] = a0
                    out_w[v, u, i, j] = min(one, max(zero, wrel))


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


@njit(cache=True, nogil=True)
def _usable_kernel(labels, measured, cmap, out):  # pragma: no cover - numba
    h, w = labels.shape
    for y in range(h):
        for x in range(w):
            lab = labels[y, x]
            if lab < 0 or not measured[y, x]:
                out[y, x] = 0
                continue
            bad = 0
            for dy in range(-1, 2):
                yy = y + dy
                for dx in range(-1, 2):
                    xx = x + dx
                    if yy < 0 or yy >= h or xx < 0 or xx >= w or labels[yy, xx] != lab or not measured[yy, xx]:
                        bad |= 1 << cmap[yy & 1, xx & 1]
            native = 1 << cmap[y & 1, x & 1]
            out[y, x] = (7 & ~bad) | native


def usable_pixels(labels: np.ndarray, measured: np.ndarray, cfa: str | None, *,
                  out: np.ndarray | None = None) -> np.ndarray:
    """Which channels of each demosaiced pixel are centred on it: the values :func:`sample_lenses` uses.

    A pixel's own CFA channel is measured.  Another channel ``c`` is interpolated from the ``c`` sites of
    its 3 x 3 neighbourhood (the bilinear demosaic; Malvar's correction needs the whole 5 x 5 and falls
    back to it elsewhere); where one of those sites is another lens's or not measured, normalised
    convolution over the rest moves the estimate towards the lens centre, up to a pixel, so channel
    ``c`` is not usable there.  A pixel the sensor did not measure (NaN in the mosaic) has no usable
    channel.  The slice extrapolates from usable values instead.

    Parameters
    ----------
    labels : ndarray, shape (H, W), int32
        Lens label of every pixel (:func:`lens_labels`).
    measured : ndarray, shape (H, W), bool
        The mosaic has a value there (``~isnan`` of the normalised, devignetted mosaic).
    cfa : str or None
        The mosaic's CFA (phase of its first row and column); None: monochrome (a measured pixel is usable).
    out : ndarray, shape (H, W), uint8, optional
        Destination.

    Returns
    -------
    ndarray, shape (H, W), uint8
        Bit ``c`` set where channel ``c`` is usable (1 for a measured monochrome pixel; 7 for a pixel
        whose 3 x 3 neighbourhood is all its lens's and measured).
    """
    out = np.empty(labels.shape, np.uint8) if out is None else out
    if cfa is None:
        np.copyto(out, measured.view(np.uint8))
        return out
    _usable_kernel(np.ascontiguousarray(labels, np.int32), np.ascontiguousarray(measured, np.bool_),
                   cfa_channel_map(cfa).astype(np.int64), out)
    return out


#: ``view_edges`` of :func:`sample_lenses` and :func:`plenodecode.decoding.decode`: name -> whether a bilinear
#: footprint cut by the micro-image's edge is extrapolated (True) or its weights renormalised (False)
VIEW_EDGES: dict[str, bool] = {"renormalise": False, "extrapolate": True}


def sample_lenses(image: np.ndarray, rel: np.ndarray, labels: np.ndarray, centres: np.ndarray,
                  offsets: np.ndarray, *, first_label: int = 0, label_cols: int | None = None,
                  matrix: np.ndarray | None = None, safe_radius: float = 0.0, usable: np.ndarray | None = None,
                  view_edges: str = "renormalise", out: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
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
    usable : ndarray, shape (H, W), uint8, optional
        Channels (bit ``c``) of each pixel to interpolate from (:func:`usable_pixels`); default every
        channel of every pixel with a value.
    view_edges : {'renormalise', 'extrapolate'}
        Where the bilinear footprint is cut (:data:`VIEW_EDGES`): 'renormalise' its weights over the
        lens's pixels with a value (the default: about 6x cheaper, but a sample near the
        micro-image's edge moves inwards, up to 0.35 view steps in an F01's outer ring), or
        'extrapolate' from the usable values (what follows), for views at their nominal offsets.
    out : (ndarray, ndarray), optional
        Destinations of the samples and weights.

    Returns
    -------
    samples : ndarray, shape (V, U, R, K, C), float32
        Value at ``p = centre + offset``: bilinear from the 2 x 2 pixels around ``p`` when all of them
        are this lens's and usable.  Otherwise (``p`` near the micro-image's edge): 'renormalise', the
        bilinear weights renormalised over the lens's pixels with a value; 'extrapolate', per channel,
        the weighted least-squares plane through the lens's usable values around ``p``, evaluated at
        ``p`` (:func:`_extrapolate`), whose stencil sums to one and has its centroid at ``p``, so the
        sample sits where the view says up to the edge (renormalised only with fewer than three usable
        values around ``p``).
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
    extrapolate = lookup(VIEW_EDGES, view_edges, param="view_edges")
    m = np.eye(3, dtype=np.float32) if matrix is None else np.asarray(matrix, np.float32)
    offsets = np.ascontiguousarray(offsets, np.float64)
    inner = np.hypot(offsets[..., 0], offsets[..., 1]) + 1.5 < safe_radius
    reach = float(np.abs(offsets).max()) + 2.0
    if usable is None:
        usable = np.isfinite(image[..., 0]).view(np.uint8)     # 0 / 1, then every channel's bit where 1
        usable *= np.uint8((1 << nch) - 1)
    elif usable.shape != (h, w) or usable.dtype != np.uint8:
        raise ValueError(f"usable must be a uint8 array of shape {(h, w)}, got {usable.dtype} {usable.shape}")
    _sample(image, np.ascontiguousarray(rel, np.float32), labels, np.ascontiguousarray(usable),
            np.ascontiguousarray(centres, np.float64),
            int(first_label), int(nc if label_cols is None else label_cols), offsets, inner, reach, m,
            np.empty((4, 9)) if extrapolate else None, out, out_w)
    return out, out_w


__all__ = ["VIEW_EDGES", "view_offsets", "plan_bands", "Band", "lens_labels", "sample_lenses", "safe_radius",
           "usable_pixels", "CELL_REACH"]
