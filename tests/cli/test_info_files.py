"""``plenodecode info`` on the other files a user finds beside raws: grids, sidecars, ground truth, the database's
index, geometric calibrations and Raytrix XML.  Each used to be refused as 'JSON, but not Lytro frame metadata'
(or, for the XML, 'not a raw LibRaw can read')."""

from __future__ import annotations

import math
from pathlib import Path

from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.types import LensletGrid
from tests.conftest import shared_path

ROOT = Path(__file__).resolve().parents[2]


def info(path):
    res = CliRunner().invoke(cli, ["info", str(path)])
    assert res.exit_code == 0, res.output
    return res.output


def test_info_describes_a_grid_a_sidecar_a_truth_and_the_index():
    grid_file = ROOT / "calib" / "B5143909630" / "MOD_0000.grid.json"
    grid = LensletGrid.from_json(grid_file.read_text())
    out = info(grid_file)
    assert "lenslet grid (from MOD_0000.RAW)" in out
    assert f"pitch {grid.pitch:.4f} px" in out and f"{grid.shape[0]} x {grid.shape[1]} lenses" in out
    assert f"sensor   {grid.sensor_shape[1]} x {grid.sensor_shape[0]}; 15 x 15 views" in out
    out = info(ROOT / "sample_raws" / "square" / "scene.json")
    assert "JSON sidecar of scene.png" in out and "raw      1100 x 1100, monochrome, black 100, white 4095" in out
    out = info(ROOT / "sample_raws" / "illum-mini" / "scene.truth.json")
    assert "ground truth of a raw 'plenodecode synth' generated" in out and "illum-mini" in out
    assert "sensor 1544 x 1072" in out
    out = info(ROOT / "calib" / "index.json")
    assert "3 white image(s) of camera(s) A000424242, B5143909630, LFM-0001; 3 grid(s) cached" in out


def test_info_describes_the_real_calinfo_and_raytrix_xml():
    from plenodecode.io.calinfo import load_geometric_calibration

    path = shared_path("lytro-f01-gridmodel", "CalInfo.json")
    cal = load_geometric_calibration(path)
    out = info(path)
    assert "geometric calibration (the Light Field Toolbox's CalInfo.json)" in out
    assert "light fields of 11 x 11 views of 379 x 379" in out and cal.lf_shape == (11, 11, 379, 379)
    assert f"[k1 k2 k3 b1 b2] = [{cal.distortion[0]:.4g}, {cal.distortion[1]:.4g}" in out
    out = info(shared_path("raytrix-r42", "sc2_klein.xml"))
    assert "Raytrix RayCalibData" in out and "its image is sc2_klein.png" in out
    assert "diameter 34.865 px" in out and "3 lens type(s)" in out


def test_other_json_is_still_refused_in_one_line(tmp_path):
    (tmp_path / "x.json").write_text('{"a": 1}')
    res = CliRunner().invoke(cli, ["info", str(tmp_path / "x.json")])
    assert res.exit_code == 1 and "JSON, but not Lytro frame metadata" in res.output


def test_info_on_a_grid_calibrate_just_wrote(tmp_path):
    name = "grid.json"
    res = CliRunner().invoke(cli, ["calibrate", str(ROOT / "sample_raws" / "f01-mini" / "MOD_0000.RAW"),
                                   "-o", str(tmp_path / name)])
    assert res.exit_code == 0, res.output
    grid = LensletGrid.from_json((tmp_path / name).read_text())
    assert "lenslet grid (fitted to white image(s): MOD_0000.RAW)" in info(tmp_path / name)
    deg = math.degrees(grid.rotation)
    assert f"pitch {grid.pitch:.4f} px, rotation {grid.rotation:.5f} rad ({deg:.3f} deg)" in info(tmp_path / name)


def test_info_of_a_decoded_light_field_names_its_colour_as_decode_did(tmp_path):
    """'decode' said 'monochrome' for the square microscope sample and 'info' on what it wrote said 'colour camera';
    both say 'monochrome' (and 'linear sRGB' for a colour light field)."""
    res = CliRunner().invoke(cli, ["decode", str(ROOT / "sample_raws" / "square" / "scene.png"), "--database",
                                   str(ROOT / "calib"), "-o", str(tmp_path / "lf.zarr")])
    assert res.exit_code == 0 and "monochrome" in res.output, res.output
    assert "(V, U, Y, X, C), monochrome" in info(tmp_path / "lf.zarr")
    res = CliRunner().invoke(cli, ["decode", str(ROOT / "sample_raws" / "f01-mini" / "scene.lfp"), "--database",
                                   str(ROOT / "calib"), "-o", str(tmp_path / "c.zarr")])
    assert res.exit_code == 0 and "linear sRGB" in res.output, res.output
    assert "(V, U, Y, X, C), linear sRGB" in info(tmp_path / "c.zarr")


def test_info_lists_a_calibration_database_and_goes_on_past_a_bad_file(tmp_path):
    """Listing the database's white images had no command ('calibrate --database' printed a count); 'info calib'
    said 'no input_Cam*.png views; expected a folder of views'.  It now lists each white image (camera, zoom,
    focus, size, grid cached, file); and 'info A B C' stopped at the first file it could not describe, while it
    now describes the others and exits 1."""
    out = info(ROOT / "calib")
    rows = [line.split() for line in out.splitlines() if line.startswith("    B5143909630")]
    assert len(rows) == 1 and rows[0][:7] == ["B5143909630", "-312", "417", "1544", "x", "1072", "cached"], out
    assert rows[0][-1].endswith("sample_raws/illum-mini/MOD_0000.RAW") and Path(rows[0][-1]).is_file(), out
    res = CliRunner().invoke(cli, ["calibrate", "--database", str(tmp_path / "db"),
                                   str(ROOT / "sample_raws" / "f01-mini")])
    assert res.exit_code == 0 and f"'plenodecode info {tmp_path / 'db'}' lists them" in res.output, res.output
    assert "A000424242" in info(tmp_path / "db") and "1 grid(s) cached" in info(tmp_path / "db")
    folder = ROOT / "sample_raws" / "illum-mini"
    res = CliRunner().invoke(cli, ["info", str(ROOT / "sample_raws"), *(str(p) for p in sorted(folder.iterdir()))])
    assert res.exit_code == 1, res.output
    assert "sample_raws: a folder holding no light field" in res.output
    for name in ("MOD_0000.RAW", "scene.lfr", "scene.truth.json", "scene.truth.npz"):
        assert f"{folder / name}: " in res.output, name
    assert "the arrays of scene.truth.json" in res.output


def test_info_describes_the_f01_lens_centre_table_not_as_a_broken_light_field():
    """'info image_cords.mat' (the lens centres that come with the F01 JPEGs) said "no 5-D 'LF' variable (j, i, l, k,
    c); expected an LFToolbox decoded light field" and exited 1.  It is a (362, 311, 2) table of (row, col) centres:
    info now gives the lattice it measures, which matches a least-squares line through each lens row of the table
    (pitch 9.932 px, rotation -0.0049 rad, the self-calibration of IMG_1.jpg gives 9.933 px and -0.00487 rad)."""
    import re

    import numpy as np
    import scipy.io as sio

    path = shared_path("lytro-f01-lenslet-jpg", "image_cords.mat")
    out = info(path)
    assert "lenslet centres (a MATLAB table, not a light field)" in out and "LFToolbox" not in out
    assert "image_cords: 362 x 311 lenses (rows x cols), (row, col) px" in out
    m = re.search(r"lattice  hex, pitch (\d+\.\d+) px along the rows, rows (\d+\.\d+) px apart .* rotation "
                  r"(-?\d\.\d+) rad", out)
    assert m, out
    pitch, spacing, rotation = map(float, m.groups())
    a = sio.loadmat(str(path))["image_cords"].astype(np.float64)
    k = np.arange(a.shape[1])
    fits = np.array([np.polyfit(k, a[r, :, 1], 1)[0] for r in range(a.shape[0])])           # col per lens
    slopes = np.array([np.polyfit(a[r, :, 1], a[r, :, 0], 1)[0] for r in range(a.shape[0])])  # row per col
    assert abs(pitch - np.median(fits)) < 0.01, (pitch, np.median(fits))
    assert abs(rotation - np.arctan(np.median(slopes))) < 3e-4, (rotation, np.arctan(np.median(slopes)))
    assert abs(spacing / pitch - math.sqrt(3) / 2) < 0.005
