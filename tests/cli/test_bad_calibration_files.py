"""A --calibration, --white or --dark file that is not what it says is a usage error naming the option, before any
raw is read: in a batch not one identical failure per raw (and a summary of failures) but nothing written."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from tests.conftest import ROOT

RAW = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"


@pytest.fixture
def bad_files(tmp_path):
    text = tmp_path / "notes.lfr"               # a text file with a raw's name
    text.write_text("hello\n")
    truncated = tmp_path / "cut.lfr"            # the first 1 MB of a real container
    truncated.write_bytes(RAW.read_bytes()[:1_000_000])
    grid = tmp_path / "grid.json"                # a mosaic sidecar, not a lenslet grid
    grid.write_text((ROOT / "sample_raws" / "square" / "scene.json").read_text())
    return {"text": text, "truncated": truncated, "grid": grid}


#: (command, option, which bad file, words of the message); decode reads --white and --dark with the raw (one
#: line, exit 1 already), a grid file is read at parsing everywhere
CASES = [("batch", "-g", "text", "not valid JSON"), ("decode", "-g", "text", "not valid JSON"),
         ("batch", "-g", "grid", "not a plenodecode lenslet grid"),
         ("decode", "-g", "grid", "not a plenodecode lenslet grid"),
         ("batch", "-w", "text", "not a Lytro container"), ("batch", "--dark", "truncated", "truncated")]


@pytest.mark.parametrize("command, option, which, words", CASES)
def test_bad_calibration_file_is_a_usage_error_naming_the_option(tmp_path, monkeypatch, bad_files, command, option,
                                                                 which, words):
    import plenodecode.batch

    def no_batch(*args, **kwargs):
        raise AssertionError("the batch started")

    monkeypatch.setattr(plenodecode.batch, "run_batch", no_batch)
    out = tmp_path / ("out" if command == "batch" else "lf.zarr")
    res = CliRunner().invoke(cli, [command, str(RAW), "-o", str(out), option, str(bad_files[which]),
                                   "--database", str(ROOT / "calib")])
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1, res.output
    long_name = {"-g": "--calibration", "-w": "--white", "--dark": "--dark"}[option]
    assert long_name in errors[0] and bad_files[which].name in errors[0] and words in errors[0], errors[0]
    assert "Traceback" not in res.output
    assert not out.exists()
