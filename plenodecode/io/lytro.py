"""Lytro LFP/LFR containers, packed raws, ``MOD_NNNN.RAW`` + ``.TXT`` pairs and their metadata.

Implements ``formats.md`` §1-3:

* the container grammar (16-byte file header, then 16-byte aligned sections ``LFM``/``LFC``
  of ``96 + N`` bytes: magic, length N, ``sha1-<hex>`` name, payload), with payloads
  resolved only through the SHA-1 names the LFM table of contents (TOC) refers to;
* the raw payload packings (:mod:`plenodecode.io.packing`);
* both metadata schemas: F01 / white-image ``image.rawDetails.*`` and Illum
  ``image.pixelFormat/pixelPacking/mosaic`` (:func:`metadata_from_lytro`);
* writers that produce the same structures (used by the synthetic generator).

Readers never write; writers write to a temporary name and rename.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import mmap
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..errors import FormatError, MetadataError, PlenodecodeError
from ..types import CFA_PATTERNS, CameraMetadata, RawCapture
from . import packing
from .atomic import atomic_outputs, refuse_existing, write_bytes_atomic

log = logging.getLogger(__name__)

__all__ = [
    "Section", "ContentItem", "LytroContainer", "read_container", "read_lytro", "metadata_from_lytro",
    "find_sidecar", "read_raw_pair", "read_raw_pair_metadata", "write_container", "write_lfr", "write_lfp",
    "write_raw_pair", "extract_contents", "lytro_metadata",
    "pack_10bit", "unpack_10bit", "pack_12bit", "unpack_12bit",
]

pack_10bit = packing.pack_10bit
unpack_10bit = packing.unpack_10bit
pack_12bit = packing.pack_12bit
unpack_12bit = packing.unpack_12bit

#: File header: PNG-style magic, version 1 (uint32 BE), header length 0 (uint32 BE).
FILE_MAGIC = b"\x89LFP\r\n\x1a\n"
LFM_MAGIC = b"\x89LFM\r\n\x1a\n"
LFC_MAGIC = b"\x89LFC\r\n\x1a\n"
FILE_HEADER = FILE_MAGIC + (1).to_bytes(4, "big") + (0).to_bytes(4, "big")
#: Section header: 8 magic + 4 version + 4 length + 80-byte name field ("sha1-" + 40 hex + zeros).
SECTION_HEADER = 96
NAME_FIELD = 80
#: Largest plausible sensor side (px); larger declared sizes are refused before allocating.
MAX_SIDE = 1 << 16
#: Known sensors: packed size in bytes -> (height, width, bits, endianness).
KNOWN_SENSORS = {
    packing.packed_size(3280, 3280, 12): (3280, 3280, 12, "big"),      # F01
    packing.packed_size(5368, 7728, 10): (5368, 7728, 10, "little"),   # Illum
}
#: The Bayer tile every Lytro file declares; ``upperLeftPixel`` says which entry is at (0, 0).
LYTRO_TILE = "r,gr:gb,b"
ILLUM_PICTURE_SCHEMA = "http://schema.lytro.com/lfp/picture/2.1.4/picture_schema.json"
ILLUM_PUBLIC_SCHEMA = "http://schema.lytro.com/lfp/lytro_illum_public/1.3.4/lytro_illum_public_schema.json"
ILLUM_PRIVATE_SCHEMA = "http://schema.lytro.com/lfp/lytro_illum_private/1.1.1/lytro_illum_private_schema.json"

_SHA1_RE = re.compile(rb"sha1-[0-9a-fA-F]{40}")
_SHA1_STR_RE = re.compile(r"^sha1-[0-9a-fA-F]{40}$")


# ---------------------------------------------------------------------------------------------
# data classes
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """One section of a Lytro container.

    Attributes
    ----------
    kind : 'LFM' or 'LFC'
        Table of contents (metadata) or content block.
    offset : int
        File offset of the section header (a multiple of 16 in real files).
    length : int
        Payload length N in bytes (header, name field and padding excluded).
    sha1 : str
        ``'sha1-'`` + 40 lower-case hex digits, the SHA-1 of the payload.
    """

    kind: str
    offset: int
    length: int
    sha1: str

    @property
    def data_offset(self) -> int:
        """File offset of the payload (``offset + 96``)."""
        return self.offset + SECTION_HEADER


@dataclass(frozen=True)
class ContentItem:
    """A payload of a container, described from the TOC key that refers to it.

    Attributes
    ----------
    name : str
        File-name-like label, unique within the container (e.g. ``'focus_stack_03'``, ``'depth_map'``).
    type : str
        'raw', 'json', 'jpeg', 'h264', 'png', 'depth', 'confidence', 'lut' (the last three
        are float32 little-endian maps) or 'binary'.
    size : int
        Payload bytes.
    shape : tuple of int or None
        ``(rows, cols)`` declared in the TOC / metadata, when known.
    sha1 : str
    key : str
        TOC path of the reference, e.g. ``'views[0].accelerations[0].depthMap.imageRef'``.
    info : dict
        Extra facts from the TOC (focus lambda, number of H.264 frames, bits per pixel, ...).
    """

    name: str
    type: str
    size: int
    shape: tuple[int, int] | None
    sha1: str
    key: str
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def dtype(self) -> str | None:
        """'float32' for depth, confidence and LUT maps, 'uint16' for the raw, else None."""
        if self.type in ("depth", "confidence", "lut"):
            return "float32"
        return "uint16" if self.type == "raw" else None

    def describe(self) -> str:
        """One-line human description, e.g. ``'jpeg 704x480'``."""
        shape = f" {self.shape[1]}x{self.shape[0]}" if self.shape else ""
        dtype = f" {self.dtype}" if self.dtype == "float32" else ""
        extra = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in self.info.items())
        return f"{self.type}{dtype}{shape}" + (f" ({extra})" if extra else "")


@dataclass(frozen=True)
class LytroContainer:
    """A parsed Lytro LFP/LFR container (see :func:`read_container`).

    Attributes
    ----------
    path : Path
    sections : tuple of Section
        In file order.
    toc : dict
        The parsed LFM JSON.
    kind : str
        'raw' (holds a packed sensor image), 'processed' (Desktop output: JPEG/H.264 stacks,
        depth maps) or 'calibration' (a ``data.C.N`` archive of files).
    model, serial : str or None
        Camera model and serial; ``model_source`` says where the model came from
        ('metadata', 'toc layout' when inferred, or 'unknown').
    metadata, private_metadata : dict or None
        The frame's metadata JSON (inline or via ``metadataRef``) when present in the file.
    white_image : bool
        The frame is tagged ``modulationFrame`` (a white image).
    """

    path: Path
    sections: tuple[Section, ...] = field(repr=False)
    toc: Mapping[str, Any] = field(repr=False)
    kind: str
    model: str | None
    serial: str | None
    model_source: str
    metadata: Mapping[str, Any] | None = field(repr=False)
    private_metadata: Mapping[str, Any] | None = field(repr=False)
    white_image: bool
    items: tuple[ContentItem, ...] = field(repr=False, default=())
    _buffer: Any = field(repr=False, compare=False, default=None)

    def has(self, sha1: str) -> bool:
        """True if a section with this SHA-1 name is in the file."""
        return _norm_sha1(sha1) in self._index()

    def _index(self) -> dict[str, Section]:
        idx: dict[str, Section] = {}
        for s in self.sections:
            idx.setdefault(s.sha1, s)
        return idx

    def section(self, sha1: str) -> Section:
        """The section named ``sha1`` ('sha1-<hex>' or bare hex, any case)."""
        s = self._index().get(_norm_sha1(sha1))
        if s is None:
            raise FormatError(f"{self.path}: the TOC refers to {sha1!r}, but no section with that SHA-1 is in "
                              "the file; the file is incomplete (it may be a Desktop export without the raw)")
        return s

    def payload(self, sha1: str) -> memoryview:
        """Payload bytes of the section named ``sha1`` (zero-copy view of the file)."""
        s = self.section(sha1)
        return memoryview(self._buffer)[s.data_offset:s.data_offset + s.length]

    def contents(self) -> list[ContentItem]:
        """Every payload the TOC refers to, described (see :class:`ContentItem`)."""
        return list(self.items)

    def item(self, sha1: str) -> ContentItem | None:
        """The content item stored in section ``sha1``, or None when the TOC does not refer to it."""
        key = _norm_sha1(sha1)
        for it in self.items:
            if it.sha1 == key:
                return it
        return None


# ---------------------------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------------------------
def _norm_sha1(s: str) -> str:
    s = str(s).strip().lower()
    return s if s.startswith("sha1-") else "sha1-" + s


def _get(obj: Any, *keys: Any, default: Any = None) -> Any:
    """``obj[k0][k1]...`` through dicts and lists; ``default`` when any step is missing or of the wrong type."""
    for k in keys:
        if isinstance(k, int):
            if not isinstance(obj, list) or not -len(obj) <= k < len(obj):
                return default
        elif not isinstance(obj, Mapping) or k not in obj:
            return default
        obj = obj[k]
    return obj


def _dict(obj: Any, *keys: Any) -> Mapping[str, Any]:
    v = _get(obj, *keys)
    return v if isinstance(v, Mapping) else {}


def _number(v: Any) -> float | None:
    """``v`` as a finite float, None if it is not a number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        f = float(v)
    except OverflowError:  # a JSON integer too large for a float
        return None
    return f if math.isfinite(f) else None


def _first_number(*values: Any) -> float | None:
    for v in values:
        f = _number(v)
        if f is not None:
            return f
    return None


def _int_side(v: Any, what: str, where: str) -> int:
    f = _number(v)
    if f is None or f != int(f):
        raise MetadataError(f"{where}{what} should be a positive integer, found {v!r}; the metadata is damaged")
    n = int(f)
    if not 1 <= n <= MAX_SIDE:
        raise FormatError(f"{where}{what} = {n} is not a plausible sensor size (expected 1..{MAX_SIDE}); "
                          "the metadata is damaged, so the image is not read")
    return n


def _json_number(x: float) -> int | float:
    """Integral values as int (as Lytro writes them), others as float."""
    x = float(x)
    return int(x) if x.is_integer() and abs(x) < 2**53 else x


def _parse_json(buf: bytes | memoryview, what: str) -> Any:
    try:
        text = bytes(buf).decode("utf-8-sig")
        return json.loads(text)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise FormatError(f"{what} is not valid JSON ({type(exc).__name__}: {str(exc)[:80]}); "
                          "the file is damaged") from None


# ---------------------------------------------------------------------------------------------
# container parsing
# ---------------------------------------------------------------------------------------------
def _scan_sections(data: Any, size: int, where: str) -> list[Section]:
    """Walk the sections of a container held in ``data`` (bytes or mmap) of ``size`` bytes."""
    if size < 16:
        raise FormatError(f"{where}: {size} bytes is too short for a Lytro container (16-byte header); "
                          "the file is truncated")
    if data[:8] != FILE_MAGIC:
        raise FormatError(f"{where}: expected the Lytro magic 89 4C 46 50 0D 0A 1A 0A, found "
                          f"{bytes(data[:8]).hex(' ')}; this is not an LFP/LFR file")
    version = int.from_bytes(data[8:12], "big")
    if version != 1:
        log.warning("%s: container version %d (expected 1); reading anyway", where, version)
    pos = 16 + int.from_bytes(data[12:16], "big")
    if pos > size:
        raise FormatError(f"{where}: header length field points beyond the end of the file; the file is damaged")
    sections: list[Section] = []
    while pos < size:
        # skip the zero padding up to the next section (at most 15 bytes in conforming files)
        start = pos
        while pos < size and pos - start < 16 and data[pos] == 0:
            pos += 1
        if pos >= size:
            break
        if data[pos] == 0:
            if not np.frombuffer(data, np.uint8, offset=pos).any():  # zero tail: end of file
                break
            raise FormatError(f"{where}: more than 15 padding bytes after offset {start}; expected a section "
                              "header; the file is damaged")
        if size - pos < 16:
            raise FormatError(f"{where}: truncated section header at offset {pos} ({size - pos} bytes left)")
        magic = bytes(data[pos:pos + 8])
        if magic == LFM_MAGIC:
            kind = "LFM"
        elif magic == LFC_MAGIC:
            kind = "LFC"
        else:
            raise FormatError(f"{where}: expected a section magic (89 4C 46 4D/43 ...) at offset {pos}, found "
                              f"{magic.hex(' ')}; the file is damaged or truncated")
        n = int.from_bytes(data[pos + 12:pos + 16], "big")
        name = bytes(data[pos + 16:pos + 16 + 45])
        if n == 0 and not name.startswith(b"sha1-"):
            sections.append(Section(kind, pos, 0, "sha1-" + hashlib.sha1(b"").hexdigest()))
            pos += 16
            continue
        if pos + SECTION_HEADER + n > size:
            raise FormatError(f"{where}: the {kind} section at offset {pos} declares {n} payload bytes, but only "
                              f"{max(0, size - pos - SECTION_HEADER)} remain; the file is truncated or damaged")
        if not _SHA1_RE.fullmatch(name):
            raise FormatError(f"{where}: the {kind} section at offset {pos} has no 'sha1-<40 hex>' name field "
                              f"(found {name[:12]!r}...); the file is damaged")
        sections.append(Section(kind, pos, n, name.decode("ascii").lower()))
        pos += SECTION_HEADER + n
    return sections


def _map_file(fh: Any) -> mmap.mmap:
    """Read-only memory map of a whole (non-empty) file; pages pre-faulted where the OS allows."""
    if hasattr(mmap, "MAP_POPULATE"):
        return mmap.mmap(fh.fileno(), 0, flags=mmap.MAP_SHARED | mmap.MAP_POPULATE, prot=mmap.PROT_READ)
    return mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)


def read_container(path: str | os.PathLike, *, verify: bool = True) -> LytroContainer:
    """Parse a Lytro LFP/LFR container (any extension; also ``data.C.N`` calibration archives).

    The file is memory-mapped; payloads are located by scanning the section headers and
    resolved only by their SHA-1 names (never by position).

    Parameters
    ----------
    path : path-like
    verify : bool
        Recompute the SHA-1 of every payload and compare it with the section's name.

    Returns
    -------
    LytroContainer

    Raises
    ------
    FormatError
        Not a Lytro container, truncated, impossible section length, SHA-1 mismatch,
        missing or unparsable table of contents.
    """
    p = Path(path)
    where = str(p)
    try:
        size = p.stat().st_size
        with open(p, "rb") as fh:
            if size < 16:
                data: Any = fh.read()
            else:
                data = _map_file(fh)
    except FileNotFoundError:
        raise FormatError(f"{where}: no such file") from None
    except IsADirectoryError:
        raise FormatError(f"{where}: is a directory, expected a Lytro LFP/LFR file") from None
    size = len(data)
    sections = _scan_sections(data, size, where)
    if verify:
        for s in sections:
            digest = hashlib.sha1(memoryview(data)[s.data_offset:s.data_offset + s.length]).hexdigest()
            if "sha1-" + digest != s.sha1:
                raise FormatError(f"{where}: SHA-1 mismatch in the {s.kind} section at offset {s.offset}: the name "
                                  f"says {s.sha1[5:17]}..., the payload hashes to {digest[:12]}...; the file is "
                                  "damaged")
    lfms = [s for s in sections if s.kind == "LFM"]
    if len(lfms) != 1:
        raise FormatError(f"{where}: expected exactly one LFM (table of contents) section, found {len(lfms)}; "
                          "the file is damaged or truncated")
    lfm = lfms[0]
    toc = _parse_json(memoryview(data)[lfm.data_offset:lfm.data_offset + lfm.length],
                      f"{where}: the table of contents (LFM)")
    if not isinstance(toc, dict):
        raise FormatError(f"{where}: the table of contents should be a JSON object, found {type(toc).__name__}")
    return _build_container(p, tuple(sections), toc, data)


def _frame_wrapper(toc: Mapping[str, Any]) -> Mapping[str, Any]:
    """The ``{frame, parameters}`` entry of the first frame in either TOC shape (or {})."""
    for keys in (("frames", 0), ("picture", "frameArray", 0), ("master", "picture", "frameArray", 0)):
        w = _get(toc, *keys)
        if isinstance(w, Mapping):
            return w
    return {}


def _tags(wrapper: Mapping[str, Any]) -> Mapping[str, Any]:
    return _dict(wrapper, "parameters", "vendorContent", "com.lytro.tags")


def _build_container(p: Path, sections: tuple[Section, ...], toc: dict, data: Any) -> LytroContainer:
    where = str(p)
    index: dict[str, Section] = {}
    for s in sections:
        index.setdefault(s.sha1, s)

    def resolve_json(ref: Any, what: str) -> Mapping[str, Any] | None:
        if not isinstance(ref, str) or _norm_sha1(ref) not in index:
            return None
        s = index[_norm_sha1(ref)]
        obj = _parse_json(memoryview(data)[s.data_offset:s.data_offset + s.length], f"{where}: the {what}")
        if not isinstance(obj, Mapping):
            raise FormatError(f"{where}: the {what} should be a JSON object, found {type(obj).__name__}")
        return obj

    wrapper = _frame_wrapper(toc)
    frame = _dict(wrapper, "frame")
    meta = frame.get("metadata") if isinstance(frame.get("metadata"), Mapping) else \
        resolve_json(frame.get("metadataRef"), "frame metadata (metadataRef)")
    private = frame.get("privateMetadata") if isinstance(frame.get("privateMetadata"), Mapping) else \
        resolve_json(frame.get("privateMetadataRef"), "private metadata (privateMetadataRef)")

    image_ref = frame.get("imageRef")
    if isinstance(_get(toc, "files"), list):
        kind = "calibration"
    elif isinstance(image_ref, str) and _norm_sha1(image_ref) in index:
        kind = "raw"
    else:
        kind = "processed"

    model = _get(meta, "camera", "model")
    model_source = "metadata"
    if not isinstance(model, str):
        model, model_source = None, "unknown"
        if isinstance(_get(toc, "picture", "frameArray"), list) and isinstance(_get(toc, "version"), Mapping):
            # Lytro Desktop <= 3 TOC shape ("version" 1.0, picture.frameArray): written only for the F01.
            model, model_source = "F01", "toc layout"
    serial = _get(private, "camera", "serialNumber")
    serial = str(serial) if isinstance(serial, (str, int)) and not isinstance(serial, bool) else None
    white = bool(_get(_tags(wrapper), "modulationFrame", default=False) is True)
    items = _describe_contents(toc, index, data, meta)
    return LytroContainer(path=p, sections=sections, toc=toc, kind=kind, model=model, serial=serial,
                          model_source=model_source, metadata=meta, private_metadata=private,
                          white_image=white, items=tuple(items), _buffer=data)


def _walk_refs(toc: Any) -> list[tuple[list[Any], list[Any], str]]:
    """Every ``'sha1-...'`` string in the TOC: (key path, ancestor chain, value); iterative, bounded."""
    out = []
    stack: list[tuple[Any, list[Any], list[Any]]] = [(toc, [], [])]
    seen = 0
    while stack:
        obj, keys, chain = stack.pop()
        seen += 1
        if seen > 1_000_000:
            break
        if isinstance(obj, Mapping):
            items = list(obj.items())
        elif isinstance(obj, list):
            items = list(enumerate(obj))
        else:
            if isinstance(obj, str) and _SHA1_STR_RE.match(obj):
                out.append((keys, chain, obj))
            continue
        for k, v in reversed(items):
            stack.append((v, keys + [k], chain + [obj]))
    return out


def _path_str(keys: Sequence[Any]) -> str:
    s = ""
    for k in keys:
        s += f"[{k}]" if isinstance(k, int) else (("." if s else "") + str(k))
    return s


def _shape_from(chain: Sequence[Any]) -> tuple[int, int] | None:
    """Nearest ancestor dict with integer ``width`` and ``height`` -> (height, width)."""
    for obj in reversed(chain):
        if isinstance(obj, Mapping):
            w, h = _number(obj.get("width")), _number(obj.get("height"))
            if w is not None and h is not None and w > 0 and h > 0 and w == int(w) and h == int(h):
                return int(h), int(w)
    return None


def _sniff(buf: memoryview) -> str | None:
    head = bytes(buf[:8])
    if head[:2] == b"\xff\xd8":
        return "jpeg"
    if head[:8] == b"\x89PNG\r\n\x1a\n":
        return "png"
    if head[:4] == b"\x00\x00\x00\x01":
        return "h264"
    if head[:1] == b"{":
        return "json"
    return None


def _describe_contents(toc: Mapping[str, Any], index: Mapping[str, Section], data: Any,
                       meta: Mapping[str, Any] | None) -> list[ContentItem]:
    items: list[ContentItem] = []
    used_names: set[str] = {"toc.json"}  # extract_contents writes the TOC under that name
    seen: set[str] = set()
    counters: dict[str, int] = {}

    def unique(name: str, typ: str) -> str:
        """``name`` made file-name safe and unique among the items' file names (name + extension)."""
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "item"
        ext = _EXT.get(typ, ".bin")
        base, k = name, 1
        while name + ext in used_names:
            name = f"{base}_{k}"
            k += 1
        used_names.add(name + ext)
        return name

    for keys, chain, value in _walk_refs(toc):
        sha = _norm_sha1(value)
        if sha in seen or sha not in index:
            continue
        seen.add(sha)
        sec = index[sha]
        buf = memoryview(data)[sec.data_offset:sec.data_offset + sec.length]
        key = keys[-1] if keys else ""
        parent_key = next((k for k in reversed(keys[:-1]) if isinstance(k, str)), "")
        str_keys = [k for k in keys if isinstance(k, str)]
        parent = chain[-1] if chain else {}
        info: dict[str, Any] = {}
        shape = None
        sniff = _sniff(buf)
        if isinstance(key, str) and key.lower().endswith("metadataref"):
            typ = "json"
            name = "frame_private" if key == "privateMetadataRef" else \
                "frame" if key == "metadataRef" and "frame" in str_keys else key[:-3]
        elif key == "imageRef" and parent_key == "frame":
            typ, name = "raw", "frame"
            if meta is not None:
                try:
                    _, _, _, _, w, h, bits, endian = metadata_from_lytro(meta)
                    shape, info = (h, w), {"bits": bits, "packing": endian}
                except PlenodecodeError:
                    pass
        elif key == "modulationDataRef":
            typ, name = "raw", "modulation"
        elif parent_key in ("depthMap", "confidenceMap", "depthLut"):
            typ = {"depthMap": "depth", "confidenceMap": "confidence", "depthLut": "lut"}[parent_key]
            name = {"depthMap": "depth_map", "confidenceMap": "confidence_map", "depthLut": "depth_lut"}[parent_key]
            shape = _shape_from(chain)
            for k in ("minLambda", "maxLambda"):
                v = next((o[k] for o in reversed(chain) if isinstance(o, Mapping) and _number(o.get(k)) is not None),
                         None)
                if v is not None:
                    info[k] = v
        elif key == "blockOfImagesRef":
            typ = "h264"
            acc_type = next((o.get("type") for o in reversed(chain) if isinstance(o, Mapping)
                             and isinstance(o.get("type"), str)), "block_of_images")
            name = acc_type.rsplit(".", 1)[-1]
            name = re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower()
            arr = parent.get("metadataArray") if isinstance(parent, Mapping) else None
            if isinstance(arr, list) and arr:
                shape = _shape_from([arr[0]])
                info["frames"] = len(arr)
        elif key == "dataRef" and isinstance(parent, Mapping) and isinstance(parent.get("name"), str):
            fname = parent["name"].replace("C:\\", "").replace("\\", "__")
            name = fname.rsplit(".", 1)[0]
            ext = fname.rsplit(".", 1)[-1].upper() if "." in fname else ""
            typ = "raw" if ext == "RAW" else "json" if ext in ("TXT", "JSON") else (sniff or "binary")
            info["file"] = parent["name"]
        elif "thumbnails" in str_keys or "thumbnailArray" in str_keys:
            typ, name = sniff or "jpeg", "thumbnail"
            shape = _shape_from(chain)
        elif "perImage" in str_keys or "imageArray" in str_keys:
            typ = sniff or "jpeg"
            stack_key = "perImage" if "perImage" in str_keys else "imageArray"
            base = "focus_stack" if stack_key == "perImage" else "refocus"
            counters[base] = counters.get(base, 0) + 1
            name = f"{base}_{counters[base] - 1:02d}"
            shape = _shape_from(chain)
            for k in ("focus", "lambda"):
                if isinstance(parent, Mapping) and _number(parent.get(k)) is not None:
                    info[k] = parent[k]
        else:
            typ = sniff or "binary"
            name = str(key)[:-3] if isinstance(key, str) and key.endswith("Ref") else (parent_key or "payload")
            name = re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower()
        if sniff in ("jpeg", "png", "h264") and typ in ("binary", "json"):
            typ = sniff
        items.append(ContentItem(name=unique(name, typ), type=typ, size=sec.length, shape=shape, sha1=sha,
                                 key=_path_str(keys), info=info))
    return items


# ---------------------------------------------------------------------------------------------
# metadata mapping
# ---------------------------------------------------------------------------------------------
def _unwrap(doc: Mapping[str, Any]) -> tuple[Mapping[str, Any], Mapping[str, Any] | None, Mapping[str, Any]]:
    """``(metadata, privateMetadata, tags)`` of a TXT document with the ``master`` wrapper."""
    wrapper = _frame_wrapper(doc)
    frame = _dict(wrapper, "frame")
    meta = frame.get("metadata")
    if not isinstance(meta, Mapping):
        raise MetadataError("the white-image TXT has no master.picture.frameArray[0].frame.metadata object; "
                            "it is not a Lytro MOD_NNNN.TXT")
    private = frame.get("privateMetadata")
    return meta, private if isinstance(private, Mapping) else None, _tags(wrapper)


def _cfa_names(tile: Any, upper_left: Any, where: str) -> list[list[str]]:
    """Names ('r', 'gr', 'gb', 'b') at the sensor's 2x2 positions from a Lytro mosaic description."""
    if not isinstance(tile, str) or not isinstance(upper_left, str):
        raise MetadataError(f"{where}mosaic should have string 'tile' and 'upperLeftPixel', found "
                            f"{tile!r}, {upper_left!r}")
    rows = [r.split(",") for r in tile.replace(" ", "").lower().split(":")]
    flat = [n for r in rows for n in r]
    if len(rows) != 2 or any(len(r) != 2 for r in rows) or sorted(flat) != ["b", "gb", "gr", "r"]:
        raise MetadataError(f"{where}mosaic tile should be a 2x2 Bayer tile like 'r,gr:gb,b', found {tile!r}")
    ul = upper_left.lower()
    if ul not in flat:
        raise MetadataError(f"{where}mosaic upperLeftPixel should be one of r, gr, gb, b, found {upper_left!r}")
    r0, c0 = divmod(flat.index(ul), 2)
    return [[rows[(r0 + i) % 2][(c0 + j) % 2] for j in range(2)] for i in range(2)]


def _levels(obj: Any, names: list[list[str]], what: str, where: str) -> np.ndarray:
    if _number(obj) is not None:
        return np.full((2, 2), float(obj))
    if not isinstance(obj, Mapping):
        raise MetadataError(f"{where}pixelFormat.{what} should be an object {{r, gr, gb, b}}, found {obj!r}")
    out = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            v = _number(obj.get(names[i][j]))
            if v is None:
                raise MetadataError(f"{where}pixelFormat.{what}.{names[i][j]} should be a number, found "
                                    f"{obj.get(names[i][j])!r}")
            out[i, j] = v
    return out


def metadata_from_lytro(meta: Mapping[str, Any], private: Mapping[str, Any] | None = None,
                        path: str | os.PathLike | None = None, *, white_image: bool | None = None,
                        default_size: tuple[int, int] | None = None,
                        ) -> tuple[CameraMetadata, str, np.ndarray, np.ndarray, int, int, int, str]:
    """Map Lytro frame metadata (F01 or Illum schema) to :class:`CameraMetadata` and raw layout.

    Reads the F01 / white-image schema (``image.rawDetails.{pixelFormat, pixelPacking, mosaic}``,
    ``image.color.ccmRgbToSrgbArray``) and the Illum LFR schema (``image.{pixelFormat,
    pixelPacking, mosaic}``, ``image.color.ccm``, ``image.iso``); see ``formats.md`` §2-3.

    Parameters
    ----------
    meta : dict
        The frame's ``metadata`` object, or a whole ``MOD_NNNN.TXT`` document (``master`` wrapper),
        whose private metadata and ``modulationFrame`` tag are then used too.
    private : dict, optional
        The ``privateMetadata`` object (``camera.serialNumber``).
    path : path-like, optional
        Only used in error messages.
    white_image : bool, optional
        The frame's ``modulationFrame`` tag, when known from elsewhere (the TOC).
    default_size : (height, width), optional
        Used when the metadata declares no image size (headerless raws of a known sensor).

    Returns
    -------
    (CameraMetadata, cfa, black, white, width, height, bits, endianness)
        ``cfa`` one of 'RGGB', 'GRBG', 'GBRG', 'BGGR' (the tile ``r,gr:gb,b`` shifted to
        ``upperLeftPixel``: 'gr' gives GRBG (Illum), 'b' gives BGGR (F01)); ``black``/``white``
        (2, 2) float64 levels at the sensor's 2x2 CFA positions; ``bits`` 10/12/...;
        ``endianness`` 'little' or 'big'.

    Raises
    ------
    MetadataError
        A required entry (levels, mosaic, size, packing) is missing or of the wrong type.
    FormatError
        The declared image size is implausible (> 65536 px a side).
    """
    where = f"{path}: " if path is not None else ""
    if not isinstance(meta, Mapping):
        raise MetadataError(f"{where}Lytro metadata should be a JSON object, found {type(meta).__name__}")
    tags: Mapping[str, Any] = {}
    doc = meta
    if "master" in meta:
        meta, private2, tags = _unwrap(meta)
        private = private if private is not None else private2
    if not isinstance(private, Mapping):
        private = None
    image = _dict(meta, "image")
    devices = _dict(meta, "devices")
    sensor = _dict(devices, "sensor")
    raw_details = image.get("rawDetails")
    src = raw_details if isinstance(raw_details, Mapping) else image
    if not image:
        raise MetadataError(f"{where}Lytro metadata has no 'image' object; it is not frame metadata")

    w_decl = _first_number(image.get("width"), sensor.get("pixelWidth"))
    h_decl = _first_number(image.get("height"), sensor.get("pixelHeight"))
    if (w_decl is None or h_decl is None) and default_size is not None:
        h_decl, w_decl = default_size
    width = _int_side(w_decl, "image.width", where)
    height = _int_side(h_decl, "image.height", where)

    pk = _dict(src, "pixelPacking")
    bits_f = _first_number(pk.get("bitsPerPixel"), sensor.get("bitsPerPixel"))
    if bits_f is None or bits_f not in (8, 10, 12, 16):
        raise MetadataError(f"{where}pixelPacking.bitsPerPixel should be 8, 10, 12 or 16, found "
                            f"{pk.get('bitsPerPixel', sensor.get('bitsPerPixel'))!r}")
    bits = int(bits_f)
    endian = pk.get("endianness")
    if endian is None:
        endian = "big" if bits == 12 else "little"
    if not isinstance(endian, str) or endian.lower() not in ("little", "big"):
        raise MetadataError(f"{where}pixelPacking.endianness should be 'little' or 'big', found {endian!r}")
    endian = endian.lower()

    mosaic = src.get("mosaic") if isinstance(src.get("mosaic"), Mapping) else sensor.get("mosaic")
    if not isinstance(mosaic, Mapping):
        raise MetadataError(f"{where}Lytro metadata has no mosaic {{tile, upperLeftPixel}}; cannot tell the Bayer "
                            "pattern")
    names = _cfa_names(mosaic.get("tile"), mosaic.get("upperLeftPixel"), where)
    cfa = "".join(n[0] for row in names for n in row).upper()
    if cfa not in CFA_PATTERNS:  # pragma: no cover - every valid shift of the tile is a Bayer pattern
        raise MetadataError(f"{where}mosaic gives an unknown CFA {cfa}")
    pf = _dict(src, "pixelFormat")
    if not pf:
        raise MetadataError(f"{where}Lytro metadata has no pixelFormat {{black, white}}; cannot tell the levels")
    black = _levels(pf.get("black"), names, "black", where)
    white = _levels(pf.get("white"), names, "white", where)
    if _number(pf.get("rightShift")) not in (None, 0.0):
        log.warning("%spixelFormat.rightShift = %s is not 0; levels used as written", where, pf.get("rightShift"))

    color = _dict(image, "color")
    gains = color.get("whiteBalanceGain")
    if not isinstance(gains, Mapping):
        gains = _get(meta, "algorithms", "awb", "computed", "gain")
    wb = None
    if isinstance(gains, Mapping):
        wb = {k: float(v) for k, v in gains.items() if k in ("r", "gr", "gb", "b", "g") and _number(v) is not None}
        wb = wb or None
    ccm_list = color.get("ccmRgbToSrgbArray", color.get("ccm"))
    ccm = None
    if isinstance(ccm_list, list) and len(ccm_list) == 9 and all(_number(x) is not None for x in ccm_list):
        vals = [float(x) for x in ccm_list]
        ccm = (tuple(vals[0:3]), tuple(vals[3:6]), tuple(vals[6:9]))

    mla = _dict(devices, "mla")
    lens = _dict(devices, "lens")
    off = _dict(mla, "sensorOffset")
    offset = tuple(_number(off.get(k)) for k in ("x", "y", "z"))
    scale = tuple(_number(_dict(mla, "scaleFactor").get(k)) for k in ("x", "y"))
    camera = _dict(meta, "camera")
    serial = _get(private, "camera", "serialNumber")
    if white_image is None:
        white_image = _get(tags, "modulationFrame") is True
    text = lambda v: str(v) if isinstance(v, (str, int)) and not isinstance(v, bool) else None  # noqa: E731

    cam = CameraMetadata(
        make=text(camera.get("make")),
        model=text(camera.get("model")),
        serial=text(serial),
        zoom_step=_number(lens.get("zoomStep")),
        focus_step=_number(lens.get("focusStep")),
        exposure_s=_number(_get(devices, "shutter", "frameExposureDuration")),
        iso=_first_number(image.get("iso"), sensor.get("iso")),
        wb_gains=wb,
        ccm=ccm,  # type: ignore[arg-type]
        pixel_pitch_m=_number(sensor.get("pixelPitch")),
        lens_pitch_m=_number(mla.get("lensPitch")),
        mla_rotation=_number(mla.get("rotation")),
        mla_offset_m=offset if all(v is not None for v in offset) else None,  # type: ignore[arg-type]
        mla_scale=scale if all(v is not None for v in scale) else None,  # type: ignore[arg-type]
        focal_length_m=_number(lens.get("focalLength")),
        f_number=_number(lens.get("fNumber")),
        is_white_image=bool(white_image),
        extra={"lytro": {"metadata": meta, "privateMetadata": private,
                         **({"document": doc} if doc is not meta else {})}},
    )
    return cam, cfa, black, white, width, height, bits, endian


# ---------------------------------------------------------------------------------------------
# raw readers
# ---------------------------------------------------------------------------------------------
def _summary(items: Iterable[ContentItem]) -> str:
    counts: dict[str, int] = {}
    for it in items:
        if it.type == "json":
            continue
        d = it.describe().split(" (")[0]
        counts[d] = counts.get(d, 0) + 1
    return ", ".join(f"{n} x {d}" if n > 1 else d for d, n in counts.items()) or "no images"


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
                          f"{_summary(c.items)}; run 'plenodecode info {where}' to see what it holds")
    if c.metadata is None:
        raise FormatError(f"{where}: the raw's frame metadata is missing (no metadata or metadataRef section); "
                          "the file is incomplete")
    cam, cfa, black, white, w, h, bits, endian = metadata_from_lytro(
        c.metadata, c.private_metadata, c.path, white_image=c.white_image)
    ref = _dict(_frame_wrapper(c.toc), "frame").get("imageRef")
    buf = c.payload(ref)
    expected = _packed_size_or_error(h, w, bits, where)
    if len(buf) != expected:
        raise FormatError(f"{where}: the raw payload is {len(buf)} bytes but the metadata declares {w} x {h} at "
                          f"{bits} bit = {expected} bytes; the file is damaged or its metadata is wrong")
    mosaic = packing.unpack(buf, h, w, bits, endian)
    return RawCapture(mosaic=mosaic, cfa=cfa, black=black, white=white, metadata=cam, path=where)


def _packed_size_or_error(h: int, w: int, bits: int, where: str) -> int:
    try:
        return packing.packed_size(h, w, bits)
    except ValueError as exc:
        raise FormatError(f"{where}: {exc}; the metadata is damaged") from None


def find_sidecar(path: str | os.PathLike) -> Path | None:
    """The JSON metadata file that belongs to a headerless Lytro raw.

    ``X.RAW`` -> ``X.TXT``, ``X.txt``, ``X.json`` or ``X.JSON`` (first that exists);
    this also covers ``IMG_0001__frame.raw`` -> ``IMG_0001__frame.json``.

    Returns
    -------
    Path or None
    """
    p = Path(path)
    for ext in (".TXT", ".txt", ".json", ".JSON"):
        cand = p.with_suffix(ext)
        if cand != p and cand.is_file():
            return cand
    return None


def _read_sidecar(side: Path) -> Any:
    try:
        raw = side.read_bytes()
    except OSError as exc:
        raise FormatError(f"{side}: cannot read the metadata sidecar: {exc.strerror}") from None
    end = raw.rfind(b"}")  # a TXT may have trailing bytes after the final '}'
    if end < 0:
        raise FormatError(f"{side}: expected a JSON object, found no '}}'; the metadata file is damaged")
    return _parse_json(raw[:end + 1], f"{side}: the metadata sidecar")


def read_raw_pair_metadata(path: str | os.PathLike,
                           ) -> tuple[CameraMetadata, str, np.ndarray, np.ndarray, int, int, int, str]:
    """Metadata of a headerless raw + sidecar pair, checked against the raw's file size.

    Returns the same tuple as :func:`metadata_from_lytro`; width, height and packing come
    from the sidecar, or, when it lacks them, from the file size of a known sensor
    (F01 3280 x 3280 12 bit, Illum 7728 x 5368 10 bit).

    Raises
    ------
    FormatError
        No sidecar, unparsable sidecar, or a raw whose size disagrees with the metadata.
    """
    p = Path(path)
    if not p.is_file():
        raise FormatError(f"{p}: no such file")
    side = find_sidecar(p)
    if side is None:
        raise FormatError(f"{p}: no metadata sidecar ({p.stem}.TXT, .txt or .json) beside the raw; put the "
                          "camera's JSON next to it")
    doc = _read_sidecar(side)
    if not isinstance(doc, Mapping):
        raise FormatError(f"{side}: expected a JSON object, found {type(doc).__name__}")
    size = p.stat().st_size
    default = KNOWN_SENSORS[size][:2] if size in KNOWN_SENSORS else None
    result = metadata_from_lytro(doc, None, side, default_size=default)
    _, _, _, _, w, h, bits, _ = result
    expected = _packed_size_or_error(h, w, bits, str(p))
    if size != expected:
        raise FormatError(f"{p}: the raw is {size} bytes but {side.name} declares {w} x {h} at {bits} bit = "
                          f"{expected} bytes; the pair does not match or the raw is truncated")
    return result


def read_raw_pair(path: str | os.PathLike) -> RawCapture:
    """Read a headerless Lytro raw with its JSON sidecar.

    Covers ``MOD_NNNN.RAW`` + ``MOD_NNNN.TXT`` white images (F01 12-bit or Illum 10-bit,
    decided from ``pixelPacking``/``bitsPerPixel``/``width``/``height``; the TXT may have
    trailing bytes after its last ``}``) and F01 ``X__frame.raw`` + ``X__frame.json``.
    White images (``modulationFrame`` true) get ``metadata.is_white_image = True``.

    Returns
    -------
    RawCapture

    Raises
    ------
    FormatError
        No or unparsable sidecar; raw size disagreeing with the metadata.
    """
    p = Path(path)
    cam, cfa, black, white, w, h, bits, endian = read_raw_pair_metadata(p)
    with open(p, "rb") as fh:
        buf = _map_file(fh)
    try:
        mosaic = packing.unpack(buf, h, w, bits, endian)
    finally:
        try:
            buf.close()
        except BufferError:  # a view is still alive; the map closes when it is collected
            pass
    return RawCapture(mosaic=mosaic, cfa=cfa, black=black, white=white, metadata=cam, path=str(p))


# ---------------------------------------------------------------------------------------------
# writers
# ---------------------------------------------------------------------------------------------
def _section_bytes(kind: str, payload: bytes) -> tuple[bytes, str]:
    """Header + name field for a section; returns (header, 'sha1-...')."""
    sha = "sha1-" + hashlib.sha1(payload).hexdigest()
    magic = LFM_MAGIC if kind == "LFM" else LFC_MAGIC
    name = sha.encode("ascii").ljust(NAME_FIELD, b"\x00")
    return magic + (0).to_bytes(4, "big") + len(payload).to_bytes(4, "big") + name, sha


def write_container(path: str | os.PathLike, toc: Mapping[str, Any], payloads: Sequence[bytes], *,
                    lfm_first: bool = True, overwrite: bool = False) -> Path:
    """Write a Lytro container: file header, the LFM (TOC JSON) and one LFC per payload.

    Sections are 16-byte aligned with zero padding; each payload's section is named by its
    SHA-1, which is what the TOC must refer to (compute it with ``'sha1-' + hashlib.sha1(p).hexdigest()``).

    Parameters
    ----------
    path : path-like
    toc : dict
        Table of contents, written as tab-indented JSON.
    payloads : sequence of bytes
        Content blocks, in file order.
    lfm_first : bool
        LFM before the LFCs (Lytro Desktop) or after them (Illum camera ``.lfr``).
    overwrite : bool

    Returns
    -------
    Path
    """
    p = Path(path)
    refuse_existing([p], overwrite)
    lfm = json.dumps(toc, indent="\t").encode("utf-8")
    order = [("LFM", lfm)] + [("LFC", bytes(x)) for x in payloads]
    if not lfm_first:
        order = order[1:] + order[:1]

    def chunks() -> Iterable[bytes]:
        yield FILE_HEADER
        for kind, payload in order:
            head, _ = _section_bytes(kind, payload)
            yield head
            yield payload
            yield b"\x00" * ((-len(payload)) % 16)

    return write_bytes_atomic(p, chunks(), overwrite=overwrite)


def _level_dict(levels: np.ndarray, names: list[list[str]]) -> dict[str, int | float]:
    return {names[i][j]: _json_number(levels[i, j]) for i in range(2) for j in range(2)}


def _upper_left_for(cfa: str) -> tuple[str, list[list[str]]]:
    for ul in ("r", "gr", "gb", "b"):
        names = _cfa_names(LYTRO_TILE, ul, "")
        if "".join(n[0] for row in names for n in row).upper() == cfa:
            return ul, names
    raise ValueError(f"raw.cfa must be one of {CFA_PATTERNS} to write a Lytro file, got {cfa!r}")  # pragma: no cover


def lytro_metadata(raw: RawCapture, *, schema: str, bits: int | None = None) -> tuple[dict, dict]:
    """Lytro ``(metadata, privateMetadata)`` JSON objects generated from a RawCapture.

    Parameters
    ----------
    raw : RawCapture
        Its ``cfa`` (a Bayer pattern), levels and :class:`CameraMetadata` are written.
    schema : 'illum' or 'rawdetails'
        'illum': the Illum LFR schema (``image.pixelFormat``, ``image.color.ccm``, ``image.iso``).
        'rawdetails': the F01 / white-image schema (``image.rawDetails``, ``ccmRgbToSrgbArray``).
    bits : int, optional
        10 (little-endian) or 12 (big-endian); default 10 for 'illum', 12 for 'rawdetails'.
    """
    from .. import __version__

    if schema not in ("illum", "rawdetails"):
        raise ValueError(f"schema must be 'illum' or 'rawdetails', got {schema!r}")
    if raw.cfa is None:
        raise ValueError("raw.cfa is None: a Lytro file needs a Bayer pattern")
    bits = bits if bits is not None else (10 if schema == "illum" else 12)
    if bits not in (10, 12):
        raise ValueError(f"bits must be 10 or 12, got {bits!r}")
    endian = "little" if bits == 10 else "big"
    m = raw.metadata
    ul, names = _upper_left_for(raw.cfa)
    h, w = raw.shape
    mosaic = {"tile": LYTRO_TILE, "upperLeftPixel": ul}
    pixel_format = {"rightShift": 0, "black": _level_dict(raw.black, names), "white": _level_dict(raw.white, names)}
    pixel_packing = {"endianness": endian, "bitsPerPixel": bits}
    color: dict[str, Any] = {}
    if m.ccm is not None:
        color["ccm" if schema == "illum" else "ccmRgbToSrgbArray"] = [float(x) for row in m.ccm for x in row]
    if m.wb_gains is not None:
        g = {k: float(v) for k, v in m.wb_gains.items()}
        if "g" in g:
            g.setdefault("gr", g["g"])
            g.setdefault("gb", g.pop("g"))
        color["whiteBalanceGain"] = g
    image: dict[str, Any] = {"width": w, "height": h, "orientation": 1}
    if schema == "illum":
        image.update(pixelPacking=pixel_packing, pixelFormat=pixel_format, mosaic=mosaic)
        if m.iso is not None:
            image["iso"] = _json_number(m.iso)
        image["color"] = color
    else:
        image.update(representation="rawPacked",
                     rawDetails={"pixelFormat": pixel_format, "pixelPacking": pixel_packing, "mosaic": mosaic},
                     color={**color, "applied": {}})
    sensor: dict[str, Any] = {"bitsPerPixel": bits, "mosaic": dict(mosaic)}
    if schema == "illum":
        sensor.update(pixelWidth=w, pixelHeight=h)
    elif m.iso is not None:
        sensor["iso"] = _json_number(m.iso)
    if m.pixel_pitch_m is not None:
        sensor["pixelPitch"] = float(m.pixel_pitch_m)
    lens: dict[str, Any] = {}
    for key, v in (("zoomStep", m.zoom_step), ("focusStep", m.focus_step),
                   ("focalLength", m.focal_length_m), ("fNumber", m.f_number)):
        if v is not None:
            lens[key] = _json_number(v) if key.endswith("Step") else float(v)
    mla: dict[str, Any] = {"tiling": "hexUniformRowMajor", "config": "com.lytro.mla.3", "defectArray": []}
    if m.lens_pitch_m is not None:
        mla["lensPitch"] = float(m.lens_pitch_m)
    if m.mla_rotation is not None:
        mla["rotation"] = float(m.mla_rotation)
    if m.mla_scale is not None:
        mla["scaleFactor"] = {"x": float(m.mla_scale[0]), "y": float(m.mla_scale[1])}
    if m.mla_offset_m is not None:
        mla["sensorOffset"] = dict(zip("xyz", (float(v) for v in m.mla_offset_m)))
    devices: dict[str, Any] = {"sensor": sensor, "lens": lens, "mla": mla}
    if m.exposure_s is not None:
        devices["shutter"] = {"frameExposureDuration": float(m.exposure_s),
                              "pixelExposureDuration": float(m.exposure_s)}
    camera: dict[str, Any] = {"firmware": f"plenodecode {__version__}"}
    if m.make is not None:
        camera["make"] = m.make
    if m.model is not None:
        camera["model"] = m.model
    meta: dict[str, Any] = {}
    if schema == "illum":
        meta.update(schema=ILLUM_PUBLIC_SCHEMA, generator="plenodecode")
    else:
        meta["type"] = "lightField"
    meta.update(image=image, devices=devices, camera=camera)
    private: dict[str, Any] = {"schema": ILLUM_PRIVATE_SCHEMA, "generator": "plenodecode"} if schema == "illum" else {}
    if m.serial is not None:
        private["camera"] = {"serialNumber": m.serial}
    return meta, private


def _tags_entry(raw: RawCapture) -> dict:
    return {"vendorContent": {"com.lytro.tags": {"darkFrame": False,
                                                 "modulationFrame": bool(raw.metadata.is_white_image)}}}


def _sha(payload: bytes) -> str:
    return "sha1-" + hashlib.sha1(payload).hexdigest()


def write_lfr(path: str | os.PathLike, raw: RawCapture, *, overwrite: bool = False) -> Path:
    """Write an Illum-camera-style ``.lfr``: 10-bit raw, LFC sections first, LFM last.

    The TOC has the 'picture 2.1' shape (``frames[0].frame.{metadataRef, privateMetadataRef,
    imageRef}``, ``thumbnails``, ``views``, ...); the metadata uses the Illum schema and is
    generated from ``raw.metadata`` (see :func:`lytro_metadata`), so :func:`read_lytro`
    returns the same mosaic, levels, CFA and metadata.

    Raises
    ------
    ValueError
        ``raw`` cannot be 10-bit packed (values >= 1024, pixel count not divisible by 4, no CFA).
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = Path(path)
    refuse_existing([p], overwrite)
    meta, private = lytro_metadata(raw, schema="illum", bits=10)
    image = packing.pack_10bit(raw.mosaic)
    meta_b = json.dumps(meta, indent="\t").encode("utf-8")
    priv_b = json.dumps(private, indent="\t").encode("utf-8")
    frame = {"metadataRef": _sha(meta_b), "privateMetadataRef": _sha(priv_b), "imageRef": _sha(image)}
    toc = {
        "schema": ILLUM_PICTURE_SCHEMA,
        "generators": ["lightning"],
        "thumbnails": [],
        "derivations": [],
        "views": [],
        "annotations": [],
        "frames": [{"frame": frame, "parameters": _tags_entry(raw)}],
    }
    return write_container(p, toc, [image, meta_b, priv_b], lfm_first=False, overwrite=overwrite)


def write_lfp(path: str | os.PathLike, raw: RawCapture, *, overwrite: bool = False) -> Path:
    """Write an F01 Lytro-Desktop-style raw ``.lfp``: LFM first, 12-bit big-endian raw, F01 schema.

    Raises
    ------
    ValueError
        ``raw`` cannot be 12-bit packed (values >= 4096, odd pixel count, no CFA).
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = Path(path)
    refuse_existing([p], overwrite)
    meta, private = lytro_metadata(raw, schema="rawdetails", bits=12)
    image = packing.pack_12bit(raw.mosaic)
    meta_b = json.dumps(meta, indent="\t").encode("utf-8")
    priv_b = json.dumps(private, indent="\t").encode("utf-8")
    toc = {
        "picture": {
            "frameArray": [{"frame": {"metadataRef": _sha(meta_b), "privateMetadataRef": _sha(priv_b),
                                      "imageRef": _sha(image)},
                            "parameters": _tags_entry(raw)}],
            "viewArray": [],
            "accelerationArray": [],
            "derivationArray": [],
        },
        "thumbnailArray": [],
        "version": {"major": 1, "minor": 0, "provisionalDate": "2012-02-07"},
    }
    return write_container(p, toc, [meta_b, priv_b, image], lfm_first=True, overwrite=overwrite)


def write_raw_pair(path: str | os.PathLike, raw: RawCapture, *, overwrite: bool = False) -> tuple[Path, Path]:
    """Write a white-image style ``MOD_NNNN.RAW`` + ``MOD_NNNN.TXT`` pair.

    Packing follows ``raw.metadata.model``: 'F01' -> 12-bit big-endian, anything else ->
    Illum 10-bit (written with ``camera.model`` 'B01', as the Illum does for its white
    images).  The TXT has the ``master.picture.frameArray[0].frame.{metadata,
    privateMetadata}`` wrapper and the ``modulationFrame`` tag from ``raw.metadata.is_white_image``.
    The sidecar's extension follows the raw's case (``.RAW`` -> ``.TXT``, ``.raw`` -> ``.txt``).

    Returns
    -------
    (raw path, txt path)
    """
    p = Path(path)
    side = p.with_suffix(".txt" if p.suffix.islower() and p.suffix else ".TXT")
    refuse_existing([p, side], overwrite)
    f01 = raw.metadata.model == "F01"
    bits = 12 if f01 else 10
    meta, private = lytro_metadata(raw, schema="rawdetails", bits=bits)
    if not f01 and meta["camera"].get("model", "ILLUM") in ("ILLUM", "Illum"):
        meta["camera"]["model"] = "B01"
    data = packing.pack(raw.mosaic, bits)
    doc = {
        "master": {
            "version": {"major": 1, "minor": 0, "provisionalDate": "2014-Sep-06"},
            "picture": {
                "viewArray": [],
                "accelerationArray": [],
                "frameArray": [{"frame": {"privateMetadata": private, "metadata": meta, "imageRef": "unknown"},
                                "parameters": _tags_entry(raw)}],
                "derivationArray": [],
            },
            "thumbnailArray": [],
        }
    }
    text = json.dumps(doc, indent="\t").replace("\n", "\r\n").encode("utf-8")
    with atomic_outputs([p, side], overwrite=overwrite) as (tmp, tmp_side):
        tmp.write_bytes(data)
        tmp_side.write_bytes(text)
    return p, side


_EXT = {"jpeg": ".jpg", "h264": ".h264", "png": ".png", "json": ".json", "raw": ".raw",
        "depth": ".npy", "confidence": ".npy", "lut": ".npy", "binary": ".bin"}


def extract_contents(path: str | os.PathLike, out_dir: str | os.PathLike, *,
                     overwrite: bool = False) -> list[Path]:
    """Save every payload of a container as a file in ``out_dir``.

    JPEGs -> ``.jpg``, H.264 blocks -> ``.h264``, depth / confidence maps and depth LUTs ->
    ``.npy`` float32 (rows, cols) (payloads are little-endian float32), JSON -> ``.json``,
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
    plan: list[tuple[Path, Any]] = [(out / "toc.json", json.dumps(c.toc, indent="\t").encode("utf-8"))]
    for it in c.items:
        buf = c.payload(it.sha1)
        target = out / (it.name + _EXT.get(it.type, ".bin"))
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
