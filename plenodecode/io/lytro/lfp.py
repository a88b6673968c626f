"""Lytro picture files: the raw of an F01 ``.lfp`` / Illum ``.lfr``, writers of both, payload extraction."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import FormatError
from ...types import CameraMetadata, RawCapture
from .. import packing
from ..atomic import atomic_outputs, refuse_existing
from .contents import EXTENSIONS, ContentItem, summarise_contents
from .container import read_container, section_name, write_container
from .fields import lookup, lookup_dict, first_frame, normalise_sha1
from .metadata import packed_size_or_error, tags_entry, lytro_metadata, metadata_from_lytro

ILLUM_PICTURE_SCHEMA = "http://schema.lytro.com/lfp/picture/2.1.4/picture_schema.json"
#: References of the picture's frame kept in ``metadata.extra['lytro']['frame_refs']`` by :func:`read_lytro`:
#: the GCT that names the camera's white image (via ``cal_file_manifest.json``) and a per-picture white image.
FRAME_REFS = ("geometryCorrectionRef", "modulationDataRef")


def frame_ref(metadata: CameraMetadata, key: str) -> str | None:
    """A reference of :data:`FRAME_REFS` kept by :func:`read_lytro` (``'sha1-<hex>'``), None when absent."""
    ref = lookup(metadata.extra, "lytro", "frame_refs", key)
    return ref if isinstance(ref, str) else None


def read_lytro(path: str | os.PathLike, *, verify: bool = True) -> RawCapture:
    """Read the raw sensor image of an F01 ``.lfp`` or Illum ``.lfr`` (either section order).

    Parameters
    ----------
    path : path-like
    verify : bool
        Check every section's SHA-1 (see :func:`read_container`).

    Returns
    -------
    RawCapture
        ``mosaic`` (H, W) uint16 as on the sensor, ``cfa``, per-position levels and
        :class:`CameraMetadata` (see :func:`metadata_from_lytro`).

    Raises
    ------
    FormatError
        A processed (Desktop) file with no raw inside, a damaged container, or a payload
        whose size disagrees with width x height x bits / 8.
    """
    c = read_container(path, verify=verify)
    where = str(c.path)
    if c.kind == "calibration":
        raise FormatError(f"{where}: is a Lytro calibration archive (data.C.N) of {len(c.items)} files, not a "
                          f"picture; run 'plenodecode info {where}' to list it")
    if c.kind != "raw":
        raise FormatError(f"{where}: holds no raw image: it is a processed Lytro Desktop file with "
                          f"{summarise_contents(c.items)}; 'plenodecode extract {where} -o DIR' writes those items out "
                          f"(images, depth maps) as files")
    if c.metadata is None:
        raise FormatError(f"{where}: the raw's frame metadata is missing (no metadata or metadataRef section); "
                          "the file is incomplete")
    cam, cfa, black, white, w, h, bits, endian = metadata_from_lytro(
        c.metadata, c.private_metadata, c.path, white_image=c.white_image)
    ref = lookup_dict(first_frame(c.toc), "frame").get("imageRef")
    buf = c.payload(ref)
    expected = packed_size_or_error(h, w, bits, where)
    if len(buf) != expected:
        raise FormatError(f"{where}: the raw payload is {len(buf)} bytes but the metadata declares {w} x {h} at "
                          f"{bits} bit = {expected} bytes; the file is damaged or its metadata is wrong")
    mosaic = packing.unpack(buf, h, w, bits, endian)
    frame = lookup_dict(first_frame(c.toc), "frame")
    refs = {k: normalise_sha1(frame[k]) for k in FRAME_REFS if isinstance(frame.get(k), str)}
    if refs:
        lytro_extra = lookup_dict(cam.extra, "lytro")
        cam = replace(cam, extra={**cam.extra, "lytro": {**lytro_extra, "frame_refs": refs}})
    return RawCapture(mosaic=mosaic, cfa=cfa, black=black, white=white, metadata=cam, path=where)


def read_modulation_white(path: str | os.PathLike, *, verify: bool = True) -> RawCapture | None:
    """The per-picture white image of a Lytro Desktop raw LFP (``frame.modulationDataRef``), or None.

    The payload is packed like the picture's raw (same size, bits and CFA); LFToolbox calls it
    ``WhiteImg``.

    Returns
    -------
    RawCapture or None
        ``mosaic`` (H, W) uint16, the picture's levels and metadata with ``is_white_image`` True;
        ``path`` is ``'<file>#modulationDataRef'``.  None when the frame has no such reference.

    Raises
    ------
    FormatError
        A damaged container, or a payload whose size disagrees with the picture's layout.
    """
    c = read_container(path, verify=verify)
    ref = lookup_dict(first_frame(c.toc), "frame").get("modulationDataRef")
    if not isinstance(ref, str) or c.metadata is None:
        return None
    cam, cfa, black, white, w, h, bits, endian = metadata_from_lytro(c.metadata, c.private_metadata, c.path)
    buf = c.payload(ref)
    expected = packed_size_or_error(h, w, bits, str(c.path))
    if len(buf) != expected:
        raise FormatError(f"{c.path}: the per-picture white image (modulationDataRef) is {len(buf)} bytes but the "
                          f"picture is {w} x {h} at {bits} bit = {expected} bytes; the file is damaged")
    return RawCapture(mosaic=packing.unpack(buf, h, w, bits, endian), cfa=cfa, black=black, white=white,
                      metadata=replace(cam, is_white_image=True), path=f"{c.path}#modulationDataRef")


def _frame_payloads(raw: RawCapture, schema: str, bits: int, *, geometry_correction: bytes | None = None,
                    modulation: RawCapture | None = None) -> tuple[bytes, bytes, bytes, dict, list[bytes]]:
    """``(image, metadata JSON, private metadata JSON, frame entry, extra payloads)`` of a picture file.

    ``image`` is ``raw.mosaic`` packed at ``bits``; the frame entry ``{frame: {metadataRef,
    privateMetadataRef, imageRef[, geometryCorrectionRef][, modulationDataRef]}, parameters}`` refers to
    the payloads by their section names; the extra payloads are the GCT and the packed per-picture white.
    """
    meta, private = lytro_metadata(raw, schema=schema, bits=bits)
    image = packing.pack(raw.mosaic, bits)
    meta_b = json.dumps(meta, indent="\t").encode("utf-8")
    priv_b = json.dumps(private, indent="\t").encode("utf-8")
    frame = {"metadataRef": section_name(meta_b), "privateMetadataRef": section_name(priv_b),
             "imageRef": section_name(image)}
    extra: list[bytes] = []
    if geometry_correction is not None:
        extra.append(bytes(geometry_correction))
        frame["geometryCorrectionRef"] = section_name(extra[-1])
    if modulation is not None:
        if modulation.shape != raw.shape:
            raise ValueError(f"modulation must be a white image of the picture's size {raw.shape}, "
                             f"got {modulation.shape}")
        extra.append(packing.pack(modulation.mosaic, bits))
        frame["modulationDataRef"] = section_name(extra[-1])
    return image, meta_b, priv_b, {"frame": frame, "parameters": tags_entry(raw)}, extra


def write_lfr(path: str | os.PathLike, raw: RawCapture, *, geometry_correction: bytes | None = None,
              modulation: RawCapture | None = None, overwrite: bool = False) -> Path:
    """Write an Illum-camera-style ``.lfr``: 10-bit raw, LFC sections first, LFM last.

    The TOC has the 'picture 2.1' shape (``frames[0].frame.{metadataRef, privateMetadataRef,
    imageRef}``, ``thumbnails``, ``views``, ...); the metadata uses the Illum schema and is
    generated from ``raw.metadata`` (see :func:`lytro_metadata`), so :func:`read_lytro`
    returns the same mosaic, levels, CFA and metadata.  ``geometry_correction`` (the bytes of the
    camera's ``*.GCT``) is stored and named by ``frame.geometryCorrectionRef``; ``modulation`` (a white
    image of the same size) by ``frame.modulationDataRef``.

    Raises
    ------
    ValueError
        ``raw`` cannot be 10-bit packed (values >= 1024, pixel count not divisible by 4, no CFA).
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = Path(path)
    refuse_existing([p], overwrite)
    image, meta_b, priv_b, frame, extra = _frame_payloads(raw, "illum", 10, geometry_correction=geometry_correction,
                                                          modulation=modulation)
    toc = {
        "schema": ILLUM_PICTURE_SCHEMA,
        "generators": ["lightning"],
        "thumbnails": [],
        "derivations": [],
        "views": [],
        "annotations": [],
        "frames": [frame],
    }
    return write_container(p, toc, [*extra, image, meta_b, priv_b], lfm_first=False, overwrite=overwrite)


def write_lfp(path: str | os.PathLike, raw: RawCapture, *, geometry_correction: bytes | None = None,
              modulation: RawCapture | None = None, overwrite: bool = False) -> Path:
    """Write an F01 Lytro-Desktop-style raw ``.lfp``: LFM first, 12-bit big-endian raw, F01 schema.

    ``geometry_correction`` and ``modulation`` as :func:`write_lfr` (a Desktop export may carry the
    picture's own white image as ``modulationDataRef``).

    Raises
    ------
    ValueError
        ``raw`` cannot be 12-bit packed (values >= 4096, odd pixel count, no CFA).
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = Path(path)
    refuse_existing([p], overwrite)
    image, meta_b, priv_b, frame, extra = _frame_payloads(raw, "rawdetails", 12,
                                                          geometry_correction=geometry_correction,
                                                          modulation=modulation)
    toc = {
        "picture": {
            "frameArray": [frame],
            "viewArray": [],
            "accelerationArray": [],
            "derivationArray": [],
        },
        "thumbnailArray": [],
        "version": {"major": 1, "minor": 0, "provisionalDate": "2012-02-07"},
    }
    return write_container(p, toc, [meta_b, priv_b, image, *extra], lfm_first=True, overwrite=overwrite)


#: The file :func:`extract_contents` writes the table of contents to.
TOC_FILE = "toc.json"


def content_file_name(item: ContentItem) -> str:
    """The file name :func:`extract_contents` gives ``item``: its name and the extension of its type."""
    return item.name + EXTENSIONS.get(item.type, ".bin")


#: Content types whose 2-D float maps :func:`extract_contents` also writes as a picture (:func:`preview_file_name`).
PREVIEW_TYPES = ("depth", "confidence")


def preview_file_name(item: ContentItem) -> str | None:
    """``<name>.png``: the colour-mapped picture :func:`extract_contents` writes beside a 2-D depth or confidence
    map's ``.npy`` (which no picture viewer opens); None for any other item."""
    return item.name + ".png" if item.type in PREVIEW_TYPES and item.shape is not None and len(item.shape) == 2 \
        else None


def _preview_png(values: np.ndarray, item: ContentItem) -> bytes:
    """PNG bytes of a (rows, cols) float32 map with its colour bar (:func:`~plenodecode.io.depthio.colour_map_image`):
    depth in the depth colour map, in the container's own units (Lytro's lambda), confidence in grey."""
    import cv2

    from ..depthio import DEPTH_CMAP, colour_map_image
    from ..images import quantise

    depth = item.type == "depth"
    rgb = colour_map_image(values, label="depth (Lytro lambda)" if depth else "confidence",
                           cmap=DEPTH_CMAP if depth else "gray",
                           title=f"{item.name}, {values.shape[1]} x {values.shape[0]}")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(quantise(rgb, 8), cv2.COLOR_RGB2BGR))
    if not ok:
        raise FormatError(f"cannot encode the picture of {item.name}")
    return buf.tobytes()


def extract_contents(path: str | os.PathLike, out_dir: str | os.PathLike, *,
                     overwrite: bool = False) -> list[Path]:
    """Save every payload of a container as a file in ``out_dir``.

    JPEGs -> ``.jpg``, H.264 blocks -> ``.h264``, depth / confidence maps and depth LUTs ->
    ``.npy`` float32 (rows, cols) (payloads are little-endian float32), the 2-D depth and confidence maps also as
    a picture with a colour bar (:func:`preview_file_name`), JSON -> ``.json``,
    the raw -> ``frame.raw`` beside ``frame.json`` (readable with :func:`read_raw_pair`),
    and the table of contents -> ``toc.json``.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    FormatError
        A damaged container, or a float map whose size disagrees with its declared shape.
    FileExistsError
        A target exists and ``overwrite`` is False (nothing is written then).
    """
    c = read_container(path)
    out = Path(out_dir)
    plan: list[tuple[Path, Any]] = [(out / TOC_FILE, json.dumps(c.toc, indent="\t").encode("utf-8"))]
    for it in c.items:
        buf = c.payload(it.sha1)
        target = out / content_file_name(it)
        if it.type in ("depth", "confidence", "lut"):
            if it.shape is not None and it.shape[0] * it.shape[1] * 4 != len(buf):
                raise FormatError(f"{c.path}: {it.name} is {len(buf)} bytes, but the TOC declares "
                                  f"{it.shape[1]} x {it.shape[0]} float32 = {it.shape[0] * it.shape[1] * 4}; "
                                  "the file is damaged")
            if len(buf) % 4:
                raise FormatError(f"{c.path}: {it.name} is {len(buf)} bytes, not a whole number of float32")
            arr = np.frombuffer(buf, "<f4").astype(np.float32)
            arr = arr.reshape(it.shape) if it.shape is not None else arr
            plan.append((target, arr))
            if preview_file_name(it) is not None:
                plan.append((out / preview_file_name(it), _preview_png(arr, it)))
        else:
            plan.append((target, buf))
    with atomic_outputs([t for t, _ in plan], overwrite=overwrite) as tmps:
        for tmp, (_, obj) in zip(tmps, plan):
            with open(tmp, "wb") as fh:
                if isinstance(obj, np.ndarray):
                    np.save(fh, obj, allow_pickle=False)
                else:
                    fh.write(obj)
    return [t for t, _ in plan]
