"""The depth pipeline every cost-volume method runs, its parameters and the choice of the disparity range.

Steps (one module per stage; a method is a preset of :func:`run_pipeline`'s parameters,
:mod:`plenodecode.depth.methods`):

0. **Matching views** (:mod:`~plenodecode.depth.views`): the grey views, plus the same views after a local
   contrast normalisation ``(I - G*I) / (sqrt(G*(I - G*I)^2) + eps)`` (Gaussian ``G`` of ``contrast_sigma``
   px) stacked as a second channel with weight ``contrast_weight``.  Faint texture in shadows and on pale
   surfaces then counts in the cost as much as strong texture (the normalisation of a normalised
   cross-correlation), while smooth, high-contrast texture keeps its low frequencies in the intensity
   channel.  ``eps`` is at least ``contrast_noise`` x the views' noise
   (:func:`~plenodecode.depth.views.noise_sigma`), so that noise in flat areas is not normalised into texture.
   On noisy views the normalised views are also smoothed (``contrast_smooth`` px, :func:`contrast_smooth_for`
   above ``contrast_smooth_noise``): the interpolation of the shifts averages white noise away at fractional
   shifts and pulls the cost's minimum off the true disparity; with the same ramp their weight goes from
   ``contrast_weight`` to ``contrast_weight_noisy`` (the normalisation lifts noise towards the level of texture).
1. **Cost volume** (:mod:`~plenodecode.depth.cost`) over uniformly spaced disparity labels: every used view
   is shifted onto the centre view and its weighted squared colour difference summed per angular sector; the
   cost of a pixel is the minimum over half-planes of views of the box-aggregated mean difference, so a
   point occluded in the views on one side of the centre still matches in the other half (Kang, Szeliski &
   Chai, CVPR 2001; Wang, Efros & Ramamoorthi, ICCV 2015, who split the angular patch at the occluder edge).
   Views are weighted by their ``lf.weight`` (Jeon et al., CVPR 2015 also build the volume over all views
   against the centre view).  On clearly noisy views (above twice ``contrast_smooth_noise``) the box radius
   is at least ``radius_noisy``.  A point seen through a gap of a few pixels is hidden from both half-planes,
   and a square box around a thin slat is mostly background: with ``strips`` the minimum also runs over
   oriented strips of views (those within ``strip_width`` of a line through the centre view), each
   aggregated along a 1-px line of its orientation and weighted by ``strip_penalty``
   (:func:`~plenodecode.depth.cost.strip_groups`).  Only rows, columns and diagonals of the view grid lie
   exactly on their line; an oblique strip's views sit up to ``strip_width`` off it, and behind a gap of that
   orientation those off the line on one side see the gap's edge moved over a point near it, so with
   ``strip_halves`` the cost volume also takes each oblique strip's two halves, the views on either side of
   its line (:func:`~plenodecode.depth.cost.strip_halves`), at a penalty raised by the strip's view weight
   over the half's.  The strips match the intensity channels only (the
   contrast channel mixes a thin structure with its surround) and scale the half-planes' cost by how much they
   beat them there (``strip_channels`` of :func:`~plenodecode.depth.cost.half_plane_cost_volume`); the
   refinement's strips, as long as its box, have their own ``refine_strip_penalty``.  Both penalties are
   lowered on noisy views (:func:`strip_penalty_for`: ``x min(1, strip_penalty_noise / sigma)``, resp.
   ``refine_penalty_noise``, at least 0.15 of it): noise puts the same floor under every group's error.
   On noisy views the penalties also apply above that floor only (``strip_floor`` x ``2 sigma_low^2``,
   :func:`strip_floor_for`, with ``sigma_low`` the noise of the pixels that match,
   :func:`~plenodecode.depth.views.noise_sigmas`, less a margin for a strip's few views): a strip that sees a
   weakly textured far plane through a gap at its noise floor no longer loses to the near disparity of the
   half-planes, whose box holds the gap's occluders.
   On noisy views (above ``contrast_smooth_noise``, ramped in up to twice it) every view's error also gets
   back the noise a fractional shift's interpolation averages away (``noise_var`` = ``shift_noise`` x the
   noise variance, with the noise's pixel-to-pixel correlation ``shift_noise_rho``; in the refinement of
   step 5 ``refine_shift_noise`` x the noise variance, over each view's weight: ``noise_weighted`` of
   :func:`~plenodecode.depth.cost.half_plane_cost_volume`): otherwise the cost is lowest at fractional shifts
   and a weakly textured surface at an integer disparity is pulled off it.
2. **Edge-aware regularisation** (:mod:`~plenodecode.depth.aggregation`): semi-global aggregation along
   ``paths`` directions (Hirschmueller, TPAMI 2008) whose large-jump penalty P2 falls at the centre view's
   intensity edges, so depth edges follow image edges (also where a mixed pixel spreads the edge over two
   steps, as along an oblique edge).  Its penalties are in units of the median per-pixel
   cost span, which can outweigh the small span of a weakly textured surface seen through a slit of a few
   pixels: the winner of the aggregated cost is gated by the matching cost
   (:func:`~plenodecode.depth.refinement.cost_gate` with ``sgm_gate_ratio``, ``sgm_gate_floor``), so a pixel
   keeps the winner of its own cost where SGM's costs it more than that ratio (thin scenes' ground-truth mean
   BadPix0.07 17.7 -> 12.5 %).  Where even the pixels that match are noisy (``sigma_low`` above
   :data:`NOISY_LOW` x ``contrast_smooth_noise``: decoded raws, not ideal light fields) P1 is at least
   ``p1_noisy_low``: a weakly textured surface seen by few views has a cost nearly flat under the noise, and a
   run of one-label steps at the plain P1 let it wander.
3. **Winner-take-all**: best label with a parabola through its neighbours' aggregated cost; confidence
   (:mod:`~plenodecode.depth.confidence`) is the product of the centre view's texture along the baselines
   against its noise, the peak ratio of the aggregated cost and the agreement of all views with the best
   half-plane at the estimate (low on featureless areas, ambiguous cost curves and occlusions), times the
   final disparity's consistency with the winner of the (unaggregated) matching cost within that winner's
   uncertainty, and the matching cost's peak ratio (low where steps 2-6 moved a pixel off what its own views
   prefer: mixed pixels at thin structures' edges) and, at the map's depth edges, how clearly the matching
   cost prefers the pixel's disparity to that of its neighbour across the edge; the view agreement, the
   consistency and that rivalry are measured at the *final* disparity, after steps 4-6 (the aggregated peak
   ratio is the winner's).
4. **Clean-up** (:mod:`~plenodecode.depth.refinement`): an edge-aware weighted median guided by the centre
   view (Ma et al., ICCV 2013), gated by the matching cost (:func:`~plenodecode.depth.refinement.cost_gate`,
   ``gate_ratio``, ``gate_floor``): a pixel keeps its value where the median's is clearly worse for the
   views, so a median window across a thin structure does not wipe it out (the same gate guards the edge
   snapping of step 6).  Every gate's floor (``gate_floor``, ``sgm_gate_floor``) is scaled by the pixel's own
   cost span, clipped to [``gate_span_min``, 1]: a floor in median-span units alone exceeded a weakly textured
   slit's whole span, so no gate kept it (thin scenes' ground-truth mean 5.76 -> 4.80 %).  On noisy views
   the ratio compares the costs above the noise's (``gate_noise``, :func:`gate_base_for`), which every label
   shares.
5. **Sub-label refinement without the fronto-parallel bias**: a second, narrow cost volume of offsets
   ``+-refine_range`` labels around the estimate, every view warped per pixel by ``d(y, x) + offset``
   (bicubic), so slanted surfaces match exactly (SGM's label penalties favour fronto-parallel steps); its
   parabolic minimum is added to the estimate.  Its strips aggregate along lines as long as its box; on
   noisy views (above ``contrast_smooth_noise``) the box radius is at least ``refine_radius_noisy``.
6. **Occlusion edges** (:mod:`~plenodecode.depth.occlusion`, parameters ``edge_*``): within ``edge_radius``
   px of a disparity jump, a pixel on the near side whose cost over *all* views (an occluder is seen by
   every view) exceeds ``edge_ratio`` x the far disparity's cost over the best wedge of views moves to the
   far side (a wedge rather than a half-plane, as the background in a concave pocket of an outline is
   hidden on two sides); a weighted median guided by the colour centre view snaps the depth edge to the
   colour edge; every band pixel then takes the side its own colour matches better over the views that see
   it (visibility from z-buffers of the map), and each pixel on the edge goes to the surface covering more
   than half of it (the pixel-centre convention of a ground truth), from the background's motion through
   it and its colour between its neighbours across the edge, both in linear light.

The disparity range (:func:`disparity_range`) comes from the caller, else the metadata
(:func:`metadata_disparity_range`), else a coarse search (:func:`estimate_disparity_range`), over
:data:`SEARCH_REFOCUS_MULTIPLE` x the refocusable range for a decoded plenoptic light field.
"""

from __future__ import annotations

import logging
import math
from typing import Any, Callable, Mapping

import cv2
import numpy as np

from ..types import LightField
from .aggregation import sgm, winner
from .confidence import estimate_confidence
from .cost import N_SECTORS, Progress, floor_less_margin, half_plane_cost_volume, make_labels
from .occlusion import EDGE_DEFAULTS, fix_occlusion_edges
from .refinement import cost_gate, refine_disparity, refine_radius_for, weighted_median
from .views import Views, add_contrast, colour_guide, noise_sigmas, prepare_views

log = logging.getLogger(__name__)

#: Matching-view parameters of :func:`run_pipeline` that every preset shares (see :func:`prepare_views`).
VIEW_DEFAULTS: dict[str, Any] = {
    "contrast_sigma": 1.5,    # local contrast normalisation of the views (Gaussian sigma, px; 0 = off)
    "contrast_eps": 0.005,    # floor of the normalisation's eps
    "contrast_noise": 3.0,    # eps = max(contrast_eps, this x the views' noise sigma); 0 = contrast_eps as given
    "contrast_smooth": 1.0,   # Gaussian sigma (px) smoothing the normalised views of noisy light fields ...
    "contrast_smooth_noise": 0.003,  # ... from 0 at this noise sigma to all of it at twice (contrast_smooth_for)
    "min_view_weight": 0.1,   # views with a lower decoder weight (relative to the centre view) are dropped
    "disparity_range": None,  # (lo, hi) px per view step; None = the metadata's, else estimated
}



def _check_range(r: Any, name: str) -> tuple[float, float]:
    try:
        lo, hi = (float(r[0]), float(r[1]))
    except (TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"{name} must be a pair (min, max) of numbers, got {r!r}") from exc
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"{name} must be finite with min < max, got {r!r}")
    return lo, hi


def metadata_disparity_range(metadata: Any) -> tuple[float, float] | None:
    """``disparity_range`` of a light field's geometry, else an HCI scene's ``[meta] disp_min / disp_max``;
    None if absent.

    ``metadata`` is a :class:`~plenodecode.types.LightFieldGeometry` (``lf.geometry``), ``lf.metadata`` or a
    legacy metadata dict (read by :meth:`LightFieldGeometry.coerce`).
    """
    from ..types import LightFieldGeometry

    geometry = LightFieldGeometry.coerce(metadata)
    if geometry.disparity_range is not None:
        return _check_range(geometry.disparity_range, "metadata['disparity_range']")
    if geometry.hci is not None and geometry.hci.disparity_range is not None:
        return _check_range(geometry.hci.disparity_range, "HCI disp_min/disp_max")
    return None


#: A decoded plenoptic light field's disparity search (when neither the caller nor the metadata gives one) spans
#: this many times its refocusable range (:func:`plenodecode.render.alpha.refocus_range`, Ng's exact range: the views
#: stay sharp within it, blur beyond; the real F01 shoe of ../shared/data reaches 1.5x).  Without it the search
#: spanned a quarter of the picture per view step (+-24 px/view on the F01) and a periodic texture's repeats
#: (the shoe's mesh) set the range to -9 .. 13 px/view: 211 labels instead of ~40, three times the time.
SEARCH_REFOCUS_MULTIPLE = 3.0


def plausible_disparity_reach(lf: LightField) -> float | None:
    """``SEARCH_REFOCUS_MULTIPLE`` x the upper end of the refocusable range (px per view step) of a decoded
    plenoptic light field (its lens footprint known); None for other light fields (HCI scenes, bare views)."""
    from ..render.alpha import lens_footprint_samples, refocus_range

    if lf.geometry.hci is not None or lens_footprint_samples(lf) is None:
        return None
    return SEARCH_REFOCUS_MULTIPLE * float(refocus_range(lf)[1])


def estimate_disparity_range(views: Views, *, max_abs: float | None = None, n_labels: int = 48,
                             margin: float = 0.15) -> tuple[float, float]:
    """Disparity range from a coarse search on 4x down-sampled views.

    Searches ``[-max_abs, max_abs]`` (default: a shift of at most a quarter of the image's smaller side at the
    outermost view; a given ``max_abs`` at most half of it), takes the 2nd and 98th percentiles of the confident
    per-pixel minima (the more confident half, a minimum on the first or last label excluded: there the cost ran
    off the search) and widens them by ``margin`` of the span (at least 0.25 px).

    Returns
    -------
    (float, float)
    """
    Y, X = views.data.shape[2:4]
    dv, du = views.offsets
    reach = float(max(np.abs(dv).max(), np.abs(du).max()))
    max_abs = 0.25 * min(Y, X) / reach if max_abs is None else min(float(max_abs), 0.5 * min(Y, X) / reach)
    f = 4 if min(Y, X) >= 64 else 1
    small = views.data[:, :, ::f, ::f] if f == 1 else _downsample(views.data, f)
    sv = Views(small, views.weight, views.centre)
    labels = np.linspace(-max_abs / f, max_abs / f, n_labels)
    cost = half_plane_cost_volume(sv, labels, radius=2)
    disp, conf = winner(cost, labels)
    inside = np.abs(disp) < labels[-1] - 0.5 * (labels[1] - labels[0])
    if inside.any():
        disp, conf = disp[inside], conf[inside]
    d = disp[conf > np.percentile(conf, 50)] * f
    if d.size == 0:
        d = disp.ravel() * f
    lo, hi = np.percentile(d, [2, 98])
    pad = max(0.25, margin * (hi - lo))
    log.info("estimated disparity range [%.2f, %.2f]", lo - pad, hi + pad)
    return float(lo - pad), float(hi + pad)


def _downsample(data: np.ndarray, f: int) -> np.ndarray:
    V, U, Y, X, C = data.shape
    out = np.empty((V, U, Y // f, X // f, C), np.float32)
    for v in range(V):
        for u in range(U):
            r = cv2.resize(data[v, u], (X // f, Y // f), interpolation=cv2.INTER_AREA)
            out[v, u] = r.reshape(Y // f, X // f, C)
    return out


def disparity_range(lf: LightField, views: Callable[[], Views], requested: Any = None
                    ) -> tuple[tuple[float, float], str]:
    """The search range: ``requested`` (``disparity_range=`` keyword), else the metadata, else estimated
    from the matching views ``views()`` builds (called only then).

    Returns
    -------
    ((lo, hi), source) with source in {'argument', 'metadata', 'estimated'}.
    """
    if requested is not None:
        return _check_range(requested, "disparity_range"), "argument"
    r = metadata_disparity_range(lf.geometry)
    if r is not None:
        return r, "metadata"
    return estimate_disparity_range(views(), max_abs=plausible_disparity_reach(lf)), "estimated"



#: Parameters of :func:`run_pipeline`: a preset (:mod:`plenodecode.depth.methods`) gives the method's own
#: ones, :data:`VIEW_DEFAULTS` and :data:`EDGE_DEFAULTS` the rest (:func:`preset_defaults`).
PIPELINE_KEYS = ("label_step", "radius", "p1", "p2", "edge_sigma", "paths", "median_radius", "refine_radius",
                 "refine_range", "refine_samples", "grey", "pattern", "contrast_sigma", "contrast_eps",
                 "contrast_noise", "contrast_smooth", "contrast_smooth_noise", "contrast_weight", "min_view_weight",
                 "disparity_range", "strips", "strip_width", "strip_halves",
                 "strip_radius", "strip_penalty", "refine_strip_penalty", "strip_penalty_noise", "refine_penalty_noise",
                 "strip_floor", "gate_ratio", "gate_floor", "gate_noise", "sgm_gate_ratio", "sgm_gate_floor",
                 "confidence_radius", "shift_noise", "refine_shift_noise", "shift_noise_rho", "radius_noisy",
                 "refine_radius_noisy", "p1_noisy_low", "gate_span_min",
                 "contrast_weight_noisy", *EDGE_DEFAULTS)


def merge_params(method: str, defaults: Mapping[str, Any], kw: Mapping[str, Any]) -> dict[str, Any]:
    """``{**defaults, **kw}``; ValueError naming the parameters of ``kw`` that ``defaults`` does not have."""
    unknown = set(kw) - set(defaults)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)} for method {method!r}; valid: {sorted(defaults)}")
    return {**defaults, **kw}


def preset_defaults(preset: Mapping[str, Any]) -> dict[str, Any]:
    """Every parameter of :func:`run_pipeline`: a method's preset, then :data:`VIEW_DEFAULTS` and
    :data:`EDGE_DEFAULTS`."""
    return {**preset, **VIEW_DEFAULTS, **EDGE_DEFAULTS}


def check_params(method: str, defaults: Mapping[str, Any], kw: Mapping[str, Any]) -> dict[str, Any]:
    """Merge keywords into the defaults (:func:`merge_params`); ValueError naming an unknown or invalid
    parameter."""
    p = merge_params(method, defaults, kw)
    for name in ("label_step", "p1", "p2", "edge_sigma", "refine_range", "contrast_eps", "p1_noisy_low"):
        if not float(p[name]) > 0:
            raise ValueError(f"{name} must be positive, got {p[name]!r}")
    for name in ("contrast_sigma", "contrast_noise", "contrast_smooth", "contrast_smooth_noise"):
        if not float(p[name]) >= 0:
            raise ValueError(f"{name} must be >= 0, got {p[name]!r}")
    if p["contrast_weight_noisy"] is not None and not float(p["contrast_weight_noisy"]) > 0:
        raise ValueError(f"contrast_weight_noisy must be positive or None, got {p['contrast_weight_noisy']!r}")
    if p["contrast_weight"] is not None and not float(p["contrast_weight"]) > 0:
        raise ValueError(f"contrast_weight must be positive or None, got {p['contrast_weight']!r}")
    if not 1 <= int(p["edge_wedge"]) <= N_SECTORS:
        raise ValueError(f"edge_wedge must be a number of sectors in [1, {N_SECTORS}], got {p['edge_wedge']!r}")
    if not float(p["edge_jump"]) > 0 or not float(p["edge_ratio"]) > 0:
        raise ValueError(f"edge_jump and edge_ratio must be positive, got edge_jump={p['edge_jump']!r}, "
                         f"edge_ratio={p['edge_ratio']!r}")
    for name in ("radius", "median_radius", "refine_radius", "edge_radius", "edge_median_radius", "confidence_radius",
                 "radius_noisy", "refine_radius_noisy"):
        if name == "refine_radius" and p[name] == "auto":
            continue
        if int(p[name]) < 0:
            raise ValueError(f"{name} must be >= 0 (or 'auto' for refine_radius), got {p[name]!r}")
    for name in ("edge_visibility", "edge_coverage", "strip_halves"):
        if not isinstance(p[name], (bool, np.bool_)):
            raise ValueError(f"{name} must be True or False, got {p[name]!r}")
    for name in ("strip_width", "strip_penalty", "refine_strip_penalty"):
        if not float(p[name]) > 0:
            raise ValueError(f"{name} must be positive, got {p[name]!r}")
    for name in ("shift_noise", "refine_shift_noise", "strips", "strip_radius", "strip_penalty_noise",
                 "refine_penalty_noise", "strip_floor",
                 "gate_ratio", "gate_noise",
                 "gate_floor", "sgm_gate_ratio", "sgm_gate_floor"):
        if not float(p[name]) >= 0:
            raise ValueError(f"{name} must be >= 0, got {p[name]!r}")
    rho = p["shift_noise_rho"]
    if not (isinstance(rho, (tuple, list)) and len(rho) == 2 and all(0.0 <= float(r) < 1.0 for r in rho)):
        raise ValueError(f"shift_noise_rho must be a pair (along y, along x) in [0, 1), got {rho!r}")
    if int(p["refine_samples"]) < 3:
        raise ValueError(f"refine_samples must be >= 3, got {p['refine_samples']!r}")
    return p


#: Views count as noisy for ``p1_noisy_low`` where the noise of the pixels that match (``sigma_low`` of
#: :func:`~plenodecode.depth.views.noise_sigmas`) is above this x ``contrast_smooth_noise`` (0.0045: between the
#: noise-free thin scenes' 0.0004-0.0032 and the decoded thin raws' 0.0057-0.0114).
NOISY_LOW = 1.5


def strip_penalty_for(penalty: float, reference_noise: float, noise: float) -> float:
    """A strip penalty (``strip_penalty`` or ``refine_strip_penalty``) for views of noise ``noise``::

        penalty * clip(reference_noise / noise, MIN_PENALTY_FRACTION, 1)

    The strips win where ``penalty x`` their mean squared error is below the half-planes'; noise puts a floor
    of ``2 sigma^2`` under both, so the ratio a strip can reach shrinks as the noise grows.  ``penalty`` holds
    up to ``reference_noise`` (0: always) and falls as ``1 / noise`` above it, to no less than
    :data:`MIN_PENALTY_FRACTION` of it: a strip averages fewer views than a half-plane and fits strong noise
    (on a 64 px test scene with noise 0.03 BadPix0.07 was 4.3 % at a quarter of 16, 12.8 % at 1.4, when the
    floor was set; today 0.22 % at a quarter, 0.16 % at 0.15).  On the decoded thin scenes (sigma 0.006-0.015)
    the cost volume's strips then keep 4-6 points more of BadPix0.07 than with a fixed 8, and the floor of 0.15
    instead of a quarter 0.4 more (means 28.16 -> 27.76 %; their ideal light fields 9.92 -> 9.77 %).

    Parameters
    ----------
    penalty : float
        The penalty on clean views.
    reference_noise : float
        Noise sigma (views' intensity scale) up to which ``penalty`` holds; 0 = always.
    noise : float
        The views' noise sigma (:func:`~plenodecode.depth.views.noise_sigma`).

    Returns
    -------
    float
    """
    if reference_noise > 0 and noise > reference_noise:
        return penalty * max(MIN_PENALTY_FRACTION, reference_noise / noise)
    return penalty


def contrast_smooth_for(smooth: float, reference_noise: float, noise: float) -> float:
    """The Gaussian sigma (px) that smooths the local contrast normalisation of views of noise ``noise``::

        smooth * clip(noise / reference_noise - 1, 0, 1)

    none up to ``reference_noise``, all of ``smooth`` from twice it (``reference_noise`` 0: always all).  The
    normalisation lifts the noise of flat areas, whose averaging by the shifts' interpolation pulls the
    cost's minimum off the true disparity (:func:`~plenodecode.depth.views.local_contrast`); noise-free
    views keep their fine texture (on hci-antinous, noise sigma 0.0017, a smoothing of 1 px raised
    BadPix0.07 from 4.0 to 7.2 %).
    """
    if not smooth > 0:
        return 0.0
    if not reference_noise > 0:
        return float(smooth)
    return float(smooth) * min(1.0, max(0.0, noise / reference_noise - 1.0))


def shift_noise_var(factor: float, reference_noise: float, noise: float) -> float:
    """``factor * noise^2`` above ``reference_noise`` (ramped in up to twice it as :func:`contrast_smooth_for`),
    0 below; the ``noise_var`` of :func:`~plenodecode.depth.cost.half_plane_cost_volume`."""
    if not factor > 0 or not noise > 0:
        return 0.0
    return float(factor) * contrast_smooth_for(1.0, reference_noise, noise) * noise * noise


def strip_floor_for(factor: float, reference_noise: float, noise_low: float, channels: int) -> float:
    """The ``strip_floor`` of :func:`~plenodecode.depth.cost.half_plane_cost_volume`: the mean error per view
    of views that differ by noise only, above which a strip's penalty applies::

        factor * ramp * 2 sigma_low^2 * channels,   ramp = clip(sigma_low / reference_noise - 1, 0, 1)

    ``sigma_low`` is the noise read on the pixels that match (:func:`~plenodecode.depth.views.noise_sigmas`),
    not lifted by the edges of thin structures, and ``ramp`` that of :func:`contrast_smooth_for`.  On clean
    views ``sigma_low`` is what a bilinear shift cannot reproduce of fine texture, which the bicubic refinement
    does: there a floor of that size made the refinement's strips win a plane's sub-pixel minimum (a textured
    plane at 0.8, sigma_low 0.0027: median error 0.013 -> 0.022 px at a floor of 1e-6), so it is ramped in
    from ``reference_noise`` on (hci-antinous 0.0013, the noise-free thin scenes 0.0004-0.0032, their decoded
    versions 0.006-0.011).
    """
    if not factor > 0 or not noise_low > 0:
        return 0.0
    return float(factor) * contrast_smooth_for(1.0, reference_noise, noise_low) * 2.0 * noise_low * noise_low * channels


def edge_floor_for(strip_floor: float, n_views: int, wedge: int) -> float:
    """The ``noise_floor`` of :func:`~plenodecode.depth.occlusion.fix_occlusion_edges`' visibility check::

        strip_floor * max(0, 1 - FLOOR_MARGIN * floor_standard_error(n_views * wedge / N_SECTORS, 9))

    the strips' floor (:func:`strip_floor_for`, the intensity channel's share of the matching views' error)
    less the margin of the smaller of its two costs, the wedge's mean over 3 x 3 pixels
    (:func:`~plenodecode.depth.cost.floor_less_margin`).
    """
    if not strip_floor > 0 or n_views < 1:
        return 0.0
    n = max(1.0, n_views * wedge / N_SECTORS)
    return floor_less_margin(strip_floor, n, 9)


#: The quantile (%) of the per-pixel minimum of the matching cost that :func:`gate_base_for` reads.
GATE_BASE_QUANTILE = 10.0


def gate_base_for(cost: np.ndarray, factor: float, reference_noise: float, noise_low: float) -> float:
    """The ``base`` of :func:`~plenodecode.depth.refinement.cost_gate`: the matching cost that noise alone
    leaves at the best label, which the gate's ratio does not scale::

        factor * ramp * P10( min_d C(p, d) ),   ramp = clip(sigma_low / reference_noise - 1, 0, 1)

    the 10th percentile (:data:`GATE_BASE_QUANTILE`) over the pixels (every other row and column) of the
    normalised cost volume's per-pixel minimum, ``sigma_low`` and ``ramp`` as :func:`strip_floor_for`.  On noisy
    views every label's cost sits on that floor, so a ratio of two costs stays near 1 and the gate let the
    weighted median move weakly textured far pixels between thin slats to the slats' disparity.
    """
    if not factor > 0 or not noise_low > 0:
        return 0.0
    ramp = contrast_smooth_for(1.0, reference_noise, noise_low)
    if not ramp > 0:
        return 0.0
    floor = float(np.percentile(cost[::2, ::2].min(axis=-1), GATE_BASE_QUANTILE))
    return float(factor) * ramp * max(0.0, floor)


#: The lowest fraction of a strip penalty that :func:`strip_penalty_for` lowers it to.
MIN_PENALTY_FRACTION = 0.15


def run_pipeline(lf: LightField, p: Mapping[str, Any], *, progress: Progress = None
                 ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Matching views -> cost volume -> SGM -> winner -> weighted median -> per-pixel refinement ->
    occlusion edges (the steps and their references are in the module docstring).

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32.
    p : mapping
        Every key of :data:`PIPELINE_KEYS`, checked (:func:`check_params`).
    progress : callable(done, total), optional
        Called per cost-volume label, per SGM path and per refinement offset.

    Returns
    -------
    disparity : ndarray (Y, X) float32
        px per view step, HCI sign convention.
    confidence : ndarray (Y, X) float32 in [0, 1]
    params : dict
        The parameters used, with the disparity range and its source, the views' noise and the contrast
        ``eps`` and weight used (``contrast_weight_used``), the strip penalties used (``strip_penalty_used``,
        ``refine_strip_penalty_used``: :func:`strip_penalty_for`), the cost volumes' ``noise_var``
        (``shift_noise_var_used``: :func:`shift_noise_var`), the noise of the matching pixels
        (``noise_sigma_low``: :func:`~plenodecode.depth.views.noise_sigmas`), the strips' noise floor
        (``strip_floor_used``: :func:`strip_floor_for`) and the cost gate's base (``gate_base_used``:
        :func:`gate_base_for`), the box radii used, the number of labels and of views.
    """
    plain = prepare_views(lf, min_view_weight=float(p["min_view_weight"]), grey=bool(p["grey"]),
                          pattern=p["pattern"])
    sigma, floor, k = float(p["contrast_sigma"]), float(p["contrast_eps"]), float(p["contrast_noise"])
    weight = None if p["contrast_weight"] is None else float(p["contrast_weight"])
    built: dict[tuple[float, float, float | None], Views] = {}

    def matching_views(eps: float, smooth: float = 0.0, w: float | None = weight) -> Views:
        if (eps, smooth, w) not in built:
            built[eps, smooth, w] = add_contrast(plain, sigma, eps, w, smooth) if sigma > 0 else plain
        return built[eps, smooth, w]

    (lo, hi), source = disparity_range(lf, lambda: matching_views(floor), p["disparity_range"])
    noise, noise_low, eps, smooth = 0.0, 0.0, floor, 0.0
    if sigma > 0 and (k > 0 or float(p["contrast_smooth"]) > 0):
        # the normalisation's floor above the noise, so that noise in flat areas is not matched as texture,
        # and its smoothing on noisy views
        noise, noise_low = noise_sigmas(plain, lo, hi)
        eps = max(floor, k * noise) if k > 0 else floor
        smooth = contrast_smooth_for(float(p["contrast_smooth"]), float(p["contrast_smooth_noise"]), noise)
        if weight is not None and p["contrast_weight_noisy"] is not None:
            # noisy views: less weight on the normalised channel, which lifts noise towards texture
            ramp = contrast_smooth_for(1.0, float(p["contrast_smooth_noise"]), noise)
            weight = (1.0 - ramp) * weight + ramp * float(p["contrast_weight_noisy"])
        log.info("view noise sigma %.4f: contrast eps %.4f, smoothing %.2f px, weight %.3f", noise, eps, smooth,
                 float("nan") if weight is None else weight)
    views = matching_views(eps, smooth, weight)
    # the intensity-only views stay alive for the edge pass's relabel only when it runs
    intensities = plain if (p["edge_visibility"] or p["edge_coverage"]) and int(p["edge_radius"]) > 0 else None
    del plain, built
    step = float(p["label_step"])
    labels = make_labels(lo, hi, step, pad=2 * step)
    n_labels, n_paths = len(labels), int(p["paths"])
    refine_radius = refine_radius_for(lf.shape[2:4], p["refine_radius"])
    if refine_radius > 0 and noise > float(p["contrast_smooth_noise"]) > 0:
        # noisy views: a longer refinement box averages the noise (never shorter than the size's own)
        refine_radius = max(refine_radius, int(p["refine_radius_noisy"]))
    n_refine = int(p["refine_samples"]) if refine_radius > 0 else 0
    total = n_labels + n_paths + n_refine

    def stage(offset: int) -> Progress:
        if progress is None:
            return None
        return lambda done, _n: progress(offset + done, total)

    log.info("cost volume: %d labels in [%.2f, %.2f] (%s), %d views", n_labels, labels[0], labels[-1], source,
             len(views.used()) + 1)
    strips = {"strips": int(p["strips"]), "strip_width": float(p["strip_width"]),
              "strip_radius": int(p["strip_radius"]),
              "strip_penalty": strip_penalty_for(float(p["strip_penalty"]), float(p["strip_penalty_noise"]), noise),
              # strips match the intensities only, not the contrast channels stacked beside them (cost.py)
              "strip_channels": views.data.shape[-1] // 2 if sigma > 0 and weight is not None else None,
              "noise_var": shift_noise_var(float(p["shift_noise"]), float(p["contrast_smooth_noise"]), noise),
              "noise_rho": (float(p["shift_noise_rho"][0]), float(p["shift_noise_rho"][1]))}
    n_strip = strips["strip_channels"] or views.data.shape[-1]
    strips["strip_floor"] = strip_floor_for(float(p["strip_floor"]), float(p["contrast_smooth_noise"]), noise_low,
                                            n_strip)
    radius, p1 = int(p["radius"]), float(p["p1"])
    if noise > 2 * float(p["contrast_smooth_noise"]) > 0:
        # clearly noisy views: a larger box averages the noise (a textured noise-free light field can measure
        # up to ~0.004: the 45 x 58 px slats-v-j1-weak scene of the tests, 9.6 -> 14.0 % with radius 3)
        radius = max(radius, int(p["radius_noisy"]))
    if noise_low > NOISY_LOW * float(p["contrast_smooth_noise"]) > 0:
        p1 = max(p1, float(p["p1_noisy_low"]))
    cost = half_plane_cost_volume(views, labels, radius=radius, progress=stage(0), **strips,
                                  halve_strips=bool(p["strip_halves"]))
    sub = cost[::4, ::4]
    span = float(np.median(sub.max(axis=-1) - sub.min(axis=-1)))
    cost *= np.float32(1.0 / max(span, 1e-12))
    guide = views.guide()
    agg = sgm(cost, guide, p1=p1, p2=float(p["p2"]), sigma=float(p["edge_sigma"]), paths=n_paths,
              progress=stage(n_labels))
    disparity, peak_ratio = winner(agg, labels)
    del agg
    own_span = None
    if float(p["gate_span_min"]) > 0:      # the gates' floors scale with each pixel's own cost span (Y, X)
        own_span = np.clip(cost.max(axis=-1) - cost.min(axis=-1), float(p["gate_span_min"]), 1.0).astype(np.float32)
    gate_base = gate_base_for(cost, float(p["gate_noise"]), float(p["contrast_smooth_noise"]), noise_low)

    def gated(before: np.ndarray, after: np.ndarray, ratio: float = float(p["gate_ratio"]),
              floor: float = float(p["gate_floor"])) -> np.ndarray:
        # a step's result, except where the matching cost clearly prefers the value before it (ratio 0: off)
        if not ratio > 0:
            return after
        if own_span is not None:
            floor = floor * own_span
        return cost_gate(cost, labels, before, after, ratio=ratio, floor=floor, base=gate_base)

    # SGM's penalties, in units of the median cost span, outweigh the small cost span of a weakly textured far
    # plane seen through a slit: where the views clearly prefer their own winner, it stays
    if float(p["sgm_gate_ratio"]) > 0:
        disparity = gated(winner(cost, labels)[0], disparity, float(p["sgm_gate_ratio"]), float(p["sgm_gate_floor"]))
    disparity = gated(disparity, weighted_median(guide, disparity, int(p["median_radius"])))
    refine_penalty = strip_penalty_for(float(p["refine_strip_penalty"]), float(p["refine_penalty_noise"]), noise)
    # the refinement's bicubic offsets average the noise of the views at their real variance, which noise_sigma
    # underestimates on decoded views (see refine_shift_noise); at least that of the pixels that match
    refine_noise_var = max(strips["noise_var"], shift_noise_var(float(p["refine_shift_noise"]),
                                                                float(p["contrast_smooth_noise"]), noise_low))
    if n_refine:
        log.info("refinement strip penalty %.2f (view noise sigma %.4f)", refine_penalty, noise)
        disparity = refine_disparity(views, disparity, half_range=float(p["refine_range"]) * step,
                                     samples=n_refine, radius=refine_radius, progress=stage(n_labels + n_paths),
                                     **{**strips, "strip_radius": max(strips["strip_radius"], refine_radius),
                                        "strip_penalty": refine_penalty,
                                        "noise_var": refine_noise_var,
                                        "noise_weighted": True})
    if int(p["edge_radius"]) > 0:
        disparity = fix_occlusion_edges(views, disparity, colour_guide(lf), radius=int(p["edge_radius"]),
                                        jump=float(p["edge_jump"]), ratio=float(p["edge_ratio"]),
                                        wedge=int(p["edge_wedge"]), median_radius=int(p["edge_median_radius"]),
                                        intensities=intensities, visibility=bool(p["edge_visibility"]),
                                        coverage=bool(p["edge_coverage"]), gate=gated,
                                        noise_floor=edge_floor_for(strips["strip_floor"], len(views.used()),
                                                                   int(p["edge_wedge"])))
    # confidence at the final disparity: the view agreement of the map after the occlusion step, so a pixel the
    # edge pass moved to the far side is judged by the views that see it there, and its consistency with the
    # winner of the matching cost (low where the steps after the matching moved it off its own views' choice)
    valid = None if lf.weight is None else np.asarray(lf.weight[views.centre]) > 0
    confidence = estimate_confidence(views, peak_ratio, disparity, radius=int(p["confidence_radius"]), valid=valid,
                                     cost=cost, labels=labels)
    del cost
    params = {**p, "radius": radius, "p1": p1, "refine_radius": refine_radius,
              "disparity_range": [float(lo), float(hi)],
              "noise_sigma": noise, "contrast_eps_used": eps, "contrast_weight_used": weight,
              "contrast_smooth_used": smooth,
              "strip_penalty_used": strips["strip_penalty"], "shift_noise_var_used": strips["noise_var"],
              "noise_sigma_low": noise_low, "strip_floor_used": strips["strip_floor"], "gate_base_used": gate_base,
              "refine_strip_penalty_used": refine_penalty,
              "disparity_range_source": source, "n_labels": n_labels, "views_used": len(views.used()) + 1}
    return disparity.astype(np.float32), confidence, params


def run_preset(lf: LightField, method: str, preset: Mapping[str, Any], /, *, progress: Progress = None,
               **params: Any) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """:func:`run_pipeline` with a method's preset (:func:`preset_defaults`) and the caller's ``params``.

    Parameters
    ----------
    lf : LightField
    method : str
        The preset's name, for error messages.
    preset : mapping
        The method's own parameters (:mod:`plenodecode.depth.methods`).
    progress : callable(done, total), optional
    **params
        Any key of :data:`PIPELINE_KEYS`, overriding the defaults.

    Returns
    -------
    As :func:`run_pipeline`.
    """
    p = check_params(method, preset_defaults(preset), params)
    return run_pipeline(lf, p, progress=progress)


__all__ = ["VIEW_DEFAULTS", "PIPELINE_KEYS", "metadata_disparity_range", "estimate_disparity_range",
           "disparity_range", "strip_penalty_for", "contrast_smooth_for", "shift_noise_var", "strip_floor_for",
           "gate_base_for", "edge_floor_for", "merge_params", "preset_defaults", "check_params",
           "run_pipeline", "run_preset"]
