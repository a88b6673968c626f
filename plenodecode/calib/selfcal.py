"""Calibration without a white image: from a scene raw, and Raytrix grids from RayCalibData.

Self-calibration (:func:`calibrate_from_scene`) cannot trust the brightness inside a
micro-image: it is the scene, and neighbouring lenses see nearly the same part of it, so any
estimator that weighs intensities (a matched filter, a centroid) is pulled the same way over
whole regions -- a coherent bias the lattice fit cannot average out.  What the scene cannot
move is the disk's *rim*, the edge between the lit disk and the dark gap around it.  The
default method ``'rim'`` therefore

1. divides the scene brightness out at the lens scale and takes the image gradient
   (:func:`~plenodecode.calib.centroids.rim_gradients`);
2. finds every disk with a fixed-radius Hough transform of the gradients
   (:func:`~plenodecode.calib.centroids.rim_votes`, Kimme, Ballard & Sklansky 1975): rim pixels vote at one
   radius along their gradient, edges of the scene scatter their votes;
3. fits, per disk, a circle of known radius to the lit part of its rim by weighted least squares
   on pixel positions (:func:`~plenodecode.calib.centroids.refine_rims`), which centres a
   half-lit disk as well as a fully lit one;
4. chooses the rim radius as the one that minimises the robust scatter of these centres about
   the fitted lattice: a wrong radius shifts every partly lit disk towards or away from its lit
   side, which shows up as scatter (measured on the synthetic cameras: the minimum lies within
   0.01 pitch of the true radius);
5. fits the lattice to the centres robustly (:mod:`.grid`).

The methods of :data:`~plenodecode.calib.centroids.CENTROID_METHODS` (intensity peaks, as for a
white image) remain available by name.

Raytrix (:func:`calibrate_raytrix`): the grid of a ``RayCalibData`` XML is used as given (with
its lens types); ``refine=True`` re-fits origin, rotation, pitch and row spacing to the disks
found in the image, keeping every lens's index and type.
"""

from __future__ import annotations

import functools
import logging
import math
import os
from pathlib import Path
from typing import Any, Callable, Mapping

import cv2
import numpy as np

from ..errors import CalibrationError, FormatError, MetadataError
from ..registry import lookup
from ..types import LensletGrid, RawCapture
from . import LATTICES
from . import centroids as _c
from . import grid as _g

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Extensions read as plain images (e.g. a lenslet mosaic saved as JPEG) when no raw reader applies.
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".exr")


def scene_image(raw: RawCapture | np.ndarray | str | os.PathLike) -> tuple[np.ndarray, dict[str, Any],
                                                                             float | None]:
    """Flattened image (H, W) float32, provenance and a pitch hint from a raw, an array or a path."""
    if isinstance(raw, (str, os.PathLike)):
        from ..io import read_raw
        p = Path(raw)
        try:
            raw = read_raw(p)
        except FormatError:
            if p.suffix.lower() not in IMAGE_EXTENSIONS:
                raise
            from ..io.images import read_image
            img = read_image(p)
            return _c.flatten_image(img), {"source": str(p)}, None
    if isinstance(raw, RawCapture):
        md = raw.metadata
        info = {"source": raw.path, "camera_model": md.model, "camera_make": md.make, "serial": md.serial,
                "zoom_step": md.zoom_step, "focus_step": md.focus_step}
        return _c.flatten_white(raw, equalise=raw.cfa is not None), info, md.lenslet_pitch_px()
    arr = np.asarray(raw)
    if arr.ndim not in (2, 3) or arr.size == 0:
        raise ValueError(f"raw must be a RawCapture, a path or a 2-D/3-D image array, got shape {arr.shape}")
    return _c.flatten_image(arr), {"source": None}, None


#: Rim radii tried by the 'rim' method, in units of the pitch (then refined by a parabola).
RIM_FRACTIONS = tuple(float(f) for f in np.round(np.arange(0.36, 0.5201, 0.02), 4))
#: Initial rim radius of the Hough transform, in units of the pitch.
RIM_START_FRACTION = 0.44
#: Disks used to choose the rim radius (the ones nearest the image centre).
RIM_SEARCH_DISKS = 2000
#: Golden-section steps refining the rim radius (interval 0.04 pitch -> 0.04 * 0.618^n).
RIM_GOLDEN_STEPS = 6


def _hough_starts(gy: np.ndarray, gx: np.ndarray, pitch: float) -> np.ndarray:
    """One start per disk: maxima of the lightly smoothed Hough accumulator, parabolic sub-pixel."""
    acc = cv2.GaussianBlur(_c.rim_votes(gy, gx, RIM_START_FRACTION * pitch), (0, 0), 0.7)
    half = max(1, int(math.floor(0.4 * pitch)))
    rr, cc = np.nonzero(_c.window_maxima(acc, half, int(math.ceil(0.5 * pitch))))
    contrast = _c.window_contrast(acc, rr, cc, half)
    if len(contrast) == 0:
        return np.zeros((0, 2))
    keep = contrast > 0.2 * float(np.percentile(contrast, 90))
    peaks = np.stack([rr[keep], cc[keep]], axis=1)
    start, ok = _c.refine_parabolic(acc, peaks, pitch, acc)
    return start[ok]


def _rim_points(img: np.ndarray, est: _c.LatticeEstimate, *, min_contrast: float,
                tick: Callable[[int], None]) -> tuple[np.ndarray, dict[str, Any]]:
    """Disk centres of a scene by the 'rim' method (module docstring, steps 1-4)."""
    gy, gx = _c.rim_gradients(img, est.pitch)
    start = _hough_starts(gy, gx, est.pitch)
    tick(2)
    if len(start) < 6:
        raise CalibrationError(f"only {len(start)} lenslet disks found in the scene; expected hundreds: "
                               "is this a raw of a plenoptic camera?")
    centre = np.array(img.shape, np.float64) / 2
    order = np.argsort(np.hypot(*(start - centre).T))
    subset = start[order[:RIM_SEARCH_DISKS]]

    warm = {"start": subset}

    def scatter(frac: float) -> float:
        # warm start: centres barely move between nearby radii
        pts, ok = _c.refine_rims(gy, gx, warm["start"], frac * est.pitch)
        warm["start"] = np.where(ok[:, None], pts, subset)
        try:
            return float(_g.fit_lattice(pts[ok], est.v1, est.v2, est.lattice).sigma)
        except CalibrationError:
            return math.inf
    fracs = list(RIM_FRACTIONS)
    sig = [scatter(f) for f in fracs]
    k = int(np.argmin(sig))
    if not math.isfinite(sig[k]):
        raise CalibrationError("no rim radius gives disk centres on a lattice; expected lit lenslet disks "
                               "separated by dark gaps (other images: calibrate_from_scene(..., method='dog'))")
    # golden-section search between the neighbours of the best trial radius (the scatter is V-shaped
    # about its minimum, so a parabola through the coarse trials would miss it)
    step = fracs[1] - fracs[0]
    lo, hi = fracs[k] - step, fracs[k] + step
    g = (math.sqrt(5) - 1) / 2
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    sa, sb = scatter(a), scatter(b)
    for _ in range(RIM_GOLDEN_STEPS):
        if sa <= sb:
            hi, b, sb = b, a, sa
            a = hi - g * (hi - lo)
            sa = scatter(a)
        else:
            lo, a, sa = a, b, sb
            b = lo + g * (hi - lo)
            sb = scatter(b)
    best, best_sig = min([(fracs[k], sig[k]), (a, sa), (b, sb)], key=lambda t: t[1])
    tick(3)
    radius = best * est.pitch
    pts, ok = _c.refine_rims(gy, gx, start, radius)
    log.debug("rim radius %.3f px (%.4f pitch), centre scatter %.3f px; %d of %d disks fitted", radius, best,
              best_sig, ok.sum(), len(ok))
    info = {"rim_radius_px": float(radius), "rim_scatter_px": float(best_sig), "n_peaks": int(len(start)),
            "rim_radius_scan": {f"{f:.2f}": (None if not math.isfinite(v) else round(v, 4))
                                for f, v in zip(fracs, sig)}}
    return pts[ok], info


def scene_centres(image: np.ndarray, grid: LensletGrid) -> tuple[np.ndarray, np.ndarray]:
    """Disk centres of a scene measured at every lens of a grid by the 'rim' method (for reports).

    Circles of the grid's rim radius (``grid.info['rim_radius_px']``, else
    ``RIM_START_FRACTION * pitch``) are fitted to the lit rims, started at the grid centres
    (:func:`~plenodecode.calib.centroids.refine_rims`), as the self-calibration measured them.

    Parameters
    ----------
    image : ndarray (H, W) float32
        Flattened scene (:func:`~plenodecode.calib.centroids.flatten_white`).
    grid : LensletGrid

    Returns
    -------
    centres : ndarray (N, 2) float64
        Sensor ``(row, col)`` of the disks measured.
    lens : ndarray (N,) int64
        Flat index into ``grid.centres()`` of the lens each was started from.
    """
    radius = float(grid.info.get("rim_radius_px") or RIM_START_FRACTION * grid.pitch)
    gy, gx = _c.rim_gradients(image, grid.pitch)
    pts, ok = _c.refine_rims(gy, gx, grid.centres(), radius)
    return pts[ok], np.flatnonzero(ok)


def _peak_points(img: np.ndarray, est: _c.LatticeEstimate, *, method: str, min_contrast: float,
                 tick: Callable[[int], None]) -> tuple[np.ndarray, dict[str, Any]]:
    """Disk centres of a scene as intensity peaks (the white-image estimators)."""
    contrast_img = _c.devignette(img, est.pitch)
    peaks, _, smoothed = _c.detect_peaks_and_filtered(contrast_img, est.pitch, min_contrast=min_contrast)
    tick(2)
    cen, ok = _c.refine_peaks(contrast_img, peaks, est.pitch, method=method, smoothed=smoothed)
    tick(3)
    return cen[ok], {"n_peaks": int(len(peaks))}


#: Self-calibration methods: name -> function(img, est, *, min_contrast, tick) -> (centres (N, 2), info);
#: in alphabetical order, as the error of an unknown name lists them.
SELFCAL_METHODS: dict[str, Callable[..., tuple[np.ndarray, dict[str, Any]]]] = dict(sorted({
    "rim": _rim_points,
    **{name: functools.partial(_peak_points, method=name) for name in _c.CENTROID_METHODS},
}.items()))


def calibrate_from_scene(raw: RawCapture | np.ndarray | str | os.PathLike, *, lattice: str = "auto",
                         pitch_hint: float | None = None, method: str = "rim", refine: bool = False,
                         min_contrast: float = 0.1, progress: Progress = None) -> LensletGrid:
    """Fit the lenslet grid from a scene raw, without a white image (self-calibration).

    Parameters
    ----------
    raw : RawCapture, ndarray (H, W) or (H, W, C), or path
        A scene raw; an array or an image file (e.g. a lenslet mosaic saved as 8-bit JPEG)
        is read as one channel (channels averaged) and low-passed with the 3x3 binomial.
    lattice : 'auto', 'hex' or 'square'
    pitch_hint : float, optional
        Expected pitch in px (default from metadata when available).
    method : str
        A key of :data:`SELFCAL_METHODS`: 'rim' (default; circles fitted to the disk rims, see
        the module docstring) or an intensity-peak estimator ('dog', 'parabolic').
    refine : bool
        Keep per-lens deviations (off by default: scene content biases single lenses).
    min_contrast : float
        Intensity-peak methods: relative disk contrast below which a peak is ignored.
    progress : callable(done, total), optional

    Returns
    -------
    LensletGrid
        ``info['source_kind']`` is 'self-calibration' (``info['self_calibrated']`` True); the
        fit statistics are those of :func:`~plenodecode.calib.grid.grid_from_points`; the 'rim' method adds ``rim_radius_px`` and the
        centre scatter of each radius tried (``rim_radius_scan``).

    Raises
    ------
    CalibrationError
        No lattice found (a black frame, or an image without lenslet structure).
    ValueError
        Unknown ``method`` or ``lattice``.
    """

    fn = lookup(SELFCAL_METHODS, method, param="method")
    if lattice not in LATTICES:
        raise ValueError(f"lattice must be one of {LATTICES}, got {lattice!r}")
    total = 4

    def tick(k: int) -> None:
        if progress is not None:
            progress(k, total)

    img, info, hint = scene_image(raw)
    if float(np.percentile(img[::7, ::7], 99.9)) <= 0.0:
        raise CalibrationError("the scene is black: no lenslet disk is lit, so the grid cannot be found; "
                               "use a white image or a brighter exposure")
    hint = pitch_hint or hint
    est = _c.estimate_lattice_vectors(img, pitch_hint=hint, lattice=lattice)
    tick(1)
    pts, extra = fn(img, est, min_contrast=min_contrast, tick=tick)
    info.update(extra)
    info.update({"source_kind": "self-calibration", "self_calibrated": True, "method": method,
                 "lattice_requested": lattice})
    grid = _g.grid_from_points(pts, est, img.shape, refine=refine, info=info)
    tick(4)
    return grid


def _reciprocal_vectors(grid: LensletGrid) -> np.ndarray:
    """The three shortest reciprocal lattice vectors (cycles/px, (row, col)), one per +- pair."""
    e_row, e_col = grid.axes()
    v1 = grid.pitch * e_col
    v2 = grid.row_spacing * e_row + grid.odd_row_shift * grid.pitch * e_col
    B = np.linalg.inv(np.stack([v1, v2], axis=0)).T  # rows b1, b2 with b_i . v_j = delta_ij
    cands = [h1 * B[0] + h2 * B[1] for h1 in (-1, 0, 1) for h2 in (0, 1) if (h2 > 0 or h1 > 0)]
    cands.sort(key=lambda k: float(np.hypot(*k)))
    n = 3 if grid.lattice == "hex" else 2
    return np.array(cands[:n])


def _refine_disks(grid: LensletGrid, image: np.ndarray, *, method: str = "dog", min_contrast: float = 0.1,
                  max_shift: float = 0.3) -> LensletGrid:
    """Refit to disk centres detected as for a white image (accurate where the disks are visible)."""
    contrast = _c.devignette(image, grid.pitch)
    peaks, _ = _c.detect_peaks(contrast, grid.pitch, min_contrast=min_contrast)
    cen, ok = _c.refine_peaks(contrast, peaks, grid.pitch, method=method)
    pts = cen[ok]
    H, W = image.shape
    edge = grid.pitch
    away = (pts[:, 0] > edge) & (pts[:, 1] > edge) & (pts[:, 0] < H - 1 - edge) & (pts[:, 1] < W - 1 - edge)
    out = _g.refit_grid(grid, pts[away], max_shift=max_shift)
    return out.replace(info={**out.info, "refit": {**out.info["refit"], "method": "disks"}})


def refine_grid(grid: LensletGrid, image: np.ndarray, *, method: str = "auto", tile_pitches: float = 5.0,
                max_shift: float = 0.3) -> LensletGrid:
    """Re-fit a grid's origin, rotation, pitch and row spacing to an image.

    ``method='disks'`` detects every micro-image disk as for a white image and refits to their
    centres (:func:`plenodecode.calib.grid.refit_grid`); accurate to a few hundredths of a pixel
    where the disks are separated by dark rims.  ``'phase'`` uses the phase of the lattice
    pattern (:func:`_refine_phase`), robust when micro-images tile the sensor without rims
    (focused cameras) but only good to ~0.1-1 px.  ``'auto'`` takes 'disks' when its per-lens
    residual sigma is below 3 % of the pitch and it used at least a third of the lenses,
    else 'phase'.
    """
    if method not in ("auto", "disks", "phase"):
        raise ValueError(f"method must be 'auto', 'disks' or 'phase', got {method!r}")
    if method in ("auto", "disks"):
        try:
            out = _refine_disks(grid, image, max_shift=max_shift)
            rf = out.info["refit"]
            n_lens = grid.shape[0] * grid.shape[1]
            if method == "disks" or (rf["sigma_px"] < 0.03 * grid.pitch and rf["n_points"] >= n_lens / 3):
                return out
            log.info("disk refit unreliable (sigma %.2f px, %d disks); using the lattice phase",
                     rf["sigma_px"], rf["n_points"])
        except CalibrationError:
            if method == "disks":
                raise
    try:
        out = _refine_phase(grid, image, tile_pitches=tile_pitches, max_shift=max_shift)
    except CalibrationError as exc:
        if method == "phase":
            raise
        reason = str(exc)
    else:
        if method == "phase" or out.info["refit"]["sigma_px"] < 0.05 * grid.pitch:
            return out
        reason = (f"the tiles disagree by {out.info['refit']['sigma_px']:.2f} px (sigma), so the image does not "
                  "constrain the grid")
    msg = f"grid refinement skipped, the given grid is kept: {reason}"
    log.warning(msg)
    warnings = list(grid.info.get("warnings", [])) + [msg]
    return grid.replace(info={**grid.info, "refit": {"method": "none", "reason": reason}, "warnings": warnings})


def _refine_phase(grid: LensletGrid, image: np.ndarray, *, tile_pitches: float = 5.0,
                  max_shift: float = 0.3) -> LensletGrid:
    """Re-fit a grid's origin, rotation, pitch and row spacing from the phase of the lattice pattern.

    The micro-image structure that repeats under every lens -- the dark rim or, in focused
    (Raytrix) images whose micro-images tile the sensor, the discontinuity at the cell borders --
    is coherent over many lenses while the scene is not.  The image is split into tiles of about
    ``tile_pitches`` lenses; in each tile the Fourier coefficients of the local gradient energy
    ``|grad(I / L)|`` at the grid's first-order reciprocal vectors ``k_i`` are measured relative to
    the grid (``c_i = sum E(x) exp(-2 pi i k_i . (x - origin))``).  A pattern shifted by ``d``
    from the grid has ``arg c_i = -2 pi k_i . d`` (plus 0 or pi, fixed from the whole image, for a
    pattern symmetric about the lens centre), so each tile gives its shift by least squares; the
    lens at each tile centre, moved by that shift, is a measured centre for
    :func:`plenodecode.calib.grid.refit_grid`, which keeps shape, indices and lens types.

    Parameters
    ----------
    grid : LensletGrid
        Starting grid (e.g. from a RayCalibData XML), within ~1/8 pitch of the truth locally.
    image : ndarray (H, W) float32
        Flattened image (:func:`~plenodecode.calib.centroids.flatten_white`).
    tile_pitches : float
        Tile side in lens pitches.

    Returns
    -------
    LensletGrid
        ``info['refit']`` records the tiles used and the parameter changes.
    """
    H, W = image.shape
    c = _c.devignette(image, grid.pitch)
    gy, gx = np.gradient(c)
    energy = np.hypot(gy, gx).astype(np.float32)
    ks = _reciprocal_vectors(grid)
    side = max(8, int(round(tile_pitches * grid.pitch)))
    nty, ntx = max(1, H // side), max(1, W // side)
    ty = np.minimum(np.arange(H) * nty // H, nty - 1)
    tx = np.minimum(np.arange(W) * ntx // W, ntx - 1)
    tile = (ty[:, None] * ntx + tx[None, :]).ravel()
    rr, cc = np.mgrid[0:H, 0:W]
    dr = (rr - grid.origin[0]).ravel()
    dc = (cc - grid.origin[1]).ravel()
    e = energy.ravel().astype(np.float64)
    coef = np.empty((nty * ntx, len(ks)), np.complex128)
    for i, k in enumerate(ks):
        ph = 2 * np.pi * (k[0] * dr + k[1] * dc)
        re = np.bincount(tile, weights=e * np.cos(ph), minlength=nty * ntx)
        im = np.bincount(tile, weights=-e * np.sin(ph), minlength=nty * ntx)
        coef[:, i] = re + 1j * im
    total = coef.sum(axis=0)
    base = np.where(np.cos(np.angle(total)) >= 0, 0.0, np.pi)  # symmetric pattern: real up to a sign
    t = np.angle(coef * np.exp(-1j * base))                      # = -2 pi k . d per tile
    wts = np.abs(coef)
    pts = []
    ii, jj = np.meshgrid(np.arange(nty), np.arange(ntx), indexing="ij")
    centres = np.stack([(ii.ravel() + 0.5) * H / nty, (jj.ravel() + 0.5) * W / ntx], axis=1)
    A_full = 2 * np.pi * ks
    for q in range(nty * ntx):
        w = wts[q] / (wts[q].max() + 1e-300)
        A = A_full * w[:, None]
        d, *_ = np.linalg.lstsq(A, -t[q] * w, rcond=None)
        # the lens nearest the tile centre, moved by the tile's shift
        a, b = grid.sensor_to_lattice(centres[q])
        i = np.round(a / grid.row_spacing)
        j = np.round(b / grid.pitch - grid.odd_row_shift * (i % 2))
        p0 = grid.lattice_to_sensor(np.array(i * grid.row_spacing),
                                    np.array((j + grid.odd_row_shift * (i % 2)) * grid.pitch))
        pts.append(p0 + d)
    pts_arr = np.array(pts)
    if len(pts_arr) < 10:
        raise CalibrationError(f"the image holds only {len(pts_arr)} tiles of {tile_pitches:g} lenses; too small to "
                               "refine the grid (use refine=False)")
    out = _g.refit_grid(grid, pts_arr, max_shift=max_shift, n_reject=1, k_sigma=5.0)
    return out.replace(info={**out.info, "refit": {**out.info["refit"], "method": "tile-phase",
                                                   "n_tiles": int(len(pts_arr))}})


def _raytrix_calibration(raw: RawCapture, cal: Any) -> Any:
    from ..io import raytrix as rx
    if cal is None:
        doc = raw.metadata.extra.get("raytrix") if isinstance(raw.metadata.extra, Mapping) else None
        if doc is None:
            raise CalibrationError("no Raytrix calibration: expected metadata.extra['raytrix'] (read the image "
                                   "with its RayCalibData XML beside it) or pass cal=")
        return rx.RaytrixCalibration.from_dict(doc)
    if isinstance(cal, rx.RaytrixCalibration):
        return cal
    if isinstance(cal, Mapping):
        return rx.RaytrixCalibration.from_dict(cal)
    if isinstance(cal, (str, os.PathLike)):
        return rx.parse_raycalib(cal)
    raise ValueError(f"cal must be a RaytrixCalibration, a dict, an XML path or None, got {type(cal).__name__}")


def calibrate_raytrix(raw: RawCapture, cal: Any = None, *, refine: bool = False,
                      refine_method: str = "auto") -> LensletGrid:
    """The lenslet grid of a Raytrix raw from its ``RayCalibData``, optionally refined on the image.

    Parameters
    ----------
    raw : RawCapture
        A Raytrix image (:func:`plenodecode.io.raytrix.read_raytrix`).
    cal : RaytrixCalibration, dict, path or None
        The calibration; default ``raw.metadata.extra['raytrix']``.
    refine : bool
        Re-fit origin, rotation, pitch and row spacing to the micro-image disks of ``raw``
        (:func:`refine_grid`); lens indices and types are kept.
    refine_method : 'auto', 'disks' or 'phase'
        See :func:`refine_grid`.

    Returns
    -------
    LensletGrid
        With ``lens_type`` from the XML's three lens types; ``info['source_kind']`` is
        'camera-file' (with ``info['refit']`` when refined).

    Raises
    ------
    CalibrationError
        No calibration available, or an unusable one.
    """
    from ..io import raytrix as rx
    calib = _raytrix_calibration(raw, cal)
    try:
        grid = rx.grid_from_raycalib(calib, raw.shape)
    except MetadataError as exc:
        raise CalibrationError(f"the RayCalibData cannot be used: {exc}") from exc
    info = {**grid.info, "source_kind": "camera-file", "source": raw.path, "serial": raw.metadata.serial,
            "camera_model": raw.metadata.model}
    grid = grid.replace(info=info)
    if refine:
        img = _c.flatten_white(raw, equalise=raw.cfa is not None)
        grid = refine_grid(grid, img, method=refine_method)
    return grid


__all__ = ["calibrate_from_scene", "calibrate_raytrix", "scene_centres", "scene_image", "refine_grid",
           "IMAGE_EXTENSIONS", "SELFCAL_METHODS", "RIM_FRACTIONS"]
