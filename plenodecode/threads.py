"""The thread pools of a process: numba, OpenCV and BLAS / OpenMP, and worker processes that share the cores.

Decoding and rendering run in threads (the decoder's bands, numba's parallel kernels, OpenCV's own
pool, BLAS).  One process may use every core; ``jobs`` worker processes must each use
``cores // jobs`` threads, or together they ask for ``jobs`` times the cores and lose time to
switching and cache thrashing.  :func:`worker_pool` starts such workers (``plenodecode batch --jobs``),
forked from a fork server that imported the heavy modules once where the platform has one;
:func:`limit_threads` caps the pools of the process it runs in (a batch task on a Dask worker).
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import multiprocessing.context
import os
import signal
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, Callable, Iterable, Iterator

#: Environment variables that size the BLAS / OpenMP thread pools when those libraries load.
THREAD_ENV_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                   "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def task_threads(limit: int | None = None) -> int:
    """Threads a computation running in the calling thread may start (its own Python thread pool, say):
    numba's setting for this thread (every core unless :func:`limit_threads` capped it), at most ``limit``."""
    import numba

    n = int(numba.get_num_threads())
    return max(1, n if limit is None else min(n, int(limit)))


def thread_counts() -> dict[str, int | None]:
    """The thread pools this process would use: numba (this thread's setting), OpenCV and BLAS.

    BLAS is what threadpoolctl reports when it is installed, else the ``OPENBLAS_NUM_THREADS`` /
    ``OMP_NUM_THREADS`` the library read when it loaded (None when neither is set: all cores).
    """
    import cv2
    import numba

    blas: int | None = None
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        value = os.environ.get("OPENBLAS_NUM_THREADS") or os.environ.get("OMP_NUM_THREADS")
        blas = int(value) if value and value.isdigit() else None
    else:
        counts = [int(p["num_threads"]) for p in threadpool_info() if p.get("user_api") == "blas"]
        blas = max(counts) if counts else None
    return {"numba": int(numba.get_num_threads()), "opencv": int(cv2.getNumThreads()), "blas": blas}


def limit_threads(threads: int) -> dict[str, int | None]:
    """Cap the thread pools of this process at ``threads`` each: numba, OpenCV, BLAS / OpenMP.

    A batch worker runs one task at a time with ``cores // workers`` threads, so the pools of all
    workers together never ask for more threads than there are cores.  BLAS and OpenMP read their
    size when they load, from :data:`THREAD_ENV_VARS`, which the local pool sets for the workers it
    starts (:func:`worker_pool`); threadpoolctl, when installed, resizes libraries already loaded.
    numba's setting holds for the calling thread (the one that runs the task).

    Parameters
    ----------
    threads : int
        Threads per pool (>= 1).

    Returns
    -------
    dict
        :func:`thread_counts` after the change.
    """
    threads = max(1, int(threads))
    import cv2
    import numba

    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    cv2.setNumThreads(threads)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        pass
    else:
        threadpool_limits(threads)
    return thread_counts()


#: Thread cap of the fork server this process started (:func:`worker_pool`); empty before.  multiprocessing keeps
#: one fork server per process, started once with the environment of that moment, so this records the state of
#: that process-wide server, whose BLAS pools were sized by it (it is not a cache: nothing is looked up here).
_FORK_SERVER_THREADS: list[int] = []


def _capped_environment(threads: int) -> dict[str, str]:
    return {var: str(threads) for var in (*THREAD_ENV_VARS, "NUMBA_NUM_THREADS")}


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` updated with ``values`` inside the block, restored after it."""
    saved = {var: os.environ.get(var) for var in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value


@contextlib.contextmanager
def _children_block_ctrl_c() -> Iterator[None]:
    """Processes started inside the block (the fork server, spawned workers) start with Ctrl-C (SIGINT) blocked,
    which an exec keeps and the fork server hands on to the workers it forks, until a worker ignores it
    (:func:`_start_worker`): a Ctrl-C reaches every process of a terminal's foreground group, and one that landed
    while the fork server imported its modules, or while a worker waited for a task, printed a traceback of that
    process after the command's 'Aborted!'.  The command stops on it and stops its workers' tasks
    (:meth:`_CappedPool.interrupt`); in this process a Ctrl-C of those milliseconds waits, it is not lost."""
    if not hasattr(signal, "pthread_sigmask"):       # no POSIX signals (Windows): no process group either
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()    # first: starting it unblocks SIGINT in this thread when done
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _stop_task(signum: int, frame: Any) -> None:
    """SIGINT in a worker's task: KeyboardInterrupt, once (the cleanup it starts is not cut off by the next)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


def _interruptible(fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` in a worker, Ctrl-C raising KeyboardInterrupt meanwhile (:meth:`_CappedPool.
    interrupt`); between tasks the worker ignores it."""
    previous = signal.signal(signal.SIGINT, _stop_task)
    try:
        return fn(*args, **kwargs)
    finally:
        signal.signal(signal.SIGINT, previous)


def _fork_server_context(threads: int, preload: tuple[str, ...]) -> multiprocessing.context.BaseContext | None:
    """The 'forkserver' context with the server started now (it imports ``preload`` in the background) with
    :data:`THREAD_ENV_VARS` = ``threads``; None where the platform has no fork server, or where this process's
    server was started with another thread cap (its BLAS pools could not be resized)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return None
    if _FORK_SERVER_THREADS and _FORK_SERVER_THREADS[0] != threads:
        return None
    from multiprocessing import forkserver

    context = multiprocessing.get_context("forkserver")
    if not _FORK_SERVER_THREADS:
        context.set_forkserver_preload(list(preload))
        with _environment(_capped_environment(threads)), _children_block_ctrl_c():
            forkserver.ensure_running()             # returns at once; the server imports ``preload`` meanwhile
        _FORK_SERVER_THREADS.append(threads)
    return context


class _CappedPool(ProcessPoolExecutor):
    """A process pool whose workers start with :data:`THREAD_ENV_VARS` = ``threads`` (see :func:`worker_pool`).

    The workers import numpy (and so BLAS) before any initializer runs, so the sizes must be in the
    environment they are started with: the variables are set in this process only while a worker (or
    the fork server) is being started (workers start on demand, from :meth:`submit`), then restored.
    """

    def __init__(self, jobs: int, threads: int, context: multiprocessing.context.BaseContext,
                 compile_notices: Callable[[str], None] | None = None, log_level: int | None = None) -> None:
        # a SimpleQueue writes to its pipe at once: a worker leaves without flushing a feeder thread
        self._notices = None if compile_notices is None else context.SimpleQueue()
        super().__init__(max_workers=jobs, mp_context=context, initializer=_start_worker,
                         initargs=(threads, self._notices, log_level))
        self._thread_env = _capped_environment(threads)
        self._relay = None
        if compile_notices is not None:
            def relay(queue=self._notices, say=compile_notices) -> None:
                for group in iter(queue.get, None):
                    say(group)
            self._relay = threading.Thread(target=relay, name="compile-notices", daemon=True)
            self._relay.start()

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        # a spawned worker starts here (one forked by the fork server has Ctrl-C blocked as the server has)
        spawned = self._mp_context.get_start_method() != "forkserver"
        with _environment(self._thread_env), _children_block_ctrl_c() if spawned else contextlib.nullcontext():
            return super().submit(functools.partial(_interruptible, fn), *args, **kwargs)

    def interrupt(self, futures: Iterable[Future]) -> None:
        """Ctrl-C for ``futures`` (the workers ignore a terminal's, :func:`_start_worker`): the pool is
        shut down without its pending tasks and each task running or already handed to a worker stops as a command
        does on Ctrl-C (KeyboardInterrupt: what it was writing is removed); returns once the workers have ended."""
        from concurrent.futures import wait as wait_for

        workers = list((self._processes or {}).values())     # the stdlib's own record of its processes
        self.shutdown(wait=False, cancel_futures=True)
        running = [f for f in futures if not f.done()]
        while running:      # again and again: a worker takes SIGINT only inside a task, and may be starting one
            for p in workers:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(p.pid, signal.SIGINT)
            running = list(wait_for(running, timeout=0.1).not_done)
        for p in workers:
            p.join()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        super().shutdown(wait=wait, cancel_futures=cancel_futures)
        if self._relay is not None and self._relay.is_alive():
            self._notices.put(None)         # after the workers' last notices: the relay says them, then ends
            if wait:
                self._relay.join()


def worker_pool(jobs: int, threads: int, *, preload: Iterable[str] = (),
                compile_notices: Callable[[str], None] | None = None,
                log_level: int | None = None) -> ProcessPoolExecutor:
    """``jobs`` worker processes, each with its numba, OpenCV and BLAS pools capped at ``threads``.

    Where the platform has a fork server (Linux, macOS), the workers are forked from it: the server is
    started by the first call, in the background, with the capped environment, and imports the modules
    ``preload`` once; each worker then starts in milliseconds with them loaded, and leaves without tearing
    an interpreter down.  Elsewhere, or when this process's server was started with another thread cap,
    the workers are spawned and import what they use themselves.

    Parameters
    ----------
    jobs : int
        Worker processes (started on demand, at most ``jobs``).
    threads : int
        Threads per pool in each worker.
    preload : iterable of str
        Modules the fork server imports (names; a module that fails to import is skipped by multiprocessing).
    compile_notices : callable(group), optional
        Called in this process (from a thread) with each numba kernel group a worker starts compiling
        (:func:`plenodecode._numba.relay_compile_notices`), e.g. :func:`plenodecode._numba.announce`: said once
        for the pool, not once per worker; without it each worker logs its own.
    log_level : int, optional
        The workers' logging level and the command's line format (``-q``: errors only); without it a worker, which
        starts with no logging set up, prints its warnings bare, whatever the command's level.
    """
    context = _fork_server_context(threads, tuple(preload)) or multiprocessing.get_context("spawn")
    return _CappedPool(jobs, threads, context, compile_notices, log_level)


def _start_worker(threads: int, notices: Any, log_level: int | None = None) -> None:
    """A pool worker's initializer: Ctrl-C ignored but in its tasks (:func:`_interruptible`; it started blocked,
    :func:`_children_block_ctrl_c`); :func:`limit_threads`; relay compile notices to ``notices`` (a queue); log at
    ``log_level`` in the command's format."""
    if hasattr(signal, "pthread_sigmask"):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    limit_threads(threads)
    if log_level is not None:
        from .errors import configure_logging

        configure_logging(log_level, force=True)
    if notices is not None:
        from . import _numba

        _numba.relay_compile_notices(notices.put)


__all__ = ["THREAD_ENV_VARS", "thread_counts", "limit_threads", "worker_pool"]
