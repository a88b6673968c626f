"""Writing depth results: PFM (HCI toolkit), float EXR, colour-mapped PNG with a legend (low-confidence pixels
greyed out), the confidence map (EXR and PNG), coloured PLY.

Every writer is atomic (temporary file in the same folder, then rename) and refuses to replace an existing
file unless ``overwrite=True``.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from ..metadata import LINEAR_COLOUR_STATES
from .atomic import atomic_output, check_destination, refuse_folder, write_bytes_atomic
from .images import quantise, write_image
from .pfm import write_pfm

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------------------------------
# PLY
# ---------------------------------------------------------------------------------------------------------------
def write_ply(path: str | os.PathLike, points: np.ndarray, colours: np.ndarray | None = None, *,
              overwrite: bool = False) -> Path:
    """Write a point cloud as binary little-endian PLY (``x y z`` float32, ``red green blue`` uchar).

    Parameters
    ----------
    points : ndarray (N, 3) float
    colours : ndarray (N, 3) uint8, optional

    Returns
    -------
    Path
    """
    pts = np.asarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colours is not None:
        col = np.asarray(colours)
        if col.shape != pts.shape or col.dtype != np.uint8:
            raise ValueError(f"colours must be uint8 of shape {pts.shape}, got {col.dtype} {col.shape}")
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    rec = np.empty(len(pts), dtype=fields)
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if colours is not None:
        rec["red"], rec["green"], rec["blue"] = col[:, 0], col[:, 1], col[:, 2]
    props = "".join(f"property {'float' if t == '<f4' else 'uchar'} {n}\n" for n, t in fields)
    header = (f"ply\nformat binary_little_endian 1.0\ncomment written by plenodecode\n"
              f"element vertex {len(pts)}\n{props}end_header\n").encode("ascii")
    return write_bytes_atomic(path, [header, rec.tobytes()], overwrite=overwrite)


def read_ply(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a PLY written by :func:`write_ply`: ``(points (N, 3) float32, colours (N, 3) uint8 or None)``."""
    from ..errors import FormatError

    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise FormatError(f"{path}: not a PLY file (no 'ply' magic or no end_header)")
    lines = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in lines:
        raise FormatError(f"{path}: only binary little-endian PLY is supported")
    n = next((int(ln.split()[2]) for ln in lines if ln.startswith("element vertex")), None)
    names = [ln.split()[2] for ln in lines if ln.startswith("property")]
    if n is None or names[:3] != ["x", "y", "z"]:
        raise FormatError(f"{path}: expected 'element vertex N' with x y z properties")
    fields = [(nm, "<f4" if nm in "xyz" else "u1") for nm in names]
    rec = np.frombuffer(data, dtype=fields, count=n, offset=end + len(b"end_header\n"))
    pts = np.stack([rec["x"], rec["y"], rec["z"]], axis=1).astype(np.float32)
    col = np.stack([rec["red"], rec["green"], rec["blue"]], axis=1) if "red" in names else None
    return pts, col


# ---------------------------------------------------------------------------------------------------------------
# colour-mapped PNG
# ---------------------------------------------------------------------------------------------------------------
#: Default colour map and percentile range of the depth PNGs (and of :func:`colour_mapped`).
DEPTH_CMAP = "turbo"
DEPTH_PERCENTILES = (1.0, 99.0)


def colour_range(values: np.ndarray, *, percentiles: tuple[float, float] = DEPTH_PERCENTILES,
                 vmin: float | None = None, vmax: float | None = None) -> tuple[float, float]:
    """The value range a colour map spans: given limits, else percentiles of the finite values.

    Parameters
    ----------
    values : ndarray, any shape, float (NaN and inf are ignored)
    percentiles : (float, float)
        Lower and upper percentile used for a limit that is not given; ``(0, 1)`` when no value is finite.
    vmin, vmax : float, optional
        Fixed limits.

    Returns
    -------
    (vmin, vmax) : float
        ``vmax = vmin + 1e-6`` when the range would be empty.
    """
    v = np.asarray(values, np.float64)
    if vmin is None or vmax is None:
        fin = v[np.isfinite(v)]
        lo, hi = (np.percentile(fin, list(percentiles)) if fin.size else (0.0, 1.0))
        vmin = lo if vmin is None else vmin
        vmax = hi if vmax is None else vmax
    if not vmax > vmin:
        vmax = vmin + 1e-6
    return vmin, vmax


def colour_mapped(values: np.ndarray, *, cmap: str = DEPTH_CMAP, percentiles: tuple[float, float] = DEPTH_PERCENTILES,
                  vmin: float | None = None, vmax: float | None = None) -> np.ndarray:
    """A disparity or depth map as RGB colours: ``cmap(clip((x - vmin) / (vmax - vmin), 0, 1))``, NaN black.

    Parameters
    ----------
    values : ndarray (Y, X), float
    cmap : str
        A matplotlib colour map name.
    percentiles, vmin, vmax
        The range, see :func:`colour_range`.

    Returns
    -------
    ndarray (Y, X, 3), float32 in [0, 1]
        Non-finite values are black.
    """
    from matplotlib import colormaps

    v = np.asarray(values, np.float64)
    finite = np.isfinite(v)
    lo, hi = colour_range(v, percentiles=percentiles, vmin=vmin, vmax=vmax)
    t = np.clip((np.where(finite, v, lo) - lo) / (hi - lo), 0.0, 1.0)
    rgb = colormaps[cmap](t)[..., :3].astype(np.float32)
    rgb[~finite] = 0.0
    return rgb


#: Default ``min_confidence`` of the depth PNGs: pixels of lower confidence are greyed out.  On the benchmark
#: scenes (``make bench-depth``, 'costvolume'; issue 20's confidence, Nov 26) the pixels below it are 10-20x as
#: often wrong (BadPix0.07) as those above and are 18 % of hci-antinous (15.8 % against 1.7 %), 14 % of the
#: decoded illum-mini scene (7.5 % against 0.4 %) and 33 % of its ideal light field (its flat background); on
#: the ant-leg microscope capture they are its featureless background.  (0.2 greyed 22 % and 21 %, and speckled
#: the ant leg's structures.)
DEFAULT_MIN_CONFIDENCE = 0.1
#: Display colour (RGB in [0, 1]) of the pixels below ``min_confidence``.
MASK_GREY = (0.62, 0.62, 0.62)
#: Colour map of the confidence PNG (0 .. 1, fixed), and the colour of the ``min_confidence`` line on its colour bar.
CONFIDENCE_CMAP = "viridis"
CONFIDENCE_MARK = "red"


def check_min_confidence(value: float, name: str = "min_confidence") -> float:
    """``value`` as a float in [0, 1]; ValueError naming ``name`` otherwise (nan included)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in [0, 1], got {value!r}") from None
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{name} must be a number in [0, 1], got {value!r}")
    return v


def colour_map_figure(values: np.ndarray, *, label: str, cmap: str = DEPTH_CMAP, vmin: float | None = None,
                      vmax: float | None = None, percentiles: tuple[float, float] = DEPTH_PERCENTILES,
                      title: str | None = None, masked: np.ndarray | None = None, width_in: float = 6.0,
                      dpi: int | None = None, fontsize: float | None = None, mark: float | None = None,
                      near: str | None = None):
    """A matplotlib Figure (no pyplot state) of ``values`` with a colour bar naming ``label``.

    Parameters
    ----------
    values : ndarray (Y, X) float
    label : str
        Colour-bar legend, with the unit.
    cmap, vmin, vmax, percentiles
        The colour map and its range; a limit not given is a percentile of the finite values that are not
        ``masked`` (:func:`colour_range`).
    title : str, optional
    masked : ndarray (Y, X) bool, optional
        Pixels drawn in :data:`MASK_GREY` (e.g. confidence below a threshold); non-finite values are left
        transparent (the figure's white background).
    width_in, dpi, fontsize
        Width of the image part (inches), resolution (default: about one pixel per value, at least 100) and
        text size (points; default matplotlib's).
    mark : float, optional
        A value drawn as a :data:`CONFIDENCE_MARK` line across the colour bar (a threshold).
    near : {'high', 'low'}, optional
        Which end of ``values`` is nearest the camera: 'high' for disparity (HCI sign), 'low' for depth.  Near is
        then the top (warm) end of the colour map and of the colour bar in both (depth: ``cmap`` reversed, its bar
        upside down), whose ends say 'near' and 'far'.  None: the map as it is, no such words.

    The figure's size and the image's place in it depend only on the shape of ``values``, whether there is a
    title, ``width_in``, ``dpi`` and ``fontsize``: two maps of one shape line up pixel for pixel.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    if near not in (None, "high", "low"):
        raise ValueError(f"near must be 'high', 'low' or None, got {near!r}")
    if near == "low":
        cmap = colormaps[cmap].reversed()
    v = np.asarray(values, np.float64)
    grey = None if masked is None else np.asarray(masked, bool)
    if grey is not None and grey.shape != v.shape:
        raise ValueError(f"masked must have shape {v.shape}, got {grey.shape}")
    shown = v if grey is None else np.where(grey, np.nan, v)
    vmin, vmax = colour_range(shown, percentiles=percentiles, vmin=vmin, vmax=vmax)
    h, w = v.shape
    scale = width_in / max(h, w)
    dpi = max(100, int(max(h, w) / width_in)) if dpi is None else int(dpi)
    # room for the colour bar, its tick labels and its legend: at least nine characters of the text size
    bar_in = max(1.6 * width_in / 6.0, 9.0 * (fontsize or 10.0) / 72.0)
    fig = Figure(figsize=(w * scale + bar_in, h * scale + (0.5 if title else 0.2) * width_in / 6.0), dpi=dpi)
    image_share = w * scale / (w * scale + bar_in)
    ax = fig.add_axes([0.02, 0.04, image_share - 0.02, 0.9 if title else 0.92])
    im = ax.imshow(np.ma.masked_invalid(shown), cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
    if grey is not None and grey.any():
        overlay = np.zeros((h, w, 4), np.float32)
        overlay[grey] = (*MASK_GREY, 1.0)
        ax.imshow(overlay, interpolation="nearest")
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=fontsize if fontsize else 9)
    cax = fig.add_axes([image_share + 0.04 * (1 - image_share), 0.1, 0.25 * (1 - image_share), 0.8])
    cb = fig.colorbar(im, cax=cax)
    cb.set_label(label, fontsize=fontsize)
    if mark is not None:
        cb.ax.axhline(mark, color=CONFIDENCE_MARK, linewidth=2.0)
    if near is not None:
        if near == "low":
            cb.ax.invert_yaxis()
        for text, y, va in (("near", 1.01, "bottom"), ("far", -0.01, "top")):
            cb.ax.text(0.5, y, text, transform=cb.ax.transAxes, ha="center", va=va, fontsize=fontsize or 9)
    if fontsize:
        cb.ax.tick_params(labelsize=fontsize)
    return fig


def colour_map_image(values: np.ndarray, **figure_options) -> np.ndarray:
    """The figure of :func:`colour_map_figure` (same keywords) rendered to an RGB array.

    Returns
    -------
    ndarray (H, W, 3) float32 in [0, 1]
        sRGB display colours.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = colour_map_figure(values, **figure_options)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return (np.asarray(canvas.buffer_rgba())[..., :3] / np.float32(255.0)).astype(np.float32)


def write_colour_map_png(path: str | os.PathLike, values: np.ndarray, *, label: str, cmap: str = DEPTH_CMAP,
                         vmin: float | None = None, vmax: float | None = None, title: str | None = None,
                         masked: np.ndarray | None = None, mark: float | None = None, near: str | None = None,
                         overwrite: bool = False) -> Path:
    """Write ``values`` (Y, X) as a colour-mapped PNG with a legend (see :func:`colour_map_figure`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    p = check_destination(path, overwrite)            # refuse before drawing
    fig = colour_map_figure(values, label=label, cmap=cmap, vmin=vmin, vmax=vmax, title=title, masked=masked,
                            mark=mark, near=near)
    FigureCanvasAgg(fig)
    with atomic_output(p, overwrite=overwrite, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    return p


# ---------------------------------------------------------------------------------------------------------------
# everything the depth command writes
# ---------------------------------------------------------------------------------------------------------------
#: Extensions ``-o`` of the depth command takes; each names the same set of files (:func:`depth_output_paths`).
DEPTH_OUTPUT_SUFFIXES = (".pfm", ".exr", ".png")


def depth_output_paths(pfm_path: str | os.PathLike, *, ply: str | os.PathLike | None = None,
                       confidence: bool = False) -> dict[str, Path]:
    """The files :func:`write_depth_outputs` writes for ``-o X.pfm``: pfm, exr (``X.exr``), png (``X.png``),
    with ``confidence`` 'confidence_exr' and 'confidence_png' (``X_confidence.exr`` / ``.png``), and ply when
    asked.  ``X.png`` or ``X.exr`` names the same set (a user asking for the picture gets it, and the rest
    beside it)."""
    p = Path(pfm_path)
    if p.suffix.lower() not in DEPTH_OUTPUT_SUFFIXES:
        raise ValueError(f"the depth output must end in .pfm, .exr or .png (all three are written), got {p.name!r}")
    p = p.with_suffix(".pfm")
    out = {"pfm": p, "exr": p.with_suffix(".exr"), "png": p.with_suffix(".png")}
    if confidence:
        out["confidence_exr"] = p.with_name(f"{p.stem}_confidence.exr")
        out["confidence_png"] = p.with_name(f"{p.stem}_confidence.png")
    if ply is not None:
        out["ply"] = Path(ply)
    return out


def display_colours(image: np.ndarray, colour_state: str) -> np.ndarray:
    """(Y, X, C) view -> (Y, X, 3) uint8 display colours.

    ``rint(255 clip(V, 0, 1))`` with ``V`` the sRGB encoding (:func:`plenodecode.io.images.srgb_encode`) of the
    view unless it is sRGB-encoded already ('srgb', 'camera-srgb-curve'; :func:`plenodecode.io.images.quantise`);
    NaN becomes 0.
    """
    img = np.asarray(image)
    if img.shape[-1] == 1:
        img = np.repeat(img, 3, axis=-1)
    return quantise(img, 8, encode_srgb=colour_state in LINEAR_COLOUR_STATES)


def write_depth_outputs(pfm_path: str | os.PathLike, values: np.ndarray, *, label: str,
                        confidence: np.ndarray | None = None, min_confidence: float = DEFAULT_MIN_CONFIDENCE,
                        points: np.ndarray | None = None, colours: np.ndarray | None = None,
                        ply: str | os.PathLike | None = None, title: str | None = None, near: str | None = None,
                        overwrite: bool = False) -> list[Path]:
    """Write a disparity or depth map as PFM + 32-bit EXR + colour-mapped PNG (+ confidence EXR and PNG)
    (+ PLY point cloud).

    Parameters
    ----------
    pfm_path : path-like
        ``X.pfm``; the EXR and PNG are ``X.exr`` and ``X.png`` beside it.
    values : ndarray (Y, X) float32
        What the files hold (disparity in px per view step, or depth in m).
    label : str
        Legend of the PNG's colour bar (e.g. 'disparity (px / view)').
    confidence : ndarray (Y, X) float in [0, 1], optional
        Written as ``X_confidence.exr`` (float32, the values) and ``X_confidence.png``, a figure laid out as
        ``X.png`` (the same size, the map at the same pixels) in :data:`CONFIDENCE_CMAP` over 0 .. 1 with
        ``min_confidence`` marked on its colour bar; the pixels of ``X.png`` with ``confidence < min_confidence``
        are grey (:data:`MASK_GREY`) and do not count in its colour range.
    min_confidence : float in [0, 1]
        0 greys out nothing.
    points, colours : ndarray (Y, X, 3), optional
        3-D points (m) and uint8 colours for the PLY; non-finite points are skipped.
    ply : path-like, optional
        Where to write the point cloud (needs ``points``).
    near : {'high', 'low'}, optional
        Which end of ``values`` is nearest (disparity: 'high', depth: 'low'): near is the warm end of the PNG's
        colours and the top of its colour bar either way (:func:`colour_map_figure`).

    Returns
    -------
    list of Path
        The files written.  Nothing is written when any output is a folder, or exists and ``overwrite`` is False.
    """
    min_confidence = check_min_confidence(min_confidence)
    paths = depth_output_paths(pfm_path, ply=ply, confidence=confidence is not None)
    for q in paths.values():        # all checked before the first is written
        refuse_folder(q)
    if not overwrite:
        clash = [q for q in paths.values() if q.exists()]
        if clash:
            raise FileExistsError(f"{clash[0]} exists; pass overwrite=True to replace it")
    v = np.asarray(values, np.float32)
    if v.ndim != 2:
        raise ValueError(f"values must be 2-D, got shape {v.shape}")
    conf = None if confidence is None else np.clip(np.nan_to_num(np.asarray(confidence, np.float32)), 0.0, 1.0)
    if conf is not None and conf.shape != v.shape:
        raise ValueError(f"confidence must have the shape of values {v.shape}, got {conf.shape}")
    if ply is not None and points is None:
        raise ValueError("ply needs points (3-D coordinates of every pixel)")
    masked = None if conf is None or min_confidence <= 0 else conf < np.float32(min_confidence)
    # both PNGs get a title, so that their maps lie at the same pixels (colour_map_figure)
    base = title or (paths["pfm"].stem if conf is not None else None)
    title = base if masked is None else f"{base}; grey: confidence < {min_confidence:g}"
    conf_title = f"{base}: confidence" + (f"; below {min_confidence:g} (red line) is grey in {paths['png'].name}"
                                          if masked is not None else "")
    written: list[Path] = []
    paths["pfm"].parent.mkdir(parents=True, exist_ok=True)
    written.append(write_pfm(paths["pfm"], v, overwrite=overwrite))
    written.append(write_image(paths["exr"], v, bit_depth=32, overwrite=overwrite))
    written.append(write_colour_map_png(paths["png"], v, label=label, title=title, masked=masked, near=near,
                                        overwrite=overwrite))
    if conf is not None:
        written.append(write_image(paths["confidence_exr"], conf, bit_depth=32, overwrite=overwrite))
        written.append(write_colour_map_png(paths["confidence_png"], conf, label="confidence (0 = no match, 1 = sure)",
                                            cmap=CONFIDENCE_CMAP, vmin=0.0, vmax=1.0, title=conf_title,
                                            mark=min_confidence if masked is not None else None, overwrite=overwrite))
    if ply is not None:
        written.append(write_point_cloud(paths["ply"], points, colours, overwrite=overwrite))
    return written


def write_point_cloud(path: str | os.PathLike, points: np.ndarray, colours: np.ndarray | None = None, *,
                      overwrite: bool = False) -> Path:
    """PLY (:func:`write_ply`) of the finite points of a per-pixel point map ``points`` (Y, X, 3) and their
    ``colours`` (Y, X, 3) uint8."""
    pts = np.asarray(points, np.float32).reshape(-1, 3)
    keep = np.isfinite(pts).all(axis=1)
    col = None if colours is None else np.asarray(colours, np.uint8).reshape(-1, 3)[keep]
    written = write_ply(path, pts[keep], col, overwrite=overwrite)
    log.info("PLY: %d of %d points", int(keep.sum()), len(keep))
    return written


__all__ = ["write_ply", "write_point_cloud", "read_ply", "write_colour_map_png", "colour_map_figure",
           "colour_map_image", "colour_range", "colour_mapped", "DEFAULT_MIN_CONFIDENCE", "MASK_GREY",
           "CONFIDENCE_CMAP", "CONFIDENCE_MARK", "check_min_confidence", "DEPTH_CMAP", "DEPTH_PERCENTILES",
           "write_depth_outputs", "depth_output_paths", "DEPTH_OUTPUT_SUFFIXES", "display_colours"]
