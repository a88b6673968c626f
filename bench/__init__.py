"""Benchmarks (not tests).  ``make bench`` runs every ``bench/bench_*.py`` module's ``run()``.

Each ``run()`` returns a list of :class:`Figure`; this module measures and prints them.
Peak memory is the peak of traced allocations (numpy registers its buffers with
tracemalloc) during one call, so it is the working set a function adds, not the
process's resident size; where arrays are mapped outside numpy's allocator (the decoded
light field) :func:`peak_rss_growth` measures the growth of the resident set instead.
"""

from __future__ import annotations

import gc
import os
import time
import tracemalloc
from dataclasses import dataclass
from typing import Any, Callable


@dataclass
class Figure:
    """One row of the benchmark table."""

    name: str
    seconds: float
    peak_mb: float | None = None
    target_s: float | None = None
    ratio: float | None = None      # speed-up against the named baseline (>1 = faster)
    baseline: str | None = None
    note: str = ""


def measure(fn: Callable[[], Any], *, repeat: int = 1, memory: bool = True) -> tuple[Any, float, float | None]:
    """Run ``fn`` and return ``(result, best wall seconds, peak traced MB)``.

    The timing runs are untraced; one extra traced run gives the peak memory.
    """
    best = float("inf")
    result = None
    for _ in range(repeat):
        gc.collect()
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    peak = None
    if memory:
        del result
        gc.collect()
        tracemalloc.start()
        result = fn()
        _, peak_b = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        peak = peak_b / 2**20
    return result, best, peak


def peak_rss_growth(fn: Callable[[], Any], *, interval: float = 0.005) -> tuple[Any, float]:
    """Run ``fn`` and return ``(result, peak growth of the resident set size in MB)``.

    The resident set (``/proc/self/statm``, Linux) is sampled every ``interval`` s on a thread while
    ``fn`` runs; unlike the traced peak of :func:`measure` it also counts memory that numpy's allocator
    does not hand out (``decoding.decoder.small_page_empty`` maps the light field itself).  NaN where
    ``/proc`` is missing.
    """
    import threading

    page_mb = os.sysconf("SC_PAGE_SIZE") / 2**20

    def rss() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * page_mb

    try:
        base = rss()
    except OSError:
        return fn(), float("nan")
    peak = [base]
    done = threading.Event()

    def sample() -> None:
        while not done.wait(interval):
            peak[0] = max(peak[0], rss())

    gc.collect()
    watcher = threading.Thread(target=sample, daemon=True)
    watcher.start()
    try:
        result = fn()
    finally:
        done.set()
        watcher.join()
    return result, max(peak[0], rss()) - base


def machine() -> str:
    """``'AMD EPYC, 2 cores'``: the CPU model (``/proc/cpuinfo``) and the processor count, for the table's header."""
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores"


def print_table(figures: list[Figure]) -> None:
    """Print figures as an aligned text table."""
    head = f"{'benchmark':58s} {'seconds':>9s} {'target':>8s} {'peak MB':>9s} {'ratio':>8s}  note"
    print(head)
    print("-" * len(head))
    for f in figures:
        target = f"<={f.target_s:g}" if f.target_s is not None else ""
        peak = f"{f.peak_mb:9.0f}" if f.peak_mb is not None else f"{'':9s}"
        ratio = f"{f.ratio:7.1f}x" if f.ratio is not None else f"{'':8s}"
        note = f.note + (f" (vs {f.baseline})" if f.baseline else "")
        status = "" if f.target_s is None else ("  ok" if f.seconds <= f.target_s else "  SLOW")
        print(f"{f.name:58s} {f.seconds:9.3f} {target:>8s} {peak} {ratio}  {note}{status}")
