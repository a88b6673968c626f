"""Checkerboard corners in the sub-aperture views of a light field.

Every view ``lf.data[j, i]`` of a capture is searched for the board's ``rows x cols`` inner corners
with OpenCV's sector-based detector (``cv2.findChessboardCornersSB``, sub-pixel accurate with
``CALIB_CB_ACCURACY``); only complete detections count.  Views darker than ``min_weight`` of the
central view's weight (the vignetted border of the angular disk) are not searched.

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


def detect_view(image: np.ndarray, board: Board) -> np.ndarray | None:
    """Inner corners of ``board`` in one grey image (Y, X) float: (rows * cols, 2) float64 ``(x, y)``
    in :func:`canonical_order`, or None when the detection is not complete.

    The image is stretched to 8 bits between its 1st and 99th percentiles and, when its shorter side is
    below :data:`MIN_DETECTION_SIZE`, enlarged by ``f`` (bicubic); corners map back by
    ``x = (x' + 0.5) / f - 0.5``.  OpenCV's RNG of the calling thread is seeded with :data:`DETECTOR_SEED`
    first, so the detection is reproducible.
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
    xy = (corners.reshape(-1, 2).astype(np.float64) + 0.5) / factor - 0.5
    return canonical_order(xy, board.rows, board.cols)


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
                   min_weight: float = MIN_VIEW_WEIGHT,
                   progress: Callable[[int, int], None] | None = None) -> ViewCorners:
    """The board's corners in every bright-enough sub-aperture view of ``lf``.

    Parameters
    ----------
    lf : LightField
        Decoded without rectification, ``data`` (V, U, Y, X, C) float32.
    board : Board, (rows, cols, square_m) or 'ROWSxCOLSxSQUARE'
    min_weight : float
        Views with a mean weight below ``min_weight`` x the central view's are skipped.
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
        xy = detect_view(luma(lf.data[j, i]), board)
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
