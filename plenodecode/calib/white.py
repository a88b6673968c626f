"""Calibration from white images: :func:`calibrate` (one or more flat fields -> LensletGrid) and its parts.

:func:`calibrate` runs :mod:`.centroids` (Bayer collapse, devignetting, lattice vectors from the
autocorrelation, sub-pixel disk centres) and :mod:`.grid` (robust lattice fit, grid extent,
per-lens refinement); :func:`calibrate_image` is its core on an already flattened image and
:func:`~plenodecode.calib.grid.grid_from_points` is the lattice fit of measured centres.
"""

from __future__ import annotations

import logging
import os
from typing import Any, Callable, Mapping, Sequence

import cv2
import numpy as np

from ..errors import CalibrationError
from ..registry import lookup
from ..types import LensletGrid, RawCapture
from . import LATTICES
from . import centroids as _c
from . import grid as _g

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None
WhiteInput = RawCapture | str | os.PathLike | Sequence[RawCapture | str | os.PathLike]

#: Normalised 99.9th percentile below which a frame counts as dark.
DARK_LEVEL = 0.02


def _as_raws(white: WhiteInput) -> list[RawCapture]:
    """A RawCapture, a path or a sequence of them -> list of RawCapture (read through plenodecode.io)."""
    if isinstance(white, RawCapture):
        return [white]
    if isinstance(white, (str, os.PathLike)):
        from ..io import read_raw
        return [read_raw(white)]
    if isinstance(white, Sequence) and not isinstance(white, (bytes, bytearray)):
        out: list[RawCapture] = []
        for item in white:
            out.extend(_as_raws(item))
        if not out:
            raise ValueError("white must name at least one white image, got an empty sequence")
        return out
    raise ValueError(f"white must be a RawCapture, a path or a sequence of them, got {type(white).__name__}")


def white_words(raw: RawCapture) -> str:
    """What a white image of ``raw``'s camera is, for a hint: 'a flat-field MOD_NNNN.RAW white image' (Lytro),
    "the microscope's radiometry (flat-field) frame" (optics known), else 'a white (flat-field) image'."""
    m = raw.metadata
    if (m.make or "").lower().startswith("lytro"):
        return "a flat-field MOD_NNNN.RAW white image of the camera"
    if m.microscope is not None and not m.microscope.empty:
        return "the microscope's radiometry (flat-field) frame"
    return "a white (flat-field) image taken through the same lenses"


def white_hint(raw: RawCapture) -> str:
    """What to give as the white image of ``raw``'s camera, in words (:func:`white_words`), with the flat-field frame
    beside ``raw`` when there is one (:func:`plenodecode.io.microscope.flat_field_beside`: "the microscope's
    radiometry (flat-field) frame, e.g. data/radiometry_frame.png beside it")."""
    from ..io.microscope import flat_field_beside

    frame = flat_field_beside(raw.path) if raw.path else None
    return white_words(raw) + (f", e.g. {frame} beside it" if frame is not None else "")


def check_not_dark(raw: RawCapture, *, level: float = DARK_LEVEL) -> float:
    """Raise CalibrationError when a frame is uniformly dark, saying what to give instead (:func:`white_hint`);
    return its normalised 99.9th percentile."""
    sub = raw.mosaic[::8, ::8].astype(np.float32)
    black = float(raw.black.mean())
    rng = float((raw.white - raw.black).mean())
    top = (float(np.percentile(sub, 99.9)) - black) / rng
    if top < level:
        name = raw.path or "the frame"
        raise CalibrationError(f"{name} is uniformly dark (99.9th percentile {top:.4f} of the white level); "
                               f"expected a white image: use {white_hint(raw)}, not a dark frame")
    return top


def scene_likeness(img: np.ndarray, pitch: float) -> float:
    """How much an image's lens-scale brightness varies beyond a smooth vignetting (0 for a white).

    The image is area-reduced to about one pixel per lens; ``std(L1 / L2)`` over the lit part,
    with ``L1`` a 1-lens and ``L2`` a 15-lens Gaussian mean.  White images give < ~0.05,
    scenes typically > 0.15.
    """
    f = max(1, int(round(pitch)))
    h, w = img.shape[0] // f, img.shape[1] // f
    if h < 8 or w < 8:
        return 0.0
    small = cv2.resize(img[:h * f, :w * f], (w, h), interpolation=cv2.INTER_AREA)
    l1 = cv2.GaussianBlur(small, (0, 0), 1.0, borderType=cv2.BORDER_REFLECT)
    l2 = cv2.GaussianBlur(small, (0, 0), 15.0, borderType=cv2.BORDER_REFLECT)
    lit = l2 > 0.1 * float(np.percentile(l2, 99))
    if lit.sum() < 16:
        return 0.0
    return float(np.std(l1[lit] / l2[lit]))


def calibrate_image(img: np.ndarray, sensor_shape: tuple[int, int], *, scale: float = 1.0, shift: float = 0.0,
                    lattice: str = "auto", pitch_hint: float | None = None, method: str = "dog",
                    refine: bool = True, refine_window: int = 5, min_contrast: float = 0.15,
                    info: dict[str, Any] | None = None,
                    estimate: _c.LatticeEstimate | None = None, progress: Progress = None) -> LensletGrid:
    """Fit the lenslet grid to a flattened image (the core of :func:`calibrate`).

    Parameters
    ----------
    img : ndarray (h, w) float32
        Flattened image (:func:`~plenodecode.calib.centroids.flatten_white`), possibly binned.
    sensor_shape : (H, W)
        Sensor size; image pixel ``p`` is sensor position ``scale * p + shift``.
    scale, shift : float
        2 and 0.5 for a 2x2-binned image, else 1 and 0.
    lattice : 'auto', 'hex' or 'square'
    pitch_hint : float, optional
        Expected pitch in sensor px.
    method : str
        Sub-pixel estimator, a key of :data:`~plenodecode.calib.centroids.CENTROID_METHODS`.
    refine : bool
        Keep per-lens refined centres where they deviate significantly from the lattice.
    refine_window : int
        Side in lenses of the block over which deviations are averaged before the significance test.
    min_contrast : float
        Relative contrast a disk must have to be detected.
    info : dict, optional
        Provenance stored in ``grid.info``.
    estimate : LatticeEstimate, optional
        Lattice vectors already estimated (in ``img`` pixels); skips the autocorrelation.
    progress : callable(done, total), optional

    Returns
    -------
    LensletGrid
    """
    if lattice not in LATTICES:
        raise ValueError(f"lattice must be one of {LATTICES}, got {lattice!r}")
    lookup(_c.CENTROID_METHODS, method, param="method")
    total = 5

    def tick(k: int) -> None:
        if progress is not None:
            progress(k, total)

    hint = None if pitch_hint is None else float(pitch_hint) / scale
    est = estimate if estimate is not None else _c.estimate_lattice_vectors(img, pitch_hint=hint, lattice=lattice)
    tick(1)
    contrast_img = _c.devignette(img, est.pitch)
    peaks, contrast, smoothed = _c.detect_peaks_and_filtered(contrast_img, est.pitch, min_contrast=min_contrast)
    tick(2)
    cen, ok = _c.refine_peaks(contrast_img, peaks, est.pitch, method=method, smoothed=smoothed)
    tick(3)
    meta = dict(info or {})
    meta.update({"method": method, "n_peaks": int(len(peaks)), "lattice_requested": lattice})
    grid = _g.grid_from_points(cen[ok], est, sensor_shape, scale=scale, shift=shift, refine=refine,
                            refine_window=refine_window, info=meta)
    tick(5)
    return grid


def _camera_info(raw: RawCapture) -> dict[str, Any]:
    md = raw.metadata
    return {"source": raw.path, "camera_model": md.model, "camera_make": md.make, "serial": md.serial,
            "zoom_step": md.zoom_step, "focus_step": md.focus_step, "exposure_s": md.exposure_s,
            "is_white_image": bool(md.is_white_image)}


def calibrate(white: WhiteInput, *, lattice: str = "auto", pitch_hint: float | None = None,
              method: str = "dog", refine: bool = True, binning: int | str = "auto",
              progress: Progress = None) -> LensletGrid:
    """Fit the lenslet grid of a camera from one or more white (flat-field) images.

    Pipeline: levels and per-CFA gain equalisation, hot-pixel fix, binomial low-pass (or 2x2
    binning when the pitch is >= 12 px), lattice vectors from the autocorrelation, devignetting
    (divide by the local-linear mean), disk peaks of a Gaussian matched filter refined to sub-pixel
    (Newton on an exactly evaluated zero-sum difference of Gaussians), robust least-squares lattice fit
    (Dansereau et al., CVPR 2013; Cho et al., ICCV 2013), and per-lens refined centres where the
    measured centres deviate significantly (smoothed over 5 x 5 lenses) from the lattice.

    A single Raytrix image whose metadata holds a ``RayCalibData`` (``extra['raytrix']``) gets
    that calibration's grid (:func:`calibrate_raytrix`).

    Parameters
    ----------
    white : RawCapture, path, or sequence of them
        Several images are averaged after normalisation (same sensor size required).
    lattice : 'auto', 'hex' or 'square'
    pitch_hint : float, optional
        Expected pitch in px (default: from metadata, lens pitch / pixel pitch); only a hint.
    method : str
        Sub-pixel centre estimator (:data:`~plenodecode.calib.centroids.CENTROID_METHODS`).
    refine : bool
        Keep significant per-lens deviations as ``grid.refined``.
    binning : 'auto', 1 or 2
        'auto' bins 2x2 when the pitch is at least 12 px (speed; accuracy is unchanged).
    progress : callable(done, total), optional

    Returns
    -------
    LensletGrid
        ``info`` holds ``source_kind`` 'white-image' (:data:`~plenodecode.calib.grid.SOURCE_KINDS`),
        the source(s), camera serial/model, zoom/focus steps, lens counts and fit statistics.

    Raises
    ------
    CalibrationError
        A dark frame, no lattice found, or a poor fit.
    ValueError
        Bad arguments.
    """
    if lattice not in LATTICES:
        raise ValueError(f"lattice must be one of {LATTICES}, got {lattice!r}")
    if binning not in ("auto", 1, 2):
        raise ValueError(f"binning must be 'auto', 1 or 2, got {binning!r}")
    if pitch_hint is not None and not (np.isfinite(pitch_hint) and pitch_hint > 2):
        raise ValueError(f"pitch_hint must be a finite lens pitch > 2 px, got {pitch_hint!r}")
    raws = _as_raws(white)
    extra = raws[0].metadata.extra
    if len(raws) == 1 and isinstance(extra, Mapping) and "raytrix" in extra:
        from .selfcal import calibrate_raytrix
        log.info("Raytrix image with RayCalibData: using its grid")
        return calibrate_raytrix(raws[0])
    shape = raws[0].shape
    for r in raws[1:]:
        if r.shape != shape:
            raise CalibrationError(f"white images differ in size ({r.shape} vs {shape}); "
                                   "pass images of one camera only")
    for r in raws:
        check_not_dark(r)
    if pitch_hint is None:
        pitch_hint = raws[0].metadata.lenslet_pitch_px()
    # lattice vectors from a central crop at full resolution; they also decide the binning
    h, w = shape
    side = 768
    r0, c0 = max(0, (h - side) // 2) & ~1, max(0, (w - side) // 2) & ~1
    crop = RawCapture(raws[0].mosaic[r0:r0 + side, c0:c0 + side], raws[0].cfa, raws[0].black, raws[0].white)
    est = _c.estimate_lattice_vectors(_c.flatten_white(crop), pitch_hint=pitch_hint, lattice=lattice)
    if binning == "auto":
        binning = 2 if est.pitch >= 12.0 else 1
    img = None
    for r in raws:
        f = _c.flatten_white(r, binning=int(binning))
        img = f if img is None else img + f
    assert img is not None
    if len(raws) > 1:
        img = img / np.float32(len(raws))
    scale, shift = (2.0, 0.5) if binning == 2 else (1.0, 0.0)
    if binning == 2:
        est = _c.LatticeEstimate(est.lattice, est.pitch / 2, est.rotation, est.v1 / 2, est.v2 / 2, est.score)
    info = _camera_info(raws[0])
    info.update({"source_kind": "white-image", "n_whites": len(raws)})
    if len(raws) > 1:
        info["sources"] = [r.path for r in raws]
    info["binning"] = int(binning)
    grid = calibrate_image(img, shape, scale=scale, shift=shift, lattice=lattice, pitch_hint=pitch_hint,
                           method=method, refine=refine, info=info, estimate=est, progress=progress)
    likeness = scene_likeness(img, grid.pitch / scale)
    warnings = []
    if not any(r.metadata.is_white_image for r in raws) and likeness > 0.12:
        warnings.append(f"this looks like a scene, not a white image (lenslet-scale brightness varies by "
                        f"{likeness:.0%}); calibrate from {white_words(raws[0])}")
        log.warning(warnings[-1])
    return grid.replace(info={**grid.info, "scene_likeness": likeness, "warnings": warnings})


__all__ = ["calibrate", "calibrate_image", "check_not_dark", "white_words", "white_hint", "scene_likeness",
           "DARK_LEVEL"]
