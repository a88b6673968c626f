"""Method registries: one style for every family of methods (design.md, house rule 2).

A registry is a plain ``dict`` ``name -> callable``.  Entries whose module is heavy (numba kernels,
OpenCV) are :func:`lazy` callables, so that importing a registry (e.g. for a CLI ``click.Choice``)
stays cheap.  Every dispatcher looks a name up with :func:`lookup`, whose error lists the valid names.

>>> REG = {"a": abs, "b": round}
>>> lookup(REG, "a", param="method")(-2)
2
>>> lookup(REG, "c", param="method")
Traceback (most recent call last):
...
ValueError: method must be one of 'a', 'b'; got 'c'
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping, TypeVar

T = TypeVar("T")


def lookup(registry: Mapping[str, T], name: Any, *, param: str = "method") -> T:
    """The entry ``registry[name]``.

    Parameters
    ----------
    registry : mapping of str -> T
    name : str
        The requested key.
    param : str
        Name of the parameter the caller took ``name`` from, for the error message.

    Raises
    ------
    ValueError
        ``name`` is not a key; the message names ``param`` and lists the valid names.
    """
    try:
        return registry[name]
    except (KeyError, TypeError):
        valid = ", ".join(repr(k) for k in registry)
        raise ValueError(f"{param} must be one of {valid}; got {name!r}") from None


def lazy(module: str, attribute: str) -> Callable[..., Any]:
    """A callable that imports ``module`` on its first call and forwards to ``module.attribute``.

    Parameters
    ----------
    module : str
        Absolute module name, e.g. ``'plenodecode.render.fourier'``.
    attribute : str
        Name of the function in that module.
    """

    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(importlib.import_module(module), attribute)(*args, **kwargs)

    call.__name__ = attribute
    call.__qualname__ = attribute
    call.__doc__ = f"``{module}.{attribute}``, imported on first call."
    return call


__all__ = ["lookup", "lazy"]
