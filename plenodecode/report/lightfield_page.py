"""An interactive light-field page: one self-contained HTML file to refocus and turn a light field.

``plenodecode export LF -o page.html --format html`` writes it (:func:`write_lightfield_page`).  The page holds

* a focal stack: ``n_slices`` photographs refocused (:func:`plenodecode.render.focal_stack`, shift-sum) at
  slopes spanning the scene's disparity range (:func:`stack_slopes`; of the confident pixels, below);
* the disparity map of the centre view (:func:`plenodecode.depth.estimate_depth`), shown colour-mapped (the
  pixels below :data:`~plenodecode.io.depthio.DEFAULT_MIN_CONFIDENCE` grey, as in the depth PNGs, the colours
  spanning the others) and embedded as float32 values (all of them: a click reads them);
* a ``k x k`` subset of the views (:func:`view_subset`);

every image inlined as a ``data:`` URI (8-bit sRGB JPEG; the depth map PNG), and a small hand-written script:

* a click on the photograph (or the depth map) at centre-view pixel ``(y, x)`` reads the disparity
  ``d = median{ D(y', x') : |y' - y| <= r, |x' - x| <= r, D finite }`` (``r = depth_window // 2``, clipped at
  the borders) and shows the slice whose slope ``s_k`` minimises ``|s_k - d|``: a surface of disparity ``d``
  is sharpest at ``s = d`` (design.md);
* a drag by ``(dy, dx)`` (a fraction of the image's height and width) shows the view of the subset nearest
  to the angular offset ``(a, b) = 2 R (dy, dx)`` from the centre view, ``R`` the subset's largest offset:
  dragging from the middle to an edge of the image reaches the outermost views;
* the slider steps through the slices.

The page opens on the slice nearest to slope 0 (the focus as captured).

The current slice, its slope and (when the camera constants are known, :mod:`plenodecode.render.alpha`)
Ng's alpha are shown as text.  The state is also kept in ``data-*`` attributes of ``#lf-viewer``
(``data-mode`` 'focus' or 'view', ``data-slice``, ``data-slope``, ``data-view`` "v,u", ``data-disparity``)
so a test or another script can read it.  Nothing is loaded from outside the file: no server, no external
script, style or font.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import logging
import math
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import MetadataError
from ..io.atomic import refuse_existing
from ..io.depthio import (DEFAULT_MIN_CONFIDENCE, DEPTH_CMAP, MASK_GREY, colour_mapped, colour_range,
                          display_colours)
from ..io.images import quantise
from ..types import COLOUR_WORDS, LightField
from .html import escape, page, write_html

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Number of focal-stack slices of a page.
DEFAULT_SLICES = 20
#: The page shows ``k x k`` views (fewer when the light field has fewer).
DEFAULT_VIEWS = 5
#: Longest side (px) of the inlined images; larger light fields are reduced (area average).
DEFAULT_MAX_SIDE = 800
#: JPEG quality of the photographs and views.
DEFAULT_JPEG_QUALITY = 88
#: Side (depth-map pixels, odd) of the window whose median disparity a click reads.
DEFAULT_DEPTH_WINDOW = 7
#: The photograph is shown at most this many times larger than its pixels (small light fields stay legible).
UPSCALE_LIMIT = 4
#: Fraction of the angular radius the view subset spans (outer views of a lenslet camera are vignetted).
VIEW_SPAN = 2.0 / 3.0


# ----------------------------------------------------------------------------- what the page shows
def stack_slopes(lf: LightField, disparity: np.ndarray, n: int) -> np.ndarray:
    """The slopes of the page's focal stack: ``n`` values over the scene's disparity range.

    The range is ``lf.geometry.disparity_range`` when the light field has one, else the 1st-99th percentiles
    of the finite values of ``disparity``; either is widened as :func:`plenodecode.render.default_slopes`
    widens it (10 % + 0.05 on each side), then kept within the refocusable range
    (:func:`plenodecode.render.refocus_range`), past which no slice is sharp (the real F01 shoe's page ran
    -1.80 .. 0.79 where -1.15 .. 1.15 refocus).

    Parameters
    ----------
    lf : LightField
    disparity : ndarray (Y, X) float32
        The centre view's disparity (px per view step).
    n : int
        Number of slices, >= 2.

    Returns
    -------
    ndarray, shape (n,), float64, increasing
    """
    from ..render import default_slopes, refocus_range

    geometry = lf.geometry
    if geometry.disparity_range is None or not all(math.isfinite(v) for v in geometry.disparity_range):
        lo, hi = colour_range(disparity)
        geometry = dataclasses.replace(geometry, disparity_range=(float(lo), float(hi)))
    slopes = default_slopes(lf.replace(geometry=geometry), n)
    reach_lo, reach_hi = refocus_range(lf)
    lo, hi = max(float(slopes[0]), reach_lo), min(float(slopes[-1]), reach_hi)
    return np.linspace(lo, hi, len(slopes)) if lo < hi else slopes     # a scene wholly outside: as measured


def stack_alphas(lf: LightField, slopes: np.ndarray) -> list[float | None] | None:
    """Ng's alpha of each slope (:func:`plenodecode.render.slope_to_alpha`); None for a slope beyond the film
    plane at infinity, and None for all when the light field lacks the camera constants."""
    from ..render import slope_per_alpha_unit

    try:
        k = slope_per_alpha_unit(lf)
    except (MetadataError, ValueError):
        return None
    return [1.0 / (1.0 - s / k) if s < k else None for s in np.asarray(slopes, np.float64)]


def view_subset(angular: tuple[int, int], k: int = DEFAULT_VIEWS) -> list[tuple[int, int]]:
    """The views a page shows: ``k x k`` (at most) evenly spaced over the inner :data:`VIEW_SPAN` of each axis.

    Along an axis of ``n`` views with centre ``c = n // 2``, the offsets are ``rint(linspace(-r, r, m))`` with
    ``r = floor(VIEW_SPAN * c)`` (at least 1 when ``n >= 2``) and ``m = min(k, 2 r + 1)``.

    Parameters
    ----------
    angular : (V, U)
    k : int
        Views per axis, >= 1.

    Returns
    -------
    list of (v, u)
        Row-major, the centre view included when ``k`` is odd.
    """
    def axis(n: int) -> list[int]:
        c = n // 2
        r = min(max(int(VIEW_SPAN * c), 1), n - 1 - c, c) if n >= 2 else 0
        offsets = np.rint(np.linspace(-r, r, min(k, 2 * r + 1))).astype(int)
        return sorted({c + int(o) for o in offsets})

    if int(k) != k or k < 1:
        raise ValueError(f"views must be a positive integer, got {k!r}")
    return [(v, u) for v in axis(angular[0]) for u in axis(angular[1])]


# ----------------------------------------------------------------------------- image encoding
def _reduced(img: np.ndarray, max_side: int, *, nearest: bool = False) -> np.ndarray:
    """``img`` (Y, X, ...) reduced so that its longest side is at most ``max_side``: area average, or the nearest
    sample with ``nearest`` (for a disparity map: NaN stays NaN and no two surfaces are mixed)."""
    import cv2

    h, w = img.shape[:2]
    scale = max_side / max(h, w)
    if scale >= 1:
        return img
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    return cv2.resize(img, size, interpolation=cv2.INTER_NEAREST if nearest else cv2.INTER_AREA)


def _data_uri(rgb8: np.ndarray, ext: str, quality: int) -> str:
    """A ``data:`` URI of an (Y, X, 3) uint8 RGB image encoded in memory as JPEG (``ext='.jpg'``) or PNG."""
    import cv2

    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] if ext == ".jpg" else [cv2.IMWRITE_PNG_COMPRESSION, 6]
    ok, buf = cv2.imencode(ext, np.ascontiguousarray(rgb8[..., ::-1]), params)
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 BGR image
        raise RuntimeError(f"OpenCV could not encode a {rgb8.shape} image as {ext}")
    mime = "image/jpeg" if ext == ".jpg" else "image/png"
    return f"data:{mime};base64,{base64.b64encode(buf.tobytes()).decode('ascii')}"


def _photo_uri(image: np.ndarray, colour: str, max_side: int, quality: int) -> str:
    """(Y, X, C) float image in the light field's colour state -> JPEG data URI (8-bit sRGB)."""
    return _data_uri(_reduced(display_colours(image, colour), max_side), ".jpg", quality)


def _float32_base64(values: np.ndarray) -> str:
    """Little-endian float32 bytes of ``values`` (row-major), base64-encoded."""
    return base64.b64encode(np.ascontiguousarray(values, "<f4").tobytes()).decode("ascii")


# ----------------------------------------------------------------------------- the page
def lightfield_page_data(lf: LightField, *, n_slices: int = DEFAULT_SLICES, views: int = DEFAULT_VIEWS,
                         depth_method: str = "costvolume", max_side: int = DEFAULT_MAX_SIDE,
                         jpeg_quality: int = DEFAULT_JPEG_QUALITY, depth_window: int = DEFAULT_DEPTH_WINDOW,
                         progress: Progress = None) -> dict[str, Any]:
    """Everything the page's script reads, as a JSON-ready dict.

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32, at least two views.
    n_slices : int
        Focal-stack slices, >= 2 (:func:`stack_slopes`).
    views : int
        Views per axis of the subset (:func:`view_subset`).
    depth_method : str
        A key of :data:`plenodecode.depth.DEPTH_METHODS`.
    max_side : int
        Longest side (px) of the inlined images and of the embedded disparity map.
    jpeg_quality : int
        1-100.
    depth_window : int
        Odd side of the median window a click reads.
    progress : callable(done, total), optional
        Called after the depth map, the focal stack and the encoding (3 steps).

    Returns
    -------
    dict
        ``slopes`` (S floats), ``alphas`` (S floats or None, or None), ``slices`` (S data URIs),
        ``views`` (list of ``{"v", "u", "a", "b", "src"}``, ``a, b`` the offsets from the centre view),
        ``centre`` ``[vc, uc]``, ``start`` (the first slice shown), ``depth`` (``width``, ``height``,
        ``window``, ``values`` base64 little-endian float32 row-major, ``src`` colour-mapped PNG,
        ``vmin``, ``vmax``, ``cmap``, ``method``), ``shape`` ``[V, U, Y, X, C]``.

    Raises
    ------
    ValueError
        A bad parameter (named).
    DecodeError
        The light field has a single view (no disparity).
    """
    from ..depth import estimate_depth
    from ..render import focal_stack

    if not isinstance(lf, LightField):
        raise ValueError(f"lf must be a LightField, got {type(lf).__name__}")
    for name, value, low in (("n_slices", n_slices, 2), ("max_side", max_side, 16), ("depth_window", depth_window, 1)):
        if int(value) != value or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if depth_window % 2 == 0:
        raise ValueError(f"depth_window must be odd, got {depth_window}")
    if not 1 <= jpeg_quality <= 100:
        raise ValueError(f"jpeg_quality must be in 1..100, got {jpeg_quality!r}")
    subset = view_subset(lf.shape[:2], views)

    steps = 10      # the depth map is most of the work (20 s of a 9 x 9 x 512 x 512 scene): steps 0-8 follow it

    def tick(done: int) -> None:
        if progress is not None:
            progress(done, steps)

    tick(0)         # a word at once, not after the depth map
    depth = estimate_depth(lf, method=depth_method,
                           progress=None if progress is None else lambda d, t: tick(min(8, 8 * d // max(t, 1))))
    tick(8)
    # the pixels below the confidence the depth PNGs grey out (a microscope's featureless background: 64 % of
    # the ant leg) are grey here too, and neither their noise nor its range sets the colours or the slopes
    confident = depth.confidence >= np.float32(DEFAULT_MIN_CONFIDENCE)
    shown = np.where(confident, depth.disparity, np.nan) if confident.any() else depth.disparity
    slopes = stack_slopes(lf, shown, int(n_slices))
    stack = focal_stack(lf, slopes)
    tick(9)
    vc, uc = lf.centre_index
    vmin, vmax = colour_range(shown)
    disparity = _reduced(depth.disparity, int(max_side), nearest=True)
    rgb = colour_mapped(disparity, vmin=vmin, vmax=vmax)
    rgb[~_reduced(confident.astype(np.uint8), int(max_side), nearest=True).astype(bool)] = MASK_GREY
    depth_rgb = quantise(rgb, 8)
    data = {
        "shape": list(lf.shape),
        "slopes": [round(float(s), 5) for s in slopes],
        "alphas": stack_alphas(lf, slopes),
        "start": int(np.argmin(np.abs(slopes))),
        "slices": [_photo_uri(s, lf.colour, max_side, jpeg_quality) for s in stack],
        "centre": [vc, uc],
        "views": [{"v": v, "u": u, "a": v - vc, "b": u - uc,
                   "src": _photo_uri(lf.data[v, u], lf.colour, max_side, jpeg_quality)} for v, u in subset],
        "depth": {"width": int(disparity.shape[1]), "height": int(disparity.shape[0]), "window": int(depth_window),
                  "values": _float32_base64(disparity), "src": _data_uri(depth_rgb, ".png", 0),
                  "vmin": float(vmin), "vmax": float(vmax), "cmap": DEPTH_CMAP, "method": depth.method,
                  "min_confidence": DEFAULT_MIN_CONFIDENCE},
    }
    tick(steps)
    return data


_STYLE = """
.lf-viewer{display:flex;flex-wrap:wrap;gap:20px;align-items:flex-start}
.lf-main{flex:3 1 480px;min-width:280px}.lf-side{flex:1 1 240px;min-width:200px;max-width:360px}
.lf-frame{position:relative;line-height:0}
.lf-frame img,.lf-side img{width:100%;height:auto;display:block;user-select:none;-webkit-user-drag:none}
#lf-photo{cursor:crosshair;touch-action:none}#lf-depth{cursor:crosshair}
#lf-marker{position:absolute;width:16px;height:16px;margin:-10px 0 0 -10px;border:2px solid #fff;
border-radius:50%;box-shadow:0 0 0 1px #000;pointer-events:none;display:none}
#lf-status{font-variant-numeric:tabular-nums;font-weight:600;margin:6px 0}
.lf-slider{width:100%}.lf-legend{display:flex;justify-content:space-between;gap:8px;font-size:.85em;color:#555}
"""

# The page's script: reads the JSON data block, answers clicks, drags and the slider (see the module docstring).
_SCRIPT = r"""
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("lf-data").textContent);
  var viewer = document.getElementById("lf-viewer");
  var photo = document.getElementById("lf-photo");
  var depthImage = document.getElementById("lf-depth");
  var marker = document.getElementById("lf-marker");
  var slider = document.getElementById("lf-slider");
  var status = document.getElementById("lf-status");
  var depth = data.depth;
  var DRAG_THRESHOLD_PX = 4;

  // The disparity map: little-endian float32, row-major, depth.height x depth.width.
  var disparity = (function () {
    var text = atob(depth.values), bytes = new Uint8Array(text.length);
    for (var i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    var view = new DataView(bytes.buffer), out = new Float32Array(depth.width * depth.height);
    for (var k = 0; k < out.length; k++) out[k] = view.getFloat32(4 * k, true);
    return out;
  })();

  // Median of the finite disparities in the window centred on (row, col), clipped at the borders.
  function medianDisparity(row, col) {
    var r = (depth.window - 1) / 2, values = [];
    for (var y = Math.max(0, row - r); y <= Math.min(depth.height - 1, row + r); y++) {
      for (var x = Math.max(0, col - r); x <= Math.min(depth.width - 1, col + r); x++) {
        var d = disparity[y * depth.width + x];
        if (isFinite(d)) values.push(d);
      }
    }
    if (values.length === 0) return NaN;
    values.sort(function (p, q) { return p - q; });
    var m = values.length >> 1;
    return values.length % 2 ? values[m] : 0.5 * (values[m - 1] + values[m]);
  }

  function nearestSlice(d) {
    var best = 0;
    for (var k = 1; k < data.slopes.length; k++) {
      if (Math.abs(data.slopes[k] - d) < Math.abs(data.slopes[best] - d)) best = k;
    }
    return best;
  }

  function nearestView(a, b) {
    var best = 0;
    for (var k = 1; k < data.views.length; k++) {
      var p = data.views[k], q = data.views[best];
      if ((p.a - a) * (p.a - a) + (p.b - b) * (p.b - b) < (q.a - a) * (q.a - a) + (q.b - b) * (q.b - b)) best = k;
    }
    return best;
  }

  function showSlice(k, note) {
    var slope = data.slopes[k], alpha = data.alphas ? data.alphas[k] : null;
    photo.src = data.slices[k];
    slider.value = k;
    viewer.dataset.mode = "focus";
    viewer.dataset.slice = k;
    viewer.dataset.slope = slope;
    var text = "slice " + (k + 1) + " of " + data.slopes.length + " \u00b7 slope " + slope.toFixed(3) + " px/view";
    if (alpha !== null) text += " \u00b7 alpha " + alpha.toFixed(4);
    status.textContent = text + (note ? " \u00b7 " + note : "");
  }

  function showView(k) {
    var view = data.views[k];
    photo.src = view.src;
    marker.style.display = "none";
    viewer.dataset.mode = "view";
    viewer.dataset.view = view.v + "," + view.u;
    status.textContent = "view (v " + view.v + ", u " + view.u + "), offset (" + view.a + ", " + view.b +
      ") from the centre \u00b7 click to refocus";
  }

  // Refocus at the point (fy, fx), given as fractions of the image's height and width.
  function focusAt(fy, fx) {
    var row = Math.min(depth.height - 1, Math.max(0, Math.floor(fy * depth.height)));
    var col = Math.min(depth.width - 1, Math.max(0, Math.floor(fx * depth.width)));
    var d = medianDisparity(row, col);
    marker.style.left = (100 * fx) + "%";
    marker.style.top = (100 * fy) + "%";
    marker.style.display = "block";
    if (!isFinite(d)) {
      status.textContent = "no disparity at this point";
      return;
    }
    viewer.dataset.disparity = d.toFixed(4);
    showSlice(nearestSlice(d), "disparity here " + d.toFixed(3));
  }

  function fractions(image, event) {
    var box = image.getBoundingClientRect();
    return [(event.clientY - box.top) / box.height, (event.clientX - box.left) / box.width];
  }

  var radius = 0;
  data.views.forEach(function (v) { radius = Math.max(radius, Math.abs(v.a), Math.abs(v.b)); });
  var drag = null;
  photo.addEventListener("pointerdown", function (event) {
    drag = {x: event.clientX, y: event.clientY, moved: false};
    photo.setPointerCapture(event.pointerId);
    event.preventDefault();
  });
  photo.addEventListener("pointermove", function (event) {
    if (drag === null) return;
    var dx = event.clientX - drag.x, dy = event.clientY - drag.y;
    if (!drag.moved && Math.sqrt(dx * dx + dy * dy) < DRAG_THRESHOLD_PX) return;
    drag.moved = true;
    var box = photo.getBoundingClientRect();
    showView(nearestView(2 * radius * dy / box.height, 2 * radius * dx / box.width));
  });
  photo.addEventListener("pointerup", function (event) {
    if (drag !== null && !drag.moved) focusAt.apply(null, fractions(photo, event));
    drag = null;
  });
  photo.addEventListener("pointercancel", function () { drag = null; });
  depthImage.addEventListener("click", function (event) { focusAt.apply(null, fractions(depthImage, event)); });
  slider.addEventListener("input", function () { showSlice(Number(slider.value), ""); });

  showSlice(data.start, "click to refocus, drag to change the viewpoint");
})();
"""


def _json_for_script(data: dict[str, Any]) -> str:
    """JSON that is safe inside ``<script type="application/json">``: every ``<`` is written ``\\u003c``, so no
    ``</script>`` or ``<!--`` can end the element (``JSON.parse`` reads it back as ``<``)."""
    return json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")


def lightfield_page_html(lf: LightField, *, title: str | None = None, **kw: Any) -> str:
    """The complete page (see the module docstring) as one HTML document.

    Parameters
    ----------
    lf : LightField
    title : str, optional
        Default: the light field's source file name, else 'light field'.
    **kw
        Keywords of :func:`lightfield_page_data`.

    Returns
    -------
    str
    """
    data = lightfield_page_data(lf, **kw)
    V, U, Y, X, C = lf.shape
    source = lf.geometry.source
    title = title or (f"Light field {Path(str(source)).name}" if source else "Light field")
    last = len(data["slopes"]) - 1
    depth = data["depth"]
    width = depth["width"]                     # the inlined images' width (px)
    viewer = (
        f'<style>{_STYLE}</style>'
        f'<div id="lf-viewer" class="lf-viewer" data-mode="focus">'
        f'<div class="lf-main" style="max-width:{max(UPSCALE_LIMIT * width, 480)}px">'
        f'<div id="lf-status" role="status">loading</div><div class="lf-frame">'
        f'<img id="lf-photo" alt="refocused photograph" draggable="false" src="{data["slices"][data["start"]]}">'
        f'<div id="lf-marker"></div></div>'
        f'<label class="muted" for="lf-slider">focal stack</label>'
        f'<input id="lf-slider" class="lf-slider" type="range" min="0" max="{last}" step="1" value="{data["start"]}">'
        f'<p class="muted">Click the photograph to focus at that point (the slice whose slope is nearest to the '
        f'median disparity of a {depth["window"]}&times;{depth["window"]} window there); drag it to look from '
        f'another viewpoint ({len(data["views"])} of the {V}&times;{U} views).</p></div>'
        f'<div class="lf-side"><img id="lf-depth" alt="disparity map" src="{depth["src"]}">'
        f'<div class="lf-legend"><span>far&nbsp;{depth["vmin"]:.3f}</span><span>disparity (px/view, '
        f'{escape(depth["cmap"])}; {escape(depth["method"])}; grey: confidence &lt; {depth["min_confidence"]:g})'
        f'</span><span>{depth["vmax"]:.3f}&nbsp;near</span></div>'
        f'<p class="muted">Slopes {data["slopes"][0]:.3f} to {data["slopes"][-1]:.3f} px per view step in '
        f'{last + 1} slices; {Y}&times;{X} px, '
        f'{"monochrome" if C == 1 else escape(COLOUR_WORDS.get(lf.colour, lf.colour))}.</p></div></div>'
        f'<script type="application/json" id="lf-data">{_json_for_script(data)}</script>'
        f'<script>{_SCRIPT}</script>'
    )
    return page(title, [viewer], subtitle="Click to refocus, drag to change the viewpoint; a page written by "
                                          "plenodecode, without any external file.")


def write_lightfield_page(lf: LightField, path: str | os.PathLike, *, overwrite: bool = False,
                          progress: Progress = None, **kw: Any) -> Path:
    """Write the interactive page of a light field (see the module docstring), atomically.

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32, at least two views.
    path : path-like
        The ``.html`` file to create.
    overwrite : bool
        Replace an existing file (otherwise :class:`FileExistsError`, raised before any work).
    progress : callable(done, total), optional
    **kw
        ``title`` and the keywords of :func:`lightfield_page_data` (``n_slices``, ``views``, ``depth_method``,
        ``max_side``, ``jpeg_quality``, ``depth_window``).

    Returns
    -------
    Path
    """
    refuse_existing([path], overwrite)
    html = lightfield_page_html(lf, progress=progress, **kw)
    out = write_html(path, html, overwrite=overwrite)
    log.info("wrote the light-field page %s (%.1f MB)", out, len(html) / 1e6)
    return out


__all__ = ["DEFAULT_SLICES", "DEFAULT_VIEWS", "DEFAULT_MAX_SIDE", "DEFAULT_JPEG_QUALITY", "DEFAULT_DEPTH_WINDOW",
           "stack_slopes", "stack_alphas", "view_subset", "lightfield_page_data", "lightfield_page_html",
           "write_lightfield_page"]
