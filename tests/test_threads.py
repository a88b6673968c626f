"""plenodecode.threads: what a computation in this thread may start; worker processes forked with their
modules loaded."""

import multiprocessing
import textwrap

import numba
import pytest

from plenodecode.threads import task_threads
from tests.test_batch_workers import _run_script


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


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(), reason="no fork server here")
def test_pool_workers_are_forked_with_the_modules_loaded(tmp_path):
    """Workers come from the fork server (not this process, not spawned) and find the preloaded modules
    imported before their first task; their numba cap holds and this process imported none of it."""
    (tmp_path / "forked_probe.py").write_text(textwrap.dedent("""
        import os, sys, time

        def probe(_):
            from plenodecode.threads import thread_counts

            loaded = "plenodecode.decoding.decoder" in sys.modules and "cv2" in sys.modules
            time.sleep(0.3)                       # long enough that both workers take a probe
            return os.getpid(), os.getppid(), loaded, thread_counts()["numba"]
    """))
    got = _run_script("""
        import json, os, sys
        from forked_probe import probe
        from plenodecode.threads import worker_pool

        if __name__ == "__main__":
            with worker_pool(2, 1, preload=["cv2", "plenodecode.decoding.decoder"]) as pool:
                rows = list(pool.map(probe, range(4)))
            print(json.dumps({"me": os.getpid(), "rows": rows, "here": "plenodecode.decoding.decoder" in sys.modules}))
    """, path=tmp_path)
    rows = got["rows"]
    assert len({r[0] for r in rows}) == 2
    assert all(r[1] != got["me"] for r in rows)              # children of the fork server
    assert all(r[2] for r in rows) and all(r[3] == 1 for r in rows)
    assert not got["here"]
