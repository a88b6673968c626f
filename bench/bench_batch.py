"""Batch throughput: 20 generated full-size 'illum-mini' raws, single process vs --jobs 2 vs a Dask cluster.

Every configuration runs the real command line (``python -m plenodecode.cli.main batch ...``) in a
fresh process into an empty output folder, so worker start-up and imports are counted as a user
would see them.  An untimed one-raw run first fills numba's on-disk cache, so no configuration pays
JIT compilation.  The two-worker ``LocalCluster`` (one thread per worker, on loopback) is started
before the clock starts, as a lab's cluster would already be running; its workers are fresh, so
their imports are counted.  A second batch on the same cluster follows (into another folder): its
workers were set up by the first, as a long-running cluster's are after its first job.  Each line also gives when the first task started and CPU seconds (sampled):
of every process that worked for the command (its tree, and the LocalCluster's workers), and of its
critical path, the command and its fork server (before and after the tasks) plus the busiest worker, with
the single process's critical path over it in brackets.  On a machine shared with other work the wall
times swing with the load while these CPU figures barely move; on idle cores the critical path is about
the wall time (an upper bound for the single process, whose decoding uses both cores in stretches, so the
bracketed ratio runs a little above the wall ratio).  Each line also gives the throughput after start-up,
``steady_raws_per_s`` of ``summary.json``: the raws started once every worker had finished its first task, per
second until the last one ended (the first tasks and everything before them, interpreter, imports, fork server,
kernel loading, are what "started ... s in" and "first task" show separately); its ratio to the single process's
is how well the workers share the cores.  Peak memory per worker is the largest ``ru_maxrss``
a worker reported (``TaskResult.worker_peak_mb`` in ``summary.json``).

Inputs are generated once into ``bench/_cache/batch_illum_mini/`` (20 scene raws as Illum .lfr,
one white image and its calibration database).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench import Figure

CACHE = Path(__file__).resolve().parent / "_cache" / "batch_illum_mini"
N_RAWS = 20
OUTPUTS = "centre,refocus"


def _inputs() -> tuple[Path, Path]:
    """Cached raws folder and calibration database (generated on first use)."""
    from plenodecode.calib.store import build_database
    from plenodecode.io.lytro import write_lfr, write_raw_pair
    from plenodecode.synthetic import simulate

    raws, whites, db = CACHE / "raws", CACHE / "whites", CACHE / "db"
    raws.mkdir(parents=True, exist_ok=True)
    for i in range(N_RAWS):
        dest = raws / f"scene_{i:02d}.lfr"
        if dest.exists():
            continue
        sim = simulate("illum-mini", seed=100 + i)
        write_lfr(dest, sim.raw)
        if i == 0 and not (whites / "MOD_0000.RAW").exists():
            whites.mkdir(exist_ok=True)
            write_raw_pair(whites / "MOD_0000.RAW", sim.white)
    if not (db / "index.json").exists():
        if not (whites / "MOD_0000.RAW").exists():
            whites.mkdir(exist_ok=True)
            write_raw_pair(whites / "MOD_0000.RAW", simulate("illum-mini", seed=100).white)
        db.mkdir(exist_ok=True)
        build_database(whites, db)
    return raws, db


def _cpu_seconds(procs: list) -> dict[int, float]:
    """pid -> CPU seconds (user + system) of each live process of ``procs`` (psutil processes)."""
    import psutil

    seen = {}
    for p in procs:
        try:
            t = p.cpu_times()
        except psutil.Error:
            continue
        seen[p.pid] = t.user + t.system
    return seen


def _watch_cpu(proc: subprocess.Popen, outside: list, interval: float = 0.2) -> dict[str, float]:
    """CPU seconds of the command ``proc`` and its process tree, sampled every ``interval`` s until it exits, and of
    the processes ``outside`` it that run its tasks (a LocalCluster's workers) over the same time.

    Returns
    -------
    dict
        ``total``: every process; ``critical``: the part no second core can overlap, the command itself plus a
        fork server (they run before and after the tasks) plus the busiest worker.  On idle cores the wall
        time is about ``critical``; on a loaded machine the two CPU figures barely change while wall times do.
    """
    import psutil

    root = psutil.Process(proc.pid)
    before = _cpu_seconds(outside)
    seen: dict[int, float] = {}
    role: dict[int, str] = {}
    while proc.poll() is None:
        try:
            family = [root, *root.children(recursive=True)]
        except psutil.Error:
            family = []
        for p in family:
            if p.pid not in role:
                try:
                    server = p.ppid() == proc.pid and "forkserver" in " ".join(p.cmdline())
                except psutil.Error:
                    continue
                role[p.pid] = "command" if p.pid == proc.pid else ("command" if server else "worker")
        seen.update(_cpu_seconds(family))
        time.sleep(interval)
    after = _cpu_seconds(outside)
    workers = [c for pid, c in seen.items() if role.get(pid) == "worker"]
    workers += [after[pid] - before[pid] for pid in after if pid in before]
    serial = sum(c for pid, c in seen.items() if role.get(pid) == "command")
    return {"total": serial + sum(workers), "critical": serial + max(workers, default=0.0)}


def _run_cli(raws: Path, db: Path, out: Path, extra: list[str], expect: str = "done",
             n: int = N_RAWS, outside: list = ()) -> tuple[float, dict]:
    """Wall seconds of the command and its summary.json, with ``cpu_s`` and ``critical_cpu_s``
    (:func:`_watch_cpu`; ``outside``: processes running its tasks outside its tree) and ``first_start_s``
    (seconds from the command's start to its first task's start) added."""
    cmd = [sys.executable, "-m", "plenodecode.cli.main", "-q", "batch", str(raws), "-o", str(out),
           "--database", str(db), "--outputs", OUTPUTS, *extra]
    started = time.time()
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    cpu = _watch_cpu(proc, list(outside))
    _, stderr = proc.communicate()
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"batch failed ({proc.returncode}): {stderr.strip()[-500:]}")
    summary = json.loads((out / "summary.json").read_text())
    if summary[expect] != n:
        raise RuntimeError(f"expected {n} raws {expect}, got {summary[expect]}")
    summary["cpu_s"], summary["critical_cpu_s"] = cpu["total"], cpu["critical"]
    summary["first_start_s"] = min(r["started"] for r in summary["results"]) - started
    return seconds, summary


def _peaks(summary: dict) -> dict[str, float]:
    peaks: dict[str, float] = {}
    for r in summary["results"]:
        if r["worker_peak_mb"] is not None:
            peaks[r["worker"]] = max(peaks.get(r["worker"], 0.0), r["worker_peak_mb"])
    return peaks


def _figure(name: str, seconds: float, summary: dict, base: float | None, extra_note: str = "",
            base_critical: float | None = None, base_rate: float | None = None) -> Figure:
    peaks = _peaks(summary)
    per_min = N_RAWS / seconds * 60.0
    steady = summary["steady_task_s"]          # BatchSummary.latency: a worker's first task pays imports and kernels
    critical_ratio = "" if base_critical is None else f" ({base_critical / summary['critical_cpu_s']:.2f}x)"
    rate = summary["steady_raws_per_s"]
    rate_ratio = "" if base_rate is None else f" = {rate / base_rate:.2f}x the single process's"
    note = (f"after start-up {rate:.2f} raws/s{rate_ratio}; {'' if base is None else f'wall ratio {base / seconds:.2f}x; '}"
            f"{per_min:.1f} raws/min; {len(peaks)} worker(s), peak RSS per worker "
            f"{'/'.join(f'{p:.0f}' for p in sorted(peaks.values()))} MB; task median "
            f"{float('nan') if steady is None else steady:.2f} s, first task {summary['first_task_s']:.1f} s, "
            f"started {summary['first_start_s']:.1f} s in; CPU s: {summary['cpu_s']:.1f} in all processes, "
            f"{summary['critical_cpu_s']:.1f} on the critical path"
            f"{critical_ratio}"
            f"{extra_note}")
    return Figure(name, seconds, max(peaks.values()) if peaks else None,
                  ratio=None if base is None else base / seconds,
                  baseline=None if base is None else "single process", note=note)


def run() -> list[Figure]:
    from distributed import LocalCluster

    raws, db = _inputs()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    label = f"batch: {N_RAWS} illum-mini"
    figures = []
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        # untimed warm-up on one raw: numba's on-disk cache is filled, so no configuration pays compilation
        warm = Path(tmp) / "warm_in"
        warm.mkdir()
        shutil.copy(raws / "scene_00.lfr", warm / "scene_00.lfr")
        _run_cli(warm, db, Path(tmp) / "warm", ["--jobs", "1"], n=1)
        t1, s1 = _run_cli(raws, db, Path(tmp) / "single", ["--jobs", "1"])
        figures.append(_figure(f"{label}, single process", t1, s1, None,
                               f"; 1-min load {load:.1f} on {os.cpu_count()} cores"))
        t2, s2 = _run_cli(raws, db, Path(tmp) / "jobs2", ["--jobs", "2"])
        figures.append(_figure(f"{label}, --jobs 2", t2, s2, t1, base_critical=s1["critical_cpu_s"],
                               base_rate=s1["steady_raws_per_s"]))
        with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            import psutil

            workers = psutil.Process().children(recursive=True)       # the cluster's worker processes
            t3, s3 = _run_cli(raws, db, Path(tmp) / "dask", ["--scheduler", cluster.scheduler_address],
                              outside=workers)
            # the same cluster's second batch: its workers were set up by the first (modules imported), as a
            # lab's long-running cluster is after its first job
            t5, s5 = _run_cli(raws, db, Path(tmp) / "dask_again", ["--scheduler", cluster.scheduler_address],
                              outside=workers)
        figures.append(_figure(f"{label}, LocalCluster 2 workers", t3, s3, t1, base_critical=s1["critical_cpu_s"],
                               base_rate=s1["steady_raws_per_s"]))
        figures.append(_figure(f"{label}, LocalCluster 2 workers, its second batch", t5, s5, t1,
                               base_critical=s1["critical_cpu_s"], base_rate=s1["steady_raws_per_s"]))
        # resuming: a second run over finished outputs only hashes the inputs
        t4, s4 = _run_cli(raws, db, Path(tmp) / "single", ["--jobs", "1"], expect="skipped")
        figures.append(Figure(f"{label}, re-run (all skipped)", t4, None, note=f"{s4['skipped']} skipped"))
    return figures


if __name__ == "__main__":
    from bench import print_table

    print_table(run())
