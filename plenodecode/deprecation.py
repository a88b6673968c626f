"""Keywords renamed to the command line's option names, still accepted for one release with a DeprecationWarning."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from typing import Any

#: ``convert`` entry of :func:`renamed_keywords`: (value of the old keyword -> value of the new one, what the
#: warning adds about the new value).
Conversion = tuple[Callable[[Any], Any], str]


def renamed_keywords(options: Mapping[str, Any], renames: Mapping[str, str], where: str, *,
                     convert: Mapping[str, Conversion] | None = None, stacklevel: int = 3) -> dict[str, Any]:
    """``options`` with every old keyword of ``renames`` (old -> new name) given under its new name, each one
    found with a DeprecationWarning naming ``where`` and the new keyword; ``convert[old]`` turns an old value
    (not None) into the new one.  ValueError naming both when a keyword is given under both names."""
    out = dict(options)
    for old, new in renames.items():
        if old not in out:
            continue
        if new in out:
            raise ValueError(f"pass {new}, not both {new} and {old} (its old name)")
        fn, note = (convert or {}).get(old, (None, ""))
        warnings.warn(f"{where}({old}=) is deprecated: pass {new}={note}", DeprecationWarning, stacklevel=stacklevel)
        value = out.pop(old)
        out[new] = fn(value) if fn is not None and value is not None else value
    return out


def renamed_fields(renames: Mapping[str, str]) -> Callable[[type], type]:
    """Class decorator of a dataclass whose fields ``renames`` (old -> new name) were renamed: its constructor
    still takes the old keywords (not :func:`dataclasses.replace`, which passes every field) and the old
    attributes still read, each with a DeprecationWarning naming the new field."""
    def decorate(cls: type) -> type:
        init = cls.__init__

        @functools.wraps(init)
        def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
            init(self, *args, **renamed_keywords(kwargs, renames, cls.__name__))

        def alias(old: str, new: str) -> property:
            def get(self: Any) -> Any:
                warnings.warn(f"{cls.__name__}.{old} is deprecated: read {new}", DeprecationWarning, stacklevel=2)
                return getattr(self, new)
            return property(get, doc=f"Deprecated name of {new}.")

        cls.__init__ = __init__
        for old, new in renames.items():
            setattr(cls, old, alias(old, new))
        return cls
    return decorate
