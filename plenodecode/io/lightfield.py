"""Saving, loading and exporting light fields (:class:`plenodecode.types.LightField`).

Formats (:data:`LIGHTFIELD_FORMATS`; ``format=None`` picks one from the path):

``zarr``  (``X.zarr`` folder)
    Zarr v3 group: array ``data`` (V, U, Y, X, C) float32 chunked one view per chunk
    ``(1, 1, Y, X, C)``, ``weight`` (V, U, Y, X) chunked ``(1, 1, Y, X)`` when present;
    attributes ``format``, ``version``, ``colour``, ``geometry``, ``metadata`` (see below).  Lossless
    float32 (``bit_depth`` is not used).  A single view is read from its own chunk.
``views``  (a folder)
    ``input_Cam000.png`` ... (HCI naming, index ``v * U + u``), 8/16-bit PNG (or TIFF with
    ``image_ext='.tif'``) or 32-bit EXR, plus ``lightfield.json`` (shape, colour, geometry, metadata,
    bit depth) and ``weight.npy`` when the light field has weights.  A folder without
    ``lightfield.json`` but with ``parameters.cfg`` is an HCI benchmark scene: its camera
    parameters become ``geometry.hci`` as :func:`plenodecode.io.hci.read_hci` reads them.
``mat``  (``X.mat``)
    LFToolbox-compatible MATLAB file: ``LF`` uint16 ``(j, i, l, k, c) = (V, U, Y, X, C + 1)``,
    the weight as the last channel (ones when the light field has none), values
    ``rint(clip(x, 0, 1) * 65535)``; ``LFMetadata`` struct (field ``plenodecode``: the JSON document
    of the other formats).  Always 16 bit.
``npy``  (``X.npy``)
    ``X.npy`` float32 data, ``X.weight.npy`` when present, ``X.json`` with colour, geometry and metadata.
    Lossless; a single view is read through a memory map.
``eslf``  (``X.png``, ``X.tif``)
    The Stanford Lytro archive mosaic ``eslf[y * V + v, x * U + u] = LF[v, u, y, x]`` as one
    8/16-bit image, the weight (if any) as an alpha channel, plus ``X.json`` with V and U.
    Without the sidecar, 14 x 14 views are assumed (the archive's layout).

Metadata schema (the document every format stores), ``version`` :data:`FORMAT_VERSION`:

* version 2: ``geometry`` is :meth:`plenodecode.types.LightFieldGeometry.to_dict` (itself versioned,
  :data:`plenodecode.types.GEOMETRY_SCHEMA_VERSION`), ``metadata`` the free-form provenance;
* version 1 (before the typed geometry): no ``geometry``; ``metadata`` is the free dict whose legacy keys
  ('source', 'calibration', 'camera', 'spatial_step_px', ...) :class:`LightField` converts.  Such files
  still load with the same geometry.

Integer formats clip to [0, 1].  ``encode_srgb=True`` applies the sRGB transfer function
before quantising and records the encoded colour state: 'srgb' for linear sRGB, 'camera-srgb-curve' for camera
RGB (no white balance or colour matrix: the sRGB tone curve, not sRGB colours; :func:`linearise` takes it back to
'camera'); by default 8-bit views and ESLF of a linear light field are encoded so (:func:`stores_display_encoded`),
by every front end alike.  Every output is written under a temporary name in the destination folder and renamed;
nothing is replaced without ``overwrite=True``.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import FormatError, MetadataError
from ..types import (COLOUR_STATES, LINEAR_COLOUR_STATES, LightField, LightFieldGeometry, encoded_colour_state,
                     linear_colour_state)
from .atomic import atomic_output, atomic_outputs, interrupts_between_steps, refuse_existing
from .generic import json_safe
from .images import quantise, read_image, srgb_decode, srgb_encode, to_unit_float, write_image

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None
FORMAT_TAG = "plenodecode.LightField"
#: Version of the saved document; 2 stores the typed geometry (see the module docstring).
FORMAT_VERSION = 2
VIEWS_JSON = "lightfield.json"
#: Angular size assumed for an ESLF image without a sidecar (Stanford Lytro archive).
ESLF_DEFAULT_VIEWS = (14, 14)


@dataclass(frozen=True)
class LightFieldFormat:
    """One entry of :data:`LIGHTFIELD_FORMATS`."""

    name: str
    save: Callable[..., None]          # save(lf, path, *, bit_depth, progress, image_ext)
    load: Callable[..., Any]           # load(path, *, view) -> LightField | ndarray
    description: str


# ----------------------------------------------------------------------------- helpers
def _attrs(lf: LightField) -> dict[str, Any]:
    return {"format": FORMAT_TAG, "version": FORMAT_VERSION, "colour": lf.colour,
            "geometry": json_safe(lf.geometry.to_dict()), "metadata": json_safe(lf.provenance)}


def _restored(data: np.ndarray, weight: np.ndarray | None, colour: str, doc: Mapping[str, Any],
              src: Path) -> LightField:
    """The light field of a saved document: version 2 has the typed ``geometry``; in version 1 the geometry
    is in the legacy keys of ``metadata``, which :class:`LightField` reads."""
    provenance = dict(doc.get("metadata") or {})
    if colour not in COLOUR_STATES:     # a state added after this version (as 'camera-srgb-curve' was)
        raise FormatError(f"{src}: colour state {colour!r} is unknown to this plenodecode (it knows "
                          f"{', '.join(COLOUR_STATES)}): written by a newer version; upgrade plenodecode")
    if doc.get("geometry") is None:
        return LightField(data, weight, colour, provenance)
    try:
        geometry = LightFieldGeometry.from_dict(doc["geometry"])
    except (MetadataError, TypeError, ValueError) as exc:
        raise FormatError(f"{src}: unreadable light-field geometry ({exc}); rewrite the light field") from exc
    return LightField(data, weight, colour, provenance, geometry)


def _check_version(doc: Mapping[str, Any], src: Path) -> None:
    if int(doc.get("version", 0) or 0) > FORMAT_VERSION:
        raise FormatError(f"{src}: light-field format version {doc.get('version')} is newer than this plenodecode "
                          f"reads ({FORMAT_VERSION}); upgrade plenodecode")


#: Light-field formats stored as image files (a views folder, an ESLF mosaic): at 8 bits they are sRGB-encoded.
IMAGE_LIGHTFIELD_FORMATS = ("views", "eslf")


def stores_display_encoded(format: str, colour: str, bit_depth: int) -> bool:
    """Whether a light field of colour state ``colour`` saved as ``format`` at ``bit_depth`` is sRGB-encoded by
    default (:func:`save_lightfield`, every front end): the 8-bit image formats (views, eslf) of a linear one are,
    as every photograph is (8-bit linear views look dark and keep 1/255 steps in the shadows); the data then load
    back as colour 'srgb', or 'camera-srgb-curve' for camera RGB (:func:`linearise` undoes either).  Every other
    format and depth stores linear light."""
    return format in IMAGE_LIGHTFIELD_FORMATS and int(bit_depth) == 8 and colour in LINEAR_COLOUR_STATES


def _encoded(lf: LightField, encode_srgb: bool) -> LightField:
    """``lf`` with the sRGB transfer function applied, its colour state the encoded one of its own
    (:func:`~plenodecode.types.encoded_colour_state`: camera RGB stays camera RGB, 'camera-srgb-curve')."""
    if not encode_srgb:
        return lf
    if lf.geometry.display_encoded:
        raise ValueError(f"encode_srgb: the light field is already sRGB-encoded (colour {lf.colour!r})")
    return lf.replace(data=srgb_encode(lf.data), colour=encoded_colour_state(lf.colour))


def linearise(lf: LightField) -> LightField:
    """The light field in linear light: an sRGB-encoded one ('srgb', 'camera-srgb-curve') through the inverse
    sRGB transfer function (:func:`plenodecode.io.images.srgb_decode`, values clipped to [0, 1]), to 'linear-srgb'
    or 'camera' (:func:`~plenodecode.types.linear_colour_state`: the primaries are kept); a linear one as it is.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32.

    Returns
    -------
    LightField
        ``data`` (V, U, Y, X, C) float32; weight and geometry kept.
    """
    if not lf.geometry.display_encoded:
        return lf
    data = np.empty(lf.shape, np.float32)
    for v in range(lf.shape[0]):              # one view row at a time: srgb_decode works in float64
        data[v] = srgb_decode(lf.data[v])
    return lf.replace(data=data, colour=linear_colour_state(lf.colour))


def _tick(progress: Progress, done: int, total: int) -> None:
    if progress is not None:
        progress(done, total)


def _check_view(view: Any, shape: tuple[int, ...]) -> tuple[int, int]:
    try:
        v, u = (int(view[0]), int(view[1]))
    except (TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"view must be a (v, u) pair of ints, got {view!r}") from exc
    if not (0 <= v < shape[0] and 0 <= u < shape[1]):
        raise ValueError(f"view {view!r} is outside the {shape[0]}x{shape[1]} views")
    return v, u


# ----------------------------------------------------------------------------- zarr
def _save_zarr(lf: LightField, path: Path, *, progress: Progress, **_: Any) -> None:
    import zarr

    V, U, Y, X, C = lf.shape
    with interrupts_between_steps() as check:       # zarr writes on its own thread: Ctrl-C between views only
        group = zarr.open_group(str(path), mode="w", attributes=_attrs(lf), zarr_format=3)
        data = group.create_array("data", shape=lf.shape, dtype="float32", chunks=(1, 1, Y, X, C), fill_value=0.0,
                                  dimension_names=("v", "u", "y", "x", "c"))
        weight = None
        if lf.weight is not None:
            weight = group.create_array("weight", shape=lf.shape[:4], dtype="float32", chunks=(1, 1, Y, X),
                                        fill_value=0.0, dimension_names=("v", "u", "y", "x"))
        for k in range(V * U):
            check()
            v, u = divmod(k, U)
            data[v, u] = lf.data[v, u]
            if weight is not None:
                weight[v, u] = np.asarray(lf.weight[v, u], np.float32)
            _tick(progress, k + 1, V * U)


def _load_zarr(path: Path, *, view: tuple[int, int] | None = None) -> LightField | np.ndarray:
    import zarr

    try:
        group = zarr.open_group(str(path), mode="r")
        attrs = dict(group.attrs)
        data = group["data"]
    except Exception as exc:  # zarr raises several unrelated types for a bad store
        raise FormatError(f"{path}: not a plenodecode Zarr light field ({exc.__class__.__name__}: {exc})") from exc
    if attrs.get("format") != FORMAT_TAG:
        raise FormatError(f"{path}: Zarr group has format {attrs.get('format')!r}, expected {FORMAT_TAG!r}")
    _check_version(attrs, path)
    if view is not None:
        v, u = _check_view(view, data.shape)
        return np.asarray(data[v, u], np.float32)
    weight = np.asarray(group["weight"][...], np.float32) if "weight" in group else None
    return _restored(np.asarray(data[...], np.float32), weight, attrs.get("colour", "camera"), attrs, path)


# ----------------------------------------------------------------------------- views
_VIEW_RE = re.compile(r"^input_Cam(\d+)\.(png|tif|tiff|exr)$", re.IGNORECASE)
#: Image type of the ``views`` format's files by bit depth, when no ``image_ext`` is given.
VIEW_EXT = {8: ".png", 16: ".png", 32: ".exr"}


def _view_name(index: int, n: int, ext: str) -> str:
    return f"input_Cam{index:0{max(3, len(str(n - 1)))}d}{ext}"


def _save_views(lf: LightField, path: Path, *, bit_depth: int, progress: Progress,
                image_ext: str | None = None, **_: Any) -> None:
    V, U, Y, X, C = lf.shape
    ext = (image_ext or VIEW_EXT[bit_depth]).lower()
    for k in range(V * U):
        v, u = divmod(k, U)
        img = lf.data[v, u] if C == 3 else lf.data[v, u, :, :, 0]
        write_image(path / _view_name(k, V * U, ext), img, bit_depth=bit_depth, colour=lf.colour)
        _tick(progress, k + 1, V * U)
    doc = {**_attrs(lf), "shape": list(lf.shape), "bit_depth": bit_depth, "image_ext": ext,
           "weight": "weight.npy" if lf.weight is not None else None}
    if lf.weight is not None:
        np.save(path / "weight.npy", np.asarray(lf.weight, np.float32))
    (path / VIEWS_JSON).write_text(json.dumps(doc, indent=1), encoding="utf-8")


def _view_files(path: Path) -> dict[int, Path]:
    files = {}
    for f in path.iterdir():
        m = _VIEW_RE.match(f.name)
        if m:
            files[int(m.group(1))] = f
    return files


def _load_views(path: Path, *, view: tuple[int, int] | None = None) -> LightField | np.ndarray:
    doc: dict[str, Any] = {}
    if (path / VIEWS_JSON).is_file():
        try:
            doc = json.loads((path / VIEWS_JSON).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise FormatError(f"{path / VIEWS_JSON}: unreadable ({exc}); rewrite the light field") from exc
        _check_version(doc, path)
    files = _view_files(path)
    if not files:
        raise FormatError(f"{path}: no input_Cam*.png/.tif/.exr views; expected a folder of views")
    if doc.get("shape"):
        V, U = int(doc["shape"][0]), int(doc["shape"][1])
    else:
        side = math.isqrt(len(files))
        if side * side != len(files):
            raise FormatError(f"{path}: {len(files)} views and no {VIEWS_JSON}; cannot tell the angular shape")
        V = U = side
    missing = [k for k in range(V * U) if k not in files]
    if missing:
        raise FormatError(f"{path}: views {missing[:5]} of {V}x{U} are missing")

    def read(k: int) -> np.ndarray:
        img = read_image(files[k])
        img = to_unit_float(img) if img.dtype.kind == "u" else img.astype(np.float32)
        if img.ndim == 2:
            img = img[..., None]
        elif img.shape[2] in (2, 4):      # drop an alpha channel
            img = img[..., :-1]
        return img

    if view is not None:
        v, u = _check_view(view, (V, U))
        return read(v * U + u)
    first = read(0)
    data = np.empty((V, U, *first.shape), np.float32)
    data[0, 0] = first
    for k in range(1, V * U):
        img = read(k)
        if img.shape != first.shape:
            raise FormatError(f"{files[k]}: shape {img.shape} differs from {files[0].name} {first.shape}")
        data[k // U, k % U] = img
    weight = None
    if doc.get("weight"):
        weight = np.load(path / doc["weight"]).astype(np.float32)
    # without lightfield.json: integer PNG/TIFF views are display images (HCI), float EXR views linear
    colour = doc.get("colour") or ("camera" if files[0].suffix.lower() == ".exr" else "srgb")
    if not doc and (path / "parameters.cfg").is_file():       # an HCI benchmark scene
        from .hci import scene_geometry, scene_parameters

        return LightField(data, weight, colour, geometry=scene_geometry(path, scene_parameters(path)))
    return _restored(data, weight, colour, doc, path)


# ----------------------------------------------------------------------------- mat (LFToolbox)
def _save_mat(lf: LightField, path: Path, *, bit_depth: int, **_: Any) -> None:
    import scipy.io

    V, U, Y, X, C = lf.shape
    lf16 = np.empty((V, U, Y, X, C + 1), np.uint16)
    lf16[..., :C] = quantise(lf.data, 16)
    lf16[..., C] = 65535 if lf.weight is None else quantise(lf.weight, 16)
    meta = {
        "plenodecode": json.dumps(_attrs(lf)),
        "Colour": lf.colour,
        "HasWeight": int(lf.weight is not None),
        "Channels": "RGBW" if C == 3 else "YW",
    }
    camera = lf.geometry.camera
    if camera is not None:
        for key, field in (("model", "CamModel"), ("serial", "CamSerial"), ("zoom_step", "ZoomStep"),
                           ("focus_step", "FocusStep"), ("exposure_s", "ExposureDuration")):
            if getattr(camera, key) is not None:
                meta[field] = getattr(camera, key)
    with open(path, "wb") as fh:
        scipy.io.savemat(fh, {"LF": lf16, "LFMetadata": meta}, do_compression=True, oned_as="row")


def _load_mat(path: Path, *, view: tuple[int, int] | None = None) -> LightField | np.ndarray:
    import scipy.io

    try:
        mat = scipy.io.loadmat(str(path), squeeze_me=True, chars_as_strings=True)
    except (NotImplementedError, ValueError, OSError) as exc:
        raise FormatError(f"{path}: not a readable MATLAB v5 file ({exc}); save LFToolbox output with "
                          "save(..., '-v7') rather than '-v7.3'") from exc
    lf = mat.get("LF")
    if lf is None or np.ndim(lf) != 5:
        raise FormatError(f"{path}: no 5-D 'LF' variable (j, i, l, k, c); expected an LFToolbox decoded light field")
    info: dict[str, Any] = {}
    meta = mat.get("LFMetadata")
    if meta is not None and getattr(meta, "dtype", None) is not None and meta.dtype.names \
            and "plenodecode" in meta.dtype.names:
        try:
            info = json.loads(str(meta["plenodecode"].item()))
        except (json.JSONDecodeError, ValueError):
            info = {}
        _check_version(info, path)
    nch = lf.shape[4]
    has_weight = nch in (2, 4)
    c = nch - 1 if has_weight else nch
    scale = 1.0 / np.iinfo(lf.dtype).max if lf.dtype.kind == "u" else 1.0
    if view is not None:
        v, u = _check_view(view, lf.shape)
        return (lf[v, u, :, :, :c] * scale).astype(np.float32)
    data = (lf[..., :c] * scale).astype(np.float32)
    weight = (lf[..., c] * scale).astype(np.float32) if has_weight else None
    if info and meta is not None and "HasWeight" in meta.dtype.names and not int(meta["HasWeight"].item()):
        weight = None
    return _restored(data, weight, info.get("colour", "camera"), info, path)


# ----------------------------------------------------------------------------- npy
def _npy_side(path: Path) -> tuple[Path, Path]:
    stem = path.with_suffix("")
    return stem.with_name(stem.name + ".weight.npy"), path.with_suffix(".json")


def _npy_files(lf: LightField, path: Path) -> list[Path]:
    wpath, jpath = _npy_side(path)
    return [path, wpath, jpath] if lf.weight is not None else [path, jpath]


def _save_npy(lf: LightField, path: Path, *, tmps: Mapping[Path, Path], **_: Any) -> None:
    """Write the files of :func:`_npy_files` to their temporaries ``tmps[destination]``."""
    wpath, jpath = _npy_side(path)
    with open(tmps[path], "wb") as fh:
        np.save(fh, np.asarray(lf.data, np.float32))
    if lf.weight is not None:
        with open(tmps[wpath], "wb") as fh:
            np.save(fh, np.asarray(lf.weight, np.float32))
    tmps[jpath].write_text(json.dumps({**_attrs(lf), "weight": wpath.name if lf.weight is not None else None},
                                      indent=1), encoding="utf-8")


def _load_npy(path: Path, *, view: tuple[int, int] | None = None) -> LightField | np.ndarray:
    wpath, jpath = _npy_side(path)
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise FormatError(f"{path}: not a .npy array ({exc})") from exc
    if arr.ndim != 5:
        raise FormatError(f"{path}: array has shape {arr.shape}, expected (V, U, Y, X, C)")
    if view is not None:
        v, u = _check_view(view, arr.shape)
        return np.array(arr[v, u], np.float32)
    doc: dict[str, Any] = {}
    if jpath.is_file():
        try:
            doc = json.loads(jpath.read_text(encoding="utf-8"))
        except json.JSONDecodeError:
            doc = {}
        if doc.get("format") != FORMAT_TAG:
            doc = {}
        _check_version(doc, jpath)
    weight = np.load(wpath).astype(np.float32) if wpath.is_file() else None
    return _restored(np.array(arr, np.float32), weight, doc.get("colour", "camera"), doc, jpath)


# ----------------------------------------------------------------------------- eslf
def eslf_from_lightfield(data: np.ndarray) -> np.ndarray:
    """ESLF mosaic of a light field: ``eslf[y * V + v, x * U + u] = data[v, u, y, x]``.

    Parameters
    ----------
    data : ndarray, shape (V, U, Y, X, C)

    Returns
    -------
    ndarray, shape (Y * V, X * U, C), same dtype
    """
    V, U, Y, X, C = data.shape
    return np.ascontiguousarray(np.transpose(data, (2, 0, 3, 1, 4))).reshape(Y * V, X * U, C)


def lightfield_from_eslf(eslf: np.ndarray, views: tuple[int, int]) -> np.ndarray:
    """Inverse of :func:`eslf_from_lightfield`: (Y * V, X * U, C) -> (V, U, Y, X, C)."""
    V, U = views
    H, W = eslf.shape[:2]
    if H % V or W % U:
        raise FormatError(f"ESLF image of {W}x{H} px is not a whole number of {V}x{U} view tiles; "
                          "give V and U in the JSON sidecar")
    img = eslf if eslf.ndim == 3 else eslf[..., None]
    return np.ascontiguousarray(img.reshape(H // V, V, W // U, U, img.shape[2]).transpose(1, 3, 0, 2, 4))


def _eslf_files(lf: LightField, path: Path) -> list[Path]:
    return [path, path.with_suffix(".json")]


def _save_eslf(lf: LightField, path: Path, *, bit_depth: int, tmps: Mapping[Path, Path], **_: Any) -> None:
    """Write the files of :func:`_eslf_files` to their temporaries ``tmps[destination]``."""
    V, U, Y, X, C = lf.shape
    nch = C + (lf.weight is not None)
    dtype = {8: np.uint8, 16: np.uint16, 32: np.float32}[bit_depth]
    tiles = np.empty((Y, V, X, U, nch), dtype)          # the ESLF image, (Y*V, X*U, nch) once reshaped
    tiles[..., :C] = quantise(lf.data, bit_depth).transpose(2, 0, 3, 1, 4)
    if lf.weight is not None:
        tiles[..., C] = quantise(lf.weight, bit_depth).transpose(2, 0, 3, 1)
    write_image(tmps[path], tiles.reshape(Y * V, X * U, nch), bit_depth=bit_depth, overwrite=True, colour=lf.colour)
    tmps[path.with_suffix(".json")].write_text(
        json.dumps({**_attrs(lf), "format": "plenodecode.eslf", "V": V, "U": U, "channels": C,
                    "alpha_is_weight": lf.weight is not None}, indent=1), encoding="utf-8")


def _load_eslf(path: Path, *, view: tuple[int, int] | None = None) -> LightField | np.ndarray:
    side = path.with_suffix(".json")
    doc: dict[str, Any] = {}
    if side.is_file():
        try:
            doc = json.loads(side.read_text(encoding="utf-8"))
        except json.JSONDecodeError:
            doc = {}
        if doc.get("format") != "plenodecode.eslf":
            doc = {}
        _check_version(doc, side)
    views = (int(doc["V"]), int(doc["U"])) if doc else ESLF_DEFAULT_VIEWS
    img = read_image(path)
    img = to_unit_float(img) if img.dtype.kind == "u" else img.astype(np.float32)
    lf = lightfield_from_eslf(img, views)
    nch = lf.shape[-1]
    c = int(doc.get("channels", 3 if nch >= 3 else 1))
    has_weight = bool(doc.get("alpha_is_weight", nch in (2, 4)))
    if view is not None:
        v, u = _check_view(view, views)
        return np.ascontiguousarray(lf[v, u, :, :, :c])
    weight = np.ascontiguousarray(lf[..., c]) if has_weight and nch > c else None
    colour = doc.get("colour", "srgb")
    return _restored(np.ascontiguousarray(lf[..., :c]), weight, colour, doc, side)


# ----------------------------------------------------------------------------- registry
LIGHTFIELD_FORMATS: dict[str, LightFieldFormat] = {
    "zarr": LightFieldFormat("zarr", _save_zarr, _load_zarr, "Zarr v3 store, one chunk per view, float32"),
    "views": LightFieldFormat("views", _save_views, _load_views, "folder of input_CamNNN images + lightfield.json"),
    "mat": LightFieldFormat("mat", _save_mat, _load_mat, "LFToolbox .mat, uint16 LF (V,U,Y,X,C+1) with weight"),
    "npy": LightFieldFormat("npy", _save_npy, _load_npy, ".npy float32 (+ .weight.npy, .json)"),
    "eslf": LightFieldFormat("eslf", _save_eslf, _load_eslf, "Stanford ESLF mosaic image (+ .json with V, U)"),
}
FOLDER_FORMATS = ("zarr", "views")
_FILE_FORMATS = {".mat": "mat", ".npy": "npy", ".png": "eslf", ".tif": "eslf", ".tiff": "eslf", ".zarr": "zarr"}
#: Image types an ESLF mosaic is written as: those :func:`detect_format` reads back as one, and that hold the
#: weight as a 4th channel (a JPEG holds 3).
ESLF_EXTENSIONS = tuple(ext for ext, name in _FILE_FORMATS.items() if name == "eslf")
#: The same, for messages: '.png, .tif or .tiff'.
ESLF_NAMES = f"{', '.join(ESLF_EXTENSIONS[:-1])} or {ESLF_EXTENSIONS[-1]}"
#: Exports that are pages for people, not light fields: extension -> the ``plenodecode export --format`` name
#: (writers: ``plenodecode.cli.export.PAGE_FORMATS``).  They never load back and are not in
#: :data:`LIGHTFIELD_FORMATS`, so no command that writes a light field picks them from a name.
PAGE_EXTENSIONS = {".html": "html", ".htm": "html"}


def _page_error(p: Path) -> str:
    return (f"{p.name}: an HTML page is an export, not a light field; `plenodecode export LF -o {p.name} "
            "--format html` writes one from a saved light field LF")


def _check_format(name: str) -> LightFieldFormat:
    if name not in LIGHTFIELD_FORMATS:
        raise ValueError(f"format must be one of {sorted(LIGHTFIELD_FORMATS)}, got {name!r}")
    return LIGHTFIELD_FORMATS[name]


def format_of_extension(path: str | os.PathLike) -> str | None:
    """The light-field format the extension of ``path`` names ('.mat' -> 'mat', '.png' -> 'eslf', ...), or None."""
    return _FILE_FORMATS.get(Path(path).suffix.lower())


def detect_format(path: str | os.PathLike, *, option: str = "format=") -> str:
    """Format name of an existing light field, or of one to write at ``path``; ``option`` is how the error names
    the way to choose the format (the keyword ``format=``, or the CLI's ``--format``).

    Existing folders: ``zarr.json`` inside -> zarr, ``lightfield.json`` or ``input_Cam*`` -> views.
    Otherwise by extension: ``.zarr`` zarr, ``.mat`` mat, ``.npy`` npy, ``.png``/``.tif`` eslf;
    a path without extension is a views folder.

    Raises
    ------
    ValueError
        No format matches; or the path is an HTML page (:data:`PAGE_EXTENSIONS`), an export that is not a
        light field.
    """
    p = Path(path)
    if p.is_dir():
        if (p / "zarr.json").is_file():
            return "zarr"
        if (p / VIEWS_JSON).is_file() or _view_files(p):
            return "views"
    found = format_of_extension(p)
    if found is not None:
        return found
    ext = p.suffix.lower()
    if ext in PAGE_EXTENSIONS:
        raise ValueError(_page_error(p))
    if ext == "" and not p.is_file():
        return "views"
    raise ValueError(f"path {p.name!r}: cannot tell the light-field format from its extension "
                     f"({', '.join(sorted(_FILE_FORMATS))} or none for a views folder); pass {option} one of "
                     f"{sorted(LIGHTFIELD_FORMATS)}")


def written_files(path: str | os.PathLike, format: str) -> list[Path]:
    """Every file or folder :func:`save_lightfield` writes for ``path`` in ``format`` (ESLF: the image and its JSON;
    npy: the array, its weight and its JSON)."""
    p = Path(path)
    return [p, p.with_suffix(".json")] if format == "eslf" else [p, *_npy_side(p)] if format == "npy" else [p]


def holds_lightfield(folder: str | os.PathLike) -> bool:
    """True for a folder that is a saved light field: a zarr store or a views folder, by the files that make it one."""
    p = Path(folder)
    return p.is_dir() and ((p / "zarr.json").is_file() or (p / VIEWS_JSON).is_file() or bool(_view_files(p)))


def refuse_foreign_folder(path: str | os.PathLike) -> None:
    """ValueError when ``path`` is a folder that holds files but no light field (zarr store, views folder): writing
    a light field there, with overwrite, would replace the folder and delete them."""
    p = Path(path)
    if not p.is_dir() or p.is_symlink():
        return
    entries = sorted(e.name for e in p.iterdir())
    if not entries or holds_lightfield(p):
        return
    shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
    raise ValueError(f"{p} is a folder of other files ({shown}), not a light field: writing the light field there "
                     "would replace the folder and delete them; choose a new output path")


def _check_depth(name: str, path: Path, bit_depth: int, image_ext: str | None) -> None:
    """ValueError, before any work, for a bit depth or image type the format ``name`` cannot write at ``path``."""
    from .images import IMAGE_FORMATS

    if name == "mat" and bit_depth != 16:
        raise ValueError(f"bit_depth must be 16 for the LFToolbox .mat format (uint16 LF), got {bit_depth}")
    if name == "eslf" and path.suffix.lower() not in ESLF_EXTENSIONS:
        raise ValueError(f"path {path.name!r}: an ESLF mosaic is written as {ESLF_NAMES} (its 4th "
                         "channel is the weight, and it loads back by that extension)")
    ext = path.suffix.lower() if name == "eslf" else (image_ext or VIEW_EXT[bit_depth]).lower() \
        if name == "views" else None
    if ext is not None and bit_depth not in IMAGE_FORMATS[ext]:
        raise ValueError(f"bit_depth {bit_depth} cannot be stored in {ext} files; use one of {IMAGE_FORMATS[ext]}")


def save_lightfield(lf: LightField, path: str | os.PathLike, *, format: str | None = None, bit_depth: int = 16,
                    overwrite: bool = False, progress: Progress = None, encode_srgb: bool | None = None,
                    image_ext: str | None = None) -> Path:
    """Write a light field in one of :data:`LIGHTFIELD_FORMATS` (see the module docstring).

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32, optional ``weight`` (V, U, Y, X).
    path : path-like
        File or folder to create.
    format : str, optional
        A key of :data:`LIGHTFIELD_FORMATS`; default from :func:`detect_format`.
    bit_depth : {8, 16, 32}
        Sample depth of image-based formats (views, eslf); ``mat`` needs 16; zarr and npy
        always store float32.
    overwrite : bool
        Replace an existing output (otherwise :class:`FileExistsError`).
    progress : callable(done, total), optional
        Called after each view (zarr, views) or once at the end.
    encode_srgb : bool, optional
        Apply the sRGB transfer function first (display export); the saved colour state is the encoded one
        ('srgb' for linear sRGB, 'camera-srgb-curve' for camera RGB).  Default
        (None): :func:`stores_display_encoded`, so 8-bit views and ESLF of a linear light field are encoded, as
        the CLI writes them; False keeps linear light.
    image_ext : str, optional
        Image type of the ``views`` format: '.png', '.tif' or '.exr' (default by bit depth).

    Returns
    -------
    Path
        The written file or folder.
    """
    if not isinstance(lf, LightField):
        raise ValueError(f"lf must be a LightField, got {type(lf).__name__}")
    if bit_depth not in (8, 16, 32):
        raise ValueError(f"bit_depth must be 8, 16 or 32, got {bit_depth!r}")
    p = Path(path)
    name = format or detect_format(p)
    fmt = _check_format(name)
    if image_ext is not None and image_ext.lower() not in (".png", ".tif", ".tiff", ".exr"):
        raise ValueError(f"image_ext must be '.png', '.tif' or '.exr', got {image_ext!r}")
    _check_depth(name, p, bit_depth, image_ext)
    refuse_foreign_folder(p)
    if encode_srgb is None:
        encode_srgb = stores_display_encoded(name, lf.colour, bit_depth)
    lf = _encoded(lf, encode_srgb)
    outputs = [p]
    if name == "npy":
        outputs += list(_npy_side(p))
    elif name == "eslf":
        outputs.append(p.with_suffix(".json"))
    refuse_existing(outputs, overwrite)
    if name in FOLDER_FORMATS:
        with atomic_output(p, overwrite=overwrite, folder=True) as tmp:
            fmt.save(lf, tmp, bit_depth=bit_depth, progress=progress, image_ext=image_ext)
    elif name == "mat":
        with atomic_output(p, overwrite=overwrite, suffix=p.suffix) as tmp:
            fmt.save(lf, tmp, bit_depth=bit_depth)
        _tick(progress, 1, 1)
    else:
        files = (_npy_files if name == "npy" else _eslf_files)(lf, p)
        with atomic_outputs(files, overwrite=overwrite, keep_suffix=True) as tmps:
            fmt.save(lf, p, bit_depth=bit_depth, tmps=dict(zip(files, tmps)))
        if name == "npy" and lf.weight is None and _npy_side(p)[0].exists():
            _npy_side(p)[0].unlink()          # a stale weight from an overwritten light field
        _tick(progress, 1, 1)
    log.info("saved %s light field %s to %s", name, lf.shape, p)
    return p


def load_lightfield(path: str | os.PathLike, *, view: tuple[int, int] | None = None,
                    format: str | None = None) -> LightField | np.ndarray:
    """Read a light field written by :func:`save_lightfield` (or an LFToolbox .mat / Stanford ESLF).

    Parameters
    ----------
    path : path-like
    view : (v, u), optional
        Return only that view, (Y, X, C) float32.  zarr reads one chunk, views one image,
        npy a memory-mapped slice; mat and eslf read the file and slice.
    format : str, optional
        Force a format instead of :func:`detect_format`.

    Returns
    -------
    LightField, or ndarray (Y, X, C) float32 when ``view`` is given.
        Integer formats come back as float32 in [0, 1].

    Raises
    ------
    FormatError
        Missing or malformed input.
    """
    p = Path(path)
    if not p.exists():
        raise FormatError(f"{p}: no such light field; check the path")
    try:
        name = format or detect_format(p)
    except ValueError as exc:
        raise FormatError(str(exc)) from exc
    return _check_format(name).load(p, view=view)


__all__ = ["LIGHTFIELD_FORMATS", "PAGE_EXTENSIONS", "LightFieldFormat", "save_lightfield", "load_lightfield",
           "linearise", "detect_format", "eslf_from_lightfield", "lightfield_from_eslf", "ESLF_DEFAULT_VIEWS",
           "ESLF_EXTENSIONS", "ESLF_NAMES", "VIEW_EXT", "FOLDER_FORMATS", "holds_lightfield", "refuse_foreign_folder",
           "written_files"]
