"""The Lytro LFP/LFR container grammar (``formats.md`` §1): read and write sections.

A file is a 16-byte header, then 16-byte aligned sections ``LFM`` (the JSON table of contents, TOC)
and ``LFC`` (content) of ``96 + N`` bytes: magic, length N, ``sha1-<hex>`` name, payload.  Payloads
are resolved only through the SHA-1 names the TOC refers to, never by position.  Calibration
archives (``data.C.N``) use the same grammar with a ``files`` list in the TOC.
"""

from __future__ import annotations

import hashlib
import json
import logging
import mmap
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ...errors import FormatError
from ..atomic import refuse_existing, write_bytes_atomic
from .contents import ContentItem, describe_contents
from .fields import lookup_dict, first_frame, lookup, normalise_sha1, parse_json, frame_tags

log = logging.getLogger(__name__)

#: File header: PNG-style magic, version 1 (uint32 BE), header length 0 (uint32 BE).
FILE_MAGIC = b"\x89LFP\r\n\x1a\n"
LFM_MAGIC = b"\x89LFM\r\n\x1a\n"
LFC_MAGIC = b"\x89LFC\r\n\x1a\n"
FILE_HEADER = FILE_MAGIC + (1).to_bytes(4, "big") + (0).to_bytes(4, "big")
#: Section header: 8 magic + 4 version + 4 length + 80-byte name field ("sha1-" + 40 hex + zeros).
SECTION_HEADER = 96
NAME_FIELD = 80

_SHA1_RE = re.compile(rb"sha1-[0-9a-fA-F]{40}")


def section_name(payload: bytes | memoryview) -> str:
    """The name of the section holding ``payload``: ``'sha1-'`` + the 40 lower-case hex digits of its SHA-1."""
    return "sha1-" + hashlib.sha1(payload).hexdigest()


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
        return normalise_sha1(sha1) in self._index()

    def _index(self) -> dict[str, Section]:
        idx: dict[str, Section] = {}
        for s in self.sections:
            idx.setdefault(s.sha1, s)
        return idx

    def section(self, sha1: str) -> Section:
        """The section named ``sha1`` ('sha1-<hex>' or bare hex, any case)."""
        s = self._index().get(normalise_sha1(sha1))
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
        key = normalise_sha1(sha1)
        for it in self.items:
            if it.sha1 == key:
                return it
        return None


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
            sections.append(Section(kind, pos, 0, section_name(b"")))
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


def map_file(fh: Any) -> mmap.mmap:
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
                data = map_file(fh)
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
    toc = parse_json(memoryview(data)[lfm.data_offset:lfm.data_offset + lfm.length],
                      f"{where}: the table of contents (LFM)")
    if not isinstance(toc, dict):
        raise FormatError(f"{where}: the table of contents should be a JSON object, found {type(toc).__name__}")
    return _build_container(p, tuple(sections), toc, data)


def _build_container(p: Path, sections: tuple[Section, ...], toc: dict, data: Any) -> LytroContainer:
    """The :class:`LytroContainer` of parsed ``sections`` of the file held in ``data``: frame metadata
    resolved through the TOC's references, kind, camera model and serial, described contents."""
    where = str(p)
    payloads: dict[str, memoryview] = {}
    for s in sections:
        payloads.setdefault(s.sha1, memoryview(data)[s.data_offset:s.data_offset + s.length])

    def resolve_json(ref: Any, what: str) -> Mapping[str, Any] | None:
        if not isinstance(ref, str) or normalise_sha1(ref) not in payloads:
            return None
        obj = parse_json(payloads[normalise_sha1(ref)], f"{where}: the {what}")
        if not isinstance(obj, Mapping):
            raise FormatError(f"{where}: the {what} should be a JSON object, found {type(obj).__name__}")
        return obj

    wrapper = first_frame(toc)
    frame = lookup_dict(wrapper, "frame")
    meta = frame.get("metadata") if isinstance(frame.get("metadata"), Mapping) else \
        resolve_json(frame.get("metadataRef"), "frame metadata (metadataRef)")
    private = frame.get("privateMetadata") if isinstance(frame.get("privateMetadata"), Mapping) else \
        resolve_json(frame.get("privateMetadataRef"), "private metadata (privateMetadataRef)")

    image_ref = frame.get("imageRef")
    if isinstance(lookup(toc, "files"), list):
        kind = "calibration"
    elif isinstance(image_ref, str) and normalise_sha1(image_ref) in payloads:
        kind = "raw"
    else:
        kind = "processed"

    model = lookup(meta, "camera", "model")
    model_source = "metadata"
    if not isinstance(model, str):
        model, model_source = None, "unknown"
        if isinstance(lookup(toc, "picture", "frameArray"), list) and isinstance(lookup(toc, "version"), Mapping):
            # Lytro Desktop <= 3 TOC shape ("version" 1.0, picture.frameArray): written only for the F01.
            model, model_source = "F01", "toc layout"
    serial = lookup(private, "camera", "serialNumber")
    serial = str(serial) if isinstance(serial, (str, int)) and not isinstance(serial, bool) else None
    white = bool(lookup(frame_tags(wrapper), "modulationFrame", default=False) is True)
    items = describe_contents(toc, payloads, meta)
    return LytroContainer(path=p, sections=sections, toc=toc, kind=kind, model=model, serial=serial,
                          model_source=model_source, metadata=meta, private_metadata=private,
                          white_image=white, items=tuple(items), _buffer=data)


def _section_header(kind: str, payload: bytes) -> bytes:
    """Magic, version 0, length and the zero-padded ``sha1-<hex>`` name field of a section (96 bytes)."""
    magic = LFM_MAGIC if kind == "LFM" else LFC_MAGIC
    name = section_name(payload).encode("ascii").ljust(NAME_FIELD, b"\x00")
    return magic + (0).to_bytes(4, "big") + len(payload).to_bytes(4, "big") + name


def write_container(path: str | os.PathLike, toc: Mapping[str, Any], payloads: Sequence[bytes], *,
                    lfm_first: bool = True, overwrite: bool = False) -> Path:
    """Write a Lytro container: file header, the LFM (TOC JSON) and one LFC per payload.

    Sections are 16-byte aligned with zero padding; each payload's section is named by its
    SHA-1, which is what the TOC must refer to (:func:`section_name` of the payload).

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
            yield _section_header(kind, payload)
            yield payload
            yield b"\x00" * ((-len(payload)) % 16)

    return write_bytes_atomic(p, chunks(), overwrite=overwrite)
