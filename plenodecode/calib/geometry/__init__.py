"""Geometric calibration of a plenoptic camera from checkerboard captures (Dansereau, Pizarro &
Williams, CVPR 2013): the ray model (:mod:`.model`, the intrinsic matrix ``H`` and the direction
distortion), and :class:`GeometricCalibration`, what a calibration holds.

Importing this package is light: names are loaded from their modules on first access.
"""

from __future__ import annotations

from ...registry import lazy_exports

#: public name -> module that defines it (imported on first access)
_LAZY = {
    "GeometricCalibration": "plenodecode.calib.geometry.model",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = sorted(_LAZY)
