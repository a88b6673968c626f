"""What a Lytro container holds: every payload its table of contents refers to, named and typed.

:func:`describe_contents` walks the TOC for ``'sha1-...'`` references and turns each into a
:class:`ContentItem` (raw, JSON, JPEG/PNG thumbnails and focus stacks, H.264 blocks, depth and
confidence maps, depth LUTs, the files of a ``data.C.N`` calibration archive).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

from ...errors import PlenodecodeError
from .fields import normalise_sha1, as_number
from .metadata import metadata_from_lytro

_SHA1_STR_RE = re.compile(r"^sha1-[0-9a-fA-F]{40}$")

#: File extension per content type (:func:`~plenodecode.io.lytro.extract_contents`).
EXTENSIONS = {"jpeg": ".jpg", "h264": ".h264", "png": ".png", "json": ".json", "raw": ".raw",
        "depth": ".npy", "confidence": ".npy", "lut": ".npy", "binary": ".bin"}


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
            w, h = as_number(obj.get("width")), as_number(obj.get("height"))
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


def describe_contents(toc: Mapping[str, Any], payloads: Mapping[str, memoryview],
                      meta: Mapping[str, Any] | None) -> list[ContentItem]:
    """Every payload the TOC refers to, in TOC order, as a :class:`ContentItem`.

    Parameters
    ----------
    toc : dict
        The parsed LFM JSON.
    payloads : mapping 'sha1-<hex>' -> memoryview
        The payload of every section in the file, by its (lower-case) name.
    meta : dict or None
        The frame's metadata, which gives the raw's size and packing.

    Returns
    -------
    list of ContentItem
        Names are file-name safe and unique together with their extension (``toc.json`` is reserved).
    """
    items: list[ContentItem] = []
    used_names: set[str] = {"toc.json"}  # extract_contents writes the TOC under that name
    seen: set[str] = set()
    counters: dict[str, int] = {}

    def unique(name: str, typ: str) -> str:
        """``name`` made file-name safe and unique among the items' file names (name + extension)."""
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "item"
        ext = EXTENSIONS.get(typ, ".bin")
        base, k = name, 1
        while name + ext in used_names:
            name = f"{base}_{k}"
            k += 1
        used_names.add(name + ext)
        return name

    for keys, chain, value in _walk_refs(toc):
        sha = normalise_sha1(value)
        if sha in seen or sha not in payloads:
            continue
        seen.add(sha)
        buf = payloads[sha]
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
                v = next((o[k] for o in reversed(chain) if isinstance(o, Mapping) and as_number(o.get(k)) is not None),
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
            # the slice's refocus depth in Lytro's lambda units: the F01 TOC's 'lambda', the Illum's 'focus' (same
            # scale: the Illum depth map's minLambda..maxLambda span its slices' values); one name for both
            for k in ("lambda", "focus"):
                if isinstance(parent, Mapping) and as_number(parent.get(k)) is not None:
                    info["lambda"] = parent[k]
                    break
        else:
            typ = sniff or "binary"
            name = str(key)[:-3] if isinstance(key, str) and key.endswith("Ref") else (parent_key or "payload")
            name = re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower()
        if sniff in ("jpeg", "png", "h264") and typ in ("binary", "json"):
            typ = sniff
        items.append(ContentItem(name=unique(name, typ), type=typ, size=len(buf), shape=shape, sha1=sha,
                                 key=_path_str(keys), info=info))
    return items


def summarise_contents(items: Iterable[ContentItem]) -> str:
    """What a container holds besides JSON, in words, e.g. ``'3 x jpeg 16x8, depth float32 4x3'``."""
    counts: dict[str, int] = {}
    for it in items:
        if it.type == "json":
            continue
        d = it.describe().split(" (")[0]
        counts[d] = counts.get(d, 0) + 1
    return ", ".join(f"{n} x {d}" if n > 1 else d for d, n in counts.items()) or "no images"
