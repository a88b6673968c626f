"""plenodecode.registry: lookup errors and lazily exported package names."""

from __future__ import annotations

import subprocess
import sys

import pytest

from plenodecode.registry import lazy, lookup


def test_lookup_lists_the_valid_names():
    reg = {"a": abs, "b": round}
    assert lookup(reg, "a") is abs
    with pytest.raises(ValueError, match="demosaic must be one of 'a', 'b'; got 'c'"):
        lookup(reg, "c", param="demosaic")


def test_lazy_entry_imports_its_module_on_first_call():
    fn = lazy("math", "hypot")
    assert fn.__name__ == "hypot" and fn(3.0, 4.0) == 5.0


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout


def test_lazy_package_names_load_on_first_access_and_are_not_shadowed_by_their_submodule():
    """Importing a package loads none of its heavy modules; after every submodule is imported, its public
    names are still the functions (no submodule shares a public name, so none can replace one)."""
    out = _run("import sys, importlib, pkgutil, types\n"
               "import plenodecode.synthetic as syn\n"
               "print('numba' in sys.modules, 'cv2' in sys.modules)\n"
               "for sub in pkgutil.iter_modules(syn.__path__):\n"
               "    importlib.import_module('plenodecode.synthetic.' + sub.name)\n"
               "from plenodecode.synthetic import simulate\n"
               "print(callable(simulate) and simulate.__module__ == 'plenodecode.synthetic.forward')\n"
               "print('simulate' in dir(syn), 'make_grid' in dir(syn))\n")
    assert out.split() == ["False", "False", "True", "True", "True"]


def test_no_submodule_is_named_like_a_public_name_of_its_package():
    import importlib
    import pkgutil

    for name in ("plenodecode", "plenodecode.synthetic", "plenodecode.render", "plenodecode.calib",
                 "plenodecode.decoding", "plenodecode.depth", "plenodecode.io", "plenodecode.pipeline"):
        package = importlib.import_module(name)
        public = set(package.__all__) - {"errors"}
        clash = public & {m.name for m in pkgutil.iter_modules(package.__path__)}
        assert not clash, (name, clash)


def test_lazy_package_unknown_name_is_an_attribute_error():
    import plenodecode.render as render

    with pytest.raises(AttributeError, match="'plenodecode.render' has no attribute 'nope'"):
        render.nope  # noqa: B018
