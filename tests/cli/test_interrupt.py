"""Ctrl-C while a Zarr light field is written: the run ends with click's 'Aborted!' and leaves nothing, not the
temporary store (zarr's I/O thread kept writing into it after it was removed) nor asyncio tracebacks at exit."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from plenodecode.io.lightfield import save_lightfield
from plenodecode.types import LightField
from tests.conftest import ROOT

#: Runs the CLI with zarr's file writer slowed down, the third file write sending SIGINT to the process first:
#: the interrupt lands while the main thread waits for that write on zarr's I/O thread.
SCRIPT = textwrap.dedent("""
    import os, signal, sys, time
    import zarr.storage._local as local

    real, calls = local._put, []

    def slow_put(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)
        return real(*args, **kwargs)

    local._put = slow_put
    from plenodecode.cli.main import cli
    cli(sys.argv[1:], prog_name="plenodecode")
""")


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_ctrl_c_during_a_zarr_write_leaves_nothing_and_no_traceback(tmp_path):
    src = tmp_path / "in" / "lf.npy"
    rng = np.random.default_rng(0)
    save_lightfield(LightField(rng.random((3, 3, 16, 20, 3), dtype=np.float32)), src)
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.run([sys.executable, "-c", SCRIPT, "export", str(src), "-o", str(out / "lf.zarr")],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode != 0, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "Aborted!", proc.stderr
    assert "Traceback" not in proc.stderr and "Task was destroyed" not in proc.stderr, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == []          # neither lf.zarr nor its temporary store
