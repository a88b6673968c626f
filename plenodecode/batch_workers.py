"""Where the tasks of :func:`plenodecode.batch.run_batch` run: local worker processes or a Dask cluster.

Both runners keep every worker busy from its start to the end of the batch and spend as little as
possible on anything else:

- local workers (:func:`run_pool`) are forked from a fork server that imported the modules a task uses
  (:data:`PRELOAD_MODULES`) once, in the background, while this process still prepares the batch
  (:func:`start_pool`, :func:`plenodecode.threads.worker_pool`); a worker then starts in milliseconds and
  leaves without tearing an interpreter down;
- on a Dask cluster (:func:`run_dask`) every worker imports those modules once before the first task
  (:func:`prepare_dask_worker`), and gets back glibc's usual allocator thresholds for the batch: the
  Dask nanny starts workers with ``MALLOC_TRIM_THRESHOLD_`` set, which pins the mmap threshold at
  128 KiB, so every array of a task is mapped and faulted in afresh (about +45 % CPU per task here);
- the largest inputs are submitted first, so no worker is left with a long task at the tail;
- this process only waits on the results (no polling) and reports progress.

A light field never travels: a task reads its raw and writes its outputs on the worker; only
:class:`~plenodecode.batch.TaskResult` records come back.  The runners know nothing of a batch's options:
:func:`~plenodecode.batch.run_batch` hands them the task (a picklable callable of the raw's path, its output
name and the worker's threads) and how to record a task whose worker was lost.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import re
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, Callable, Sequence

from .errors import one_line

#: ``task(path, name=..., threads=...) -> result``, run on a worker (picklable: a module-level function or a
#: ``functools.partial`` of one).
Task = Callable[..., Any]
#: ``lost(path, exc) -> result``: the result recorded, in this process, for a task whose worker died.
Lost = Callable[[Path, BaseException], Any]
#: ``progress(done, total)`` or None.
Progress = Callable[[int, int], None] | None

log = logging.getLogger(__name__)

#: Modules every batch task imports (reading Lytro / Raytrix / camera raws, the calibration choice and its
#: check, decoding, the image products, writing): imported once per fork server or Dask worker.
PRELOAD_MODULES = ("numpy", "cv2", "numba", "OpenImageIO", "plenodecode.batch", "plenodecode.pipeline",
                   "plenodecode.calib.check", "plenodecode.calib.store", "plenodecode.calib.centroids",
                   "plenodecode.decoding.decoder", "plenodecode.decoding.demosaic_kernels",
                   "plenodecode.decoding.resample", "plenodecode.io.lytro", "plenodecode.io.raytrix",
                   "plenodecode.io.generic", "plenodecode.io.images", "plenodecode.io.depthio",
                   "plenodecode.render", "plenodecode.render.shiftsum")
#: Further modules of a batch output (:data:`plenodecode.batch.BATCH_OUTPUTS`), preloaded when it is asked for.
PRELOAD_BY_OUTPUT = {"lightfield": ("plenodecode.io.lightfield",), "views": ("plenodecode.io.lightfield",),
                     "depth": ("plenodecode.depth.methods",)}

#: glibc's mallopt parameters, and the thresholds its dynamic adjustment settles at for large arrays on
#: 64-bit (mmap threshold up to DEFAULT_MMAP_THRESHOLD_MAX = 32 MiB; trim threshold twice the mmap threshold).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_THRESHOLD_LARGE = 32 << 20
_TRIM_THRESHOLD_LARGE = 64 << 20
#: glibc's defaults, restored when the environment did not set a threshold.
_MMAP_THRESHOLD_DEFAULT = 128 << 10
_TRIM_THRESHOLD_DEFAULT = 128 << 10


def preload_modules(outputs: Sequence[str]) -> tuple[str, ...]:
    """:data:`PRELOAD_MODULES` and those of ``outputs`` (:data:`PRELOAD_BY_OUTPUT`), without repeats."""
    extra = [m for o in outputs for m in PRELOAD_BY_OUTPUT.get(o, ())]
    return tuple(dict.fromkeys((*PRELOAD_MODULES, *extra)))


def largest_first(tasks: Sequence[tuple[Path, str]]) -> list[int]:
    """Indices of ``tasks`` by decreasing input size (ties in input order): the longest tasks start first, so
    the workers finish together instead of one running a long task alone at the tail."""
    def size(i: int) -> int:
        try:
            return os.stat(tasks[i][0]).st_size
        except OSError:
            return 0
    return sorted(range(len(tasks)), key=lambda i: -size(i))


# ------------------------------------------------------------------------------ local
def start_pool(jobs: int, outputs: Sequence[str]) -> tuple[ProcessPoolExecutor, int]:
    """``jobs`` local workers with ``cores // jobs`` threads each (:func:`plenodecode.threads.worker_pool`); the
    fork server starts importing :func:`preload_modules` now, while the caller prepares the batch.

    Returns
    -------
    (ProcessPoolExecutor, int)
        The pool and the threads per worker.
    """
    from . import _numba
    from .threads import worker_pool

    threads = max(1, (os.cpu_count() or 1) // jobs)
    # a kernel group the workers compile is said once, here (the CLI: one line on stderr), not once per worker
    return worker_pool(jobs, threads, preload=preload_modules(outputs), compile_notices=_numba.announce,
                       log_level=logging.getLogger().getEffectiveLevel()), threads


def run_pool(pool: ProcessPoolExecutor, tasks: list[tuple[Path, str]], task: Task, lost: Lost,
             outputs: Sequence[str], jobs: int, limit: int, threads: int, progress: Progress) -> list[Any]:
    """``task(path, name=name, threads=threads)`` for each ``(path, name)`` of ``tasks`` on the local ``pool``
    (:func:`start_pool` of ``jobs`` and ``outputs``), at most ``limit`` submitted at a time, largest first.

    A worker that dies (e.g. killed for memory) fails the tasks in flight (``lost``) and the pool is restarted
    for the rest.  ``pool`` is shut down on return; on Ctrl-C (which the workers ignore) their tasks are interrupted
    first.  Results in the order of ``tasks``.
    """
    from .io.atomic import interrupts_between_steps

    results: list[Any] = [None] * len(tasks)
    order = largest_first(tasks)
    pending: dict[Future, int] = {}
    nxt = finished = 0
    try:
        while nxt < len(order) or pending:
            while nxt < len(order) and len(pending) < limit:
                idx = order[nxt]
                f, n = tasks[idx]
                try:
                    with interrupts_between_steps():    # Ctrl-C: once the worker being started has its task
                        pending[pool.submit(task, f, name=n, threads=threads)] = idx
                except BrokenProcessPool:
                    pool.shutdown(wait=False, cancel_futures=True)
                    pool = start_pool(jobs, outputs)[0]
                    continue
                nxt += 1
            done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            for fut in done:
                idx = pending.pop(fut)
                try:
                    results[idx] = fut.result()
                except Exception as exc:  # the worker process died: report it, keep going
                    results[idx] = lost(tasks[idx][0], exc)
                finished += 1
                if progress is not None:
                    progress(finished, len(tasks))
    except KeyboardInterrupt:
        pool.interrupt(pending)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return results


# ------------------------------------------------------------------------------- Dask
def _mallopt(param: int, value: int) -> bool:
    """glibc's ``mallopt(param, value)``; False where the C library is not glibc."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return bool(libc.mallopt(ctypes.c_int(param), ctypes.c_int(value)))
    except (OSError, AttributeError):
        return False


def _pinned_thresholds() -> bool:
    """True when this process's environment fixed glibc's malloc thresholds (as the Dask nanny does)."""
    return any(os.environ.get(v) for v in ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_"))


def prepare_dask_worker(modules: Sequence[str]) -> dict[str, Any]:
    """Set up a Dask worker for batch tasks (run there once, by ``client.run``): import ``modules`` and, where
    the environment pinned glibc's malloc thresholds, raise them to those glibc itself settles at for large
    arrays (mmap threshold 32 MiB, trim threshold 64 MiB) until :func:`release_dask_worker`.

    Returns
    -------
    dict
        ``import_s``: seconds spent importing; ``malloc``: whether the thresholds were raised.
    """
    import importlib

    t0 = time.perf_counter()
    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError:        # an optional reader; the task says what is missing if it needs it
            pass
    raised = _pinned_thresholds() and _mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_LARGE) \
        and _mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD_LARGE)
    return {"import_s": time.perf_counter() - t0, "malloc": raised}


def release_dask_worker() -> bool:
    """Give a Dask worker back the malloc thresholds its environment set (after :func:`prepare_dask_worker`)."""
    if not _pinned_thresholds():
        return False
    trim = int(os.environ.get("MALLOC_TRIM_THRESHOLD_") or _TRIM_THRESHOLD_DEFAULT)
    mmap = int(os.environ.get("MALLOC_MMAP_THRESHOLD_") or _MMAP_THRESHOLD_DEFAULT)
    return _mallopt(_M_MMAP_THRESHOLD, mmap) and _mallopt(_M_TRIM_THRESHOLD, trim)


#: ``[scheme://]host:port`` of a Dask scheduler (an IPv6 host in brackets); 'inproc://' addresses as they are.
_SCHEDULER_ADDRESS = re.compile(r"^(?:(?:tcp|tls|ws|wss|ucx)://)?"         # protocol
                                r"(?:\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+)"          # [IPv6] or host
                                r":(?P<port>[0-9]{1,5})/?$")


def check_scheduler_address(address: str) -> str:
    """``address`` if it has the shape of a Dask scheduler address (``tcp://10.0.0.5:8786``, ``host:8786``).

    Raises
    ------
    ValueError
        No port, a port outside 1-65535, another scheme, spaces (a typo that Dask would only refuse after a minute).
    """
    text = str(address).strip()
    if text.startswith("inproc://"):
        return text
    m = _SCHEDULER_ADDRESS.match(text)
    if m is None or not 1 <= int(m.group("port")) <= 65535:
        raise ValueError(f"scheduler: expected a Dask scheduler address tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786), "
                         f"got {address!r}")
    return text


#: Seconds to wait for a Dask scheduler to answer (Dask's own default, 30 s, kept a batch with a mistyped or
#: stopped scheduler silent for half a minute); a shorter ``distributed.comm.timeouts.connect`` is kept.
SCHEDULER_CONNECT_S = 5.0


def connect_scheduler(scheduler: Any) -> tuple[Any, bool]:
    """A Dask ``Client`` of ``scheduler`` (an address, checked by :func:`check_scheduler_address`, or a Client)
    and whether it is our own to close.

    Raises
    ------
    ValueError
        A malformed address.
    OSError
        The scheduler cannot be reached within :data:`SCHEDULER_CONNECT_S` seconds.
    """
    import dask
    from dask.utils import parse_timedelta
    from distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    address = check_scheduler_address(scheduler)
    timeout = min(SCHEDULER_CONNECT_S, parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), "s"))
    return Client(address, timeout=timeout, set_as_default=False), True


def run_dask(tasks: list[tuple[Path, str]], task: Task, lost: Lost, outputs: Sequence[str], scheduler: Any,
             max_in_flight: int | None, progress: Progress) -> list[Any]:
    """The same tasks as :func:`run_pool` (one thread each) on a Dask distributed cluster, largest first, results
    streamed back as they finish; at most ``max_in_flight`` (default twice the workers) submitted at a time.

    Every worker is set up once (:func:`prepare_dask_worker`) before the first task and released
    (:func:`release_dask_worker`) at the end.
    """
    from distributed import as_completed

    client, own = connect_scheduler(scheduler)
    try:
        try:
            setup = client.run(prepare_dask_worker, preload_modules(outputs))
        except Exception as exc:  # e.g. workers with another plenodecode: their tasks say so one by one
            log.warning("dask workers not set up (%s); running the tasks without", one_line(exc))
        else:
            log.info("dask workers set up: %s", setup)
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        limit = max_in_flight or 2 * n_workers
        results: list[Any] = [None] * len(tasks)
        index: dict[str, int] = {}
        queue = iter(largest_first(tasks))
        tag = os.urandom(4).hex()

        def submit_next() -> Any:
            i = next(queue, None)
            if i is None:
                return None
            f, n = tasks[i]
            fut = client.submit(task, str(f), name=n, threads=1, key=f"plenodecode-batch-{tag}-{i}", pure=False)
            index[fut.key] = i
            return fut

        first = [fut for fut in (submit_next() for _ in range(limit)) if fut is not None]
        finished = 0
        ac = as_completed(first, loop=client.loop)
        for fut in ac:
            i = index.pop(fut.key)
            try:
                results[i] = fut.result()
            except Exception as exc:   # worker lost (KilledWorker) or unpicklable result
                results[i] = lost(tasks[i][0], exc)
            fut.release()
            finished += 1
            if progress is not None:
                progress(finished, len(tasks))
            nxt = submit_next()
            if nxt is not None:
                ac.add(nxt)
        try:
            client.run(release_dask_worker)
        except Exception as exc:  # a worker left meanwhile: nothing to give back there
            log.info("dask workers not released: %s", exc)
        return results
    finally:
        if own:
            client.close()


__all__ = ["PRELOAD_MODULES", "PRELOAD_BY_OUTPUT", "preload_modules", "largest_first", "start_pool", "run_pool",
           "prepare_dask_worker", "release_dask_worker", "run_dask"]
