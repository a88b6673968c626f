"""Where batch tasks run: forked local workers with preloaded modules, Dask worker set-up, submission order."""

from __future__ import annotations

import importlib
import json
import os
import platform
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from plenodecode.batch import BATCH_OUTPUTS
from plenodecode.batch_workers import (PRELOAD_BY_OUTPUT, PRELOAD_MODULES, largest_first, preload_modules,
                                       prepare_dask_worker, release_dask_worker)
from plenodecode.cli.main import cli
from tests.test_batch import _files, data  # noqa: F401  (the generated raws and database)

ROOT = Path(__file__).resolve().parents[1]


def _run_script(code: str, env: dict[str, str] | None = None, path: Path | None = None) -> dict:
    """Run ``code`` in a fresh interpreter (``path``, then this tree first on the module path); its last stdout
    line is JSON."""
    search = [str(p) for p in (path, ROOT) if p is not None]
    full_env = {**os.environ, "PYTHONPATH": os.pathsep.join([*search, os.environ.get("PYTHONPATH", "")]),
                **(env or {})}
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          env=full_env, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_largest_inputs_are_submitted_first(tmp_path):
    sizes = [3, 10, 1, 10, 0]
    tasks = []
    for i, size in enumerate(sizes):
        f = tmp_path / f"raw{i}.lfr"
        f.write_bytes(b"x" * size)
        tasks.append((f, f"raw{i}"))
    tasks.append((tmp_path / "missing.lfr", "missing"))          # fails later, in its task; sorted as empty
    assert largest_first(tasks) == [1, 3, 0, 2, 4, 5]


def test_preloaded_modules_exist_and_follow_the_outputs():
    """A misspelt name would be skipped silently by the fork server: every listed module must import."""
    listed = {*PRELOAD_MODULES, *(m for mods in PRELOAD_BY_OUTPUT.values() for m in mods)}
    for name in sorted(listed):
        importlib.import_module(name)
    assert set(PRELOAD_BY_OUTPUT) <= set(BATCH_OUTPUTS)
    mods = preload_modules(("centre", "depth", "lightfield", "views"))
    assert len(mods) == len(set(mods)) and mods[:len(PRELOAD_MODULES)] == PRELOAD_MODULES
    assert "plenodecode.depth.methods" in mods and "plenodecode.io.lightfield" in mods
    assert preload_modules(("centre",)) == PRELOAD_MODULES


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's mallopt")
def test_dask_worker_setup_lifts_the_pinned_malloc_thresholds():
    """Under the Dask nanny's MALLOC_TRIM_THRESHOLD_ every 1 MiB array is mapped and faulted in afresh
    (256 page faults each); after prepare_dask_worker the heap is reused; release gives the pinning back."""
    got = _run_script("""
        import json, resource
        import numpy as np
        from plenodecode.batch_workers import prepare_dask_worker, release_dask_worker

        def faults():
            before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
            for _ in range(50):
                a = np.ones(1 << 18, np.float32)
                del a
            return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

        pinned = faults()
        setup = prepare_dask_worker(["numpy", "no_such_module_here"])
        lifted = faults()
        released = release_dask_worker()
        print(json.dumps({"pinned": pinned, "setup": setup, "lifted": lifted, "released": released,
                          "again": faults()}))
    """, env={"MALLOC_TRIM_THRESHOLD_": "65536"})
    assert got["setup"]["malloc"] and got["released"]
    assert got["pinned"] > 50 * 200                   # 256 pages of 4 KiB per array
    assert got["lifted"] < got["pinned"] / 10
    assert got["again"] > 50 * 200


def test_dask_worker_setup_leaves_an_unpinned_allocator_alone(monkeypatch):
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_", raising=False)
    setup = prepare_dask_worker(["json"])
    assert setup["malloc"] is False and setup["import_s"] >= 0
    assert release_dask_worker() is False


def test_cli_jobs_2_writes_the_bytes_of_one_process(data, tmp_path):  # noqa: F811
    """``--jobs 2`` through the CLI: two forked workers, the same files as ``--jobs 1``."""
    outs = {}
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs{jobs}"
        res = CliRunner().invoke(cli, ["-q", "batch", str(data["shoot"]), "-o", str(out), "--database",
                                       str(data["db"]), "--jobs", jobs, "--outputs", "centre,refocus", "--slope",
                                       "0.25"])
        assert res.exit_code == 0, res.output
        summary = json.loads((out / "summary.json").read_text())
        assert summary["done"] == 3
        outs[jobs] = (_files(out), {r["worker"] for r in summary["results"]})
    assert len(outs["1"][1]) == 1 and len(outs["2"][1]) == 2
    assert outs["2"][0] == outs["1"][0] and sum(k.endswith(".png") for k in outs["1"][0]) >= 3 * 2


def test_pool_workers_find_a_relative_database_after_a_chdir(data, tmp_path, monkeypatch):  # noqa: F811
    """Forked workers keep the working folder their fork server started in: the database path is resolved
    before it travels."""
    from plenodecode.batch import BatchOptions, run_batch
    from plenodecode.threads import worker_pool

    monkeypatch.chdir(tmp_path)
    worker_pool(2, max(1, (os.cpu_count() or 1) // 2)).shutdown()   # the server runs, started here if not before
    monkeypatch.chdir(data["db"].parent)
    summary = run_batch([data["shoot"] / "take1", data["shoot"] / "take2"], tmp_path / "out",
                        BatchOptions(outputs=("centre",), database="db"), jobs=2)
    assert [r.status for r in summary.results] == ["done", "done"], [r.error for r in summary.results]
    assert len({r.worker for r in summary.results}) == 2
