"""Ctrl-C while a Zarr light field is written: the run ends with click's 'Aborted!' and leaves nothing, not the
temporary store (zarr's I/O thread kept writing into it after it was removed) nor asyncio tracebacks at exit."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from plenodecode.io.lightfield import save_lightfield
from plenodecode.types import LightField
from tests.conftest import ROOT

#: Every script below gives SIGINT back its KeyboardInterrupt first: a suite started as a background job (``make test
#: &``) runs with SIGINT ignored, which its processes inherit, and Python then installs no handler of its own.
#: Runs the CLI with zarr's file writer slowed down, the third file write sending SIGINT to the process first:
#: the interrupt lands while the main thread waits for that write on zarr's I/O thread.
SCRIPT = textwrap.dedent("""
    import os, signal, sys, time
    signal.signal(signal.SIGINT, signal.default_int_handler)   # as in a terminal, though run from a background job
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


#: Runs the CLI with the function MODULE.NAME sending SIGINT to the process on its CALL-th call, before it runs.
WRITER_SCRIPT = textwrap.dedent("""
    import importlib, os, signal, sys
    signal.signal(signal.SIGINT, signal.default_int_handler)   # as in a terminal, though run from a background job

    module, name, call = importlib.import_module(os.environ["MODULE"]), os.environ["NAME"], int(os.environ["CALL"])
    real, calls = getattr(module, name), []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == call:
            os.kill(os.getpid(), signal.SIGINT)
        return real(*args, **kwargs)

    setattr(module, name, interrupted)
    from plenodecode.cli.main import cli
    cli(sys.argv[1:], prog_name="plenodecode")
""")


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("command, output, module, name, call", [
    ("views", "views", "plenodecode.io.images", "write_image", 5),        # the fifth view's PNG
    ("export", "lf.mat", "zlib", "compress", 1)])                         # inside scipy.io.savemat
def test_ctrl_c_while_views_or_a_mat_file_are_written_leaves_nothing(tmp_path, command, output, module, name, call):
    """Probed as the Zarr write was: Ctrl-C while 'views' writes its PNG folder or 'export --format mat' its file
    ends with 'Aborted!' and leaves no part of the output (both write under a temporary name)."""
    src = tmp_path / "in" / "lf.npy"
    save_lightfield(LightField(np.random.default_rng(0).random((3, 3, 16, 20, 3), dtype=np.float32)), src)
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.run([sys.executable, "-c", WRITER_SCRIPT, command, str(src), "-o", str(out / output)]
                          + (["--format", "mat"] if command == "export" else []),
                          capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "MODULE": module, "NAME": name,
                               "CALL": str(call)})
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "Aborted!" and "Traceback" not in proc.stderr, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == []


#: Runs the CLI with its batch progress callback sending SIGINT to the whole process group (a terminal's Ctrl-C:
#: the command, its fork server and its workers alike) once STOP_AT raws are finished (0: as the work starts,
#: while the fork server still imports its modules).
BATCH_SCRIPT = textwrap.dedent("""
    import os, signal, sys
    signal.signal(signal.SIGINT, signal.default_int_handler)   # as in a terminal, though run from a background job
    import plenodecode.cli.batch as batch_cli

    real, stop_at = batch_cli.progress_bar, int(os.environ["STOP_AT"])

    def progress_bar(label, ctx=None):
        bar = real(label, ctx)

        def callback(done, total):
            bar(done, total)
            if done == stop_at:
                os.killpg(os.getpgid(0), signal.SIGINT)
        return callback

    batch_cli.progress_bar = progress_bar
    from plenodecode.cli.main import cli
    cli(sys.argv[1:], prog_name="plenodecode")
""")


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("jobs, stop_at", [(2, 0), (2, 1), (1, 1)])
def test_ctrl_c_during_a_batch_leaves_finished_raws_only_and_no_traceback(tmp_path, jobs, stop_at):
    """Ctrl-C in a terminal reaches the batch's workers and fork server too: one landing while the fork server
    imported its modules printed its traceback after 'Aborted!', one reaching a worker waiting for a task printed
    'Process ForkServerProcess-1: Traceback ... KeyboardInterrupt', and a run stopped before any raw was finished
    left its empty output folder.  Now the workers ignore it and the command stops them: stderr ends with
    'Aborted!' and holds no traceback, the raws finished stay whole (a new run resumes them) and nothing else is
    left, not even the output folder when none was finished."""
    shoot = tmp_path / "shoot"
    for i in range(3):
        (shoot / f"t{i}").mkdir(parents=True)
        shutil.copy(ROOT / "sample_raws" / "f01-mini" / "scene.lfp", shoot / f"t{i}" / f"scene{i}.lfp")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-c", BATCH_SCRIPT, "batch", str(shoot), "-o", str(out), "--database",
                           str(ROOT / "calib"), "--outputs", "photo,views", "--jobs", str(jobs)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path, start_new_session=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "STOP_AT": str(stop_at)})
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "Aborted!", proc.stderr
    assert "Traceback" not in proc.stderr and "Error" not in proc.stderr and "Process " not in proc.stderr, proc.stderr
    if stop_at == 0:
        assert not out.exists(), sorted(p.name for p in out.iterdir())
        return
    left = sorted(p.name for p in out.iterdir())
    assert 1 <= len(left) < 3 and all(name.startswith("scene") for name in left), left     # no hidden staging
    for name in left:                                        # each whole: what a finished raw holds
        assert (out / name / ".done.json").is_file() and len(list((out / name / "views").glob("*.png"))) == 81, name
