"""Rendering: refocusing (shift-sum, Fourier slice), focal stacks, all-in-focus images, perspective views.

Conventions (design.md): a light field is ``(V, U, Y, X, C)`` float32; a refocus slope ``s`` is in spatial
samples per view step and a surface of disparity ``d`` is sharp at ``s = d``; ``alpha`` is Ng's relative film
depth (1 = focus as captured), converted by :func:`alpha_to_slope` (derivation in
:mod:`plenodecode.render.alpha`).

Modules: ``refocus_methods`` (:func:`refocus` and the method registry), ``shiftsum``, ``fourier``, ``alpha``,
``focalstack``, ``allinfocus`` (:func:`all_in_focus` and its method registry), ``viewpoints``
(:func:`perspective`, parallax);
``plenodecode.render.refocus`` is the function.

Importing this package is light (no numba, no OpenCV): the names of the compiled modules (``shiftsum``,
``fourier``, ``focalstack``, ``allinfocus``) load on first access, and :data:`REFOCUS_METHODS` holds lazy
entries, so the CLI can list the methods for its help.
"""

from __future__ import annotations

from ..registry import lazy_exports
from ._common import aperture_mask
from .alpha import (REFOCUS_CONSTANTS, alpha_to_slope, distance_to_slope, refocus_constants, refocus_range,
                    refocus_range_units, slope_per_alpha_unit, slope_to_alpha, slope_to_distance)
from .viewpoints import parallax_path, perspective, render_parallax
from .refocus_methods import REFOCUS_METHODS, refocus

#: public name -> module that defines it (imported on first access: numba kernels or OpenCV)
_LAZY = {
    **dict.fromkeys(["all_in_focus", "ALL_IN_FOCUS_METHODS"], "plenodecode.render.allinfocus"),
    **dict.fromkeys(["default_slopes", "depth_from_focus", "focal_stack", "focus_curve",
                     "focus_measure", "refocus_per_pixel", "sharpest_slope"], "plenodecode.render.focalstack"),
    "FourierRefocuser": "plenodecode.render.fourier",
    "shift_sum": "plenodecode.render.shiftsum",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = [
    "refocus", "focal_stack", "all_in_focus", "perspective", "parallax_path", "render_parallax",
    "REFOCUS_METHODS", "REFOCUS_CONSTANTS", "alpha_to_slope", "slope_to_alpha", "slope_per_alpha_unit",
    "refocus_constants", "refocus_range", "refocus_range_units", "distance_to_slope", "slope_to_distance",
    "aperture_mask", "shift_sum", "FourierRefocuser", "focus_measure", "focus_curve",
    "sharpest_slope", "depth_from_focus", "refocus_per_pixel", "default_slopes", "ALL_IN_FOCUS_METHODS",
]
