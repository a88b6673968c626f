"""The fast depth method: a sparse occlusion-aware cost volume with 4-path semi-global aggregation.

The views on the horizontal, vertical and two diagonal lines through the centre view (the 'star' of
epipolar-plane-image methods, Wanner & Goldluecke 2012; Shin et al. 2018) carry the parallax of all four
directions with a quarter of the views of a 9 x 9 light field.  The same building blocks as the accurate
method then run with coarser labels and fewer aggregation paths:

1. the matching images of :mod:`plenodecode.depth.costvolume` (grey + local contrast normalisation) and the
   half-plane minimum of the box-aggregated squared difference to the centre view over the star views
   (Kang, Szeliski & Chai, CVPR 2001: the half on the far side of an occluder is unoccluded);
2. semi-global aggregation along 4 paths with an edge-adaptive jump penalty (Hirschmueller, TPAMI 2008);
3. parabolic sub-label minimum, peak-ratio confidence, weighted-median clean-up guided by the centre view;
4. the per-pixel refinement of :mod:`plenodecode.depth.costvolume` (a narrow cost volume of offsets around
   the estimate, views warped per pixel) over the star views;
5. the occlusion-edge fix of :mod:`plenodecode.depth.costvolume` (visibility check, colour-guided weighted
   median, per-pixel visibility and coverage relabels in the band around depth edges).

The cost volume's labels run on all cores, up to 4 threads (OpenCV releases the GIL).
"""

from __future__ import annotations

import logging
from typing import Any, Callable

import numpy as np

from ..types import LightField
from . import _core

log = logging.getLogger(__name__)

#: Default parameters (keywords of :func:`estimate`).
DEFAULTS: dict[str, Any] = {
    "label_step": 0.25,
    "radius": 1,
    "p1": 0.2,
    "p2": 3.0,
    "edge_sigma": 0.02,
    "paths": 4,
    "median_radius": 3,
    "refine_radius": "auto",  # per-pixel refinement over the star views (see costvolume); 0 = off
    "refine_range": 1.0,
    "refine_samples": 5,
    "grey": True,             # match one luma channel
    "pattern": "star",        # the views on the 4 lines through the centre
    "contrast_weight": 0.05,  # normalised views stacked beside the intensities with this weight (None: replace)
    **_core.VIEW_DEFAULTS,
    **_core.EDGE_DEFAULTS,
}


def estimate(lf: LightField, *, progress: Callable[[int, int], None] | None = None,
             **kw: Any) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Disparity and confidence of the centre view (see the module docstring).

    Parameters
    ----------
    lf : LightField
    progress : callable(done, total), optional
    **kw
        Any key of :data:`DEFAULTS`.

    Returns
    -------
    disparity (Y, X) float32, confidence (Y, X) float32 in [0, 1], params dict
    """
    p = _core.check_params("fast", DEFAULTS, kw)
    return _core.run_pipeline(lf, p, progress=progress)
