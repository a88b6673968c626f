"""The thread pools of a process: numba, OpenCV and BLAS / OpenMP, and worker processes that share the cores.

Decoding and rendering run in threads (the decoder's bands, numba's parallel kernels, OpenCV's own
pool, BLAS).  One process may use every core; ``jobs`` worker processes must each use
``cores // jobs`` threads, or together they ask for ``jobs`` times the cores and lose time to
switching and cache thrashing.  :func:`worker_pool` starts such workers (``plenodecode batch --jobs``);
:func:`limit_threads` caps the pools of the process it runs in (a batch task on a Dask worker).
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

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


class _CappedPool(ProcessPoolExecutor):
    """A spawn-context process pool whose workers start with :data:`THREAD_ENV_VARS` = ``threads``.

    The workers import numpy (and so BLAS) before any initializer runs, so the sizes must be in the
    environment they are started with: the variables are set in this process only while a worker is
    being started (workers start on demand, from :meth:`submit`), then restored.
    """

    def __init__(self, jobs: int, threads: int) -> None:
        super().__init__(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                         initializer=limit_threads, initargs=(threads,))
        self._thread_env = {var: str(threads) for var in (*THREAD_ENV_VARS, "NUMBA_NUM_THREADS")}

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        saved = {var: os.environ.get(var) for var in self._thread_env}
        os.environ.update(self._thread_env)
        try:
            return super().submit(fn, *args, **kwargs)
        finally:
            for var, value in saved.items():
                if value is None:
                    os.environ.pop(var, None)
                else:
                    os.environ[var] = value


def worker_pool(jobs: int, threads: int) -> ProcessPoolExecutor:
    """``jobs`` spawned worker processes, each with its numba, OpenCV and BLAS pools capped at ``threads``."""
    return _CappedPool(jobs, threads)


__all__ = ["THREAD_ENV_VARS", "thread_counts", "limit_threads", "worker_pool"]
