"""Safe access to fields of Lytro JSON documents (tables of contents, frame metadata, TXT sidecars).

A damaged or foreign file must give a :class:`~plenodecode.errors.FormatError` or a default, never a
``KeyError``/``TypeError``: every lookup here tolerates missing keys and wrong types.
"""

from __future__ import annotations

import json
import math
from typing import Any, Mapping

from ...errors import FormatError


def normalise_sha1(s: str) -> str:
    """A section name as the file stores it: ``'sha1-'`` + lower-case hex, from bare hex or any case."""
    s = str(s).strip().lower()
    return s if s.startswith("sha1-") else "sha1-" + s


def lookup(obj: Any, *keys: Any, default: Any = None) -> Any:
    """``obj[k0][k1]...`` through dicts and lists; ``default`` when any step is missing or of the wrong type."""
    for k in keys:
        if isinstance(k, int):
            if not isinstance(obj, list) or not -len(obj) <= k < len(obj):
                return default
        elif not isinstance(obj, Mapping) or k not in obj:
            return default
        obj = obj[k]
    return obj


def lookup_dict(obj: Any, *keys: Any) -> Mapping[str, Any]:
    """:func:`lookup`, but {} unless the value found is a dict."""
    v = lookup(obj, *keys)
    return v if isinstance(v, Mapping) else {}


def as_number(v: Any) -> float | None:
    """``v`` as a finite float, None if it is not a number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        f = float(v)
    except OverflowError:  # a JSON integer too large for a float
        return None
    return f if math.isfinite(f) else None


def first_number(*values: Any) -> float | None:
    """The first of ``values`` that is a finite number (see :func:`as_number`), else None."""
    for v in values:
        f = as_number(v)
        if f is not None:
            return f
    return None


def json_number(x: float) -> int | float:
    """Integral values as int (as Lytro writes them), others as float."""
    x = float(x)
    return int(x) if x.is_integer() and abs(x) < 2**53 else x


def parse_json(buf: bytes | memoryview, what: str) -> Any:
    """JSON of a UTF-8 payload (BOM allowed); a FormatError naming ``what`` when it is not valid JSON."""
    try:
        text = bytes(buf).decode("utf-8-sig")
        return json.loads(text)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise FormatError(f"{what} is not valid JSON ({type(exc).__name__}: {str(exc)[:80]}); "
                          "the file is damaged") from None


def first_frame(toc: Mapping[str, Any]) -> Mapping[str, Any]:
    """The ``{frame, parameters}`` entry of the first frame in either TOC shape (or {})."""
    for keys in (("frames", 0), ("picture", "frameArray", 0), ("master", "picture", "frameArray", 0)):
        w = lookup(toc, *keys)
        if isinstance(w, Mapping):
            return w
    return {}


def frame_tags(wrapper: Mapping[str, Any]) -> Mapping[str, Any]:
    """The ``parameters.vendorContent['com.lytro.tags']`` of a frame entry (``modulationFrame``, ...) or {}."""
    return lookup_dict(wrapper, "parameters", "vendorContent", "com.lytro.tags")
