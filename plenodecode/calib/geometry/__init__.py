"""Geometric calibration of a lenslet plenoptic camera from checkerboard captures (Dansereau et al. 2013).

:func:`calibrate_geometry` (:mod:`.captures`) decodes each capture without rectification, finds the
board's corners in its sub-aperture views (:mod:`.corners`), estimates ``H`` and the board poses in
closed form (:mod:`.initial`), then refines ``H``, the direction distortion and the poses jointly by
ray reprojection (:mod:`.solve`); :mod:`.gauge` states which entries of ``H`` the data fix.
The result is a :class:`plenodecode.raymodel.GeometricCalibration`.
"""

from __future__ import annotations

from ...registry import lazy_exports

#: public name -> module that defines it (imported on first access)
_LAZY = {
    "calibrate_geometry": "plenodecode.calib.geometry.captures",
    "GeometryRun": "plenodecode.calib.geometry.captures",
    "Board": "plenodecode.raymodel",
    "detect_corners": "plenodecode.calib.geometry.corners",
    "to_solver_gauge": "plenodecode.calib.geometry.gauge",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = list(_LAZY)
