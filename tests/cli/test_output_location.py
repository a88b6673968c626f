"""An output that cannot be created (a file where its folder should be, a folder that cannot be written) is refused
before any work, in one line naming the option, with nothing written; a write that fails mid-run anyway (a
read-only or full disk) ends in one line, not a traceback."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from plenodecode import pipeline
from plenodecode.cli.main import cli
from tests.conftest import ROOT, shared_path

RAW = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"
WHITE = ROOT / "sample_raws" / "illum-mini" / "MOD_0000.RAW"

#: (command line with OUT for the output path; the option that names it)
COMMANDS = [
    ([RAW, "-o", "OUT.png"], "-o / --output"),
    (["refocus", RAW, "-o", "OUT.png"], "-o / --output"),
    (["decode", RAW, "-o", "OUT.zarr"], "-o / --output"),
    (["decode", RAW, "-o", "OUT.npy"], "-o / --output"),
    (["depth", RAW, "-o", "OUT.pfm"], "-o / --output"),
    (["views", RAW, "-o", "OUT"], "-o / --output"),
    (["parallax", RAW, "-o", "OUT.gif"], "-o / --output"),
    (["batch", RAW, "-o", "OUT"], "-o / --output"),
    (["synth", "square", "-o", "OUT"], "-o / --output"),
    (["calibrate", WHITE, "-o", "OUT.json"], "-o / --output"),
    (["calibrate", WHITE, "-o", "grid.json", "--report", "OUT.html"], "--report"),
]


def no_work(*args, **kwargs):
    raise AssertionError("an input was opened before the output was checked")


def one_error(res) -> str:
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1, res.output
    assert "Traceback" not in res.output
    return errors[0]


@pytest.mark.parametrize("args, option", COMMANDS, ids=[" ".join(str(a) for a in c[0][:2]) for c in COMMANDS])
def test_output_under_a_file_is_refused_before_any_work(tmp_path, monkeypatch, args, option):
    """'-o notes.txt/photo.png': the old code decoded first, then said '[Errno 17] File exists: notes.txt; pass
    --overwrite' (which cannot help); an unwritable folder gave a traceback."""
    monkeypatch.setattr(pipeline, "open_input", no_work)
    monkeypatch.setattr(pipeline.source, "open_input", no_work)
    monkeypatch.setattr("plenodecode.io.read_raw", no_work)
    monkeypatch.chdir(tmp_path)
    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me")
    out = blocker / "sub" / "out"
    argv = [str(out) + str(a)[3:] if str(a).startswith("OUT") else str(a) for a in args] + ["--overwrite"]
    res = CliRunner().invoke(cli, argv)
    assert res.exit_code == 2, (res.output, res.exception)
    line = one_error(res)
    assert option in line and "notes.txt is a file, not a folder" in line
    assert "--overwrite" not in line                    # overwriting cannot make a file a folder
    assert blocker.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]      # nothing written


def test_extract_into_a_file_does_not_ask_for_the_overwrite_it_was_given(tmp_path):
    """'extract X -o notes.txt --overwrite' said 'notes.txt exists and is not a folder; pass --overwrite'."""
    lfp = shared_path("lytro-containers", "IMG_0002-dm.lfp")
    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me")
    res = CliRunner().invoke(cli, ["extract", str(lfp), "-o", str(blocker), "--overwrite"])
    assert res.exit_code == 2, res.output
    line = one_error(res)
    assert "notes.txt is a file" in line and "pass --overwrite" not in line
    assert blocker.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_export_under_a_file_is_refused(tmp_path):
    lf = shared_path("hci-antinous")
    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me")
    res = CliRunner().invoke(cli, ["export", str(lf), "-o", str(blocker / "lf.mat")])
    assert res.exit_code == 2, res.output
    assert "-o / --output" in one_error(res)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_refused_before_any_work(tmp_path, monkeypatch):
    monkeypatch.setattr(pipeline, "open_input", no_work)
    monkeypatch.setattr(pipeline.source, "open_input", no_work)
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        res = CliRunner().invoke(cli, [str(RAW), "-o", str(locked / "photo.png")])
    finally:
        locked.chmod(0o755)
    assert res.exit_code == 2, res.output
    assert "no permission to write in" in one_error(res)
    assert not list(locked.iterdir())


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc (a folder nobody can write in)")
def test_a_write_that_fails_mid_run_is_one_line_without_traceback(tmp_path):
    """/proc refuses new files even to root (where the check before the work cannot tell): the old code decoded,
    then printed a 50-line FileNotFoundError traceback naming a temporary file '/proc/.photo.png.<pid>-...tmp.png'."""
    res = CliRunner().invoke(cli, [str(RAW), "-o", "/proc/photo.png", "-w", str(WHITE)])
    assert res.exit_code in (1, 2), res.output      # 2: refused up front (not root); 1: refused on writing (root)
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    errors = [line for line in res.output.splitlines() if line.lower().startswith("error")]
    assert len(errors) == 1 and "/proc/photo.png" in errors[0] and ".tmp" not in errors[0], res.output
    assert "Traceback" not in res.output
