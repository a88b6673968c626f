"""What a product asks of the input's metadata, checked as soon as the input is read (before the calibration,
which may self-calibrate for seconds, and before any decoding).

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps): :func:`~plenodecode.pipeline.
open_source` runs :func:`check_product` between step 1 (read) and step 2 (calibrate); :func:`~plenodecode.
pipeline.render_product` runs it again for a :class:`~plenodecode.pipeline.Source` made by hand; a batch runs it
on every raw before calibrating it.

Three requests need metadata (:data:`REQUESTS`):

* 'alpha': Ng's relative film depth, turned into a slope by :func:`plenodecode.render.alpha.alpha_to_slope`
  with the camera constants of :data:`~plenodecode.render.alpha.REFOCUS_CONSTANTS` ('refocus' with
  ``alpha=``, 'focal-stack' with ``units='alpha'``);
* 'distance': a focus distance in metres, turned into a slope by
  :func:`~plenodecode.render.alpha.distance_to_slope` ('refocus' with ``focus_distance=``): the same constants and
  the camera's own focus distance; it does not apply to a light-field microscope;
* 'metric': metric depth (:func:`plenodecode.depth.metric.depth_constants`; 'depth' with ``metric`` or
  ``points``, ``focus_distance`` standing in for the camera's); never for a focused-plenoptic (Raytrix) raw,
  whose depth is virtual depth (:data:`FOCUSED_NOT_METRIC`).

A light field rectified by a geometric calibration takes its metric geometry from the calibration, so
'distance' and 'metric' are not checked against the camera's metadata then (``rectified=True``).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable, Mapping

from ..errors import MetadataError, MissingConstantsError
from ..types import LightField, RawCapture


def _refocus_request(options: Mapping[str, Any]) -> tuple[str, str] | None:
    if options.get("alpha") is not None:
        return "alpha", "alpha"
    return ("focus_distance", "distance") if options.get("focus_distance") is not None else None


def _stack_request(options: Mapping[str, Any]) -> tuple[str, str] | None:
    return ("units", "alpha") if options.get("units") == "alpha" else None


def _depth_request(options: Mapping[str, Any]) -> tuple[str, str] | None:
    for keyword in ("metric", "points"):
        if options.get(keyword):
            return keyword, "metric"
    return None


#: Product -> ``fn(options) -> (the keyword that asks, what it asks: 'alpha', 'distance' or 'metric')``, or
#: None when the options ask nothing of the metadata: every place where the workflow turns an alpha or a
#: distance into a slope (:func:`~plenodecode.render.refocus_methods.focus_slope`, the 'alpha' entry of
#: :data:`~plenodecode.pipeline.products.STACK_UNITS`) or a disparity into metres.
REQUESTS: dict[str, Callable[[Mapping[str, Any]], tuple[str, str] | None]] = {
    "refocus": _refocus_request,
    "photo": _refocus_request,
    "focal-stack": _stack_request,
    "depth": _depth_request,
}

#: What to use instead, per keyword that asks for a conversion to a slope (library spelling; the CLI names its
#: own options).
INSTEAD = {"alpha": "refocus by slope instead", "units": "give START and STOP as slopes (units='slope')",
           "focus_distance": "refocus by slope instead"}


def _name(item: LightField | RawCapture) -> str:
    """The file name of the input, as an error message names it."""
    path = item.path if isinstance(item, RawCapture) else item.geometry.source
    return Path(path).name if path else ("the raw" if isinstance(item, RawCapture) else "the light field")


def _decoded_geometry(item: LightField | RawCapture) -> Any:
    """Something with the ``.geometry`` the input will have once decoded (:mod:`plenodecode.depth.metric` reads
    it): a light field's own; for a raw :func:`~plenodecode.render.alpha.decoded_geometry_stand_in`."""
    if isinstance(item, LightField):
        return item
    from ..render.alpha import decoded_geometry_stand_in

    return SimpleNamespace(geometry=decoded_geometry_stand_in(item.metadata))


#: What each request needs the constants for, as messages say it.
NEEDS = {"alpha": "alpha (Ng's film depth -> slope)", "distance": "a focus distance (metres -> slope)",
         "metric": "metric depth"}

#: Why a light-field microscope (its optics known) has no alpha, as a focus distance does not apply to it
#: (:func:`plenodecode.render.alpha.distance_to_slope`); the error's ``instead`` says to refocus by slope.
MICROSCOPE_NO_ALPHA = (f"{NEEDS['alpha']} does not apply to a light-field microscope (no main lens focused at a "
                       "distance: its depth is measured from the native object plane)")


def _missing(item: LightField | RawCapture, need: str, options: Mapping[str, Any]
             ) -> tuple[str, tuple[str, ...], bool] | None:
    """Why ``item`` cannot serve the request ``need`` of :data:`NEEDS`, the constants missing (empty when
    the reason names the options that supply them) and whether a slope serves instead (:data:`INSTEAD`); None
    when it can.

    Alpha asks :func:`~plenodecode.render.alpha.missing_refocus_constants`; a distance or metric depth of a
    camera also asks its focus distance, and anything else is tried on the decoded geometry's stand-in
    (:func:`~plenodecode.render.alpha.distance_to_slope`, :func:`~plenodecode.depth.metric.depth_constants`).
    Only a missing constant counts (a MetadataError): bad values are reported where they are used, with the
    real sampling.
    """
    from ..depth.metric import depth_constants, depth_model
    from ..render.alpha import distance_to_slope, missing_refocus_constants

    stand_in = _decoded_geometry(item)
    overrides = {} if options.get("focus_distance") is None else {"focus_distance_m": options["focus_distance"]}
    model = depth_model(stand_in, overrides)
    if need == "alpha" and model == "microscope":      # its constants would not help: there is no main lens
        return MICROSCOPE_NO_ALPHA, (), True
    camera = need == "alpha" or model == "plenoptic"
    missing = missing_refocus_constants(stand_in.geometry) if camera else ()
    if missing:
        return (f"{NEEDS[need]} needs the camera constant{'s' * (len(missing) > 1)} {', '.join(missing)}, which its "
                "metadata does not have"), missing, True
    if need == "alpha":
        return None
    try:
        if need == "distance":
            distance_to_slope(1.0, stand_in.geometry)
        else:
            depth_constants(stand_in, **overrides)
    except MetadataError as exc:
        if camera:
            return (f"{NEEDS[need]} needs the distance the camera was focused at (focus_distance_m, or "
                    "infinityLambda and the MLA-sensor gap), which its metadata does not have", ("focus_distance_m",),
                    True)
        return str(exc), (), False
    except ValueError:
        return None
    return None


def check_focus_distance(item: LightField | RawCapture, focus_distance_m: float | None) -> None:
    """Refuse, before decoding, a focus distance given for a plenoptic camera's metric depth that is not beyond
    its main lens's focal length (no image forms there: :func:`plenodecode.depth.metric.plenoptic_constants` would
    fail after the whole depth estimate).  ValueError saying both lengths; None passes."""
    from ..depth.metric import depth_model

    if focus_distance_m is None:
        return
    stand_in = _decoded_geometry(item)
    f = getattr(stand_in.geometry, "focal_length_m", None)
    if f is None or depth_model(stand_in, {"focus_distance_m": focus_distance_m}) != "plenoptic":
        return
    if focus_distance_m <= f:
        raise ValueError(f"{focus_distance_m:g} m is not beyond the main lens's focal length ({f * 1000:.3g} mm) of "
                         f"{_name(item)}: give the distance the camera was focused at, in metres")


#: Why a focused-plenoptic raw's depth stays in virtual depth (:func:`check_product`).
FOCUSED_NOT_METRIC = ("a focused-plenoptic (Raytrix) raw's depth is virtual depth (v = a / B): metres need the main "
                      "lens and the MLA-sensor distance B, which its RayCalibData does not hold; write virtual depth "
                      "instead (without --metric and --ply)")


#: Why a focused-plenoptic (Raytrix) raw has no alpha or focus distance (:func:`check_product`), and what to do.
FOCUSED_NO_FOCUS_CONSTANTS = ("{need} needs the main lens and the MLA-sensor distance, which a focused-plenoptic "
                              "(Raytrix) raw's RayCalibData does not hold; refocus it at a virtual depth "
                              "('plenodecode refocus {raw} --virtual-depth V'), or its views (one pixel per lens) by "
                              "slope (--slope S --views-anyway)")


def is_focused_raw(item: LightField | RawCapture) -> bool:
    """True for a raw read with a Raytrix RayCalibData that has lens types (its grid will have them:
    :attr:`~plenodecode.pipeline.Source.focused`), known before calibrating."""
    if not isinstance(item, RawCapture) or item.metadata is None:
        return False
    cal = (item.metadata.extra or {}).get("raytrix")
    return isinstance(cal, Mapping) and bool(cal.get("lens_types"))


def check_product(item: LightField | RawCapture, name: str, *, rectified: bool = False, focused: bool | None = None,
                  **options: Any) -> None:
    """Refuse a product request that the input's metadata cannot serve, without calibrating or decoding.

    Parameters
    ----------
    item : RawCapture or LightField
        The input as read (a raw's :class:`~plenodecode.types.CameraMetadata` stands for the light field it
        decodes to: :func:`_decoded_geometry`).
    name : str
        A product of :data:`~plenodecode.pipeline.PRODUCTS` (products that ask nothing of the metadata pass).
    rectified : bool
        The light field will be rectified by a geometric calibration, which gives the metric geometry (a focus
        distance and metric depth are then not checked against the camera's metadata).
    focused : bool, optional
        The input is a focused-plenoptic raw: its grid has lens types (:attr:`~plenodecode.pipeline.Source.focused`,
        also with a grid given by hand); None: as its metadata says (:func:`is_focused_raw`).
    **options
        The product's options, as :func:`~plenodecode.pipeline.render_product` takes them.

    Raises
    ------
    MissingConstantsError
        ``keyword`` names the option that asked (:data:`REQUESTS`), ``missing`` the constants not found (empty
        when the message names the options that supply them, e.g. a microscope's optics), ``need`` what needs
        them (:data:`NEEDS`).
    """
    request = REQUESTS.get(name)
    asked = request(options) if request is not None else None
    if asked is None:
        return
    keyword, need = asked
    if need == "metric" and (is_focused_raw(item) if focused is None else focused):
        failure: tuple[str, tuple[str, ...], bool] | None = (FOCUSED_NOT_METRIC, (), False)
    else:
        failure = None if (rectified and need != "alpha") else _missing(item, need, options)
    if failure is not None:
        why, missing, by_slope = failure
        source = _name(item)
        if missing and need != "metric" and (is_focused_raw(item) if focused is None else focused):
            # 'refocus by slope' alone would send a Raytrix raw to the views its commands refuse
            why, missing, by_slope = FOCUSED_NO_FOCUS_CONSTANTS.format(need=NEEDS[need], raw=source), (), False
        instead = INSTEAD.get(keyword) if by_slope else None
        raise MissingConstantsError(f"{source}: {why}" + (f"; {instead}" if instead else ""), keyword=keyword,
                                    missing=missing, source=source, need=NEEDS[need], reason=why, instead=instead)


__all__ = ["NEEDS", "MICROSCOPE_NO_ALPHA", "REQUESTS", "FOCUSED_NOT_METRIC", "FOCUSED_NO_FOCUS_CONSTANTS",
           "check_product", "is_focused_raw"]
