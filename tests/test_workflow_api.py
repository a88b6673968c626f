"""The workflow layer at top level (``pd.open_source`` ... ``pd.run_batch``): a Python user reaches what the CLI
does without importing submodules, and gets the CLI's pixels."""

import numpy as np
from click.testing import CliRunner

import plenodecode as pd
from plenodecode.cli.main import cli
from plenodecode.io.images import read_image
from tests.conftest import ROOT, shared_path

SCENE = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"


def test_workflow_entry_points_are_top_level_names():
    from plenodecode import batch, pipeline

    for name in ("open_source", "render_product", "write_product", "write_parallax", "write_depth", "PRODUCTS"):
        assert getattr(pd, name) is getattr(pipeline, name), name
    assert pd.run_batch is batch.run_batch and pd.BatchOptions is batch.BatchOptions
    assert {"open_source", "render_product", "write_product", "run_batch", "BatchOptions"} <= set(dir(pd))


def test_python_refocus_of_a_sample_raw_is_the_cli_file_pixel_for_pixel(tmp_path, monkeypatch):
    """``plenodecode refocus scene.lfr --slope 0.5 -o cli.png`` and open_source/render_product/write_product
    write the same 16-bit pixels."""
    monkeypatch.chdir(ROOT)         # the CLI's default database is ./calib
    cli_png, py_png = tmp_path / "cli.png", tmp_path / "py.png"
    res = CliRunner().invoke(cli, ["refocus", str(SCENE), "--slope", "0.5", "-o", str(cli_png)])
    assert res.exit_code == 0, res.output
    src = pd.open_source(SCENE, database="calib")
    pd.write_product(pd.render_product(src, "refocus", slope=0.5), py_png)
    cli_img, py_img = read_image(cli_png), read_image(py_png)
    assert cli_img.shape == py_img.shape == src.lightfield.shape[2:4] + (3,)
    assert float(cli_img.std()) > 0.01       # a picture, not a blank frame
    np.testing.assert_array_equal(py_img, cli_img)


def test_python_centre_view_of_a_real_f01_raw_is_the_cli_file(tmp_path):
    """The same on a real capture (Lytro F01 lenslet JPEG, self-calibrated from the scene as the CLI does)."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    cli_png, py_png = tmp_path / "cli.png", tmp_path / "py.png"
    res = CliRunner().invoke(cli, ["views", str(jpeg), "--view", "4", "4", "-o", str(cli_png)])
    assert res.exit_code == 0, res.output
    pd.write_product(pd.render_product(pd.open_source(jpeg), "views", view=(4.0, 4.0)), py_png)
    cli_img, py_img = read_image(cli_png), read_image(py_png)
    assert cli_img.shape == (383, 382, 3) and float(cli_img.std()) > 0.005
    np.testing.assert_array_equal(py_img, cli_img)


def test_run_batch_takes_one_folder_as_a_string(tmp_path, monkeypatch):
    """``pd.run_batch("shoot", ...)``: the old code searched each character of the string as a path ('/' the whole
    disk; here, in a folder without 's', 'h', 'o', 't', nothing at all)."""
    import shutil

    monkeypatch.chdir(tmp_path)
    (tmp_path / "shoot").mkdir()
    shutil.copy(SCENE, tmp_path / "shoot" / "scene.lfr")
    summary = pd.run_batch("shoot", "out", pd.BatchOptions(database=str(ROOT / "calib")), jobs=1)
    assert [r.status for r in summary.results] == ["done"]
    assert summary.results[0].source == str(tmp_path / "shoot" / "scene.lfr")
    assert (tmp_path / "out" / "scene").is_dir()


def test_run_batch_refuses_bad_arguments_before_any_work(tmp_path):
    """An options dict (AttributeError 'dict' object has no attribute 'database' before) and an output under a
    file (a bare '[Errno 20] Not a directory') are refused in words naming the keyword, with nothing created."""
    import pytest

    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me")
    with pytest.raises(TypeError, match="options must be a BatchOptions"):
        pd.run_batch([SCENE], tmp_path / "out", {"outputs": ("photo",)}, jobs=1)
    with pytest.raises(NotADirectoryError, match="notes.txt is a file, not a folder"):
        pd.run_batch([SCENE], blocker / "out", jobs=1)
    with pytest.raises(ValueError, match="scheduler"):
        pd.run_batch([SCENE], tmp_path / "out", scheduler="bogus")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
