"""Occlusion handling at depth edges: the foreground fattening of window-based matching removed.

* :func:`fix_occlusion_edges`: the pass every method ends with (parameters :data:`EDGE_DEFAULTS`): a
  visibility check against the best wedge of views, a colour-guided weighted median, then
  :func:`visibility_relabel` and :func:`coverage_relabel` in the band around each depth jump.
* :func:`nearest_surface`: a z-buffer of one view rendered from the centre view's disparity map.
* :func:`two_colour_edge`, :func:`mixing_agrees`: where a pixel's colour lies between its neighbours across
  an edge, the centre view's own estimate of how much of it an occluder covers.
"""

from __future__ import annotations

import logging
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable

import cv2
import numpy as np

from .._numba import njit
from ..imaging import luma
from .confidence import image_noise
from .cost import half_plane_cost_volume, worker_threads
from .views import Views

log = logging.getLogger(__name__)

#: Occlusion-edge pass parameters of :func:`plenodecode.depth.pipeline.run_pipeline`, the same for every method.
EDGE_DEFAULTS: dict[str, Any] = {
    "edge_radius": 4,         # fix_occlusion_edges within this many px of a jump; 0 = off
    "edge_jump": 0.3,         # disparity jump (px per view step) that makes a depth edge (0.5: the band test
                              # '> 0.5' missed the thin scenes' 0.5 jumps; thin GT 9.66 -> 9.27 %)
    "edge_ratio": 1.5,        # near-side pixels whose all-view cost exceeds this x the far wedge cost move back
    "edge_wedge": 2,          # the far cost's views: the best wedge of this many of the 8 sectors (2 = 90 deg)
    "edge_median_radius": 5,  # colour-guided weighted median over the edge band (0 = off)
    "edge_visibility": True,  # then every band pixel takes the side its own colour matches (visibility_relabel)
    "edge_coverage": True,    # then edge pixels take the surface covering most of them (coverage_relabel)
}



#: How far (px) from every nearer pixel of the map :func:`coverage_relabel` takes the centre view's sample of
#: the background, the regressor of its fit.  1 px clears the bicubic sample's inner 2 x 2 taps; its outer
#: taps (the negative lobes, at most 0.094 x 0.594 = 0.056 each in 2-D) may reach the occluder, a small error
#: that costs less than the views it adds (bilinear samples, whose support 1 px does clear, smooth the
#: regressor: illum-mini ideal MSE x100 0.150 against 0.080 bicubic).  At 2 px, the whole 4 x 4 support, a
#: background seen through an oblique gap narrower than 5 px, or one that a 0.5 px jump moves by less than
#: 2 px in most views, was never clear of the occluder: the fit had fewer than ``min_views`` views on 98 of
#: the 184 pixels on the wrong side of slits-o-j1-tex's outlines and 146 of 207 on slats-o-j0.5-tex's, which
#: kept the side the matching gave them.  Whether the background is textured enough to fit is still judged
#: on the views clear by 2 px where there are enough of them (a disc over a flat background: 35 of 74 pixels
#: wrong without that, 14 with it and before).  Thin scenes' ground-truth mean BadPix0.07 6.96 -> 6.72 %,
#: decoded 19.62 -> 19.45 %; illum-mini ideal / decoded 0.41 / 1.22 -> 0.38 / 1.19 % (MSE x100 0.114 / 0.418
#: -> 0.080 / 0.371); hci-antinous 4.21 -> 4.20 % (MSE x100 1.779 -> 1.814).
BACKGROUND_MARGIN = 1


def _edge_band(disparity: np.ndarray, radius: int, jump: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(near, far, band): local max and min of the disparity over a (2 radius + 1)^2 window, and the pixels
    where they differ by more than ``jump`` (within ``radius`` of a depth discontinuity)."""
    k = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    near = cv2.dilate(disparity, k)
    far = cv2.erode(disparity, k)
    return near, far, (near - far) > np.float32(jump)


@njit(cache=True, nogil=True)
def _splat_max(disparity, dv, du, out):
    # z-buffer of one view: every centre pixel p lands at p - d(p) (dv, du) in the view; the four pixels around
    # that point keep the largest (nearest) disparity landing on them
    Y, X = disparity.shape
    for y in range(Y):
        for x in range(X):
            d = disparity[y, x]
            ty = y - d * dv
            tx = x - d * du
            fy = int(math.floor(ty))
            fx = int(math.floor(tx))
            for qy in range(fy, fy + 2):
                if 0 <= qy < Y:
                    for qx in range(fx, fx + 2):
                        if 0 <= qx < X and d > out[qy, qx]:
                            out[qy, qx] = d


def nearest_surface(disparity: np.ndarray, dv: float, du: float) -> np.ndarray:
    """Z-buffer of the view at offset ``(dv, du)``: (Y, X) float32, the largest disparity of the centre-view
    pixels ``p`` whose image ``p - d(p) (dv, du)`` falls within one pixel, ``-inf`` where none does."""
    out = np.full(disparity.shape, -np.inf, np.float32)
    _splat_max(np.ascontiguousarray(disparity, np.float32), float(dv), float(du), out)
    return out


def _side_fill(disparity: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """Normalised convolution of the disparity over ``mask``: each pixel's Gaussian-weighted mean of the
    masked pixels (its own value where no masked pixel is near)."""
    m = mask.astype(np.float32)
    num = cv2.GaussianBlur(disparity * m, (0, 0), sigma)
    den = cv2.GaussianBlur(m, (0, 0), sigma)
    return np.where(den > 1e-3, num / np.maximum(den, 1e-6), disparity).astype(np.float32)


def _pixel_image_shape(n: int) -> tuple[int, int]:
    """(rows, cols) of an image holding ``n`` scattered pixels for cv2.remap, whose maps must be under 32767
    wide: rows of 1024."""
    cols = min(n, 1024)
    return -(-n // cols), cols


def _as_pixel_image(a: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Per-pixel values ``a`` (n, ...) laid out as a (rows, cols, ...) image, zero-padded."""
    flat = np.zeros((rows * cols,) + a.shape[1:], a.dtype)
    flat[:len(a)] = a
    return flat.reshape((rows, cols) + a.shape[1:])


def _hypothesis_sigma(radius: int) -> float:
    """Width (px) of the Gaussian over which a side's hypothesis averages its band pixels: ``radius / 2``, at
    least 1."""
    return max(radius / 2.0, 1.0)


def _band_hypotheses(d: np.ndarray, radius: int, jump: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(band, is_near, h_near, h_far), all (Y, X): the pixels within ``radius`` of a jump (:func:`_edge_band`)
    whose two sides differ by more than ``jump``, which of them are on the near side (``d > (max + min) / 2``
    over the window), and the near and far hypotheses: Gaussian-weighted means (``sigma = radius / 2``) of the
    band's pixels on each side."""
    near, far, band = _edge_band(d, radius, jump)
    is_near = d > 0.5 * (near + far)
    sigma = _hypothesis_sigma(radius)
    h_near = _side_fill(d, band & is_near, sigma)
    h_far = _side_fill(d, band & ~is_near, sigma)
    band &= (h_near - h_far) > np.float32(jump)
    return band, is_near, h_near, h_far


def visibility_relabel(intensities: Views, disparity: np.ndarray, *, radius: int = 4, jump: float = 0.5,
                       ratio: float = 1.5, search: float = 0.2, min_visible: float = 0.05,
                       despeckle: bool = True, settle: bool = True, refit: bool = True) -> np.ndarray:
    """Move edge pixels to the side of a depth edge their own colour matches in the views that see it.

    Within ``radius`` px of a jump (:func:`_edge_band`) each pixel has two hypotheses, the disparity of the
    near side and of the far side around it (Gaussian-weighted means of the pixels on each side,
    ``sigma = radius / 2``).  Its per-pixel cost (no box: a box beside an edge mixes both surfaces) is

        C(p, h) = min_{|e| <= search}  sum_{t in vis(p, h + e)} w_t |I_t(p - (h + e) o_t) - I_c(p)|^2
                                        / sum_{t in vis(p, h + e)} w_t

    over the intensities (the local contrast normalisation mixes both surfaces near an edge), bicubic.
    A near hypothesis is seen by every view.  A far one is hidden in view ``t`` when a z-buffer of the
    current map (:func:`nearest_surface`) has a surface nearer by more than ``jump / 2`` at its image: the
    occlusion reasoning of Kang, Szeliski & Chai (CVPR 2001) with the occluders taken from the map itself
    rather than from a fixed split of the views.  Fewer than ``min_visible`` of the view weight: no far
    hypothesis, and no move either way.  A point seen through a slit of a few pixels is seen by only the
    strip of views along it: with visibility from the true map, the far pixels beside the near surface of
    oblique 1-5 px slits (slits-o-j1-tex) are seen by 13 % of the view weight (median), and those views
    prefer the far side on 95 % of the pixels the pipeline had wrong; the z-buffers of a map whose slit is
    still narrowed by fattening hide it in more views, which leaves fewer, still visible ones.  Hence
    ``min_visible`` 0.05, not 0.25 (thin scenes' ground-truth mean BadPix0.07 10.8 -> 9.7 %).  A pixel
    moves to the other side when that side's cost is ``ratio`` times lower and it
    touches that side, one pixel layer per round, up to ``radius`` rounds; with ``despeckle`` a 3 x 3 median
    over the band then removes isolated decisions (:func:`fix_occlusion_edges` with a cost gate applies that
    median gated instead: the plain one wipes out 1 px slats and slits the views support, slats-v-j1-tex
    4.5 -> 1.4 % wrong, the thin scenes' ground-truth mean 9.3 -> 7.8 %).

    With ``settle``, last, a band pixel whose own side the views prefer (its cost there lower than the other
    side's, the z-buffers from the relabelled map) takes that side's hypothesis where the hypothesis matches
    its own colour at least as well as its value does (``C`` at the two, no search): a window that straddles
    the edge, or a pixel that mixes both surfaces, leaves values between them (a 0.5 px jump's mix is
    cheapest in between), which the side tests alone kept; on a slanted surface a value the pixel's own colour
    supports better than the smooth hypothesis stays.  Thin scenes' ground-truth mean BadPix0.07 6.49 ->
    6.22 %, decoded 18.94 -> 18.12 %; hci-antinous 4.18 -> 4.07 % (MSE x100 1.820 -> 1.793).  On a weakly
    textured far plane the two costs differ by little, and a hypothesis the plane's biased values pulled
    off can win by chance: the 12 oblique scenes at 45 x 58 px and 9 x 9 views go 22.2 -> 21.8 % in the
    mean, but slats-o-j1-weak 24.0 -> 26.0 % and slats-o-j0.5-weak 51.8 -> 53.0 %.

    With ``refit``, first, the far hypothesis is fitted again to the views: each far-side band pixel takes the
    offset of the search that its visible views prefer, and the hypothesis becomes the Gaussian-weighted mean
    (same ``sigma``) of those pixels' ``h_far + e``, over the pixels whose best offset lies strictly inside the
    search (one at its end points at the other surface or at a mixed pixel; the old hypothesis stays where no
    such pixel is near).  The far side's values are the ones the box costs pulled towards the occluder: a
    weakly textured plane between oblique 1-5 px slats 0.5 px nearer (slats-o-j0.5-weak) had 1937 of its 6248
    far pixels 0.07-0.25 px too near in the end: the hypothesis averaged from them was too, and ``settle``
    then wrote it.  The 12 oblique thin scenes (ideal light fields) went from a BadPix0.07 sum of 158.8 to
    139.1 (slats-o-j0.5-weak 25.5 -> 12.2 %, slats-o-j0.5-tex 14.0 -> 10.5 %), the 24 others 65.2 -> 68.7
    (weakly textured slits lose most, slits-v-j1-weak 5.0 -> 6.2 %); decoded thin 108.7 -> 103.1;
    hci-antinous 4.07 -> 4.00 % (MSE x100 1.793 -> 1.771).  The near hypothesis, fitted the same way over all
    views, gained the thin scenes 3.6 more but cost hci-antinous 0.41 (4.00 -> 4.41 %): it stays the mean.

    This places the thin rims the box costs cannot: the 1-3 px band of an occluder's silhouette that has
    the background's colour, which the colour-guided median of :func:`fix_occlusion_edges` gives to an
    equally dark background.

    Parameters
    ----------
    intensities : Views
        Views without contrast channels (:func:`prepare_views` with ``contrast_sigma=0``).
    disparity : ndarray (Y, X) float32
    despeckle : bool
        End with the 3 x 3 median over the band (:func:`_despeckle`).
    settle : bool
        Before it, give a band pixel its side's hypothesis where the views support both (see above).
    refit : bool
        Fit the far hypothesis to the offsets its pixels' views prefer before the rounds (see above).

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    d = np.ascontiguousarray(disparity, np.float32)
    band, is_near, h_near, h_far = _band_hypotheses(d, radius, jump)
    ys, xs = np.nonzero(band)
    out = d.copy()
    if len(ys) == 0:
        return out
    n = len(ys)
    rows, cols = _pixel_image_shape(n)

    def as_image(a: np.ndarray) -> np.ndarray:
        return _as_pixel_image(a, rows, cols)

    px, py = as_image(xs.astype(np.float32)), as_image(ys.astype(np.float32))
    hyp = {"near": as_image(h_near[ys, xs]), "far": as_image(h_far[ys, xs])}
    centre = as_image(intensities.data[intensities.centre][ys, xs])                # (rows, cols, C)
    offsets = np.linspace(-search, search, 5).astype(np.float32)
    dv_all, du_all = intensities.offsets
    used = intensities.used()
    threads = worker_threads()
    total = np.float32(sum(float(intensities.weight[vu]) for vu in used))
    margin = np.float32(0.5 * jump)

    def offset_costs(h0: np.ndarray, current: np.ndarray | None, search_offsets: np.ndarray) -> np.ndarray:
        # the visible views' mean squared difference at every offset, (K, rows, cols); current: the map the
        # z-buffers come from (None: every view sees the hypothesis).  The views are split into 4 parts, each
        # with its own sums, run on threads (the z-buffer kernel and OpenCV release the GIL); the fixed split
        # keeps the sums the same on any number of cores.
        with ThreadPoolExecutor(max_workers=threads) as pool:
            parts = list(pool.map(lambda i: view_sums(h0, current, used[i::4], search_offsets), range(4)))
        cost = sum(p[0] for p in parts)
        seen = sum(p[1] for p in parts)
        return np.where(seen >= min_visible * total, cost / np.maximum(seen, 1e-12), np.inf)

    def best_cost(h0: np.ndarray, current: np.ndarray | None, search_offsets: np.ndarray = offsets
                  ) -> np.ndarray:
        # min over the offsets (n,)
        return offset_costs(h0, current, search_offsets).min(axis=0).reshape(-1)[:n]

    def view_sums(h0: np.ndarray, current: np.ndarray | None, views: list[tuple[int, int]],
                  search_offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cost = np.zeros((len(search_offsets), rows, cols), np.float32)
        seen = np.zeros((len(search_offsets), rows, cols), np.float32)
        for vu in views:
            w = np.float32(intensities.weight[vu])
            dv, du = np.float32(dv_all[vu]), np.float32(du_all[vu])
            zbuf = None if current is None else nearest_surface(current, dv, du)
            for k, e in enumerate(search_offsets):
                h = h0 + e
                mx, my = px - h * du, py - h * dv
                sample = cv2.remap(intensities.data[vu], mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
                diff = np.square(sample.reshape(centre.shape) - centre).sum(axis=-1)
                if zbuf is None:
                    visible = w
                else:
                    z = cv2.remap(zbuf, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
                    visible = (z <= h + margin).astype(np.float32) * w
                cost[k] += visible * diff
                seen[k] += visible
        return cost, seen

    side = is_near[ys, xs]
    if refit:
        # the far hypothesis from the offsets its own side's pixels' views prefer (see the docstring)
        c = offset_costs(hyp["far"], d, offsets)
        e = offsets[c.argmin(axis=0)].reshape(-1)[:n]
        support = np.zeros(d.shape, bool)
        support[ys, xs] = ~side & np.isfinite(c.min(axis=0).reshape(-1)[:n]) & \
            (np.abs(e) < np.float32(search) - np.float32(1e-6))
        old_far = hyp["far"].reshape(-1)[:n]
        value = np.zeros(d.shape, np.float32)
        value[ys, xs] = old_far + np.where(support[ys, xs], e, np.float32(0.0))   # the old one where no support
        hyp["far"] = as_image(_side_fill(value, support, _hypothesis_sigma(radius))[ys, xs])
    near_cost = best_cost(hyp["near"], None)
    near_value, far_value = hyp["near"].reshape(-1)[:n], hyp["far"].reshape(-1)[:n]
    r = np.float32(ratio)
    ring = np.ones((3, 3), np.uint8)
    # one pixel layer per round: a pixel may join a side only next to it, and the next layer is judged with
    # the z-buffers of the map that includes this one (a far point beside an eroded occluder looks visible
    # in views where the occluder's cut-off rim hides it)
    for _ in range(max(1, radius)):
        far_cost = best_cost(hyp["far"], out)
        near_map = np.zeros(d.shape, bool)
        near_map[ys, xs] = side
        next_to_near = cv2.dilate(near_map.astype(np.uint8), ring).astype(bool)[ys, xs]
        next_to_far = cv2.dilate((band & ~near_map).astype(np.uint8), ring).astype(bool)[ys, xs]
        to_far = side & (far_cost * r < near_cost) & next_to_far
        # a far hypothesis too few views see is undecided, not refuted: a point seen through a gap of a few
        # pixels is visible only in the strip of views along the gap
        to_near = ~side & (near_cost * r < far_cost) & np.isfinite(far_cost) & next_to_near
        if not (to_far.any() or to_near.any()):
            break
        out[ys[to_far], xs[to_far]] = far_value[to_far]
        out[ys[to_near], xs[to_near]] = near_value[to_near]
        side = (side & ~to_far) | to_near
        log.debug("visibility relabel: %d band pixels, %d to the far side, %d to the near side", n,
                  int(to_far.sum()), int(to_near.sum()))
    if settle:
        # the side the views prefer, with the z-buffers of the relabelled map; then the hypothesis where it
        # explains the pixel's colour at least as well as the pixel's own value (no search)
        far_cost = best_cost(hyp["far"], out)
        exact = np.zeros(1, np.float32)
        own = as_image(out[ys, xs])
        to_near = side & (near_cost < far_cost) & \
            (best_cost(hyp["near"], None, exact) <= best_cost(own, None, exact))
        to_far = ~side & (far_cost < near_cost) & \
            (best_cost(hyp["far"], out, exact) <= best_cost(own, out, exact))
        out[ys[to_near], xs[to_near]] = near_value[to_near]
        out[ys[to_far], xs[to_far]] = far_value[to_far]
        log.debug("visibility relabel: %d near and %d far band pixels take their side's hypothesis",
                  int(to_near.sum()), int(to_far.sum()))
    if despeckle:
        out = _despeckle(out, band)
    return out


def _despeckle(disparity: np.ndarray, band: np.ndarray) -> np.ndarray:
    """A 3 x 3 median of the disparity over ``band``: where both sides match about equally (one flat colour on
    both) the per-pixel decisions of :func:`visibility_relabel` are speckled.  (Y, X) float32, a new array."""
    med = cv2.medianBlur(np.ascontiguousarray(disparity, np.float32), 3)
    return np.where(band, med, disparity).astype(np.float32)


def two_colour_edge(image: np.ndarray, ys: np.ndarray, xs: np.ndarray, normal: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel's colour lies between its two neighbours across an edge, and how flat the two sides
    are: (mixing, flatness), each (n,) float64,

        m = (I(p) - I(p - n)) . (I(p + n) - I(p - n)) / |I(p + n) - I(p - n)|^2
        f = (|I(p + 2n) - I(p + n)| + |I(p - 2n) - I(p - n)|) / |I(p + n) - I(p - n)|

    with ``n`` the unit ``normal`` (n, 2) as (y, x), ``I`` the (Y, X, C) ``image`` (bilinear).  On an edge
    between two flat colours ``m`` is the fraction of pixel ``p`` the ``+n`` side covers and ``f = 0``; a side
    whose colour still changes a pixel further out (texture, shading, a second edge) raises ``f``.  NaN where
    the two neighbours have the same colour."""
    img = np.ascontiguousarray(image, np.float32)
    img = img if img.ndim == 3 else img[..., None]
    rows, cols = _pixel_image_shape(len(ys))

    def at(k: float) -> np.ndarray:
        mx = _as_pixel_image((xs + k * normal[:, 1]).astype(np.float32), rows, cols)
        my = _as_pixel_image((ys + k * normal[:, 0]).astype(np.float32), rows, cols)
        sample = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return sample.reshape(rows * cols, -1)[:len(ys)].astype(np.float64)

    back_out, back, front, front_out = at(-2.0), at(-1.0), at(1.0), at(2.0)
    own = img[ys, xs].astype(np.float64)
    step = front - back
    contrast = np.einsum("nc,nc->n", step, step)
    spread = np.linalg.norm(front_out - front, axis=1) + np.linalg.norm(back_out - back, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        valid = contrast > 1e-12
        mixing = np.where(valid, np.einsum("nc,nc->n", own - back, step) / contrast, np.nan)
        flatness = np.where(valid, spread / np.sqrt(contrast), np.nan)
    return mixing, flatness


def mixing_agrees(mixed: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Where the centre view's colour mixing (:func:`two_colour_edge`) backs a coverage estimate: both on the
    same side of 1/2, and the mixing a mix, inside (0, 1).  A colour outside the range between its two
    neighbours' (the dark band of a shaded silhouette, darker than the wall and the lit surface) says
    nothing about coverage.  Arrays (n,); NaN mixing never agrees."""
    same_side = ((mixed > 0.5) & (covered > 0.5)) | ((mixed < 0.5) & (covered < 0.5))
    return same_side & (mixed > 0.0) & (mixed < 1.0)


def coverage_relabel(intensities: Views, disparity: np.ndarray, *, radius: int = 4, jump: float = 0.5,
                     significance: float = 2.0, agreed_significance: float = 0.5, min_views: int = 6,
                     flat_edge: float = 0.2, mixing_margin: float = 0.1) -> np.ndarray:
    """Give each pixel on a depth edge to the surface that covers most of it, measured by the background's
    motion through it.

    A pixel ``p`` cut by an occluder's outline is a mix: a fraction ``a`` of it shows the occluder (disparity
    ``h_n``) and ``1 - a`` the background (``h_f``).  Followed along the occluder, in view ``t`` (offset
    ``o_t``) it reads

        N_t = I_t(p - h_n o_t) = a S + (1 - a) B(p + (h_f - h_n) o_t)

    where ``B`` is the background as the centre view shows it: the occluder's part stays put while the
    background slides through the rest.  A weighted least-squares fit

        N_t = c_0 + (1 - a) B_t + c_v dv_t + c_u du_t

    over the views whose background point the centre view shows unoccluded (no near surface within
    :data:`BACKGROUND_MARGIN` px of it in the map) gives ``1 - a``; the offset terms absorb what changes
    linearly across the aperture (an occluder disparity a little off moves the outline across the pixel in
    proportion to the offset, which the fit would otherwise read as background showing through).  Where
    ``a`` lies on the other side of 1/2 than the map by more than ``significance`` standard errors, the pixel
    takes the other side's hypothesis: the pixel-centre convention of a ground truth (a mixed pixel belongs
    to the surface at its centre).  A second, independent estimate of the same fraction comes from the centre view
    alone: where the pixel's colour lies between its neighbours one pixel outward and inward along the edge normal
    (:func:`two_colour_edge`; the normal is the gradient of the near side's indicator smoothed with ``sigma = 1``).
    Where the two agree on the other side, ``agreed_significance`` standard errors suffice; a colour outside the
    range between its neighbours' (mixing outside (0, 1): the dark band of a shaded silhouette) is no mix and does
    not agree (:func:`mixing_agrees`).

    The centre view's samples of ``B`` carry the same noise as the views' (decoded light fields), which
    shrinks the fitted ``1 - a`` by the reliability ``1 - s^2 / var(B)`` (regression dilution: errors in
    the regressor) and reads as coverage.  Beside a small jump the background point clears the occluder in
    a few views on one side only, where it moves by a few pixels, much of that a linear trend the offset
    terms take: with a weak texture what is left of ``B`` is mostly noise.  The noise variance ``s^2`` is
    the centre view's white noise (:func:`~plenodecode.depth.confidence.image_noise`, robust); a pixel
    whose reliability is below 1/2 is not decided by the regression (illum-mini decoded, a 0.5 px edge beside
    a weakly textured wall: with ``jump`` 0.3 the far pixels along it went to the near side).

    Where the regression cannot decide (fewer than ``min_views`` views, a background without texture or
    with a reliability below 1/2, not significant), a clean two-colour edge in the centre view decides
    alone: both sides flat a pixel further out (flatness below ``flat_edge``) and the mixing more than
    ``mixing_margin`` from 1/2.  The regression needs a background that moves; this needs two surfaces of
    different colour, and the flatness keeps out the shaded rims the colour of the background, where the
    mixing says nothing about coverage.  Only pixels next to the other side are tested, once; the others
    keep their side.  A decided pixel takes its surface's hypothesis also where the map had it on that side
    already: matching puts a mixed pixel between the two surfaces (with a jump of 0.5 px the mix's cost is
    lowest in between), and such a value, on the right side but neither surface, was kept (thin scenes'
    ground-truth mean BadPix0.07 6.72 -> 6.49 %, decoded 19.45 -> 18.94 %; illum-mini ideal / decoded
    0.38 / 1.19 -> 0.07 / 0.99 %; hci-antinous 4.20 -> 4.18 %, MSE x100 1.814 -> 1.820).  Both models mix
    light, so a linear light field's views are taken with their display encoding undone
    (:meth:`Views.linear`); stored sRGB values are used as stored.

    Photo-consistency alone cannot do this: with a smooth background a mixed pixel matches the occluder's
    disparity almost as well as a fully covered one, so the relabel before it (:func:`visibility_relabel`)
    gives the occluder pixels it covers only in small part.

    Parameters
    ----------
    intensities : Views
        Views without contrast channels; the regression reduces colour views to luma.
    disparity : ndarray (Y, X) float32
    radius, jump : the band and hypotheses of :func:`_band_hypotheses`.
    significance, agreed_significance : float
        Standard errors of the regression's ``a - 1/2`` needed to move a pixel, alone and with the centre
        view's colour mixing agreeing.
    flat_edge, mixing_margin : float
        Where the regression does not decide: the centre view's flatness and ``|mixing - 1/2|`` that do.

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    d = np.ascontiguousarray(disparity, np.float32)
    out = d.copy()
    band, is_near, h_near, h_far = _band_hypotheses(d, radius, jump)
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)
    near_px, far_px = band & is_near, band & ~is_near
    edge = (near_px & cv2.dilate(far_px.astype(np.uint8), cross).astype(bool)) | \
           (far_px & cv2.dilate(near_px.astype(np.uint8), cross).astype(bool))
    ys, xs = np.nonzero(edge)
    if len(ys) == 0:
        return out

    rows, cols = _pixel_image_shape(len(ys))
    px, py = (_as_pixel_image(a.astype(np.float32), rows, cols) for a in (xs, ys))
    hn, hf = (_as_pixel_image(h[ys, xs], rows, cols) for h in (h_near, h_far))
    # the models mix light: the display encoding of linear light fields' views is undone
    centre_light = intensities.linear(intensities.centre)
    centre = luma(centre_light)
    # a background point is seen unoccluded where no pixel within BACKGROUND_MARGIN px is nearer
    k = 2 * BACKGROUND_MARGIN + 1
    nearest_around = cv2.dilate(d, np.ones((k, k), np.uint8))
    nearest_clear = cv2.dilate(d, np.ones((5, 5), np.uint8))
    visible_below = hf + np.float32(0.5 * jump)
    dv_all, du_all = intensities.offsets
    # weighted least squares of y = follow on (1, x = back, dv, du); the view-offset terms absorb a colour
    # change linear across the aperture (a slightly wrong occluder disparity moves its outline across the
    # pixel in proportion to the offset, as a smooth background gradient moves past it)
    moments = np.zeros((4, 4, rows, cols), np.float64)
    rhs = np.zeros((4, rows, cols), np.float64)
    syy = np.zeros((rows, cols), np.float64)
    count = np.zeros((rows, cols), np.int32)
    # the same moments over the views whose background sample's whole bicubic support (2 px) is clear
    clear_moments = np.zeros((4, 4, rows, cols), np.float64)
    clear_count = np.zeros((rows, cols), np.int32)
    for vu in intensities.used():
        dv, du = np.float32(dv_all[vu]), np.float32(du_all[vu])
        follow = cv2.remap(luma(intensities.linear(vu)), px - hn * du, py - hn * dv, cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REPLICATE)
        bx, by = px + (hf - hn) * du, py + (hf - hn) * dv
        back = cv2.remap(centre, bx, by, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
        z = cv2.remap(nearest_around, bx, by, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                      borderValue=np.inf)
        ok = z < visible_below
        w = ok * np.float64(intensities.weight[vu])
        r = np.stack([np.ones_like(w), back.astype(np.float64), np.full_like(w, dv), np.full_like(w, du)])
        y = follow.astype(np.float64)
        moments += w * r[:, None] * r[None, :]
        rhs += w * r * y
        syy += w * y * y
        count += ok
        clear = cv2.remap(nearest_clear, bx, by, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=np.inf) < visible_below
        clear_moments += (clear * np.float64(intensities.weight[vu])) * r[:, None] * r[None, :]
        clear_count += clear
    n = len(ys)
    m = np.moveaxis(moments.reshape(4, 4, -1)[..., :n], -1, 0) + 1e-9 * np.eye(4)
    inverse = np.linalg.inv(m)                                          # (n, 4, 4)
    b = rhs.reshape(4, -1)[:, :n].T                                      # (n, 4)
    coef = np.einsum("nij,nj->ni", inverse, b)
    sw = np.maximum(m[:, 0, 0], 1e-12)
    count = count.reshape(-1)[:n]
    # residual variance per view, unbiased for the 4 fitted parameters
    residual = (np.maximum(syy.reshape(-1)[:n] - np.einsum("ni,ni->n", coef, b), 0.0) / sw
                * count / np.maximum(count - 4, 1))
    x_spread = 1.0 / np.maximum(inverse[:, 1, 1], 1e-30)              # sum w (x - its fit on 1, dv, du)^2
    # the regressor, the centre view, is as noisy as the views it explains: least squares shrinks the
    # background's coefficient by the reliability 1 - noise / spread (regression dilution), which reads as
    # coverage
    noise = image_noise(centre, robust=True) ** 2
    reliability = 1.0 - noise * sw / x_spread
    stderr = np.sqrt(residual / x_spread)
    covered = 1.0 - coef[:, 1]
    # the centre view's own estimate: the normal points into the near side
    indicator = cv2.GaussianBlur(is_near.astype(np.float32), (0, 0), 1.0)
    normal = np.stack([g[ys, xs] for g in np.gradient(indicator)], axis=1).astype(np.float64)
    normal /= np.maximum(np.hypot(normal[:, 0], normal[:, 1]), 1e-12)[:, None]
    mixed, flatness = two_colour_edge(centre_light, ys, xs, normal)
    agree = mixing_agrees(mixed, covered)
    # a background that varies over the views by less than one 8-bit grey level (beyond a linear trend) is
    # flat: no slope; one that varies by less than twice the noise shrinks the coefficient by more than half
    textured = (x_spread / sw > (1.0 / 255.0) ** 2) & (reliability > 0.5)
    # within 2 px of the map's near side a background sample may hold part of the occluder (a mixed pixel the
    # map gives the far side, the bicubic's outer taps): over a flat background that alone varies over the
    # views, and the fit reads it as texture.  Where enough views' samples are clear by 2 px, they judge
    # whether the background is textured
    clear_m = np.moveaxis(clear_moments.reshape(4, 4, -1)[..., :n], -1, 0) + 1e-9 * np.eye(4)
    clear_spread = 1.0 / np.maximum(np.linalg.inv(clear_m)[:, 1, 1], 1e-30)
    clear_flat = clear_spread / np.maximum(clear_m[:, 0, 0], 1e-12) <= (1.0 / 255.0) ** 2
    textured &= ~((clear_count.reshape(-1)[:n] >= min_views) & clear_flat)
    needed = np.where(agree, agreed_significance, significance)
    tested = (count >= min_views) & textured & (np.abs(covered - 0.5) > needed * stderr)
    clean_edge = ~tested & (flatness < flat_edge) & (np.abs(mixed - 0.5) > mixing_margin)
    decided = tested | clean_edge
    estimate = np.where(clean_edge, mixed, covered)
    side = is_near[ys, xs]
    # a decided pixel takes its surface's hypothesis, also on the side it was on (a mix matched in between)
    to_near, to_far = decided & (estimate > 0.5), decided & (estimate < 0.5)
    out[ys[to_near], xs[to_near]] = h_near[ys[to_near], xs[to_near]]
    out[ys[to_far], xs[to_far]] = h_far[ys[to_far], xs[to_far]]
    log.debug("coverage relabel: %d edge pixels, %d to the near side (%d from the far side), %d to the far side "
              "(%d from the near side)", len(ys), int(to_near.sum()), int((to_near & ~side).sum()),
              int(to_far.sum()), int((to_far & side).sum()))
    return out


def fix_occlusion_edges(views: Views, disparity: np.ndarray, guide: np.ndarray, *, radius: int = 4,
                        jump: float = 0.5, ratio: float = 1.5, wedge: int = 2, median_radius: int = 5,
                        intensities: Views | None = None, visibility: bool = True, coverage: bool = True,
                        gate: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                        noise_floor: float = 0.0) -> np.ndarray:
    """Remove the foreground fattening at depth discontinuities.

    Four steps, all restricted to the band within ``radius`` px of a disparity jump larger than ``jump``
    (:func:`_edge_band`):

    1. **Visibility check.**  A pixel on the near side of a jump (``d > (near + far) / 2``) claims to lie on
       the occluder, and nothing occludes an occluder: every view must then see it, so its cost over *all*
       views (:func:`half_plane_cost_volume` with one sector, views warped per pixel by ``d``) must be small.
       A background pixel fattened by the occluder is seen by all views only on its own surface: its cost at
       the far disparity ``far`` over the views on the un-occluded side is lower.  Those views are the best
       wedge of ``wedge`` of the 8 angular sectors (2: a 90 degree wedge).  A half-plane would do beside a
       straight edge, but in a concave pocket of the occluder's outline the background is hidden from views
       on two sides and every half-plane still looks past the occluder.  Pixels with
       ``C_all(d) - F > ratio * max(C_wedge(far) - F, 0)`` take ``far``, ``F`` the cost noise alone leaves
       (``noise_floor``; 0 on clean views) (the occlusion reasoning of Kang, Szeliski & Chai, CVPR 2001 and
       Wang, Efros & Ramamoorthi, ICCV 2015, used as a left-right style consistency test).
    2. **Edge snapping.**  A weighted median of the disparity guided by the centre view in colour
       (Ma et al., ICCV 2013; ``cv2.ximgproc.weightedMedianFilter``, radius ``median_radius``) replaces the
       band, so the remaining depth edge follows the colour edge.
    3. **Per-pixel visibility** (:func:`visibility_relabel`, when ``intensities`` are given and ``visibility``):
       every band pixel takes the side whose disparity its own colour matches ``ratio`` times better in the
       views that see it.  The median of step 2 puts the edge at the strongest colour edge, which cuts off an
       occluder's silhouette rim when the rim is as dark as the background.
    4. **Coverage** (:func:`coverage_relabel`, when ``intensities`` are given and ``coverage``): a pixel on
       the edge goes to the surface that covers more than half of it, measured by how much of the
       background's motion across the views shows through it and by where its colour lies between its
       neighbours across the edge.

    Parameters
    ----------
    views : Views
        The matching views (the ones the cost volume used).
    disparity : ndarray (Y, X) float32
    guide : ndarray (Y, X, 3) or (Y, X, 1) uint8
        :func:`plenodecode.depth.views.colour_guide`.
    intensities : Views, optional
        The views without contrast channels, for steps 3 and 4 (None: both are skipped).
    visibility, coverage : bool
        Run step 3, step 4.
    gate : callable(before, after) -> map, optional
        Applied to the edge snapping of step 2 (:func:`plenodecode.depth.refinement.cost_gate`): the median
        may not replace a thin structure that the matching cost supports by the surface around it; and to
        the moves of step 3 to the near side (the far side of a slit of a few pixels is seen by the strip of
        views along it only, which the matching cost's strips weigh; without this gate the thin scenes'
        ground-truth mean BadPix0.07 was 12.5 % instead of 11.4 %).
    noise_floor : float
        The per-view mean error of step 1's costs on views that differ by noise only, less what it strays by
        chance (:func:`plenodecode.depth.pipeline.edge_floor_for`); subtracted before the ratio, which a noise
        floor shared by both costs pulls towards 1 (0 = off).

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    d = np.ascontiguousarray(disparity, np.float32)
    near, far, band = _edge_band(d, radius, jump)
    if not band.any():
        return d.copy()
    zero = np.zeros(1)
    c_all = half_plane_cost_volume(views, zero, radius=1, base=d, n_sectors=1)[..., 0]
    c_far = half_plane_cost_volume(views, zero, radius=1, base=far, span=wedge)[..., 0]
    if noise_floor > 0:
        nf = np.float32(noise_floor)
        c_all = c_all - nf
        c_far = np.maximum(c_far - nf, np.float32(0.0))
    switch = band & (d > 0.5 * (near + far)) & (c_all > np.float32(ratio) * c_far)
    d = np.where(switch, far, d).astype(np.float32)
    log.debug("occlusion edges: %.2f %% of pixels in the band, %.2f %% moved to the far side",
              100.0 * band.mean(), 100.0 * switch.mean())
    if median_radius > 0:
        _, _, band = _edge_band(d, radius, jump)
        g = guide if guide.ndim == 2 or guide.shape[-1] in (1, 3) else guide[..., :3]
        # with a colour guide OpenCV clusters the colours by k-means++ from the calling thread's cv::RNG, which is
        # thread-local: seed the RNG of a short-lived thread of its own, so the same input gives the same map and
        # no other RNG of the process is seeded (the thread, and its RNG, end with the call)
        def seeded_weighted_median(guide: np.ndarray, values: np.ndarray) -> np.ndarray:
            cv2.setRNGSeed(0)
            return cv2.ximgproc.weightedMedianFilter(guide, values, int(median_radius), 25.5)

        with ThreadPoolExecutor(max_workers=1) as own_thread:
            wm = own_thread.submit(seeded_weighted_median, np.ascontiguousarray(g), d).result()
        snapped = np.where(band, wm, d).astype(np.float32)
        d = snapped if gate is None else gate(d, snapped)
    if intensities is not None and visibility:
        relabelled = visibility_relabel(intensities, d, radius=radius, jump=jump, ratio=ratio,
                                        despeckle=gate is None)
        if gate is not None:
            # a move to the near side, gated: a far point seen through a thin gap is judged by the few views
            # along the gap, which the matching cost's strips weigh and the per-pixel costs do not
            relabelled = np.where(relabelled > d, gate(d, relabelled), relabelled).astype(np.float32)
            # the despeckling median, gated too: a 3 x 3 median wipes out a 1-px slit or slat the views support
            relabelled = gate(relabelled, _despeckle(relabelled, _band_hypotheses(d, radius, jump)[0]))
        d = relabelled
    if intensities is not None and coverage:
        d = coverage_relabel(intensities, d, radius=radius, jump=jump)
    return d



__all__ = ["EDGE_DEFAULTS", "BACKGROUND_MARGIN", "fix_occlusion_edges", "visibility_relabel", "coverage_relabel",
           "two_colour_edge", "mixing_agrees", "nearest_surface"]
