"""Step 4 of the workflow: the named products (:data:`PRODUCTS`) rendered from a :class:`Source`.

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from ..registry import lazy, lookup
from ..types import LensletGrid, LightField, RawCapture
from .inputs import Progress
from .needs import check_product
from .source import Source

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Rendered:
    """A rendered product, before writing.

    Attributes
    ----------
    product : str
        Its key in :data:`PRODUCTS`.
    images : sequence of (str, ndarray)
        File stem and image (H, W, C) float32 of every image; one for single-image products.  A folder of many
        images may render each one when it is read (:class:`ViewImages`).
    colour : str
        Colour state of the images (:data:`~plenodecode.types.COLOUR_STATES`); decides the display encoding.
    folder : bool
        The product is a folder of images (and ``documents``), not one file.
    documents : tuple of (str, callable)
        JSON files written beside the images: file name and ``fn(ext) -> mapping``, the content given the
        image type the images are written as (documents list the image files).
    data : mapping
        Other results (depth map, animation frames, slopes, ...).
    """

    product: str
    images: Sequence[tuple[str, Any]]
    colour: str
    folder: bool = False
    documents: tuple[tuple[str, Callable[[str], Mapping[str, Any]]], ...] = ()
    data: Mapping[str, Any] = field(default_factory=dict)

    def file_names(self, ext: str) -> list[str]:
        """The names written into a folder product: images ``<stem>.<ext>``, then the documents."""
        stems = self.images.stems if isinstance(self.images, ViewImages) else [stem for stem, _ in self.images]
        return [f"{stem}.{ext}" for stem in stems] + [name for name, _ in self.documents]


class ViewImages(Sequence):
    """Every view of a light field as ``(view_VV_UU, image)`` pairs, each image rendered by
    :func:`plenodecode.render.perspective` when it is read: a folder of views costs one view's memory at a time,
    not a copy of the light field.  A view partly outside the micro-images (data in fewer than
    :data:`~plenodecode.imaging.MIN_VIEW_DATA` of its samples, :func:`~plenodecode.imaging.view_data_share`) is
    black: it would show the lenses' edges and the gaps between them as stripes and holes.  ``dark`` lists them."""

    def __init__(self, lf: LightField) -> None:
        import numpy as np

        from ..imaging import MIN_VIEW_DATA, view_data_share

        self.lf = lf
        self.stems = view_names(lf.shape)
        share = np.ones(lf.shape[:2]) if lf.weight is None else view_data_share(lf.weight)
        self.dark = [(int(v), int(u)) for v, u in zip(*np.nonzero(share < MIN_VIEW_DATA))]

    def __len__(self) -> int:
        return len(self.stems)

    def __getitem__(self, i: int) -> tuple[str, Any]:
        import numpy as np

        from ..render import perspective

        nu = self.lf.shape[1]
        k = range(len(self))[i]
        if (k // nu, k % nu) in self.dark:
            return self.stems[k], np.zeros(self.lf.shape[2:], self.lf.data.dtype)
        return self.stems[k], perspective(self.lf, k // nu, k % nu)


def render_centre(src: Source) -> Rendered:
    """The centre view ``(V // 2, U // 2)`` (:func:`plenodecode.render.perspective`: its edge gaps filled), image
    (Y, X, C)."""
    from ..render import perspective

    lf = src.lightfield
    return Rendered("centre", (("centre", perspective(lf, *lf.centre_index)),), lf.colour)


def view_names(shape: Sequence[int]) -> list[str]:
    """File stems of all views of a light field of ``shape`` (V, U, ...): ``view_VV_UU``."""
    return [f"view_{v:02d}_{u:02d}" for v in range(shape[0]) for u in range(shape[1])]


def render_views(src: Source, *, view: tuple[float, float] | None = None, interp: str = "linear") -> Rendered:
    """Every sub-aperture view (a folder of ``view_VV_UU`` images), or with ``view=(v, u)`` the perspective view
    at that (fractional) position; both by :func:`plenodecode.render.perspective` (``interp`` 'linear' or
    'cubic'), which fills the views' edge gaps."""
    from ..render import perspective

    lf = src.lightfield
    if view is not None:
        return Rendered("views", (("view", perspective(lf, view[0], view[1], interp=interp)),), lf.colour)
    return Rendered("views", ViewImages(lf), lf.colour, folder=True)


def refocus_stem(*, slope: float | None = None, alpha: float | None = None) -> str:
    """File stem of a refocused photograph: ``refocus_s+0.30`` (slope) or ``refocus_a1.020`` (alpha)."""
    return f"refocus_s{slope:+.2f}" if slope is not None else f"refocus_a{alpha:.3f}"


def _one_focus(slope: Any, alpha: Any, focus_at: Any, focus_distance: Any) -> str:
    """The one focus keyword given (ValueError, in the workflow's names, unless exactly one)."""
    given = [k for k, v in (("slope", slope), ("alpha", alpha), ("focus_at", focus_at),
                            ("focus_distance", focus_distance)) if v is not None]
    if len(given) != 1:
        raise ValueError(f"pass exactly one of slope, alpha, focus_at and focus_distance, got {given or 'none'}")
    return given[0]


def _focus_point(focus_at: Any, shape: Sequence[int]) -> tuple[float, float]:
    """``focus_at = (x, y)`` as the ``at = (y, x)`` of :func:`~plenodecode.render.refocus_methods.focus_slope`
    inside the centre view of a light field of ``shape`` (V, U, Y, X, C); ValueError naming ``focus_at``."""
    from ..render.refocus_methods import check_point

    try:
        x, y = (float(v) for v in focus_at)
        return check_point((y, x), shape[2:4])
    except (TypeError, ValueError):
        raise ValueError(f"focus_at must be an (x, y) pair inside the centre view (x: column 0 to {shape[3] - 1}, "
                         f"y: row 0 to {shape[2] - 1}), got {focus_at!r}") from None


def render_refocus(src: Source, *, slope: float | None = None, alpha: float | None = None,
                   focus_at: tuple[float, float] | None = None, focus_distance: float | None = None,
                   focus_at_method: str = "depth", method: str = "shift-sum", aperture: float = 1.0,
                   upsample: int = 1, progress: Progress = None) -> Rendered:
    """One photograph focused by one of ``slope``, ``alpha``, ``focus_at``, ``focus_distance`` (metres)
    (:func:`~plenodecode.render.refocus_methods.focus_slope`); outside
    :func:`~plenodecode.render.alpha.refocus_range_units` it is still rendered, with a one-line warning
    (ValueError, without it, beyond :func:`~plenodecode.render._common.check_slope_reach`).

    ``focus_at = (x, y)``: column then row, in samples of the centre view, the order of ``--focus-at X,Y`` (not
    the (row, column) of :func:`plenodecode.refocus`'s ``at``); ``focus_at_method`` how the slope there is found:
    'depth' (the depth map) or 'sharpness' (``--no-depth``).  ``progress``: of the depth map a point is focused
    by (seconds on a large light field).  ``data``: 'slope' (chosen), 'alpha', 'focus_distance', 'method',
    'aperture', 'range'."""
    from ..render import refocus, refocus_range_units
    from ..render._common import check_slope_reach
    from ..render.refocus_methods import FOCUS_AT_METHODS, focus_slope

    lookup(FOCUS_AT_METHODS, focus_at_method, param="focus_at_method")
    lf = src.lightfield
    at = _focus_point(focus_at, lf.shape) if _one_focus(slope, alpha, focus_at, focus_distance) == "focus_at" else None
    chosen = focus_slope(lf, slope=slope, alpha=alpha, at=at, distance_m=focus_distance,
                         at_method=focus_at_method, progress=progress)
    check_slope_reach(lf, chosen)       # a slope refused is refused without the out-of-range warning first
    span = refocus_range_units(lf)
    if not span.contains(chosen):
        log.warning("slope %.3g px/view%s is outside the refocusable range (%s): nothing in it can be sharp",
                    chosen, "" if alpha is None else f" (alpha {alpha:g})", span.describe())
    img = refocus(lf, slope=chosen, method=method, aperture=aperture, upsample=upsample)
    stem = refocus_stem(alpha=alpha) if alpha is not None else refocus_stem(slope=chosen)
    return Rendered("refocus", ((stem, img),), lf.colour,
                    data={"slope": chosen, "alpha": alpha, "focus_distance": focus_distance, "method": method,
                          "aperture": aperture, "range": span})


def check_focus_reach(src: Source, product: str, **options: Any) -> None:
    """Refuse, before a raw is decoded, a 'refocus' (``slope``, ``alpha`` or ``focus_distance``) or 'focal-stack'
    (``start``, ``stop``, ``n``, ``units``) whose slope moves the outermost views past the whole picture: the
    ValueError :func:`~plenodecode.render._common.check_slope_reach` gives after decoding, found from the shape
    and camera constants the calibration gives (:func:`~plenodecode.decoding.rectify.decoded_shape`,
    :func:`~plenodecode.decoding.rectify.decoded_geometry`).  Passes whatever needs the decoded light field
    (a light-field input, a point ``focus_at``, an alpha or distance of a rectified light field, a conversion the
    metadata cannot make): rendering checks those."""
    import numpy as np

    from ..decoding.rectify import decoded_geometry, decoded_shape
    from ..errors import PlenodecodeError
    from ..render._common import check_slope_reach
    from ..render.alpha import alpha_to_slope, distance_to_slope

    if src.raw is None or "lightfield" in src.__dict__:
        return
    shape = decoded_shape(src.calibration.grid, src.decode_options.get("n_views"))
    geometry = None if src.geometry is not None else decoded_geometry(src.raw, src.calibration.grid)
    try:
        if product == "focal-stack":
            values = np.linspace(options["start"], options["stop"], int(options["n"]))
            units = options.get("units", "slope")
            if units != "slope" and geometry is None:
                return
            slopes = lookup(STACK_UNITS, units, param="units")(values, geometry)
        elif options.get("slope") is not None:
            slopes = float(options["slope"])
        elif options.get("alpha") is not None and geometry is not None:
            slopes = alpha_to_slope(float(options["alpha"]), geometry)
        elif options.get("focus_distance") is not None and geometry is not None:
            slopes = distance_to_slope(float(options["focus_distance"]), geometry)
        else:
            return
    except (PlenodecodeError, ValueError):
        return
    check_slope_reach(shape, slopes, name="slopes" if product == "focal-stack" else "slope")


def check_disparity_reach(src: Source, disparity_range: tuple[float, float] | None) -> None:
    """ValueError when a depth search range ``(lo, hi)`` (px per view step) reaches past the slope at which the
    outermost views still overlap the centre one (:func:`~plenodecode.render._common.slope_reach`: 17.9 px/view
    on the bundled illum-mini), before decoding (a raw's decoded shape comes from its calibration): nothing
    there can match, and the search costs time in proportion."""
    if disparity_range is None:
        return
    from ..decoding.rectify import decoded_shape
    from ..render._common import slope_reach

    shape = src.lightfield.shape if src.raw is None else decoded_shape(src.calibration.grid,
                                                                        src.decode_options.get("n_views"))
    reach, worst = slope_reach(shape), max(abs(disparity_range[0]), abs(disparity_range[1]))
    if worst > reach:
        raise ValueError(f"a disparity of {worst:g} px/view moves the outermost views past the whole {shape[2]} x "
                         f"{shape[3]} picture, where no view overlaps the centre one; search within |disparity| <= "
                         f"{reach:.3g} here")


def focal_stack_names(n: int, ext: str) -> list[str]:
    """Files of a focal stack of ``n`` slices: ``slice_000.<ext>`` ..., ``all_in_focus.<ext>``, the JSON."""
    return [f"slice_{i:03d}.{ext}" for i in range(n)] + [f"all_in_focus.{ext}", "focal_stack.json"]


def _slopes_as_given(values: Any, lf: LightField) -> Any:
    return values


#: Most slices of one focal stack (a larger count is refused before any work).
MAX_STACK_SLICES = 512


def stack_problem(start: float, stop: float, n: int, units: str = "slope") -> str | None:
    """What is wrong with a focal stack of ``n`` slices from ``start`` to ``stop`` (``units``), as a phrase for the
    caller to name its option or keyword in, or None: N must be 2 to :data:`MAX_STACK_SLICES`, START and STOP
    finite (and > 0 as alphas)."""
    import math

    if not 2 <= n <= MAX_STACK_SLICES:
        return f"N must be 2 to {MAX_STACK_SLICES}, got {n}"
    if not (math.isfinite(start) and math.isfinite(stop)):
        return f"START and STOP must be finite, got {start:g}:{stop:g}"
    if units == "alpha" and not (start > 0 and stop > 0):
        return f"alphas must be > 0 (units 'alpha'), got {start:g}:{stop:g}"
    return None


#: Units of a focal stack's START and STOP -> ``fn(values, lf) -> slopes`` (px per view step).
STACK_UNITS: dict[str, Callable[..., Any]] = {
    "slope": _slopes_as_given,
    "alpha": lazy("plenodecode.render.alpha", "alpha_to_slope"),
}


def render_focal_stack(src: Source, *, start: float, stop: float, n: int, units: str = "slope",
                       method: str = "shift-sum", aperture: float = 1.0, upsample: int = 1,
                       progress: Progress = None) -> Rendered:
    """``n`` photographs from ``start`` to ``stop`` (slopes, or alphas with ``units='alpha'``), the all-in-focus
    image made from them, and ``focal_stack.json`` (slopes, alphas, method, file names).

    The all-in-focus image renders every pixel at the slope of its sharpest slice
    (:func:`~plenodecode.render.allinfocus.all_in_focus_from_stack`): it reuses the stack, where the
    depth-guided default of the 'all-in-focus' product estimates depth first (a full-size
    15 x 15 x 434 x 625 light field: 10 s, against 1 s from the stack; bench_allinfocus).
    """
    import numpy as np

    from ..render import focal_stack, slope_to_alpha
    from ..render.allinfocus import all_in_focus_from_stack

    if not 2 <= int(n) <= MAX_STACK_SLICES:
        raise ValueError(f"n (slices of a focal stack) must be 2 to {MAX_STACK_SLICES}, got {n}")
    lf = src.lightfield
    slopes = lookup(STACK_UNITS, units, param="units")(np.linspace(start, stop, n), lf)
    imgs = focal_stack(lf, slopes, method=method, aperture=aperture, upsample=upsample, progress=progress)
    aif = all_in_focus_from_stack(lf, imgs, np.asarray(slopes), aperture=aperture)
    try:
        alphas = [float(a) for a in slope_to_alpha(np.asarray(slopes), lf)]
    except Exception:  # noqa: BLE001 - alphas are informative only; the camera may not be known
        alphas = None
    stems = [f"slice_{i:03d}" for i in range(n)]

    def document(ext: str) -> dict[str, Any]:
        return {"slopes": [float(s) for s in slopes], "alphas": alphas, "method": method, "aperture": aperture,
                "files": [f"{s}.{ext}" for s in stems], "all_in_focus": f"all_in_focus.{ext}"}

    return Rendered("focal-stack", (*zip(stems, imgs), ("all_in_focus", aif)), lf.colour, folder=True,
                    documents=(("focal_stack.json", document),), data={"slopes": slopes})


def render_all_in_focus(src: Source, *, method: str = "depth", slopes: Sequence[float] | None = None,
                        aperture: float = 1.0, progress: Progress = None, **options: Any) -> Rendered:
    """An image sharp everywhere (:func:`plenodecode.render.all_in_focus`): by default every pixel at the
    disparity of the 'fast' depth estimate, from the views that see it; ``method='focal-stack'`` (with
    ``slopes``, default the light field's) the sharpest slice of a focal stack.  ``options`` are the method's
    (``depth_method``, ``refocus_method``, ...)."""
    from ..render import all_in_focus

    lf = src.lightfield
    img = all_in_focus(lf, method=method, slopes=slopes, aperture=aperture, progress=progress, **options)
    return Rendered("all-in-focus", (("all_in_focus", img),), lf.colour)


def parallax_frame_names(n: int, ext: str = "png") -> list[str]:
    """Files of the ``n`` numbered frames of a parallax product: ``frame_000.<ext>`` ..."""
    return [f"frame_{i:03d}.{ext}" for i in range(n)]


def render_parallax(src: Source, *, frames: int = 24, radius: float | None = None, interp: str = "linear",
                    progress: Progress = None) -> Rendered:
    """Perspective views along a circle of viewpoints (:func:`plenodecode.render.render_parallax`): the
    numbered frames ``frame_000`` ... and, in ``data['animation']``, the (N, Y, X, 3) frames of the animation."""
    from ..render import render_parallax as parallax

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:     # named as this function takes it
        raise ValueError(f"frames must be a positive integer, got {frames!r}")
    lf = src.lightfield
    out = parallax(lf, frames, radius, interp=interp, progress=progress)
    anim = out if out.shape[-1] == 3 else out.repeat(3, axis=-1)
    stems = [Path(name).stem for name in parallax_frame_names(len(out))]
    return Rendered("parallax", tuple(zip(stems, out)), lf.colour, folder=True,
                    data={"animation": anim})


def render_depth(src: Source, *, method: str | None = None, disparity_range: tuple[float, float] | None = None,
                 metric: bool = False, points: bool = False, focus_distance: float | None = None,
                 progress: Progress = None) -> Rendered:
    """Disparity of the centre view (:func:`plenodecode.depth.estimate_depth`), px per view step; with ``metric``
    also depth in metres (micrometres from the native object plane for a light-field microscope,
    :func:`plenodecode.depth.metric.depth_unit`), with ``points`` the 3-D point of every pixel and its display
    colour.

    ``data``: 'depthmap' (DepthMap), 'values' (Y, X) float32 (depth in 'unit' with ``metric``, else disparity),
    'unit', 'label', 'near' (which values are nearest: 'high' for disparity, 'low' for depth), and with ``points``
    'points' (Y, X, 3) in 'unit' and 'colours' (Y, X, 3) uint8.

    A focused-plenoptic (Raytrix) raw (``src.focused``) is not decoded (its views have one pixel per lens):
    :func:`render_focused_depth` gives its virtual depth at the total-focus image's resolution.
    """
    from ..depth import DEFAULT_METHOD, disparity_to_depth, estimate_depth
    from ..depth.metric import depth_constants, depth_to_points, depth_unit

    if src.focused:     # metric and points were refused by check_product (render_product)
        return render_focused_depth(src, disparity_range=disparity_range, progress=progress)
    lf = src.lightfield
    method = method or DEFAULT_METHOD
    overrides = {} if focus_distance is None else {"focus_distance_m": focus_distance}
    unit, scale = depth_unit(lf, **overrides)      # micrometres for a light-field microscope, else metres
    if metric or points:
        depth_constants(lf, **overrides)    # fail before the estimate when the camera geometry is missing
    kw = {} if disparity_range is None else {"disparity_range": disparity_range}
    dm = estimate_depth(lf, method=method, progress=progress, **kw)
    depth = disparity_to_depth(dm, lf, **overrides) if (metric or points) else None
    data: dict[str, Any] = {"depthmap": dm, "method": method, "unit": unit if metric else "px / view step",
                            "values": depth * scale if metric else dm.disparity,
                            "label": f"depth ({unit})" if metric else "disparity (px / view step)",
                            "near": "low" if metric else "high"}     # which values are nearest: the colour maps
    if points:
        from ..io.depthio import display_colours

        data["points"] = depth_to_points(depth, lf, **overrides) * scale
        data["colours"] = display_colours(lf.centre_view(), lf.colour)
    return Rendered("depth", (), lf.colour, data=data)


def render_focused_depth(src: Source, *, disparity_range: tuple[float, float] | None = None,
                         progress: Progress = None) -> Rendered:
    """Virtual depth of a focused-plenoptic (Raytrix) raw on its total-focus image's grid
    (:func:`plenodecode.depth.focused.estimate_focused_depth`: per raw pixel against the neighbouring
    micro-images, carried to the total focus by its own mapping, so depth and :func:`render_total_focus`'s
    photograph align pixel for pixel).

    ``data``: 'values' (Ho, Wo) float32 virtual depth ``v = a / B``, 'label', 'unit', 'method' ('focused'),
    'focused' (the FocusedDepth), 'depthmap', a DepthMap whose 'disparity' is the micro-image disparity
    ``D / v`` (px per lens step) with the confidence, and 'near' (which values are nearest, as
    :func:`render_depth`): 'high' for upright (Galilean) micro-images, such as the real R42's, 'low' for inverted
    (Keplerian) ones.  The main lens images a nearer object farther behind it (thin lens); a Galilean camera's
    virtual image lies behind the MLA, so that is farther from the MLA (larger ``a``, larger ``v``), a Keplerian
    camera's in front of it, so nearer the MLA (smaller ``v``).

    Metric depth has no scale here: 'depth' with ``metric`` or ``points`` is refused for a focused raw by
    :func:`~plenodecode.pipeline.needs.check_product` (:func:`render_product`), before any work.

    Raises
    ------
    ValueError
        A light-field input; ``disparity_range`` (px per view step: a light field's).
    """
    import numpy as np

    from ..depth import DepthMap
    from ..depth.focused import VIRTUAL_DEPTH_LABEL, VIRTUAL_DEPTH_UNIT, estimate_focused_depth

    if src.raw is None:
        raise ValueError("a focused-plenoptic depth map is estimated on a raw; the input is a light field")
    if disparity_range is not None:
        raise ValueError("disparity_range (px per view step) is a light field's; a focused-plenoptic raw is searched "
                         "over its lens types' virtual depth range")
    image, white, _ = _focused_input(src, "depth")
    grid = src.calibration.grid
    # aligned with the total focus the photograph shows, rendered once when a batch asks for both
    fd = estimate_focused_depth(image, grid, white=white, render=_total_focus(src), progress=progress)
    with np.errstate(invalid="ignore", divide="ignore"):
        disparity = (np.float32(grid.pitch) / fd.virtual_depth).astype(np.float32)
    dm = DepthMap(disparity=disparity, confidence=fd.confidence, method="focused", params=dict(fd.params))
    return Rendered("depth", (), "srgb", data={
        "depthmap": dm, "method": "focused", "focused": fd, "values": fd.virtual_depth, "unit": VIRTUAL_DEPTH_UNIT,
        "label": VIRTUAL_DEPTH_LABEL, "near": "low" if fd.params.get("keplerian") else "high"})


def check_total_focus_patch(grid: LensletGrid, patch: Any) -> None:
    """Raise ValueError naming ``patch`` unless it is None or every value lies in ``(0, 2 * grid.radius)`` px:
    a patch is cut from one micro-image, so it is smaller than the micro-image diameter."""
    import numpy as np

    if patch is None:
        return
    p, hi = np.asarray(patch, np.float64), 2.0 * float(grid.radius)
    if not (np.all(np.isfinite(p)) and np.all(p > 0) and np.all(p < hi)):
        raise ValueError(f"patch must lie in (0, {hi:.1f}) px (0 < P < the micro-image diameter), got "
                         f"{patch if p.ndim == 0 else 'an array outside it'}; P = lens pitch / virtual depth")


def _focused_input(src: Source, what: str) -> tuple[Any, Any, str]:
    """What a focused-plenoptic renderer reads: ``(image, white, colour state)``.

    A Raytrix RGB export (:func:`plenodecode.io.raytrix.is_rgb_export`: its RawCapture holds the luminance)
    is read again in colour, linear sRGB (:func:`~plenodecode.io.raytrix.read_raytrix_linear_rgb`), and so is
    its white image when that is an export too (else the white's normalised mosaic divides every channel);
    any other raw is rendered from its mosaic (demosaiced within the micro-images), in camera RGB.
    ``src`` holds a raw; ``what`` names the product in the warning for a grid without lens types.  Read (and
    warned about) once per source (:meth:`~plenodecode.pipeline.Source.shared`).
    """
    return src.shared("focused-input", lambda: _read_focused_input(src, what))


def _read_focused_input(src: Source, what: str) -> tuple[Any, Any, str]:
    if not src.focused:
        log.warning("the lenslet grid of %s has no lens types: %s expects a focused-plenoptic raw",
                    src.raw.path or "the raw", what)
    from ..io.raytrix import is_rgb_export, read_raytrix_linear_rgb

    white = src.calibration.white
    if not is_rgb_export(src.raw):
        return src.raw, white, "camera"
    if white is not None:
        from ..decoding.devignette import normalise

        white = read_raytrix_linear_rgb(white.path) if is_rgb_export(white) else \
            normalise(white.mosaic, white.black, white.white)
    return read_raytrix_linear_rgb(src.raw.path), white, "linear-srgb"


def _total_focus(src: Source, *, patch: float | Any | None = None, sharpness: float = 2.0,
                 progress: Progress = None) -> Any:
    """The FocusedRender of :func:`plenodecode.decoding.focused.render_total_focus` on the source's focused input;
    with the per-lens patch sizes (``patch`` None) rendered once per source and ``sharpness``, as the photograph,
    the 'total-focus' product and the depth map (aligned with it) all ask for it."""
    from ..decoding.focused import render_total_focus as total_focus

    image, white, _ = _focused_input(src, "total focus")

    def render() -> Any:
        return total_focus(image, src.calibration.grid, patch=patch, white=white, sharpness=sharpness,
                           progress=progress)

    return render() if patch is not None else src.shared(("total-focus", float(sharpness)), render)


def _camera_to_srgb(image: Any, state: str, raw: RawCapture, colour: str) -> tuple[Any, str]:
    """A focused rendering in camera RGB converted as the decoder does, ``srgb = CCM @ diag(gains) @ camera``
    (:func:`plenodecode.decoding.colour.colour_matrix`), when ``colour='linear-srgb'`` and the metadata has a CCM."""
    from ..decoding.colour import apply_matrix, colour_matrix

    if image.shape[-1] != 3 or state != "camera" or colour != "linear-srgb":
        return image, state
    matrix = colour_matrix(raw.metadata)
    if matrix is None:
        log.warning("the raw's metadata has no colour matrix (ccm): the focused rendering stays in camera RGB")
        return image, state
    return apply_matrix(image, matrix), "linear-srgb"


def _check_colour(colour: str) -> None:
    from ..decoding.colour import DECODE_COLOURS

    if colour not in DECODE_COLOURS:
        raise ValueError(f"colour must be one of {DECODE_COLOURS}, got {colour!r}")


def render_total_focus(src: Source, *, patch: float | Any | None = None, sharpness: float = 2.0,
                       colour: str = "linear-srgb", progress: Progress = None) -> Rendered:
    """All-in-focus rendering of a focused-plenoptic (Raytrix) raw from its micro-images
    (:func:`plenodecode.decoding.focused.render_total_focus`), devignetted by the calibration's white.

    A colour raw (a CFA, demosaiced within each micro-image) is rendered in camera RGB and, with
    ``colour='linear-srgb'``, converted as the decoder does: ``srgb = CCM @ diag(gains) @ camera``
    (:func:`plenodecode.decoding.colour.colour_matrix`); without a CCM in the metadata it stays 'camera'.
    A Raytrix RGB export is rendered from its colour image, linear sRGB (:func:`_focused_input`).

    Parameters
    ----------
    src : Source
        A raw with its calibration.
    patch : float or ndarray (rows, cols), optional
        Patch size P per lens, px (lens pitch / virtual depth); default estimated per lens.
    sharpness : float
        Exponent of the per-lens focus weight (0: plain blending).
    colour : {'linear-srgb', 'camera'}
    progress : callable(done, total), optional

    Returns
    -------
    Rendered
        One image ``total_focus`` (Ho, Wo, C) float32, C = 3 for a colour raw; ``data['render']`` the
        :class:`~plenodecode.decoding.focused.FocusedRender` (patch sizes, focus, scale).

    Raises
    ------
    ValueError
        The input is not a raw (a light field has no micro-images); ``patch`` out of range
        (:func:`check_total_focus_patch`); an unknown ``colour``.
    """
    if src.raw is None:
        raise ValueError("total-focus renders a focused-plenoptic raw; the input is a light field")
    check_total_focus_patch(src.calibration.grid, patch)
    _check_colour(colour)
    state = _focused_input(src, "total focus")[2]
    res = _total_focus(src, patch=patch, sharpness=sharpness, progress=progress)
    out, state = _camera_to_srgb(res.image, state, src.raw, colour)
    return Rendered("total-focus", (("total_focus", out),), state, data={"render": res})


def virtual_depth_stem(virtual_depth: float) -> str:
    """File stem of a focused raw refocused at a virtual depth: ``refocus_v2.50``."""
    return f"refocus_v{virtual_depth:.2f}"


def render_focused_refocus(src: Source, *, virtual_depth: float, colour: str = "linear-srgb") -> Rendered:
    """A focused-plenoptic (Raytrix) raw refocused at ``virtual_depth``
    (:func:`plenodecode.decoding.focused.render_at_virtual_depth`: patches of ``lens pitch / virtual_depth`` px,
    the lens types in focus there weighted most), in colour as :func:`render_total_focus`.

    Returns
    -------
    Rendered
        One image ``refocus_v<V>`` (Ho, Wo, C) float32; ``data['render']`` the FocusedRender.

    Raises
    ------
    ValueError
        A light-field input; ``virtual_depth`` outside the camera's range
        (:func:`plenodecode.decoding.focused.check_virtual_depth`); an unknown ``colour``.
    """
    from ..decoding.focused import check_virtual_depth, render_at_virtual_depth

    if src.raw is None:
        raise ValueError("a refocus at a virtual depth renders a focused-plenoptic raw; the input is a light field")
    check_virtual_depth(src.calibration.grid, virtual_depth)
    _check_colour(colour)
    image, white, state = _focused_input(src, "a refocus at a virtual depth")
    res = render_at_virtual_depth(image, src.calibration.grid, virtual_depth, white=white)
    out, state = _camera_to_srgb(res.image, state, src.raw, colour)
    return Rendered("focused-refocus", ((virtual_depth_stem(virtual_depth), out),), state,
                    data={"render": res, "virtual_depth": virtual_depth})


def photo_focus(focused: bool, *, refocus: bool = False) -> dict[str, Any]:
    """How the camera's photograph is focused when no focus is asked for (the one rule of :func:`render_photo`
    and ``plenodecode RAW -o photo.png``): ``{'total_focus': True}`` for a focused-plenoptic (Raytrix) raw, whose
    decoded views have one pixel per lens (a thumbnail), unless ``refocus`` (a refocusing option was asked for:
    the decoded light field is refocused); else ``{'slope': 0.0}``, the focus as captured."""
    return {"total_focus": True} if focused and not refocus else {"slope": 0.0}


def render_photo(src: Source, *, slope: float | None = None, alpha: float | None = None,
                 focus_distance: float | None = None, aperture: float = 1.0) -> Rendered:
    """The camera's photograph, as ``plenodecode RAW -o photo.png`` writes it without a focus option
    (:func:`photo_focus`): a focused-plenoptic (Raytrix) raw's total focus (:func:`render_total_focus`), else the
    photograph refocused (:func:`render_refocus`, through the synthetic ``aperture``) at ``slope``, ``alpha`` or
    ``focus_distance`` (metres), by default as captured.  The rendered product says which ('total-focus' or
    'refocus')."""
    chosen = photo_focus(src.focused)
    if chosen.get("total_focus"):
        return render_total_focus(src)
    if slope is None and alpha is None and focus_distance is None:
        slope = chosen["slope"]
    return render_refocus(src, slope=slope, alpha=alpha, focus_distance=focus_distance, aperture=aperture)


#: Product name -> ``fn(source, **options) -> Rendered``; the same names in the CLI, batch and Python.
PRODUCTS: dict[str, Callable[..., Rendered]] = {
    "photo": render_photo,
    "centre": render_centre,
    "views": render_views,
    "refocus": render_refocus,
    "focal-stack": render_focal_stack,
    "all-in-focus": render_all_in_focus,
    "parallax": render_parallax,
    "depth": render_depth,
    "total-focus": render_total_focus,
    "focused-refocus": render_focused_refocus,
}


#: Keywords of the products renamed to their CLI option's name -> the new name (still accepted, with a
#: DeprecationWarning, by :func:`render_product`); ``at`` was (row, column), ``focus_at`` is (x, y); ``at_method``
#: (``--no-depth``: 'sharpness') is the method of ``focus_at``.
RENAMED_OPTIONS = {"distance_m": "focus_distance", "at": "focus_at", "at_method": "focus_at_method"}
_CONVERT_OPTIONS = {"at": (lambda rc: (rc[1], rc[0]), "(x, y), the column first as --focus-at X,Y")}


def render_product(src: Source, name: str, **options: Any) -> Rendered:
    """Render the product ``name`` (a key of :data:`PRODUCTS`) of ``src`` with its ``options`` (the keywords of its
    ``render_*`` function, named as the CLI options); the options are first checked against the input's metadata
    (:func:`~plenodecode.pipeline.needs.check_product`), before ``src`` is decoded.  The old names of
    :data:`RENAMED_OPTIONS` still work, with a DeprecationWarning."""
    from ..deprecation import renamed_keywords

    options = renamed_keywords(options, RENAMED_OPTIONS, "render_product", convert=_CONVERT_OPTIONS)
    render = lookup(PRODUCTS, name, param="product")
    check_product(src.input, name, rectified=src.geometry is not None, focused=src.focused, **options)
    return render(src, **options)
