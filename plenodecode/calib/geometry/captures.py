"""Geometric calibration from a set of checkerboard captures: detect, initialise, refine, report quality.

:func:`calibrate_geometry` is the public entry (``plenodecode.calibrate_geometry``);
:func:`run_geometric_calibration` returns everything a report needs (:class:`GeometryRun`).
Files are opened by :mod:`plenodecode.pipeline.geometry`; this module takes light fields (or raws
with their lenslet grid) in memory.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ...errors import CalibrationError
from ...raymodel import Board, GeometricCalibration
from ...types import LightField, RawCapture, LensletGrid
from .corners import MIN_VIEW_WEIGHT, ViewCorners, detect_corners
from .initial import initial_estimate
from .solve import Observations, Reprojection, reprojection, solve

log = logging.getLogger(__name__)

#: Fewest captures with a board found that a calibration accepts.
MIN_CAPTURES = 3
#: Demosaic method raws are decoded with for a geometric calibration.  With 'malvar' (the decoder's default)
#: ``H00``, ``H20``, ``H11``, ``H31`` come out ~1 % low on a generated F01 set even from the views of weight
#: >= 0.85 (bilinear: within 0.30 %, 16 captures; bench/bench_geometry.py).  The slicer no longer moves
#: views at the micro-image's edge (it leaves out demosaiced channels whose 3 x 3 stencil was cut), so
#: what remains is in malvar's 5 x 5 correction near the edge (issue 22): it is applied only where its stencil is
#: whole, so pixels within about 2 px of the last measured one stay plain bilinear (blurrier).  A view whose
#: bilinear footprint straddles that boundary gets a kernel with a blurrier outer side: exact for a linear
#: radiance (its centroid is right) but edges and texture come out inwards, i.e. compressed parallax.  Moving the
#: boundary inwards moves the compression to the inner views (f01-mini textured plane, 1.5 px per view step:
#: ring 1 / 3 scale 1.0001 / 0.9883 -> 0.9923 / 0.9967).
CAPTURE_DEMOSAIC = "bilinear"
#: How captures are sliced at the micro-image's edge (``decode(view_edges=)``): 'extrapolate' keeps the outer
#: views at their nominal offsets; the default 'renormalise' pulls them up to 0.35 view steps inwards, and H
#: from 16 generated F01 captures came out 0.64 % off instead of 0.30 % (bench/bench_geometry.py).
CAPTURE_VIEW_EDGES = "extrapolate"
#: Hot-pixel repair of captures (``decode(hot_pixels=)``): 'isolated' repairs only pixels brighter than their 8
#: adjacent ones too.  The default rule also took sharp board edges on the micro-images' rims for hot pixels
#: (20-364 per generated F01 capture, for ~34 defects) and filled them from inside the disk, which compressed
#: the parallax of the views 2.2-3.6 steps off centre by 2-5e-3 and put H's entries ~0.25 % low in every set
#: (bench/bench_geometry.py).
CAPTURE_HOT_PIXELS = "isolated"
#: The keywords of :func:`plenodecode.decoding.decode` a capture is decoded with, wherever it is decoded
#: (here from a RawCapture, in :mod:`plenodecode.pipeline.geometry` from files).
CAPTURE_DECODE = {"demosaic": CAPTURE_DEMOSAIC, "view_edges": CAPTURE_VIEW_EDGES, "hot_pixels": CAPTURE_HOT_PIXELS}
#: Cells per spatial sample (each axis) of the raster :func:`field_coverage` measures areas on.
COVERAGE_CELLS_PER_SAMPLE = 1
#: A calibration whose boards leave more than this fraction of the field beyond their largest radius logs a
#: warning: the distortion there is extrapolated (issue 22: 16 generated captures that reached 80 % of the
#: F01 field's radius got its distortion 2.4 % right inside, 9.2 % off in the field's corners).
MAX_EXTRAPOLATED_FIELD = 0.05


@dataclass(frozen=True)
class GeometryRun:
    """A geometric calibration with what it was made from.

    Attributes
    ----------
    calibration : GeometricCalibration
    board : Board
    names : list of str
        The captures used, in the order of ``calibration.poses``.
    corners : list of ViewCorners
        Their detections.
    errors : Reprojection
        Final residuals of every observation (``errors.capture`` indexes ``names``).
    skipped : list of (name, reason)
        Captures left out.
    """

    calibration: GeometricCalibration
    board: Board
    names: list[str]
    corners: list[ViewCorners]
    errors: Reprojection
    skipped: list[tuple[str, str]]


def _lightfield_and_samples(item, grid: LensletGrid | None, white: RawCapture | None):
    """(LightField, LensSamples or None) of a capture: a raw is decoded with :data:`CAPTURE_DECODE`, keeping its
    lens samples (the corners are fitted on them); a (LightField, LensSamples) pair is taken as it is."""
    if isinstance(item, LightField):
        return item, None
    if isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], LightField):
        return item
    if isinstance(item, RawCapture):
        if grid is None:
            raise ValueError("raws need grid= (the lenslet grid of the white image the captures are decoded with)")
        from ...decoding.decoder import decode_samples

        return decode_samples(item, grid, white=white, **CAPTURE_DECODE)
    raise TypeError(f"expected LightField, (LightField, LensSamples) or RawCapture, got {type(item).__name__}")


def _quality(errors: Reprojection, names: Sequence[str], corners: Sequence[ViewCorners]) -> dict[str, Any]:
    per_capture = [{"capture": name, "views": found.count, "rms_ray_m": errors.rms_m(c), "rms_px": errors.rms_px(c)}
                   for c, (name, found) in enumerate(zip(names, corners))]
    return {"rms_ray_m": errors.rms_m(), "rms_px": errors.rms_px(), "per_capture": per_capture}


def field_coverage(corners: Sequence[ViewCorners], intrinsics: np.ndarray,
                   centre: Sequence[float] = (0.0, 0.0)) -> dict[str, float]:
    """How much of the field of view the boards of a calibration set covered.

    Every corner observation ``n = (i, j, k, l)`` is moved to the central view by its measured direction:
    ``(u, v) = H n`` (no distortion) and ``(k', l') = A^-1 ((u, v) - H (i_c, j_c, 0, 0, 1))`` with
    ``A = H[2:4, 2:4]``, so ``(k', l')`` is where the central view sees that direction.  The field is the
    central view, ``-0.5 <= k' <= X - 0.5``, ``-0.5 <= l' <= Y - 0.5``, rastered at
    :data:`COVERAGE_CELLS_PER_SAMPLE` cells per sample; the distortion model is radial about ``centre``
    (``b``, a direction), ``r = |(u, v) - b|``.

    Returns
    -------
    dict of float
        ``area``: fraction of the field inside the convex hull of some capture's corners (the area a
        board covered); ``radius``: the largest ``r`` of any corner over the largest ``r`` of the field (its
        corners); ``beyond_radius``: fraction of the field farther from ``centre`` than any corner, where
        the distortion is extrapolated, not measured.
    """
    from scipy.spatial import ConvexHull, QhullError

    h = np.asarray(intrinsics, dtype=np.float64)
    n_v, n_u, n_y, n_x = corners[0].lf_shape
    centre_view = np.array([(n_u - 1) / 2.0, (n_v - 1) / 2.0, 0.0, 0.0, 1.0])
    offset = h[2:4] @ centre_view
    inverse = np.linalg.inv(h[2:4, 2:4])
    b = np.asarray(centre, dtype=np.float64)
    cells = int(COVERAGE_CELLS_PER_SAMPLE)
    kk, ll = np.meshgrid((np.arange(n_x * cells) + 0.5) / cells - 0.5, (np.arange(n_y * cells) + 0.5) / cells - 0.5)
    field = np.stack([kk.ravel(), ll.ravel()], axis=-1)                      # cell centres (k', l')
    field_dirs = field @ h[2:4, 2:4].T + offset
    field_r = np.linalg.norm(field_dirs - b, axis=-1)
    outline = np.array([[-0.5, -0.5], [n_x - 0.5, -0.5], [-0.5, n_y - 0.5], [n_x - 0.5, n_y - 0.5]])
    field_max = np.linalg.norm(outline @ h[2:4, 2:4].T + offset - b, axis=-1).max()
    covered = np.zeros(len(field), bool)
    largest = 0.0
    for found in corners:
        if found.count == 0:
            continue
        views = np.repeat(found.views.astype(np.float64), found.corners.shape[1], axis=0)
        samples = np.column_stack([views, found.corners.reshape(-1, 2), np.ones(len(views))])
        dirs = samples @ h[2:4].T
        largest = max(largest, float(np.linalg.norm(dirs - b, axis=-1).max()))
        kl = (dirs - offset) @ inverse.T
        try:
            hull = ConvexHull(kl)
        except QhullError:                     # degenerate (collinear corners): no area
            continue
        covered |= np.all(field @ hull.equations[:, :2].T + hull.equations[:, 2] <= 1e-9, axis=1)
    return {"area": float(covered.mean()), "radius": float(largest / field_max),
            "beyond_radius": float(np.mean(field_r > largest))}


def run_geometric_calibration(raws_or_lightfields: Iterable[LightField | RawCapture],
                              board: Board | tuple[int, int, float] | str, *, names: Sequence[str] | None = None,
                              grid: LensletGrid | None = None, white: RawCapture | None = None,
                              distortion: bool = True, min_weight: float = MIN_VIEW_WEIGHT,
                              progress: Callable[[int, int], None] | None = None) -> GeometryRun:
    """:func:`calibrate_geometry` with its detections, residuals and skipped captures (for reports).

    ``raws_or_lightfields`` may be a generator (decoded one by one); ``progress`` is called only when
    ``names`` gives the number of captures.

    Raises
    ------
    CalibrationError
        Fewer than :data:`MIN_CAPTURES` captures show the whole board, or the light fields differ in shape.
    """
    board = Board.of(board)
    names = None if names is None else [str(n) for n in names]
    total = None if names is None else len(names)
    used, corners, skipped = [], [], []
    shape = None
    n = -1
    for n, item in enumerate(raws_or_lightfields):     # one light field in memory at a time
        if names is not None and n >= len(names):
            raise ValueError(f"names has {len(names)} entries for more captures")
        name = f"capture {n + 1}" if names is None else names[n]
        if isinstance(item, Exception):     # a file that could not be read (pipeline.geometry): skipped, as a set of
            log.warning("%s: %s; skipped", name, item)      # files is (one bad file does not end the run)
            skipped.append((name, str(item)))
            if progress is not None and total is not None:
                progress(n + 1, total)
            continue
        lf, samples = _lightfield_and_samples(item, grid, white)
        if shape is not None and lf.shape[:4] != shape:
            raise CalibrationError(f"{name}: light field of shape {lf.shape[:4]}, the others {shape}; decode every "
                                   "capture with the same white image and grid")
        shape = lf.shape[:4]
        found = detect_corners(lf, board, min_weight=min_weight, samples=samples)
        if found.count == 0:
            reason = f"no complete {board.rows} x {board.cols} board in the {found.searched} views searched"
            log.warning("%s: %s; skipped", name, reason)
            skipped.append((name, reason))
        else:
            log.info("%s: board found in %d of %d views", name, found.count, found.searched)
            used.append(name)
            corners.append(found)
        if progress is not None and total is not None:
            progress(n + 1, total)
    if names is not None and n + 1 != len(names):
        raise ValueError(f"names has {len(names)} entries for {n + 1} captures")
    if len(corners) < MIN_CAPTURES:
        raise CalibrationError(f"the board ({board.describe()}) was found in {len(corners)} of {n + 1} "
                               f"captures; a calibration needs at least {MIN_CAPTURES}: check --board (inner "
                               "corners, not squares) and take captures that show the whole board")
    obs = Observations.of(corners, board)
    h, poses = initial_estimate(corners, board)
    initial = reprojection(obs, h, np.zeros(5), poses)
    h, dist, poses = solve(obs, h, poses, distortion=distortion)
    errors = reprojection(obs, h, dist, poses)
    log.info("ray reprojection RMS %.4g mm (initial %.4g mm), %.3g px", errors.rms_m() * 1e3,
             initial.rms_m() * 1e3, errors.rms_px())
    info = {"method": "plenodecode checkerboard calibration (Dansereau et al. 2013 ray model)",
            "board": {"corners": [board.rows, board.cols], "spacing_m": [board.square_m, board.square_m]},
            "captures": list(used), "skipped": [{"capture": n, "reason": r} for n, r in skipped],
            "initial_rms_ray_m": initial.rms_m(), "distortion_estimated": bool(distortion),
            **_quality(errors, used, corners)}
    coverage = field_coverage(corners, h, dist[3:])
    info["coverage"] = coverage
    if distortion and coverage["beyond_radius"] > MAX_EXTRAPOLATED_FIELD:
        log.warning("the boards reached %.0f %% of the field's radius: the distortion over the outer %.0f %% of "
                    "the field is extrapolated, not measured; add captures with the board near the image's corners",
                    100 * coverage["radius"], 100 * coverage["beyond_radius"])
    cal = GeometricCalibration(intrinsics=h, distortion=dist, lf_shape=shape, poses=poses, info=info)
    return GeometryRun(calibration=cal, board=board, names=used, corners=corners, errors=errors, skipped=skipped)


def calibrate_geometry(raws_or_lightfields: Iterable[LightField | RawCapture],
                       board: Board | tuple[int, int, float] | str, *, names: Sequence[str] | None = None,
                       grid: LensletGrid | None = None, white: RawCapture | None = None, distortion: bool = True,
                       min_weight: float = MIN_VIEW_WEIGHT,
                       progress: Callable[[int, int], None] | None = None) -> GeometricCalibration:
    """Calibrate a plenoptic camera's ray geometry from checkerboard captures (Dansereau et al., CVPR 2013).

    Each capture is decoded without rectification (raws: with ``grid`` and ``white``, the same for all,
    with :data:`CAPTURE_DECODE`: the bilinear demosaic, and views extrapolated at the micro-images' edge),
    the board's inner corners are found in its sub-aperture views (:func:`.corners.detect_corners`: the
    sector detector, then a fit of each corner to the view's lens samples, or to the view of a bare light field),
    ``H`` and the poses are initialised in closed form (:mod:`.initial`), then ``H``, the distortion
    ``[k1, k2, k3, b1, b2]`` and the poses are refined jointly by minimising the 3-D distance between each
    corner and the ray of each sample that sees it (:mod:`.solve`; each capture weighted by the inverse of
    its mean squared distance).  A capture without a complete board is
    skipped (logged, and listed in ``info['skipped']``).

    Parameters
    ----------
    raws_or_lightfields : iterable of LightField, (LightField, LensSamples), RawCapture or Exception
        10-20 captures of a flat checkerboard at various distances and tilts, same zoom and focus.  The corners
        of a raw, or of a light field given with its lens samples (:func:`plenodecode.decoding.decode_samples`),
        are fitted on the samples (:func:`.corners.refine_corners_on_samples`); those of a bare light field on
        its views.  An exception stands for a file that could not be read: skipped with its message.
    board : Board, (rows, cols, square_m) or 'ROWSxCOLSxSQUARE_M'
        Inner corners (not squares) and their spacing in metres.
    names : sequence of str, optional
        Names of the captures, for logs and the report.
    grid, white : LensletGrid, RawCapture, optional
        How raws are decoded.
    distortion : bool
        Estimate the distortion (else it stays 0).
    min_weight : float
        Views darker than this fraction of the central view's weight are not searched.
    progress : callable(done, total), optional
        Called after each capture's detection.

    Returns
    -------
    GeometricCalibration
        ``intrinsics`` (5, 5) for 0-based samples (re-centred, ``H02 = 0``: :mod:`.gauge`), ``distortion``,
        ``lf_shape``, ``poses`` (N, 6) of the captures used, ``info`` with the board, the captures used and
        skipped, the RMS ray (m) and pixel reprojection errors, overall and per capture, and ``coverage``
        (:func:`field_coverage`: how much of the field the boards covered; the distortion beyond the largest
        radius they reached is extrapolated, and a warning is logged when that is over
        :data:`MAX_EXTRAPOLATED_FIELD` of the field).
    """
    items = list(raws_or_lightfields)
    names = [f"capture {n + 1}" for n in range(len(items))] if names is None else names
    return run_geometric_calibration(items, board, names=names, grid=grid, white=white,
                                     distortion=distortion, min_weight=min_weight, progress=progress).calibration
