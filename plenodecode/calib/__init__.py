"""Calibration: the lenslet grid of a plenoptic camera from white images (or from a scene raw).

>>> from plenodecode.calib import calibrate
>>> grid = calibrate("calib/B5143909630/MOD_0000.RAW")      # doctest: +SKIP
>>> grid.centres().shape                                     # doctest: +SKIP
(234794, 2)

:func:`calibrate` (:mod:`.white`) runs :mod:`.centroids` (Bayer collapse, devignetting, lattice
vectors from the autocorrelation, sub-pixel disk centres) and :mod:`.grid` (robust lattice fit,
grid extent, per-lens refinement).  :func:`calibrate_from_scene` (:mod:`.selfcal`) needs no white
image: it fits circles to the disk rims, which the scene cannot move; :func:`calibrate_raytrix`
uses a Raytrix ``RayCalibData``; :mod:`.store` is the white-image database
(:func:`.store.calibration_for` gives a raw's grid and the white image it came from).

Importing this package is light (no OpenCV, no numba): the functions are loaded from their
modules on first access, so the CLI can read :data:`LATTICES` or :mod:`.store` for its help.
"""

from __future__ import annotations

from ..registry import lazy_exports

#: Lattice choices accepted by :func:`calibrate`.
LATTICES = ("auto", "hex", "square")

#: public name -> module that defines it (imported on first access)
_LAZY = {
    "calibrate": "plenodecode.calib.white",
    "calibrate_image": "plenodecode.calib.white",
    "grid_from_points": "plenodecode.calib.grid",
    "check_not_dark": "plenodecode.calib.white",
    "scene_likeness": "plenodecode.calib.white",
    "DARK_LEVEL": "plenodecode.calib.white",
    "_as_raws": "plenodecode.calib.white",  # used by plenodecode.report.calibration
    "calibrate_from_scene": "plenodecode.calib.selfcal",
    "calibrate_raytrix": "plenodecode.calib.selfcal",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = ["calibrate", "calibrate_image", "grid_from_points", "calibrate_from_scene", "calibrate_raytrix",
           "check_not_dark", "scene_likeness", "LATTICES"]
