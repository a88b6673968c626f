"""Checkerboard corners in the sub-aperture views of a light field.

Every view ``lf.data[j, i]`` of a capture is searched for the board's ``rows x cols`` inner corners
with OpenCV's sector-based detector (``cv2.findChessboardCornersSB``, sub-pixel accurate with
``CALIB_CB_ACCURACY``); only complete detections count, and each corner is then fitted by a blurred X-junction
in a window that stays inside the corner's squares: to the view's lens samples on the hex lattice when the
decoder handed them out (:func:`refine_corners_on_samples`), else to the view itself (:func:`refine_corners`).  Views
darker than ``min_weight`` of the central view's weight (the vignetted border of the angular disk) are not
searched.

The detector may start its corner list at any corner of the board; :func:`canonical_order` puts the
list of every view in the same order (rows running to the image's right, columns down), so that the
board frame is the same in all views of a capture and right-handed like the camera frame.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...imaging import luma
from ...raymodel import Board
from ...types import LightField

log = logging.getLogger(__name__)

#: Views whose mean weight is below this fraction of the central view's are not searched.  The outer views
#: of a decoded lenslet image (F01: the ring at 4 view steps, weight 0.48-0.76) sample the edge of the
#: micro-images.  The slicer used to renormalise there and moved them ~0.2-0.3 view steps inwards (H00, H20,
#: H11, H31 4-5 % low); it now extrapolates and a ramp shows them in place (tests/decoding/test_slice.py),
#: but their corners stay 1.5-2x noisier and a one-sided stencil still moves a sharp edge a little: on
#: 8 / 16 generated F01 captures (bilinear demosaic), views >= 0.5 give max |H error| 1.50 / 1.12 %, >= 0.85 1.06 / 0.30 %
#: (bench/bench_geometry.py), so the outer ring stays out.
MIN_VIEW_WEIGHT = 0.85
#: A view whose corners miss the positions the other views' parallax predicts by more than this (px) is
#: dropped as a misdetection (:func:`consistent_views`).
MAX_VIEW_MISFIT_PX = 1.0
#: Seed of OpenCV's per-thread RNG before each detection (:func:`detect_view`).
DETECTOR_SEED = 0
#: Views smaller than this (px, shorter side) are enlarged before detection: the sector detector
#: needs several pixels per square.
MIN_DETECTION_SIZE = 240


@dataclass(frozen=True)
class ViewCorners:
    """The board corners found in the views of one capture.

    Attributes
    ----------
    views : (n, 2) int64
        ``(i, j)`` (angular column, row) of each view with a complete detection.
    corners : (n, rows * cols, 2) float64
        ``(k, l)`` (spatial column, row, 0-based, pixel centres at integers) of each corner, in the
        order of :meth:`Board.points`.
    searched : int
        Views searched (bright enough).
    lf_shape : (V, U, Y, X)
    """

    views: np.ndarray
    corners: np.ndarray
    searched: int
    lf_shape: tuple[int, int, int, int]

    @property
    def count(self) -> int:
        return int(len(self.views))


def canonical_order(corners: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Corners (rows * cols, 2) ``(x, y)`` re-ordered so rows run to the right and columns down.

    Of the symmetries of the ``rows x cols`` grid (flips of either axis, and transposition when the
    board is square) the one maximising ``(c[0, -1] - c[0, 0]) . (1, 0) + (c[-1, 0] - c[0, 0]) . (0, 1)``
    is kept: every view of a capture then lists the corners alike, whatever corner the detector
    started from.
    """
    grid = np.asarray(corners, dtype=np.float64).reshape(rows, cols, 2)
    candidates = [grid[::a, ::b] for a in (1, -1) for b in (1, -1)]
    if rows == cols:
        candidates += [c.transpose(1, 0, 2) for c in candidates]
    scores = [(c[0, -1, 0] - c[0, 0, 0]) + (c[-1, 0, 1] - c[0, 0, 1]) for c in candidates]
    return np.ascontiguousarray(candidates[int(np.argmax(scores))]).reshape(-1, 2)


def detect_view(image: np.ndarray, board: Board, *, refine: bool = True) -> np.ndarray | None:
    """Inner corners of ``board`` in one grey image (Y, X) float: (rows * cols, 2) float64 ``(x, y)``
    in :func:`canonical_order`, or None when the detection is not complete.

    The image is stretched to 8 bits between its 1st and 99th percentiles and, when its shorter side is
    below :data:`MIN_DETECTION_SIZE`, enlarged by ``f`` (bicubic); corners map back by
    ``x = (x' + 0.5) / f - 0.5``.  OpenCV's RNG of the calling thread is seeded with :data:`DETECTOR_SEED`
    first, so the detection is reproducible.  With ``refine`` the corners are then fitted to ``image`` itself
    (:func:`refine_corners`): on 10 generated F01 captures decoded by the pipeline their RMS error fell from
    0.069 to 0.039 px, and the part common to all views of a capture (which no number of views averages out)
    from up to 0.06 to 0.03 px, most of it at the board's edge (bench/bench_geometry.py).
    """
    import cv2

    img = np.asarray(image, dtype=np.float32)
    lo, hi = np.percentile(img, (1.0, 99.0))
    if not hi > lo:
        return None
    img8 = np.clip((img - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)
    factor = max(1, int(np.ceil(MIN_DETECTION_SIZE / min(img8.shape))))
    if factor > 1:
        img8 = cv2.resize(img8, None, fx=factor, fy=factor, interpolation=cv2.INTER_CUBIC)
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    # the sector detector draws from OpenCV's RNG of the calling thread: seeded for each view, the same image
    # always gives the same corners (unseeded, a calibration depended on what ran before it).  Exhaustive:
    # without it the search is ~20 % cheaper but slid a small board (3 x 4 corners) by a square in whole
    # captures' views, which the parallax check then dropped (issue 22)
    cv2.setRNGSeed(DETECTOR_SEED)
    found, corners = cv2.findChessboardCornersSB(img8, (board.cols, board.rows), flags=flags)
    if not found or corners is None or len(corners) != board.rows * board.cols:
        return None
    xy = canonical_order((corners.reshape(-1, 2).astype(np.float64) + 0.5) / factor - 0.5, board.rows, board.cols)
    if refine:
        xy, _ = refine_corners(np.asarray(image, dtype=np.float64), xy, board.rows, board.cols)
    return xy


def parallax_misfit(views: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """How far (px) each view's corners are from the parallax the other views show, (n,) float64.

    A flat board's corner ``p`` moves with the view ``(i, j)`` by a parallax proportional to the view's
    offset: ``x_p(i, j) = a_p + B_p (i, j)`` (``a_p`` 2-vector, ``B_p`` 2 x 2: its disparity per view step
    along each axis; exact for the ray model without distortion).  The model is estimated robustly, so
    that several misdetected views do not bend it: each column of ``B_p`` is the median, over the pairs
    of views one step apart along that axis, of the corner's displacement between them; ``a_p`` is the
    median over views of ``x_p - B_p (i, j)``.  A view's misfit is its largest corner distance from
    the model: a detection that slid by a whole square (which an affine fit to the other views would
    absorb), or put its corner list in another order, misses by about a square.

    Parameters
    ----------
    views : (n, 2) int
        ``(i, j)`` of each view.
    corners : (n, P, 2) float
        Its corners, in the same order in every view.
    """
    views = np.asarray(views, dtype=np.int64).reshape(-1, 2)
    corners = np.asarray(corners, dtype=np.float64)
    index = {tuple(v): n for n, v in enumerate(views.tolist())}
    disparity = np.zeros((2,) + corners.shape[1:])          # (axis, P, 2): displacement per view step
    for axis, step in enumerate(((1, 0), (0, 1))):
        pairs = [(index[(i + step[0], j + step[1])], n) for n, (i, j) in enumerate(views.tolist())
                 if (i + step[0], j + step[1]) in index]
        if pairs:
            after, before = np.array(pairs).T
            disparity[axis] = np.median(corners[after] - corners[before], axis=0)
    moved = np.einsum("na,apc->npc", views.astype(np.float64), disparity)
    origin = np.median(corners - moved, axis=0)
    return np.linalg.norm(corners - moved - origin, axis=-1).max(axis=1)


def consistent_views(views: np.ndarray, corners: np.ndarray, *,
                     max_misfit_px: float = MAX_VIEW_MISFIT_PX) -> np.ndarray:
    """Mask (n,) of the views whose :func:`parallax_misfit` is at most ``max_misfit_px``.

    Fewer than 3 views are all kept (no majority to check them against).
    """
    if len(views) < 3:
        return np.ones(len(views), bool)
    return parallax_misfit(views, corners) <= max_misfit_px


def view_weights(lf: LightField) -> np.ndarray:
    """Mean weight of each view, (V, U) float64 (mean luma when the light field has no weight)."""
    if lf.weight is not None:
        return lf.weight.mean(axis=(2, 3), dtype=np.float64)
    return luma(lf.data).mean(axis=(2, 3), dtype=np.float64)


def detect_corners(lf: LightField, board: Board | tuple[int, int, float] | str, *,
                   min_weight: float = MIN_VIEW_WEIGHT, refine: bool = True, samples=None,
                   progress: Callable[[int, int], None] | None = None) -> ViewCorners:
    """The board's corners in every bright-enough sub-aperture view of ``lf``.

    Parameters
    ----------
    lf : LightField
        Decoded without rectification, ``data`` (V, U, Y, X, C) float32.
    board : Board, (rows, cols, square_m) or 'ROWSxCOLSxSQUARE'
    min_weight : float
        Views with a mean weight below ``min_weight`` x the central view's are skipped.
    refine : bool
        Fit each corner after the detector: to the view (:func:`refine_corners`), or, with ``samples``, to
        the view's lens samples (:func:`refine_corners_on_samples`).
    samples : LensSamples, optional
        The samples ``lf`` was resampled from (:func:`plenodecode.decoding.decoder.decode_samples`).
    progress : callable(done, total), optional

    Returns
    -------
    ViewCorners
        Only the views where all ``rows * cols`` corners were found, consistently with the other views
        (:func:`consistent_views`).
    """
    board = Board.of(board)
    if not 0 <= min_weight <= 1:
        raise ValueError(f"min_weight must be in [0, 1], got {min_weight!r}")
    V, U, Y, X, _ = lf.shape
    weights = view_weights(lf)
    bright = weights >= min_weight * weights[V // 2, U // 2]
    todo = [(i, j) for j in range(V) for i in range(U) if bright[j, i]]
    views, found = [], []
    for n, (i, j) in enumerate(todo):
        xy = detect_view(luma(lf.data[j, i]), board, refine=refine and samples is None)
        if xy is not None and refine and samples is not None:
            xy, _ = refine_corners_on_samples(luma(samples.data[j, i]), samples.position, samples.weight[j, i], xy,
                                              board.rows, board.cols)
        if xy is not None:
            views.append((i, j))
            found.append(xy)
        if progress is not None:
            progress(n + 1, len(todo))
    corners = np.array(found, dtype=np.float64).reshape(-1, board.rows * board.cols, 2)
    views = np.array(views, dtype=np.int64).reshape(-1, 2)
    keep = consistent_views(views, corners)
    log.debug("board found in %d of %d views searched, %d inconsistent dropped", len(views), len(todo),
              int(np.sum(~keep)))
    return ViewCorners(views=views[keep], corners=corners[keep], searched=len(todo), lf_shape=(V, U, Y, X))


#: Pixels of blur (decoding and the sample's footprint) kept between the window of :func:`refine_corners` and
#: the next edge of the pattern: the window's radius is the distance from the corner to the far side of its
#: 2 x 2 squares less this.
REFINE_EDGE_MARGIN_PX = 1.0
#: Bounds (px) on the window radius of :func:`refine_corners`.
REFINE_RADIUS_PX = (2.0, 6.0)
#: A corner the model fit moves further than this (px) from the detector's, or that does not converge, keeps
#: the detector's position.
REFINE_MAX_SHIFT_PX = 0.75
#: Fits of :func:`refine_corners`, each with its disk centred on the previous fit's corner.
REFINE_PASSES = 2


def _window_radii(grid: np.ndarray) -> np.ndarray:
    """Per corner of ``grid`` (rows, cols, 2), the distance (px) from it to the nearest outer edge of the 2 x 2
    squares around it: for every neighbour along one grid line, its distance from the other grid line through
    the corner (the outer edge of those squares runs through the neighbour parallel to that line)."""
    rows, cols, _ = grid.shape
    out = np.full((rows, cols), np.inf)

    def along(axis: int) -> np.ndarray:            # direction of the grid line along ``axis`` at every corner
        d = np.gradient(grid, axis=axis)            # the same differences refine_corners starts its edges from
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    for axis in (0, 1):                             # neighbours along ``axis``, from the grid line across it
        line = along(1 - axis)
        normal = np.stack([-line[..., 1], line[..., 0]], axis=-1)
        for step in (1, -1):
            neighbour = np.roll(grid, -step, axis=axis)
            dist = np.abs(np.sum((neighbour - grid) * normal, axis=-1))
            valid = np.ones((rows, cols), bool)
            index = [slice(None), slice(None)]
            index[axis] = slice(-1, None) if step == 1 else slice(0, 1)
            valid[tuple(index)] = False
            out = np.where(valid, np.minimum(out, dist), out)
    return out


def _tanh_edge(d: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The edge of :func:`refine_corners`, ``E(d) = tanh(d / sigma)``: ``E``, ``dE / dd``, ``dE / dsigma``."""
    t = np.tanh(d / sigma)
    slope = (1 - t ** 2) / sigma
    return t, slope, -slope * d / sigma


def _junction(q: np.ndarray, px: np.ndarray, py: np.ndarray, edge=_tanh_edge) -> tuple[np.ndarray, np.ndarray]:
    """The X-junction ``I = a + b E(n1 . (p - c)) E(n2 . (p - c))`` at pixels (N, P) for parameters q (N, 7)
    ``(cx, cy, th1, th2, sigma, a, b)``, with ``edge(d, sigma) -> (E, dE / dd, dE / dsigma)`` (default
    :func:`_tanh_edge`): values (N, P) and their Jacobian (N, P, 7)."""
    dx, dy = px - q[:, :1], py - q[:, 1:2]
    c1, s1, c2, s2 = np.cos(q[:, 2:3]), np.sin(q[:, 2:3]), np.cos(q[:, 3:4]), np.sin(q[:, 3:4])
    d1, d2 = c1 * dx + s1 * dy, c2 * dx + s2 * dy
    sigma, a, b = q[:, 4:5], q[:, 5:6], q[:, 6:7]
    e1, de1, ds1 = edge(d1, sigma)
    e2, de2, ds2 = edge(d2, sigma)
    g1, g2 = b * de1 * e2, b * e1 * de2                                     # dI / d d1, dI / d d2
    jac = np.stack([-(g1 * c1 + g2 * c2), -(g1 * s1 + g2 * s2),             # d / d (cx, cy)
                    g1 * (c1 * dy - s1 * dx), g2 * (c2 * dy - s2 * dx),       # d / d (th1, th2)
                    b * (ds1 * e2 + e1 * ds2), np.ones_like(d1), e1 * e2], axis=-1)
    return a + b * e1 * e2, jac


def _fit_junctions(img: np.ndarray, params: np.ndarray, radius: np.ndarray, iterations: int) -> np.ndarray:
    """Levenberg-Marquardt fit of :func:`_junction` (one damping per corner) to the pixels of ``img``
    within ``radius`` (N,) of the starting ``params[:, :2]`` (an anti-aliased disk); (N, 7) float64."""
    half = int(np.ceil(radius.max() + 1.0))
    oy, ox = np.mgrid[-half:half + 1, -half:half + 1]
    centre = np.rint(params[:, :2]).astype(np.int64)
    px = centre[:, None, 0] + ox.ravel()[None]                     # (N, P) pixel columns
    py = centre[:, None, 1] + oy.ravel()[None]
    inside = (px >= 0) & (px < img.shape[1]) & (py >= 0) & (py < img.shape[0])
    distance = np.hypot(px - params[:, :1], py - params[:, 1:2])
    weight = np.clip(radius[:, None] - distance + 0.5, 0.0, 1.0) * inside
    value = img[np.clip(py, 0, img.shape[0] - 1), np.clip(px, 0, img.shape[1] - 1)]
    return _fit_junction_points(px, py, value, weight, params, iterations)


def _box_edge(d: np.ndarray, sigma: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A step edge (-1 | +1) averaged over a box of ``width`` and blurred by a Gaussian of ``sigma``, at
    signed distances ``d``: ``E(d) = 2 (psi(d + w/2) - psi(d - w/2)) / w - 1`` with
    ``psi(x) = x Phi(x / sigma) + sigma phi(x / sigma)`` (the integral of the Gaussian's CDF ``Phi``);
    returns ``E``, ``dE / dd`` and ``dE / dsigma``."""
    from scipy.special import ndtr

    hi, lo = (d + width / 2) / sigma, (d - width / 2) / sigma
    pdf_hi, pdf_lo = np.exp(-0.5 * hi ** 2) / np.sqrt(2 * np.pi), np.exp(-0.5 * lo ** 2) / np.sqrt(2 * np.pi)
    cdf_hi, cdf_lo = ndtr(hi), ndtr(lo)
    value = 2.0 * sigma * (hi * cdf_hi + pdf_hi - lo * cdf_lo - pdf_lo) / width - 1.0
    return value, 2.0 * (cdf_hi - cdf_lo) / width, 2.0 * (pdf_hi - pdf_lo) / width


def _fit_junction_points(px: np.ndarray, py: np.ndarray, value: np.ndarray, weight: np.ndarray, params: np.ndarray,
                         iterations: int, box: float = 0.0) -> np.ndarray:
    """Levenberg-Marquardt fit of :func:`_junction` (one damping per corner) to the values (N, P) at
    ``(px, py)`` (N, P) with weights (N, P), from ``params`` (N, 7); (N, 7) float64.  ``box`` > 0 fits
    :func:`_box_edge` edges of that box width instead of ``tanh``."""
    params = params.copy()
    if box > 0:
        def model(q, x, y):
            return _junction(q, x, y, edge=lambda d, sigma: _box_edge(d, sigma, box))
    else:
        model = _junction
    _, jac = model(params, px, py)            # (a, b) enter linearly: solved first
    basis = jac[..., 5:]
    gram = np.einsum("np,npi,npj->nij", weight, basis, basis) + 1e-12 * np.eye(2)
    params[:, 5:] = np.linalg.solve(gram, np.einsum("np,npi,np->ni", weight, basis, value)[..., None])[..., 0]
    predicted, jac = model(params, px, py)
    cost = np.einsum("np,np->n", weight, (value - predicted) ** 2)
    damping = np.full(len(params), 1e-3)
    for _ in range(iterations):
        normal = np.einsum("np,npi,npj->nij", weight, jac, jac)
        gradient = np.einsum("np,npi,np->ni", weight, jac, value - predicted)
        diagonal = np.maximum(np.einsum("nii->ni", normal), 1e-12)
        step = np.linalg.solve(normal + damping[:, None, None] * (diagonal[:, :, None] * np.eye(7)),
                               gradient[..., None])[..., 0]
        trial = params + step
        trial[:, 4] = np.clip(trial[:, 4], 0.1, 10.0)
        trial_predicted, trial_jac = model(trial, px, py)
        trial_cost = np.einsum("np,np->n", weight, (value - trial_predicted) ** 2)
        better = trial_cost < cost
        params[better], predicted[better], jac[better], cost[better] = (trial[better], trial_predicted[better],
                                                                         trial_jac[better], trial_cost[better])
        damping = np.where(better, damping / 3, damping * 4)
        if np.all(np.abs(step[:, :2]).max(axis=1) < 1e-4):
            break
    return params


def refine_corners(image: np.ndarray, corners: np.ndarray, rows: int, cols: int, *,
                   iterations: int = 30, passes: int = REFINE_PASSES) -> tuple[np.ndarray, np.ndarray]:
    """Corners of a detected board refined by fitting an X-junction model to the image around each.

    Near an inner corner ``c`` the image is two straight edges crossing (perspective maps lines to lines, so
    this holds for any pose) blurred alike: ::

        I(p) = a + b tanh(n1 . (p - c) / sigma) tanh(n2 . (p - c) / sigma),   n_k = (cos th_k, sin th_k)

    fitted (``c``, ``th_1``, ``th_2``, ``sigma``, ``a``, ``b``) by Levenberg-Marquardt to the pixels within a
    disk that stays inside the corner's 2 x 2 squares (:func:`_window_radii` less :data:`REFINE_EDGE_MARGIN_PX`,
    within :data:`REFINE_RADIUS_PX`).  Nothing outside those squares (the next edges, the board's margin)
    enters, so a corner is not pulled by its foreshortened neighbours as by the sector detector's
    fixed-size kernel; the blurred junction is point-symmetric about ``c``, so a symmetric blur does not
    move it either.  The disk is centred on the detector's corner, then (``passes`` > 1) on the fit's.

    Parameters
    ----------
    image : (Y, X) float
        The view (luma), pixel centres at integers.
    corners : (rows * cols, 2) float
        ``(x, y)`` from the detector, in :func:`canonical_order`.

    Returns
    -------
    corners : (rows * cols, 2) float64
        Refined; a corner whose fit fails or moves more than :data:`REFINE_MAX_SHIFT_PX` keeps its input.
    refined : (rows * cols,) bool
        Which were refined.
    """
    img = np.asarray(image, dtype=np.float64)
    c0, params, radius = _junction_start(corners, rows, cols)
    for _ in range(max(1, int(passes))):
        params = _fit_junctions(img, params, radius, iterations)
    return _accept(c0, params)


def _junction_start(corners: np.ndarray, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detector corners (rows * cols, 2), the fit's start (N, 7): edges along the grid lines through each
    corner, sigma 1 px, ``a = b = 0`` (solved first) and the window radii (N,) of :func:`refine_corners`."""
    c0 = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    grid = c0.reshape(rows, cols, 2)
    radius = np.clip(_window_radii(grid).ravel() - REFINE_EDGE_MARGIN_PX, *REFINE_RADIUS_PX)
    row_dir = np.gradient(grid, axis=1).reshape(-1, 2)
    col_dir = np.gradient(grid, axis=0).reshape(-1, 2)
    theta = np.stack([np.arctan2(row_dir[:, 1], row_dir[:, 0]) + np.pi / 2,
                      np.arctan2(col_dir[:, 1], col_dir[:, 0]) + np.pi / 2], axis=1)
    params = np.column_stack([c0, theta, np.ones(len(c0)), np.zeros((len(c0), 2))])
    return c0, params, radius


def _accept(c0: np.ndarray, params: np.ndarray, valid: np.ndarray | bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The fitted corners where the fit is finite, moved at most :data:`REFINE_MAX_SHIFT_PX` and sigma < 10;
    the detector's elsewhere.  Returns (N, 2) float64 and the mask (N,) bool of fitted ones."""
    shift = np.linalg.norm(params[:, :2] - c0, axis=1)
    ok = np.all(np.isfinite(params), axis=1) & (shift <= REFINE_MAX_SHIFT_PX) & (params[:, 4] < 10.0) & valid
    return np.where(ok[:, None], params[:, :2], c0), ok


#: Width (decoded px) of the box each lens sample averages the scene over, in the edge model of
#: :func:`refine_corners_on_samples`: one lens footprint (the generator's is 1 x 1 decoded sample; a hex cell of
#: the same area projects like a box of 1.05).  On 12 generated sets (bench/bench_geometry.py) the fit with
#: ``tanh`` edges (0) left the shared corner error near the focus as it was and put H 1.00 % off on k1 = 4.
SAMPLE_FOOTPRINT_PX = 1.0
#: A corner with fewer lens samples than this in its window keeps the detector's position
#: (:func:`refine_corners_on_samples`; the junction has 7 parameters).
MIN_WINDOW_SAMPLES = 12


def refine_corners_on_samples(values: np.ndarray, positions: np.ndarray, weights: np.ndarray, corners: np.ndarray,
                              rows: int, cols: int, *, iterations: int = 30, passes: int = REFINE_PASSES,
                              box: float = SAMPLE_FOOTPRINT_PX) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine_corners` fitted to a view's samples on the lens lattice, where they were measured.

    The window is that of :func:`refine_corners` (a disk inside the corner's 2 x 2 squares), but its points are
    the view's lens samples (:class:`plenodecode.decoding.decoder.LensSamples`) at their positions ``p_s`` on
    the hex lattice, in the decoded view's pixel coordinates, instead of the pixels the hex -> rect step
    interpolated from them; each enters with weight ``w_s * disk(|p_s - c|)``, ``w_s`` its reliability.  A
    sample averages the scene over its lens's footprint, so each edge is a step averaged over a box of
    ``box`` px and blurred by a Gaussian of fitted ``sigma`` (the defocus, the pixel and the interpolations):
    ::

        I(p) = a + b E(n1 . (p - c)) E(n2 . (p - c)),   E(d) = 2 (psi(d + w/2) - psi(d - w/2)) / w - 1,
        psi(x) = x Phi(x / sigma) + sigma phi(x / sigma)

    (``box`` = 0: ``E(d) = tanh(d / sigma)``, :func:`refine_corners`'s model).  Near the focus every view
    samples an edge at the same lens positions and the box is most of its blur: ``tanh`` there misplaced
    the corners alike in all views (bench/bench_geometry.py).

    Parameters
    ----------
    values : (R, K) float
        The view's samples (luma) on the lens lattice.
    positions : (R, K, 2) float
        Their ``(x, y)`` in the view's pixel coordinates.
    weights : (R, K) float
        Their reliability (0 = no sample); the slicer's sample weights.
    corners : (rows * cols, 2) float
        ``(x, y)`` from the detector on the decoded view, in :func:`canonical_order`.
    box : float
        Footprint width ``w`` (px), default :data:`SAMPLE_FOOTPRINT_PX`.

    Returns
    -------
    corners : (rows * cols, 2) float64
        Refined; a corner whose fit fails, has fewer than :data:`MIN_WINDOW_SAMPLES` samples or moves more than
        :data:`REFINE_MAX_SHIFT_PX` keeps its input.
    refined : (rows * cols,) bool
    """
    from scipy.spatial import cKDTree

    v = np.asarray(values, dtype=np.float64).ravel()
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    w = np.asarray(weights, dtype=np.float64).ravel()
    keep = (w > 0) & np.isfinite(v) & np.all(np.isfinite(pos), axis=1)
    v, pos, w = v[keep], pos[keep], w[keep]
    c0, params, radius = _junction_start(corners, rows, cols)
    if len(v) < MIN_WINDOW_SAMPLES:
        return c0.copy(), np.zeros(len(c0), bool)
    tree = cKDTree(pos)
    count = np.zeros(len(c0), np.int64)
    for _ in range(max(1, int(passes))):
        near = tree.query_ball_point(params[:, :2], radius + 0.5)
        count = np.array([len(n) for n in near], np.int64)
        index = np.zeros((len(c0), max(1, int(count.max()))), np.int64)
        present = np.zeros(index.shape, bool)
        for n, found in enumerate(near):
            index[n, :len(found)] = found
            present[n, :len(found)] = True
        px, py = pos[index, 0], pos[index, 1]
        distance = np.hypot(px - params[:, :1], py - params[:, 1:2])
        weight = np.clip(radius[:, None] - distance + 0.5, 0.0, 1.0) * w[index] * present
        params = _fit_junction_points(px, py, v[index], weight, params, iterations, box)
    return _accept(c0, params, count >= MIN_WINDOW_SAMPLES)
