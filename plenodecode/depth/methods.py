"""Depth methods: named presets of one pipeline, the registry and the dispatcher :func:`estimate_depth`.

* ``'costvolume'`` (default, accurate, :data:`COSTVOLUME`): all views, labels 0.1 px apart, 8 aggregation
  paths, a wide refinement.
* ``'fast'`` (:data:`FAST`): the views on the horizontal, vertical and two diagonal lines through the centre
  view (the 'star' of epipolar-plane-image methods, Wanner & Goldluecke, CVPR 2012; Shin et al., CVPR 2018),
  which carry the parallax of all four directions with a quarter of the views of a 9 x 9 light field;
  labels 0.25 px apart and 4 aggregation paths.
* ``'focus'`` (:func:`plenodecode.depth.focus.estimate`): depth from focus, the sharpest slice of a focal
  stack per pixel.

Both presets run :func:`plenodecode.depth.pipeline.run_pipeline` (the steps and references are there) with
the shared :data:`~plenodecode.depth.pipeline.VIEW_DEFAULTS` and
:data:`~plenodecode.depth.occlusion.EDGE_DEFAULTS`.  Importing this module stays light: the pipeline (numba,
OpenCV) is imported on the first estimate.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from ..registry import lazy, lookup
from ..types import LightField

log = logging.getLogger(__name__)

#: The accurate method's own parameters of :func:`plenodecode.depth.pipeline.run_pipeline`.
COSTVOLUME: dict[str, Any] = {
    "label_step": 0.1,        # px per view step between labels
    "radius": 2,              # box aggregation radius of the matching cost (1: thin GT / decoded 11.4 / 33.7 %,
                              # 2: 10.8 / 32.2 %; hci-antinous 4.03 / 4.21 %, MSE x100 1.81 / 1.89)
    "confidence_radius": 1,   # box radius of the confidence's view agreement (2: thin GT AUSE/rnd 0.58, 1: 0.49)
    "p1": 0.15,               # SGM small-step penalty, in units of the median per-pixel cost span: labels are
                              # 0.1 px apart, so a ramp of one-label steps replaces a 0.5 px jump (5 labels) at
                              # 5 P1, 0.5 at 0.1 against P2 = 3, and SGM filled 6 px gaps between slats with
                              # ramps.  0.1 / 0.15 / 0.2: 12 oblique thin GT scenes' sum of BadPix0.07 187.8 /
                              # 177.6 / 171.1, decoded thin mean 23.25 / 22.03 / 21.07 %, hci-antinous 4.21 /
                              # 4.21 / 4.43 %, MSE x100 1.764 / 1.779 / 1.827: 0.15 keeps antinous where it was
                              # (its steep slopes need ramps near depth jumps)
    "p2": 3.0,                # SGM jump penalty (same units), lowered at image edges
    "edge_sigma": 0.02,       # guide step (grey centre view in [0, 1]) that halves P2
    "paths": 8,
    "median_radius": 5,       # weighted-median clean-up radius (0 = off)
    "refine_radius": "auto",  # box radius of the refinement cost: 'auto' = min(Y, X) / 85 in [3, 6]; 0 = off
    "refine_range": 1.0,      # refinement searches +- this many label steps around the estimate
    "refine_samples": 9,
    "grey": True,             # match one luma channel (one third of the colour cost volume's work)
    "pattern": None,          # all views
    "contrast_weight": 0.07,  # normalised views stacked beside the intensities with this weight (None: replace)
    "strips": 12,             # oriented strips of views for thin structures: orientations 15 deg apart (0 = off)
    "strip_width": 0.35,      # half-width of a strip, view steps (0.35: oblique strips keep the views nearest the line)
    "strip_halves": True,     # the cost volume's oblique strips also split at their line (cost.strip_halves): the
                              # 12 oblique thin GT scenes' sum of BadPix0.07 202.0 -> 186.7, the 24 others 78.3 -> 76.0
    "strip_radius": 2,        # radius of the 1-px line aggregation along a strip's orientation
    "strip_penalty": 8.0,     # factor on a strip's cost (a strip wins only where it is this much better)
    "refine_strip_penalty": 16.0,  # the same in the refinement, whose long strips (refine_radius) fit faint texture
    "strip_penalty_noise": 0.002,   # strip_penalty holds for views of noise sigma up to this, x (this / sigma)
    "refine_penalty_noise": 0.002,  # above, at least 0.15 of it (0: fixed); the same for refine_strip_penalty
    "strip_floor": 1.0,       # the strip penalties apply above this x 2 sigma_low^2 on noisy views only, and the
                              # edge pass's visibility check compares costs above it (pipeline.strip_floor_for,
                              # edge_floor_for; decoded thin means 22.03 -> 20.74 %, with gate_noise 20.65 -> 19.62
                              # %; thin GT, hci-antinous unchanged: their sigma_low is below 0.003)
    "gate_ratio": 2.0,        # clean-ups may not raise a pixel's matching cost above this x its own (0 = off)
    "gate_floor": 0.02,       # ... plus this x the pixel's own cost span (gate_span_min; cost units: the median
                              # per-pixel cost span)
    "gate_noise": 1.0,        # ... above this x the noise's cost on noisy views (pipeline.gate_base_for; 0 = off;
                              # decoded thin means 22.03 -> 20.65 %)
    "sgm_gate_ratio": 5.0,    # SGM's winner gives way to the matching cost's own where it costs more than this x
    "sgm_gate_floor": 0.03,   # ... plus this (0 ratio = off); see the pipeline's step 2
    "shift_noise": 1.0,       # noise_var of the cost volumes = this x noise sigma^2 above contrast_smooth_noise
                              # (pipeline step 1; decoded thin means 31.04 -> 28.16 %, 1 vs 0)
    "refine_shift_noise": 2.8,  # the refinement's noise_var is at least this x sigma_low^2 (the noise of the pixels
                              # that match), each view's over its weight (cost.half_plane_cost_volume's
                              # noise_weighted): noise_sigma reads 0.60 x the noise of decoded views (0.0062
                              # against 0.0103 on an illum-mini plane, noisy minus noise-free decode), as
                              # neighbouring views share sensor pixels (noise correlation 0.43), so 2.8 =
                              # (1 / 0.60)^2.  Without it the bicubic refinement pulled a decoded weak plane at -1
                              # to -0.92 (BadPix0.07 9.6 -> 74.3 %, now 1.1 %; at 0: 67.9 -> 17.5 %); decoded
                              # thin mean 17.18 -> 17.12 %, thin GT 5.767 -> 5.762 %, illum-mini dec 0.85 -> 0.78 %
    "shift_noise_rho": (0.0, 0.3),  # correlation of the noise of neighbouring pixels (y, x): 0.0 / 0.28-0.30 on
                              # a decoded illum-mini plane's views (the hex resampling interpolates along rows)
    "refine_radius_noisy": 5, # refinement box radius at least this on views noisier than contrast_smooth_noise
                              # (decoded thin means 32.24 -> 31.04 % at shift_noise 0; illum-mini dec 2.42 -> 2.21 %)
    "contrast_weight_noisy": 0.03,  # contrast_weight on noisy views (ramped in from contrast_smooth_noise to twice it)
    "gate_span_min": 0.1,     # the gate floors above scale with the pixel's own cost span (clipped to [this, 1]):
                              # in median-span units they exceeded a weakly textured pixel's whole span, so no
                              # gate ever kept its slit or slat (36 thin GT scenes' mean 5.76 -> 4.80 % with
                              # gate_floor 0.02; decoded 22.48 -> 21.78 %; illum-mini GT 0.08 -> 0.06 %)
    "p1_noisy_low": 0.5,      # SGM's p1 where even the pixels that match are noisy (pipeline.NOISY_LOW: decoded
                              # raws): the 36 thin decoded scenes' mean 24.76 -> 22.48 %, illum-mini dec 0.69 ->
                              # 0.59 %; not on the ideal light fields.  A refinement box of 9 px there as well gave
                              # 21.99 %, but the f01-mini sample raw 6.1 -> 9.0 %, so it was not kept
    "radius_noisy": 3,        # the cost volume's box radius on views noisier than twice contrast_smooth_noise
                              # (decoded thin means 27.76 -> 26.79 %, illum-mini dec 2.34 -> 2.09 %)
}

#: The fast method's own parameters: the star views, coarser labels, 4 paths, fewer refinement offsets.
FAST: dict[str, Any] = {
    "label_step": 0.25,
    "radius": 1,
    "p1": 0.2,
    "p2": 3.0,
    "edge_sigma": 0.02,
    "paths": 4,
    "confidence_radius": 1,
    "median_radius": 3,
    "refine_radius": "auto",  # per-pixel refinement over the star views; 0 = off
    "refine_range": 1.0,
    "refine_samples": 5,
    "grey": True,             # match one luma channel
    "pattern": "star",        # the views on the 4 lines through the centre
    "contrast_weight": 0.05,  # normalised views stacked beside the intensities with this weight (None: replace)
    "strips": 0,              # no strips: the star's few views make thin strips
    "strip_width": 0.5,
    "strip_halves": False,
    "strip_radius": 2,
    "strip_penalty": 1.0,
    "refine_strip_penalty": 1.0,
    "strip_penalty_noise": 0.0,
    "refine_penalty_noise": 0.0,
    "strip_floor": 0.0,
    "gate_ratio": 0.0,
    "gate_floor": 0.05,
    "gate_noise": 0.0,
    "sgm_gate_ratio": 0.0,
    "sgm_gate_floor": 0.03,
    "shift_noise": 0.0,
    "refine_shift_noise": 0.0,
    "shift_noise_rho": (0.0, 0.0),
    "refine_radius_noisy": 0,
    "radius_noisy": 0,
    "p1_noisy_low": 0.2,
    "gate_span_min": 0.0,
    "contrast_weight_noisy": None,
}

#: Pipeline presets: method name -> its own parameters.
PRESETS: dict[str, dict[str, Any]] = {"costvolume": COSTVOLUME, "fast": FAST}

Estimator = Callable[..., tuple[np.ndarray, np.ndarray, dict[str, Any]]]


def _preset_method(name: str) -> Estimator:
    """The registry entry of a preset: ``estimate(lf, *, progress=None, **params)`` running
    :func:`plenodecode.depth.pipeline.run_preset` (imported on the first call)."""
    run_preset = lazy("plenodecode.depth.pipeline", "run_preset")

    def estimate(lf: LightField, *, progress: Callable[[int, int], None] | None = None,
                 **params: Any) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        return run_preset(lf, name, PRESETS[name], progress=progress, **params)

    estimate.__name__ = estimate.__qualname__ = f"estimate_{name}"
    estimate.__doc__ = (f"The '{name}' preset of the depth pipeline: disparity, confidence, params "
                        f"(parameters: :data:`{name.upper()}` and the shared defaults).")
    return estimate


#: Depth methods: name -> ``estimate(lf, *, progress=None, **params) -> (disparity, confidence, params)``.
DEPTH_METHODS: dict[str, Estimator] = {
    "costvolume": _preset_method("costvolume"),
    "fast": _preset_method("fast"),
    "focus": lazy("plenodecode.depth.focus", "estimate"),
}
#: The method :func:`estimate_depth` uses when none is given.
DEFAULT_METHOD = "costvolume"


@dataclass(frozen=True)
class DepthMap:
    """Disparity of the centre view with its confidence.

    Attributes
    ----------
    disparity : ndarray (Y, X) float32
        px per view step, HCI sign convention (positive = closer than the focus plane).
    confidence : ndarray (Y, X) float32 in [0, 1]
        1 = unambiguous match, 0 = no information.
    method : str
        Key of :data:`DEPTH_METHODS`.
    params : dict
        Parameters used (defaults included), the disparity range and its source, and ``seconds``.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    method: str
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.disparity.ndim != 2 or self.disparity.dtype != np.float32:
            raise ValueError(f"disparity must be a 2-D float32 array, got {self.disparity.dtype} {self.disparity.shape}")
        if self.confidence.shape != self.disparity.shape or self.confidence.dtype != np.float32:
            raise ValueError(f"confidence must be float32 of shape {self.disparity.shape}, got "
                             f"{self.confidence.dtype} {self.confidence.shape}")

    @property
    def shape(self) -> tuple[int, int]:
        """``(Y, X)``."""
        return self.disparity.shape  # type: ignore[return-value]


def estimate_depth(lf: LightField, *, method: str = DEFAULT_METHOD,
                   progress: Callable[[int, int], None] | None = None, **kw: Any) -> DepthMap:
    """Estimate the disparity of the centre view of a light field.

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32.  ``lf.weight`` (when present) down-weights views; views whose median
        weight is below ``min_view_weight`` (default 0.1) of the centre view's are not used.
    method : str
        A key of :data:`DEPTH_METHODS`.
    progress : callable(done, total), optional
    **kw
        Method parameters (a preset's keys, :data:`COSTVOLUME` or :data:`FAST`, and the shared
        ``VIEW_DEFAULTS`` and ``EDGE_DEFAULTS`` of :mod:`plenodecode.depth.pipeline`; for 'focus' the keys
        of :data:`plenodecode.depth.focus.DEFAULTS`), e.g. ``disparity_range=(lo, hi)``; without it the range
        comes from ``lf.metadata['disparity_range']`` (or an HCI scene's disp_min/disp_max), else it is
        estimated by a coarse search.

    Returns
    -------
    DepthMap

    Raises
    ------
    ValueError
        Unknown method (the message lists the names) or parameter.
    DecodeError
        The light field has a single view or an empty centre view.
    """
    if not isinstance(lf, LightField):
        raise ValueError(f"lf must be a LightField, got {type(lf).__name__}")
    estimate = lookup(DEPTH_METHODS, method, param="method")
    if (lf.geometry.calibration or {}).get("lens_type") is not None:
        log.warning("this light field was decoded from a focused-plenoptic (Raytrix) raw: its views have one pixel "
                    "per lens, and so will this depth map; plenodecode.estimate_focused_depth(raw, grid) gives the "
                    "virtual depth of every pixel of its total-focus image")
    t0 = time.perf_counter()
    disparity, confidence, params = estimate(lf, progress=progress, **kw)
    seconds = time.perf_counter() - t0
    log.info("depth '%s': %.2f s", method, seconds)
    return DepthMap(disparity=np.ascontiguousarray(disparity, np.float32),
                    confidence=np.ascontiguousarray(confidence, np.float32),
                    method=method, params={**params, "seconds": seconds})


__all__ = ["COSTVOLUME", "FAST", "PRESETS", "DEPTH_METHODS", "DEFAULT_METHOD", "DepthMap", "estimate_depth"]
