"""Matching cost: disparity labels and the occlusion-aware half-plane cost volume.

* :func:`make_labels`: uniformly spaced disparity labels over a range.
* :func:`half_plane_groups`: the used views per angular sector (:func:`sector_of`) and the weight of each
  group of consecutive sectors.
* :func:`strip_groups`, :func:`line_kernel`: the views near a line through the centre view and the 1-px wide
  segment that aggregates their cost along that line, for thin structures; :func:`strip_halves`: the views of
  an oblique strip on either side of its line.
* :func:`half_plane_cost_volume`: the photo-consistency cost of every label, the minimum over half-planes
  of views (Kang, Szeliski & Chai, CVPR 2001) and, when asked, over oriented strips of views, optionally
  around a per-pixel base disparity.
* :func:`interpolated_noise_gain`: how much noise a fractional shift averages away, which the cost volume
  adds back on noisy views.
* :func:`floor_standard_error`: how far a strip's mean error on noise alone strays from its noise floor;
  :func:`floor_less_margin`: that floor less the margin the strips' penalty keeps below it.
"""

from __future__ import annotations

import logging
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import cv2
import numpy as np

from ..imaging import remap_view, shift_view
from ..threads import task_threads
from .views import Views

log = logging.getLogger(__name__)

#: A progress callback ``(done, total)``, or None.
Progress = Callable[[int, int], None] | None

#: Standard errors of its mean that a strip's error may fall below the noise floor (``strip_floor`` of
#: :func:`half_plane_cost_volume`) by chance.
FLOOR_MARGIN = 2.0

#: Number of angular sectors the views are split into; a half-plane is ``N_SECTORS // 2`` consecutive sectors.
N_SECTORS = 8


def worker_threads() -> int:
    """Threads for the depth kernels that release the GIL: the calling thread's share of the cores
    (:func:`plenodecode.threads.task_threads`: all of them, or a batch worker's cap), at most 4."""
    return task_threads(4)


def sector_of(dv: float, du: float, n: int = N_SECTORS) -> int:
    """Angular sector (0..n-1) of the view offset ``(dv, du)``: sector ``k`` covers angles
    ``[-pi + k 2pi/n, -pi + (k + 1) 2pi/n)`` of ``atan2(dv, du)``."""
    a = math.atan2(dv, du) + math.pi + 1e-9
    return int(a // (2 * math.pi / n)) % n



def make_labels(lo: float, hi: float, step: float, *, pad: float = 0.0) -> np.ndarray:
    """Uniform labels covering ``[lo - pad, hi + pad]`` with spacing at most ``step``; float64."""
    if not step > 0:
        raise ValueError(f"label_step must be positive, got {step!r}")
    a, b = lo - pad, hi + pad
    n = max(3, int(math.ceil((b - a) / step)) + 1)
    return np.linspace(a, b, n)



def half_plane_groups(views: Views, n_sectors: int, span: int) -> tuple[list[list[tuple[int, int]]], np.ndarray]:
    """Views per angular sector and the weight of each group of ``span`` consecutive sectors.

    Returns
    -------
    sectors : list of n_sectors lists of (v, u)
    group_weight : ndarray (n_sectors,) float64
        Total view weight of group ``h`` = sectors ``h .. h + span - 1`` (mod n); ``span = n_sectors // 2``
        makes half-planes.
    """
    dv, du = views.offsets
    sectors: list[list[tuple[int, int]]] = [[] for _ in range(n_sectors)]
    for v, u in views.used():
        sectors[sector_of(dv[v, u], du[v, u], n_sectors)].append((v, u))
    sw = np.array([sum(float(views.weight[vu]) for vu in s) for s in sectors])
    hw = np.array([sum(sw[(h + i) % n_sectors] for i in range(span)) for h in range(n_sectors)])
    return sectors, hw


def strip_groups(views: Views, n_orientations: int, width: float
                 ) -> list[tuple[float, list[tuple[int, int]], float]]:
    """The used views within ``width`` view steps of a line through the centre view, per orientation.

    Orientation ``k`` is the angle ``phi_k = k pi / n_orientations`` of a structure's edge in the image
    (0 = horizontal, rows; ``pi / 2`` = vertical, columns); its unit direction is ``t = (sin phi, cos phi)``
    as ``(y, x)`` and its normal ``n = (cos phi, -sin phi)``.  View ``o = (dv, du)`` belongs to strip ``k``
    when ``|n . o| <= width``: the views that look past a thin occluder (or through a thin gap) of that
    orientation along it rather than across it, which see a point between two occluding edges when both
    half-planes of views are blocked (the line through the centre with the edge's orientation of Wang, Efros
    & Ramamoorthi, ICCV 2015, narrowed from a half-plane to a strip).

    Returns
    -------
    list of (phi, views, weight)
        One entry per orientation with at least 2 used views; ``weight`` is their total view weight.
    """
    dv, du = views.offsets
    used = views.used()
    out = []
    for k in range(int(n_orientations)):
        phi = math.pi * k / n_orientations
        ny, nx = math.cos(phi), -math.sin(phi)
        members = [vu for vu in used if abs(ny * dv[vu] + nx * du[vu]) <= width + 1e-9]
        if len(members) >= 2:
            out.append((phi, members, sum(float(views.weight[vu]) for vu in members)))
    return out


def strip_halves(views: Views, strips: list[tuple[float, list[tuple[int, int]], float]]
                 ) -> list[list[tuple[list[tuple[int, int]], float]]]:
    """The two halves of every strip whose views do not all lie on its line, split by the side of the line.

    A strip at an angle the view grid has no line of views along (anything but rows, columns and diagonals)
    holds views up to ``width`` off its line, ``n . o != 0``.  Behind a gap of that orientation, such a view
    sees the gap's edges moved across it by ``(d_near - d_far) n . o`` relative to the far point, so a point
    near one edge is hidden from the views off the line on that edge's side and seen by those on the other:
    the half-plane argument of :func:`half_plane_cost_volume` across the strip.  Half ``s`` holds the views
    with ``s n . o >= 0`` (the views on the line belong to both); a strip whose views are all on its line
    (``n . o = 0``) has no halves.

    Returns
    -------
    list, one entry per strip: ``[]`` or two ``(views, weight)``, each half with at least 2 views.
    """
    dv, du = views.offsets
    out = []
    for phi, members, _ in strips:
        ny, nx = math.cos(phi), -math.sin(phi)
        side = {vu: ny * dv[vu] + nx * du[vu] for vu in members}
        halves = []
        if any(abs(a) > 1e-9 for a in side.values()):
            for sign in (1.0, -1.0):
                part = [vu for vu in members if sign * side[vu] >= -1e-9]
                if len(part) >= 2:
                    halves.append((part, sum(float(views.weight[vu]) for vu in part)))
        out.append(halves)
    return out


def line_kernel(phi: float, radius: int) -> np.ndarray:
    """A normalised 1-px wide segment along the direction ``(sin phi, cos phi)`` (y, x): (2 r + 1, 2 r + 1)
    float32 summing to 1.

    Its ``2 radius + 1`` points step one pixel along the axis the direction is closer to, ``k t / max(|t_y|,
    |t_x|)`` for ``k = -r .. r``, and are splatted bilinearly: exact pixels for rows, columns and diagonals.
    Aggregating a cost with it stays on a thin structure of that orientation (an oriented window, as the
    parallelograms of Zhang et al.'s spinning parallelogram operator, 2016, are oriented)."""
    r = int(radius)
    k = np.zeros((2 * r + 1, 2 * r + 1), np.float32)
    ty, tx = math.sin(phi), math.cos(phi)
    scale = 1.0 / max(abs(ty), abs(tx))
    for i in range(-r, r + 1):
        y, x = r + i * ty * scale, r + i * tx * scale
        y0, x0 = math.floor(y), math.floor(x)
        fy, fx = y - y0, x - x0
        for yy, xx, w in ((y0, x0, (1 - fy) * (1 - fx)), (y0 + 1, x0, fy * (1 - fx)),
                          (y0, x0 + 1, (1 - fy) * fx), (y0 + 1, x0 + 1, fy * fx)):
            if w > 1e-9 and 0 <= yy <= 2 * r and 0 <= xx <= 2 * r:
                k[yy, xx] += w
    return k / k.sum()


def floor_standard_error(n_views: float, n_pixels: int) -> float:
    """Standard error of a strip's mean error on views that differ by white noise only, relative to its
    expectation ``2 sigma^2``::

        sqrt((1 + 3 / n) / (2 L))

    for ``n`` views and a line of ``L`` pixels: per pixel ``e_v = (a_v - c)^2`` with ``a_v``, ``c`` of variance
    ``sigma^2`` has variance ``8 sigma^4``, and two views' errors share the centre view's noise, covariance
    ``2 sigma^4``, so their mean has variance ``(2 + 6 / n) sigma^4``, averaged over ``L`` independent pixels
    (the centre view's noise does not average over the views: 0.35 for a row of 14 views and 5 pixels).
    """
    return math.sqrt((1.0 + 3.0 / max(float(n_views), 1e-9)) / (2.0 * max(int(n_pixels), 1)))


def floor_less_margin(floor: float, n_views: float, n_pixels: int) -> float:
    """A noise floor less :data:`FLOOR_MARGIN` standard errors (:func:`floor_standard_error`) of a mean over
    ``n_views`` views and ``n_pixels`` pixels, at least 0: ``floor max(0, 1 - FLOOR_MARGIN SE)``, what such a
    mean on noise alone stays above but by chance."""
    return float(floor) * max(0.0, 1.0 - FLOOR_MARGIN * floor_standard_error(n_views, n_pixels))


def interpolated_noise_gain(f: np.ndarray | float, interpolation: int, rho: float = 0.0) -> np.ndarray | float:
    """Variance of noise after a 1-D interpolation at fraction ``f`` of a pixel, relative to before::

        g(f) = sum_i w_i^2 + 2 rho sum_i w_i w_{i+1}

    with ``w_i`` the taps (linear: ``1 - f, f``, so ``g = 1 - 2 (1 - rho) f (1 - f)``; else OpenCV's cubic,
    ``a = -0.75``) and ``rho`` the noise's correlation between neighbouring pixels along that axis.  ``f`` in
    [0, 1) (scalar or array); 1 at ``f = 0``, lowest at ``f = 1/2`` (white noise: 0.5 linear, 0.72 cubic).
    """
    f = np.asarray(f, np.float32) if not np.isscalar(f) else float(f)
    if interpolation != cv2.INTER_CUBIC:
        return 1 - 2 * (1 - rho) * f * (1 - f)
    a = -0.75

    def near(t):   # |t| <= 1
        return ((a + 2) * t - (a + 3)) * t * t + 1

    def far(t):    # 1 < |t| < 2
        return ((a * t - 5 * a) * t + 8 * a) * t - 4 * a

    w = (far(1 + f), near(f), near(1 - f), far(2 - f))
    return (sum(t * t for t in w) + 2 * rho * (w[0] * w[1] + w[1] * w[2] + w[2] * w[3])) / sum(w) ** 2


def half_plane_cost_volume(views: Views, labels: np.ndarray, *, radius: int = 2, interpolation: int = cv2.INTER_LINEAR,
                           base: np.ndarray | None = None, progress: Progress = None,
                           n_sectors: int = N_SECTORS, span: int | None = None,
                           threads: int | None = None, strips: int = 0, strip_width: float = 0.5,
                           strip_radius: int = 2, strip_penalty: float = 1.0,
                           strip_channels: int | None = None, noise_var: float = 0.0,
                           noise_rho: tuple[float, float] = (0.0, 0.0), noise_weighted: bool = False,
                           halve_strips: bool = False,
                           strip_floor: float = 0.0) -> np.ndarray:
    """Occlusion-aware matching cost for every label.

    For label ``d`` every used view is shifted onto the centre view (:func:`shift_view`), and the
    weighted squared colour difference to the centre view is summed per angular sector.  A half-plane of
    views (``n_sectors / 2`` consecutive sectors, Kang, Szeliski & Chai, CVPR 2001; the occluder-edge split
    of the angular patch of Wang, Efros & Ramamoorthi, ICCV 2015) sees an occluded point in none of its views
    when the occluder lies on the other side, so the cost is the minimum over the ``n_sectors`` half-planes of
    the box-aggregated (``(2 radius + 1)^2``) mean squared difference::

        C(p, d) = min_h  box_r[ sum_{(v,u) in h} w_vu |I_vu(p - d o_vu) - I_c(p)|^2 ] / sum_{h} w_vu

    A thin structure (a slat, a gap, a slit of a few pixels) breaks both assumptions: a point seen through a
    gap is hidden from the views on *both* sides, and a square box around a 1-px slat is mostly background.
    With ``strips > 0`` the minimum also runs over ``strips`` oriented strips of views
    (:func:`strip_groups`), each aggregated along a 1-px segment of its own orientation
    (:func:`line_kernel`, radius ``strip_radius``) and scaled by ``strip_penalty`` (>= 1 makes a strip win
    only where it is clearly better, as it averages fewer views)::

        C(p, d) = min( min_h ..., min_k  penalty * line_k[ sum_{(v,u) in strip k} w_vu |...|^2 ] / sum_k w_vu )

    (above a noise floor, ``strip_floor``, only the excess is penalised: ``floor + penalty max(m - floor, 0)``)

    (with ``halve_strips`` also over the halves of the oblique strips, see below).

    Parameters
    ----------
    views : Views
    labels : ndarray (L,) float64
        Disparities (px per view step).
    radius : int
        Box aggregation radius (0 = none).
    interpolation : int
        OpenCV interpolation flag of the shifts.
    base : ndarray (Y, X) float32, optional
        A disparity map: the labels are then offsets from it and every view is warped per pixel with
        ``base + label`` (:func:`remap_view`), which follows slanted surfaces exactly.
    progress : callable(done, total), optional
        Called after every label.
    n_sectors, span : int
        The views are split into ``n_sectors`` angular sectors and the minimum is taken over the groups of
        ``span`` consecutive sectors (default ``n_sectors // 2``: half-planes).  A narrower group (a wedge of
        ``span * 360 / n_sectors`` degrees) leaves out more of the views that look past the occluder's edge.
    threads : int, optional
        Labels computed concurrently (OpenCV releases the GIL); default: the number of CPU cores, at most 4.
    strips, strip_width, strip_radius, strip_penalty
        Number of strip orientations (0 = none), their half-width in view steps, the radius of their line
        aggregation and the factor on their cost (see above).
    halve_strips : bool
        The minimum also runs over the two halves of every strip whose views are not all on its line
        (:func:`strip_halves`), each half's penalty multiplied by its strip's view weight over its own
        (``penalty W_k / W_half``: a half averages fewer views, so it must win by more).  On the grid of views
        only rows, columns and diagonals have views exactly on their line; an oblique strip holds views up to
        ``strip_width`` off it, which see the edges of a gap of that orientation moved across it, and a point
        near one edge is then seen by the views off the line on the other edge's side only.
    strip_floor : float
        The mean error per view (over the strip channels) of views that differ by noise only (0 = none).  A
        strip's (or half's) mean error ``m`` counts as ``floor + penalty max(m - floor, 0)`` rather than
        ``penalty m``: the penalty guards against the few views of a strip fitting texture by chance, but on
        noisy views it also multiplied the noise every label shares, so that a strip that sees a weakly
        textured far plane through a gap at its noise floor lost to the half-planes' near disparity,
        whose box holds the gap's textured occluders (decoded slats-h-j0.5-weak, medians over the far pixels in
        units of ``2 sigma^2``: the best strip's penalised error 3.6 at the far disparity, 5.6 at the near one;
        the half-planes' 23 and 5.8).
        A mean below the floor counts as the floor, so the strips' noise does not pull the minimum; each strip
        or half uses the floor less :data:`FLOOR_MARGIN` standard errors of its mean
        (:func:`floor_standard_error`, its views and line pixels), the amount a few views' noise falls short of
        it by chance, which the penalty must still cover (a noisy 7 x 7-view plane, noise 0.024: BadPix0.07
        0.26 % without a floor, 1.8 % at the full floor, 0.54 % with the margin and the pipeline's gate base).
    strip_channels : int, optional
        The strips' cost sums only the first ``strip_channels`` channels (None: all).  The pipeline passes
        the intensity channels: a local contrast normalisation stacked beside them
        (:func:`~plenodecode.depth.views.add_contrast`) mixes a thin structure with the other surface within
        its Gaussian, whose position differs from view to view, so a point seen through a 1-5 px gap never
        matches in that channel (on the thin scenes the raw winner of the strips was right on 84-95 % of
        far pixels with the intensities alone, 14-79 % with the contrast channel).
    noise_var, noise_rho
        Noise variance per intensity channel (the first ``strip_channels``; 0 = off) and its correlation
        between neighbouring pixels ``(along y, along x)``.  A shift by a fraction ``f`` of a pixel averages
        neighbouring pixels and so lowers the noise in the difference to the centre view
        (:func:`interpolated_noise_gain`): on noisy views the cost is lowest where the shifts are fractional,
        which pulls a weakly textured surface off an integer disparity.  Every view's error gets back
        ``noise_var (1 - g(f_y) g(f_x))`` per channel, so the noise term is the same at every label: a decoded
        weakly textured plane at disparity -1 (illum-mini raw) went from BadPix0.07 84.4 % (winner +0.089 off)
        to 0.4 % with ``noise_var`` 4 x :func:`~plenodecode.depth.views.noise_sigma` squared (``rho`` 0).
    noise_weighted
        False: every view's noise variance is ``noise_var``.  True: a view of weight ``w < 1`` has
        ``noise_var / w``, so that its compensation, once weighted, is ``noise_var (1 - g)`` like a full view's:
        a decoder divides a vignetted view by its white level ``w``, which multiplies the shot noise of its
        ``w`` times fewer photons by ``1 / sqrt(w)`` (a decoded illum-mini plane: noise sigma 1.5 / 1.8 / 2.5 x
        the centre view's in views of weight 0.54 / 0.20 / 0.13, against ``1 / sqrt(w)`` = 1.4 / 2.2 / 2.8).

    Returns
    -------
    ndarray, shape (Y, X, L), float32
        Labels last (the layout :func:`sgm` and :func:`winner` read).
    """
    if threads is None:
        threads = worker_threads()
    span = max(1, n_sectors // 2) if span is None else int(span)
    if not 1 <= span <= n_sectors:
        raise ValueError(f"span must be in [1, n_sectors={n_sectors}], got {span!r}")
    sectors, hw = half_plane_groups(views, n_sectors, span)
    if not np.all(hw > 0):
        # too few views for every group (e.g. a 1 x N light field): fall back to the plain mean over views
        n_sectors = span = 1
        sectors = [[vu for s in sectors for vu in s]]
        hw = np.array([sum(float(views.weight[vu]) for vu in sectors[0])])
    dv, du = views.offsets
    data = views.data
    Y, X, C = data.shape[2:]
    if C == 1:
        data = data[..., 0]
    centre = np.ascontiguousarray(data[views.centre])
    L = len(labels)
    out = np.empty((Y, X, L), np.float32)
    ones = np.ones((1, C), np.float32)
    n_strip = C if strip_channels is None else min(C, max(1, int(strip_channels)))
    # the channels a strip's cost sums: the first n_strip (the intensities), or None = the same as the groups
    strip_mask = None if n_strip == C else (np.arange(C) < n_strip).astype(np.float32)[None, :]
    ksize = (2 * radius + 1, 2 * radius + 1)
    sector_of_view = {vu: i for i, s in enumerate(sectors) for vu in s}
    lines = strip_groups(views, strips, strip_width) if strips > 0 else []
    line_kernels = [line_kernel(phi, strip_radius) for phi, _, _ in lines]
    strips_of_view: dict[tuple[int, int], list[int]] = {vu: [] for vu in sector_of_view}
    for i, (_, members, _) in enumerate(lines):
        for vu in members:
            strips_of_view[vu].append(i)
    halves = strip_halves(views, lines) if lines and halve_strips else [[] for _ in lines]
    # (strip, half) of every half, and the halves each view belongs to
    half_index = [(i, k) for i, hs in enumerate(halves) for k in range(len(hs))]
    halves_of_view: dict[tuple[int, int], list[int]] = {vu: [] for vu in sector_of_view}
    for j, (i, k) in enumerate(half_index):
        for vu in halves[i][k][0]:
            halves_of_view[vu].append(j)
    weights = {vu: np.float32(views.weight[vu]) for vu in sector_of_view}
    grid = None
    if base is not None:
        base = np.ascontiguousarray(base, np.float32)
        if base.shape != (Y, X):
            raise ValueError(f"base must have shape {(Y, X)}, got {base.shape}")
        yy, xx = np.mgrid[0:Y, 0:X].astype(np.float32)
        grid = (yy, xx)

    def group_minimum(sums: list[np.ndarray]) -> np.ndarray:
        # min over the groups of span consecutive sectors of the box-aggregated mean error
        best = None
        for h in range(n_sectors):
            hsum = sums[h].copy()
            for i in range(1, span):
                hsum += sums[(h + i) % n_sectors]
            hsum *= np.float32(1.0 / hw[h])
            if radius > 0:
                hsum = cv2.boxFilter(hsum, -1, ksize)
            best = hsum if best is None else np.minimum(best, hsum, out=best)
        return best

    def group_floor(members: list[tuple[int, int]]) -> np.float32:
        # the noise floor less FLOOR_MARGIN standard errors of a strip's (or half's) mean: its views' effective
        # number (Kish: (sum w)^2 / sum w^2) and its line's 2 strip_radius + 1 pixels
        if not strip_floor > 0:
            return np.float32(0.0)
        w = np.array([float(views.weight[vu]) for vu in members])
        n = w.sum() ** 2 / max(float((w * w).sum()), 1e-12)
        return np.float32(floor_less_margin(strip_floor, n, 2 * strip_radius + 1))

    line_floors = [group_floor(members) for _, members, _ in lines]
    half_floors = [group_floor(halves[i][k][0]) for i, k in half_index]

    def penalised(mean: np.ndarray, penalty: float, floor: np.float32) -> np.ndarray:
        # a strip's (or half's) mean error m as floor + penalty max(m - floor, 0): penalty * m for floor 0
        if not floor > 0:
            mean *= np.float32(penalty)
            return mean
        mean -= floor
        np.maximum(mean, np.float32(0.0), out=mean)
        mean *= np.float32(penalty)
        mean += floor
        return mean

    def one_label(k: int) -> None:
        # one label's cost into out[:, :, k]; own buffers, so labels can run on several threads (OpenCV
        # releases the GIL)
        d = labels[k]
        sums = [np.zeros((Y, X), np.float32) for _ in range(n_sectors)]
        # with strip channels: the groups' error over those channels alone, the strips' reference
        channel_sums = [np.zeros((Y, X), np.float32) for _ in range(n_sectors)] if strip_mask is not None else None
        line_sums = [np.zeros((Y, X), np.float32) for _ in lines]
        half_sums = [np.zeros((Y, X), np.float32) for _ in half_index]
        dmap = None if base is None else base + np.float32(d)
        for vu, sector in sector_of_view.items():
            if dmap is None:
                warped = shift_view(data[vu], float(d), dv[vu], du[vu], interpolation)
            else:
                warped = remap_view(data[vu], dmap, dv[vu], du[vu], grid, interpolation)
            diff = cv2.subtract(warped, centre)
            sq = cv2.multiply(diff, diff)
            err = cv2.transform(sq, ones).reshape(Y, X) if C > 1 else sq
            if noise_var > 0:
                # the noise an interpolation averages away at fractional shifts, added back (see noise_var)
                if dmap is None:
                    sy, sx = d * dv[vu], d * du[vu]
                else:
                    sy, sx = dmap * np.float32(dv[vu]), dmap * np.float32(du[vu])
                gain = (interpolated_noise_gain(sy - np.floor(sy), interpolation, noise_rho[0])
                        * interpolated_noise_gain(sx - np.floor(sx), interpolation, noise_rho[1]))
                var = noise_var / float(weights[vu]) if noise_weighted and 0 < weights[vu] < 1 else noise_var
                comp = np.float32(var * n_strip) * (np.float32(1.0) - np.asarray(gain, np.float32))
                err = err + comp
            else:
                comp = None
            if weights[vu] != 1.0:
                err *= weights[vu]
            cv2.add(sums[sector], err, dst=sums[sector])
            strip_err = err
            if channel_sums is not None and lines:
                strip_err = cv2.transform(sq, strip_mask).reshape(Y, X)
                if comp is not None:
                    strip_err = strip_err + comp
                if weights[vu] != 1.0:
                    strip_err *= weights[vu]
                cv2.add(channel_sums[sector], strip_err, dst=channel_sums[sector])
            for i in strips_of_view[vu]:
                cv2.add(line_sums[i], strip_err, dst=line_sums[i])
            for j in halves_of_view[vu]:
                cv2.add(half_sums[j], strip_err, dst=half_sums[j])
        best = group_minimum(sums)
        if lines:
            strip_best = None
            for (_, _, weight), kernel, lsum, lfloor in zip(lines, line_kernels, line_sums, line_floors):
                lsum = penalised(cv2.filter2D(lsum, -1, kernel * np.float32(1.0 / weight)), strip_penalty, lfloor)
                strip_best = lsum if strip_best is None else np.minimum(strip_best, lsum, out=strip_best)
            for (i, h), hsum, hfloor in zip(half_index, half_sums, half_floors):
                # a half averages fewer views than its strip: its penalty grows by the ratio of their weights
                part_weight = halves[i][h][1]
                factor = strip_penalty * lines[i][2] / part_weight
                hmean = cv2.filter2D(hsum, -1, line_kernels[i] * np.float32(1.0 / part_weight))
                np.minimum(strip_best, penalised(hmean, factor, hfloor), out=strip_best)
            if channel_sums is None:
                np.minimum(best, strip_best, out=best)
            else:
                # the strips win by the factor they beat the groups in the strip channels
                reference = group_minimum(channel_sums)
                tiny = np.float32(1e-9)
                best *= np.minimum(np.float32(1.0), (strip_best + tiny) / (reference + tiny))
        out[:, :, k] = best

    workers = min(max(1, int(threads)), L)
    if workers == 1:
        for k in range(L):
            one_label(k)
            if progress is not None:
                progress(k + 1, L)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for i, _ in enumerate(pool.map(one_label, range(L))):
                if progress is not None:
                    progress(i + 1, L)
    return out



__all__ = ["N_SECTORS", "Progress", "worker_threads", "sector_of", "make_labels", "half_plane_groups",
           "strip_groups", "strip_halves", "line_kernel", "interpolated_noise_gain", "floor_standard_error",
           "floor_less_margin", "FLOOR_MARGIN", "half_plane_cost_volume"]
