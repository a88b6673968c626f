"""Cold start: the four everyday commands on ``sample_raws/illum-mini``, first run vs warm run.

Each command runs as a user types it (``python -m plenodecode.cli.main ...``, a fresh process),
first with an empty numba cache (its own new temporary ``NUMBA_CACHE_DIR``: the first command
after installing), then again with the cache that first run filled (warm, best of ``WARM_RUNS``).
Wall seconds are a monotonic clock around the child; CPU seconds are the child's user + system
time (``resource.getrusage(RUSAGE_CHILDREN)``), the figure to trust when the machine is shared.

Issue 21's target: a cold command takes at most ``max(2 x warm, warm + 5 s)``; the table judges the wall
seconds, and the note the same target on CPU seconds (the verdict to trust on a loaded machine).

``python -m bench.bench_coldstart`` prints the table on its own.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from bench import Figure

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_raws" / "illum-mini"
WARM_RUNS = 2


@dataclass
class Run:
    """Wall and CPU (user + system) seconds of one child process."""

    wall: float
    cpu: float


def _commands(out: Path) -> list[tuple[str, list[str]]]:
    """(name, argv after ``plenodecode``); ``depth`` reads the light field ``decode`` wrote."""
    raw = str(SAMPLE / "scene.lfr")
    db = str(ROOT / "calib")
    lf = str(out / "lf.zarr")
    return [
        ("RAW --refocus 1.0", [raw, "--refocus", "1.0", "-o", str(out / "x.png"), "--database", db]),
        ("decode -o lf.zarr", ["decode", raw, "-o", lf, "--database", db]),
        ("calibrate MOD_0000.RAW", ["calibrate", str(SAMPLE / "MOD_0000.RAW"), "-o", str(out / "g.json")]),
        ("depth lf.zarr", ["depth", lf, "-o", str(out / "d.pfm")]),
    ]


def run_cli(argv: list[str], cache_dir: Path, *, cwd: Path = ROOT) -> Run:
    """Run ``plenodecode ARGV`` in a fresh process with ``NUMBA_CACHE_DIR=cache_dir``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), PYTHONPATH=str(ROOT))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "plenodecode.cli.main", *argv, "--overwrite"],
                          cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"plenodecode {' '.join(argv)} failed:\n{proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return Run(wall, cpu)


def measure_commands() -> list[tuple[str, Run, Run]]:
    """(name, cold run, best warm run) of each command; every cold run starts from an empty cache."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="plenodecode-coldstart-") as tmp:
        tmp = Path(tmp)
        out = tmp / "out"
        out.mkdir()
        for i, (name, argv) in enumerate(_commands(out)):
            cache = tmp / f"numba-{i}"
            print(f"#   {name}: cold", file=sys.stderr, flush=True)
            cold = run_cli(argv, cache)
            warm = min((run_cli(argv, cache) for _ in range(WARM_RUNS)), key=lambda r: r.wall)
            rows.append((name, cold, warm))
            shutil.rmtree(cache, ignore_errors=True)
    return rows


def run() -> list[Figure]:
    figures = []
    for name, cold, warm in measure_commands():
        limit = max(2 * warm.wall, warm.wall + 5.0)
        cpu_limit = max(2 * warm.cpu, warm.cpu + 5.0)
        verdict = "ok" if cold.cpu <= cpu_limit else "over"
        figures.append(Figure(f"cold start: {name} (cold, empty numba cache)", cold.wall, target_s=limit,
                              note=f"CPU {cold.cpu:.1f} s (same target on CPU: <= {cpu_limit:.1f} s, {verdict})"))
        figures.append(Figure(f"cold start: {name} (warm)", warm.wall, note=f"CPU {warm.cpu:.1f} s"))
    return figures


if __name__ == "__main__":
    from bench import machine, print_table

    print(machine())
    print_table(run())
