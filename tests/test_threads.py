"""plenodecode.threads: what a computation in this thread may start."""

import numba

from plenodecode.threads import task_threads


def test_task_threads_follows_the_numba_cap_of_the_calling_thread():
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        assert task_threads() == 1 and task_threads(4) == 1
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        assert task_threads() == numba.config.NUMBA_NUM_THREADS
        assert task_threads(1) == 1
    finally:
        numba.set_num_threads(before)
