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
import sys
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


def lazy_exports(package: str, exports: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` (PEP 562) of a package whose public names load on first use.

    A package whose modules are heavy (numba, OpenCV) lists its public names with their modules and
    does ``__getattr__, __dir__ = lazy_exports(__name__, _LAZY)``: importing the package then imports
    none of them, and ``from package import name`` works as before.  A name is cached in the package on
    first access.  No submodule may share a public name (importing it would bind the module to that name).

    Parameters
    ----------
    package : str
        The package's ``__name__``; the package must be executing (in ``sys.modules``).
    exports : mapping of str -> str
        Public name -> absolute name of the module that defines it.
    """
    module = sys.modules[package]

    def __getattr__(name: str) -> Any:
        source = exports.get(name)
        if source is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(source), name)
        setattr(module, name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(module)) | set(exports))

    return __getattr__, __dir__


__all__ = ["lookup", "lazy", "lazy_exports"]
