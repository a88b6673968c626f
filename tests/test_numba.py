"""plenodecode._numba: the kernel cache lives in the user cache directory; a compile is announced once."""

import os
import subprocess
import sys
from pathlib import Path

from plenodecode import _numba
from plenodecode.warmup import WARMUP_GROUPS
from tests.conftest import ROOT


def test_default_cache_dir_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _numba.default_cache_dir() == tmp_path / "plenodecode" / "numba"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert _numba.default_cache_dir() == Path.home() / ".cache" / "plenodecode" / "numba"


def test_groups_cover_every_kernel_module_and_warmup():
    kernel_modules = sorted(str(p.relative_to(ROOT).with_suffix("")).replace(os.sep, ".")
                            for p in (ROOT / "plenodecode").rglob("*.py") if "\n@njit" in p.read_text())
    assert kernel_modules, "no kernel module found"
    for module in kernel_modules:
        assert _numba.group_of(module) is not None, module
    assert set(_numba.KERNEL_GROUPS.values()) == set(WARMUP_GROUPS)
    assert _numba.group_of("plenodecode.decoding.focused") == "total-focus"
    assert _numba.group_of("plenodecode.decoding.slice") == "decode"
    assert _numba.group_of("plenodecode.io.images") is None


def test_kernels_compile_into_numba_cache_dir_and_say_so_once(tmp_path):
    """A fresh process, a fresh cache: the first call compiles (one notice), the files land in the cache
    directory and not beside the module; a second process loads them (no notice)."""
    code = ("import numpy as np\n"
            "from plenodecode import _numba\n"
            "_numba.set_compile_notice(lambda m: print('NOTICE', m))\n"
            "from plenodecode.calib.centroids.peaks import window_contrast\n"
            "g = np.array([[0.0, 2.0, 5.0], [1.0, 4.0, 0.5]], np.float32)\n"
            "for _ in range(2):\n"
            "    print(window_contrast(g, np.array([0, 1]), np.array([2, 1]), 1))\n")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    run = [sys.executable, "-c", code]
    first = subprocess.run(run, capture_output=True, text=True, check=True, env=env).stdout
    assert first.count("NOTICE compiling calibration kernels (first run only") == 1
    assert "[4.5 4. ]" in first
    assert any((tmp_path / "cache").rglob("*.nbi"))
    package_caches = [p for p in (ROOT / "plenodecode").rglob("*.nbi")]
    assert not package_caches, package_caches
    second = subprocess.run(run, capture_output=True, text=True, check=True, env=env).stdout
    assert "NOTICE" not in second and "[4.5 4. ]" in second


def test_run_in_blocks_covers_the_range_once_in_order():
    seen = []

    def call(i0, i1):
        seen.append((i0, i1))
        return list(range(i0, i1))

    out = _numba.run_in_blocks(call, 103, blocks_per_thread=5)
    assert [i for block in out for i in block] == list(range(103))        # results in block order, no gap/overlap
    assert sorted(seen) == seen or len(seen) == len(out)
    assert len(out) > 1
    assert _numba.run_in_blocks(call, 0) == []
    assert _numba.run_in_blocks(call, 1) == [[0]]
