"""The 'focus' depth method: depth from focus, the per-pixel slope of the sharpest slice of a focal stack.

A surface of disparity ``d`` is sharpest in the photograph refocused at slope ``s = d`` (design.md), so the
slope that maximises a local focus measure (Tenengrad, Krotkov 1988) over a focal stack is the disparity
(:func:`plenodecode.render.focalstack.depth_from_focus`).  No correspondence search: robust on
smooth texture, blurred at depth edges by the measure's window.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..render.focalstack import depth_from_focus, focal_stack
from ..types import LightField
from .cost import make_labels
from .pipeline import disparity_range, merge_params
from .views import prepare_views

#: Parameters of :func:`estimate`.
DEFAULTS: dict[str, Any] = {
    "label_step": 0.1,               # slope spacing of the focal stack, px per view step
    "window": 9,                     # box size of the focus measure
    "smooth": 5,                     # median filter of the slope map: 1 (none), 3 or 5
    "refocus_method": "shift-sum",   # a key of plenodecode.render.REFOCUS_METHODS
    "disparity_range": None,         # (lo, hi) px per view step; None = the metadata's, else estimated
}


def estimate(lf: LightField, *, progress: Callable[[int, int], None] | None = None,
             **params: Any) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Disparity and confidence of the centre view from a focal stack.

    The stack's slopes are uniformly spaced ``label_step`` apart over the disparity range (chosen as by the
    cost-volume methods, :func:`plenodecode.depth.pipeline.disparity_range`) widened by two steps on each
    side; per pixel the sharpest slope is refined by a parabola and the map median-filtered
    (:func:`~plenodecode.render.focalstack.depth_from_focus`).

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32.
    progress : callable(done, total), optional
        Called as the focal stack advances.
    **params
        Any key of :data:`DEFAULTS`.

    Returns
    -------
    disparity : ndarray (Y, X) float32
        px per view step, HCI sign convention.
    confidence : ndarray (Y, X) float32 in [0, 1)
        ``1 - mean / peak`` of the pixel's focus measure over the stack (0: a flat curve, e.g. no texture).
    params : dict
        The parameters used, with the disparity range, its source and the number of slopes.
    """
    p = merge_params("focus", DEFAULTS, params)
    step = float(p["label_step"])
    (lo, hi), source = disparity_range(lf, lambda: prepare_views(lf, grey=True), p["disparity_range"])
    slopes = make_labels(lo, hi, step, pad=2 * step)
    stack = focal_stack(lf, slopes, method=p["refocus_method"], progress=progress)
    disparity, peak_ratio = depth_from_focus(stack, slopes, window=int(p["window"]), smooth=int(p["smooth"]))
    # depth_from_focus gives peak / mean - 1 in [0, inf)
    confidence = (peak_ratio / (1.0 + peak_ratio)).astype(np.float32)
    used = {**p, "disparity_range": [float(lo), float(hi)], "disparity_range_source": source,
            "n_labels": len(slopes)}
    return disparity, confidence, used


__all__ = ["DEFAULTS", "estimate"]
