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


def _cached_kernels(cache: Path) -> set[str]:
    """Names of the compiled kernels (``module.function``) in a numba cache directory."""
    return {p.name.split("-")[0] for p in cache.rglob("*.nbi")}


def test_the_calibration_notice_shows_once_for_a_white_then_its_scene(tmp_path):
    """'plenodecode calibrate radiometry_frame.png -o w.json && plenodecode calibrate --scene light_field.png -o
    s.json --report s.html' on a fresh cache said 'compiling calibration kernels (first run only, ~3 s)...' twice:
    the scene's rim fit compiles kernels the white's fit does not (as a report at full resolution does).  The first
    command's notice now stands for the group: the second compiles its ~1 s of kernels without repeating it."""
    from tests.conftest import shared_path

    white = shared_path("lf-microscopy-antleg", "radiometry_frame.png")
    scene = shared_path("lf-microscopy-antleg", "light_field.png")
    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "plenodecode", "calibrate"]
    first = subprocess.run([*cmd, str(white), "-o", str(tmp_path / "w.json")], capture_output=True, text=True,
                           env=env, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    after_white = _cached_kernels(cache)
    second = subprocess.run([*cmd, "--scene", str(scene), "-o", str(tmp_path / "s.json"), "--report",
                             str(tmp_path / "s.html")], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert second.returncode == 0, second.stderr
    compiled_by_scene = _cached_kernels(cache) - after_white
    assert {"rims._rim_fit", "rims._splat_votes"} <= compiled_by_scene, compiled_by_scene   # it did compile
    notices = [line for out in (first.stderr, second.stderr) for line in out.splitlines() if "compiling" in line]
    # what the first command compiles: 0.9-1.0 s for a white, 1.9 s for a full-size scene (COMPILE_SECONDS), not 3 s
    assert notices == ["compiling calibration kernels (first run only, ~1-2 s)..."], (first.stderr, second.stderr)
    from importlib import metadata

    assert "compiling" in first.stderr and [p.name for p in (cache / "compile-notices").iterdir()] == \
        [f"calibration-{metadata.version('plenodecode')}-numba{metadata.version('numba')}"]


def test_warmup_compiles_the_self_calibration_kernels(tmp_path):
    """'plenodecode warmup' then 'calibrate --scene' still compiled the rim-fit kernels and said so: the warmup's
    calibration group fitted a white image only.  It now self-calibrates its scene too."""
    code = ("from plenodecode.warmup import _synthetic, _calibration\n"
            "state = {}\n_synthetic(state)\n_calibration(state)\n")
    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert {"rims._rim_fit", "rims._splat_votes"} <= _cached_kernels(cache)
