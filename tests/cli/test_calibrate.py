"""``plenodecode calibrate`` through click's CliRunner, and the HTML calibration report."""

from __future__ import annotations

import json
from pathlib import Path
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.lytro import write_raw_pair
from plenodecode.report.calibration import vignetting_profile, write_calibration_report
from plenodecode.synthetic import simulate, simulate_white
from plenodecode.types import LensletGrid

SHAPE = (260, 320)


@pytest.fixture(scope="module")
def white_pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("whites")
    raw, truth = simulate_white("f01-mini", seed=4, shape=SHAPE, rotation=0.003, offset=(0.4, -0.2))
    p, _ = write_raw_pair(d / "MOD_0000.RAW", raw)
    return p, truth


def run(*args):
    return CliRunner().invoke(cli, list(map(str, args)), obj={}, catch_exceptions=False)


def test_calibrate_writes_grid_and_report(white_pair, tmp_path):
    path, truth = white_pair
    out, rep = tmp_path / "grid.json", tmp_path / "report.html"
    r = run("calibrate", path, "-o", out, "--report", rep)
    assert r.exit_code == 0, r.output
    grid = LensletGrid.from_json(out.read_text())
    from scipy.spatial import cKDTree
    t = truth.centres()
    R = truth.radius
    full = (t[:, 0] - R >= 0) & (t[:, 0] + R <= SHAPE[0] - 1) & (t[:, 1] - R >= 0) & (t[:, 1] + R <= SHAPE[1] - 1)
    d, _ = cKDTree(grid.centres()).query(t[full])
    assert np.sqrt(np.mean(d ** 2)) < 0.05
    html = rep.read_text()
    assert html.count("data:image/png;base64,") == 3          # overlays, residuals, vignetting
    assert "Fitted parameters" in html and "pitch (along rows)" in html and f"{grid.pitch:.5f}" in html
    assert "http://" not in html and "https://" not in html   # self-contained
    # no overwrite without --overwrite (usage error, exit 2); with it, fine
    r = run("calibrate", path, "-o", out)
    assert r.exit_code == 2 and "--overwrite" in r.output
    assert run("calibrate", path, "-o", out, "--overwrite", "--lattice", "hex").exit_code == 0


def test_bad_inputs_exit_1_with_one_line(white_pair, tmp_path):
    path, _ = white_pair
    dark = replace(simulate_white("f01-mini", shape=SHAPE)[0], mosaic=np.full(SHAPE, 168, np.uint16))
    write_raw_pair(tmp_path / "MOD_0009.RAW", dark)
    r = CliRunner().invoke(cli, ["calibrate", str(tmp_path / "MOD_0009.RAW"), "-o", str(tmp_path / "g.json")],
                           obj={})
    assert r.exit_code == 1
    err = r.output.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "dark" in err[0]
    assert not (tmp_path / "g.json").exists()
    # a scene raw where a white is expected: calibrates but warns
    sim = simulate("f01-mini", seed=1, shape=(300, 300))
    write_raw_pair(tmp_path / "scene.RAW", replace(sim.raw, metadata=replace(sim.raw.metadata, is_white_image=False)))
    r = CliRunner().invoke(cli, ["calibrate", str(tmp_path / "scene.RAW"), "-o", str(tmp_path / "s.json")], obj={})
    assert r.exit_code == 0 and LensletGrid.from_json((tmp_path / "s.json").read_text()).info["warnings"][0].startswith(
        "this looks like a scene")       # logged once (test_each_warning_once_with_a_report)
    r = run("calibrate", path)
    assert r.exit_code == 2 and "-o" in r.output


def test_database_build_and_wrong_camera(white_pair, tmp_path):
    path, _ = white_pair
    db = tmp_path / "calib"
    r = run("calibrate", "--database", db, path.parent)
    assert r.exit_code == 0, r.output
    assert json.loads((db / "index.json").read_text())["entries"][0]["grid"]
    # the matching camera: the grid comes from the database
    raw, _ = simulate_white("f01-mini", seed=9, shape=SHAPE)
    write_raw_pair(tmp_path / "pic" / "frame.RAW", replace(raw, metadata=replace(raw.metadata, is_white_image=False)))
    r = run("calibrate", "--database", db, "--for", tmp_path / "pic" / "frame.RAW", "-o", tmp_path / "g.json")
    assert r.exit_code == 0, r.output
    # another camera: exit 1, the message names the serial the database holds
    other = replace(raw, metadata=replace(raw.metadata, serial="A999", is_white_image=False))
    write_raw_pair(tmp_path / "pic2" / "frame.RAW", other)
    r = CliRunner().invoke(cli, ["calibrate", "--database", str(db), "--for", str(tmp_path / "pic2" / "frame.RAW"),
                                 "-o", str(tmp_path / "h.json")], obj={})
    assert r.exit_code == 1 and raw.metadata.serial in r.output and "A999" in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_report_function_atomic_and_warnings(white_pair, tmp_path):
    path, truth = white_pair
    from plenodecode.io import read_raw
    raw = read_raw(path)
    off = truth.replace(origin=(truth.origin[0] + 2.0, truth.origin[1]))      # a wrong grid is flagged
    rep = write_calibration_report(off, raw, tmp_path / "r.html")
    html = rep.read_text()
    assert "more than 0.5 px from the grid" in html or "RMS residual" in html
    with pytest.raises(FileExistsError):
        write_calibration_report(off, raw, tmp_path / "r.html")
    write_calibration_report(truth, raw, tmp_path / "r.html", overwrite=True)
    assert "no problems found" in (tmp_path / "r.html").read_text()
    assert not list(tmp_path.glob(".*.tmp"))


def test_vignetting_profile_of_a_radial_falloff():
    yy, xx = np.mgrid[0:201, 0:301]
    r = np.hypot(yy - 100, xx - 150)
    img = (1.0 - 0.002 * r).astype(np.float32)
    radius, mean = vignetting_profile(img, bins=20)
    ok = np.isfinite(mean)
    np.testing.assert_allclose(mean[ok], 1.0 - 0.002 * radius[ok], atol=0.01)


def test_real_antleg_radiometry_frame_is_judged_about_its_relay_lens_distortion(tmp_path):
    """The ant leg's lens array is imaged through a relay lens: its centres depart from a regular lattice by a
    smooth field of ~1.7 px (RMS 0.57 px), which the decoder follows lens by lens; the report said 'bad'.
    About that field the centres scatter by 0.07 px: 'good', and the summary line says why."""
    import re

    from tests.conftest import shared_path

    res = CliRunner().invoke(cli, ["calibrate", str(shared_path("lf-microscopy-antleg", "radiometry_frame.png")),
                                   "-o", str(tmp_path / "grid.json"), "--report", str(tmp_path / "grid.html")])
    assert res.exit_code == 0, res.output
    line = re.search(r"RMS (\d\.\d+) px \((\d\.\d+) px about a smooth distortion of up to (\d\.\d+) px\)", res.output)
    assert line, res.output
    rms, rest, field = map(float, line.groups())
    assert rms > 0.4 and rest < 0.1 and field > 1.0
    assert "verdict: good" in (tmp_path / "grid.html").read_text()


def test_real_antleg_corner_lenses_follow_the_distortion(tmp_path):
    """The relay lens's distortion grows past the lattice fit's 4-sigma cut in the ant leg's bottom-left corner
    (1.5-2.5 px): 60 of its 108 lenses were left out of the per-lens refinement and decoded at their lattice
    position, 0.81 px (up to 2.5 px) from their disks; the report's residual map showed a yellow corner under
    'verdict: good' and its histogram an RMS line (the lattice's 0.57 px) past every bar.  The lenses the smooth
    deviations explain now join the refinement: the corner's centres are within 0.15 px of the disks on average."""
    import re

    from plenodecode.io import read_raw
    from plenodecode.report.calibration import _white_measure
    from tests.conftest import shared_path

    white = shared_path("lf-microscopy-antleg", "radiometry_frame.png")
    res = CliRunner().invoke(cli, ["calibrate", str(white), "-o", str(tmp_path / "grid.json"),
                                   "--report", str(tmp_path / "grid.html")])
    assert res.exit_code == 0, res.output
    grid = LensletGrid.from_json((tmp_path / "grid.json").read_text())
    m = _white_measure(grid, [read_raw(white)])
    a = m["assigned"]
    centres, off = m["centres"][a], np.hypot(*m["residuals"][a].T)
    corner = (centres[:, 0] > 1800) & (centres[:, 1] < 300)
    assert corner.sum() > 100 and off[corner].mean() < 0.15 and off[corner].max() < 0.5, (off[corner].mean(),
                                                                                          off[corner].max())
    assert np.mean(off > 0.5) < 0.004                                 # 0.2 % of the lenses (was 0.8 %)
    html = (tmp_path / "grid.html").read_text()
    assert re.search(r"lenses more than 0.5 px off</td><td>0\.[0-3]%", html), "0.5 px row"


def test_database_for_a_raw_without_serial_takes_only_a_white_of_its_sensor_size(white_pair, tmp_path):
    """'calibrate --database DB --for IMG_1.jpg' (a 3280 x 3280 JPEG mosaic, no serial) took the database's only
    camera (a 260 x 320 sensor here), warned twice, and failed 'the database entry belongs to another sensor' after
    loading its grid, advising '-g' / '--white', which calibrate does not have.  Now the database's white images of
    another sensor size are not candidates, and the one line says so, naming calibrate's own ways."""
    path, _ = white_pair
    db = tmp_path / "calib"
    assert run("calibrate", "--database", db, path.parent).exit_code == 0
    raw, _ = simulate_white("f01-mini", seed=9, shape=(300, 300))
    write_raw_pair(tmp_path / "pic" / "frame.RAW", replace(raw, metadata=replace(raw.metadata, serial=None,
                                                                                is_white_image=False)))
    r = CliRunner().invoke(cli, ["calibrate", "--database", str(db), "--for", str(tmp_path / "pic" / "frame.RAW"),
                                 "-o", str(tmp_path / "g.json")], obj={})
    lines = r.output.strip().splitlines()
    assert r.exit_code == 1 and len(lines) == 1, r.output
    assert "no white image of its sensor size 300 x 300" in lines[0] and "(320 x 260)" in lines[0], lines
    assert "calibrate --scene" in lines[0] and "(-g)" not in lines[0] and not (tmp_path / "g.json").exists()
    # a serial-less raw of the database's sensor size: that camera's white, one warning, a path the user can open
    write_raw_pair(tmp_path / "pic2" / "frame.RAW", replace(raw, mosaic=np.zeros(SHAPE, np.uint16), metadata=replace(
        raw.metadata, serial=None, is_white_image=False)))
    r = CliRunner().invoke(cli, ["calibrate", "--database", str(db), "--for", str(tmp_path / "pic2" / "frame.RAW"),
                                 "-o", str(tmp_path / "g.json")], obj={})
    assert r.exit_code == 0, r.output
    said = r.stderr.splitlines()
    assert sum("no camera serial" in line for line in said) <= 1, said
    white = [line for line in said if line.startswith("white image ")][0].split()[2]
    assert Path(white).resolve() == path.resolve()
    assert LensletGrid.from_json((tmp_path / "g.json").read_text()).sensor_shape == SHAPE


@pytest.mark.parametrize("args, words", [
    (["--database", "DB", "FOLDER", "-o", "g.json"], "-o/--output does nothing with --database DIR"),
    (["--database", "DB", "FOLDER", "--report", "r.html"], "--report does nothing with --database DIR"),
    (["--database", "DB", "FOLDER", "--scene"], "--scene does nothing with --database DIR"),
    (["--database", "DB", "--for", "WHITE", "WHITE", "-o", "g.json"], "so WHITE (MOD_0000.RAW) is not used"),
    (["--for", "WHITE", "-o", "g.json"], "--for MOD_0000.RAW picks a white image from a calibration database, and "
                                         "there is none (looked for its index.json in "),
    (["--for", "WHITE", "-o", "g.json", "--scene"], "--scene does nothing with --for MOD_0000.RAW"),
], ids=["output", "report", "scene", "white-and-for", "for-alone", "for-scene"])
def test_database_options_that_would_be_ignored_are_refused(white_pair, tmp_path, monkeypatch, args, words):
    """'calibrate --database DB FOLDER -o grid.json' indexed the folder and wrote no grid.json, in silence (so did
    --report and --scene); '--for RAW' without --database said 'give at least one WHITE image'.  Each is now a
    usage error naming the option, before anything is written."""
    path, _ = white_pair
    monkeypatch.chdir(tmp_path)           # no calib/ here (the project's would serve --for alone)
    names = {"DB": tmp_path / "db", "FOLDER": path.parent, "WHITE": path}
    full = [str(names.get(a, tmp_path / a if a.endswith((".json", ".html")) else a)) for a in args]
    r = CliRunner().invoke(cli, ["calibrate", *full], obj={})
    errors = [line for line in r.output.splitlines() if line.startswith("Error:")]
    assert r.exit_code == 2 and len(errors) == 1 and words in errors[0], r.output
    assert list(tmp_path.iterdir()) == []


def test_each_warning_once_with_a_report(tmp_path):
    """'calibrate radiometry_frame.png --report r.html' printed the reader's two warnings (no sidecar, estimated
    black) twice: the report read the white image again; a scene given as a white printed 'this looks like a
    scene' twice (logged, then echoed as 'warning:').  Each now once, and the report still judges the grid."""
    import shutil
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    shutil.copy(root / "sample_raws" / "square" / "scene_white.png", tmp_path / "white.png")   # no sidecar
    env = {**__import__("os").environ, "PYTHONPATH": str(root)}
    proc = subprocess.run([sys.executable, "-m", "plenodecode", "calibrate", str(tmp_path / "white.png"),
                           "-o", str(tmp_path / "g.json"), "--report", str(tmp_path / "r.html")],
                          capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("no JSON sidecar") == 1 and proc.stderr.count("black estimated") == 1, proc.stderr
    assert "RMS 0.0" in (tmp_path / "r.html").read_text()           # judged: the white's grid fits
    sim = simulate("f01-mini", seed=1, shape=(300, 300))
    write_raw_pair(tmp_path / "scene.RAW", replace(sim.raw, metadata=replace(sim.raw.metadata, is_white_image=False)))
    proc = subprocess.run([sys.executable, "-m", "plenodecode", "calibrate", str(tmp_path / "scene.RAW"),
                           "-o", str(tmp_path / "s.json"), "--report", str(tmp_path / "s.html")],
                          capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr.count("this looks like a scene") == 1, proc.stderr
    assert "verdict: bad" in (tmp_path / "s.html").read_text()
    # what the report calls bad, the command says too (it printed the RMS alone, e.g. 'RMS 1.274 px')
    high = [line for line in proc.stderr.splitlines() if "is high for a white image (good <= 0.1 px" in line]
    assert len(high) == 1 and f"{tmp_path / 's.html'} shows where" in high[0], proc.stderr
    assert "is high for a white image" not in subprocess.run(
        [sys.executable, "-m", "plenodecode", "calibrate", str(tmp_path / "white.png"), "-o", str(tmp_path / "w.json")],
        capture_output=True, text=True, env=env, cwd=tmp_path).stderr


def test_a_mistyped_pitch_hint_is_named_in_the_error(white_pair, tmp_path):
    """'calibrate MOD_0000.RAW --pitch 99' (for 9.9) said only 'only N lenslet centres detected ... is this a white
    image of a plenoptic camera?'; the one line now names the --pitch hint and the metadata's pitch."""
    path, truth = white_pair
    r = CliRunner().invoke(cli, ["calibrate", str(path), "-o", str(tmp_path / "g.json"), "--pitch", "99"], obj={})
    lines = r.output.strip().splitlines()
    assert r.exit_code == 1 and lines[-1].startswith("error:"), r.output
    assert "with --pitch 99 px as the hint; its metadata says 9.928 px" in lines[-1], lines
    assert not (tmp_path / "g.json").exists()
    r = run("calibrate", path, "-o", tmp_path / "g.json", "--pitch", "9.9")
    assert r.exit_code == 0 and abs(LensletGrid.from_json((tmp_path / "g.json").read_text()).pitch - truth.pitch) < 0.01


def test_refine_of_a_white_image_is_refused(white_pair, tmp_path):
    """'calibrate MOD_0000.RAW --refine' ignored --refine (it refines a Raytrix RayCalibData grid) in silence."""
    path, _ = white_pair
    r = CliRunner().invoke(cli, ["calibrate", str(path), "-o", str(tmp_path / "g.json"), "--refine"], obj={})
    errors = [line for line in r.output.splitlines() if line.startswith("Error:")]
    assert r.exit_code == 2 and len(errors) == 1 and "Invalid value for --refine:" in errors[0], r.output
    assert "MOD_0000.RAW has none" in errors[0] and not (tmp_path / "g.json").exists()


def test_a_wrong_lattice_type_is_one_line_not_a_traceback(white_pair, tmp_path):
    """'calibrate radiometry.png --lattice hex' on a square white ended in a numpy 'LinAlgError: Singular matrix'
    traceback, and a hex white forced '--lattice square' wrote a grid through every other row ('RMS 0.029 px',
    exit 0) that matched 18 % of its disks.  Both are one line naming --lattice now, with no grid written."""
    from pathlib import Path as _P

    square = _P(__file__).resolve().parents[2] / "sample_raws" / "square" / "scene_white.png"
    for white, lattice, words in ((white_pair[0], "square", "disks detected fit a square lattice (the others lie "
                                                            "between its lenses)"),
                                  (square, "hex", "the detected centres do not form a hex lattice")):
        r = CliRunner().invoke(cli, ["calibrate", str(white), "-o", str(tmp_path / "g.json"), "--lattice", lattice],
                               obj={})
        lines = r.output.strip().splitlines()
        assert r.exit_code == 1 and lines[-1].startswith("error:") and words in lines[-1], r.output
        assert "--lattice" in lines[-1] and "Traceback" not in r.output and not (tmp_path / "g.json").exists()
    assert run("calibrate", white_pair[0], "-o", tmp_path / "g.json", "--lattice", "hex").exit_code == 0
    scene = square.with_name("scene.png")                  # self-calibration with the wrong type names it too
    r = CliRunner().invoke(cli, ["calibrate", "--scene", str(scene), "-o", str(tmp_path / "s.json"), "--lattice",
                                 "hex"], obj={})
    assert r.exit_code == 1 and "(with --lattice hex: leave it out to detect the lattice)" in r.output, r.output


@pytest.mark.parametrize("out, report, option, words", [
    ("g.json", "g.json", "--report", "must differ from -o/--output"),
    ("g.html", "r.json", "-o / --output", "g.html names an HTML page; the grid is JSON"),
    ("g.json", "r.txt", "--report", "the report is an HTML page: name it .html, not r.txt"),
], ids=["same", "swapped", "not-html"])
def test_report_and_grid_names_are_checked_before_any_work(white_pair, tmp_path, out, report, option, words):
    """'-o g.json --report g.json' wrote the grid, then failed with "FileExistsError: ... pass overwrite=True" (a
    traceback, naming a keyword); '-o g.html --report r.json' wrote a JSON named .html and a page named .json."""
    path, _ = white_pair
    r = CliRunner().invoke(cli, ["calibrate", str(path), "-o", str(tmp_path / out), "--report", str(tmp_path / report)],
                           obj={})
    errors = [line for line in r.output.splitlines() if line.startswith("Error:")]
    assert r.exit_code == 2 and len(errors) == 1 and f"Invalid value for {option}:" in errors[0], r.output
    assert words in errors[0] and list(tmp_path.iterdir()) == []


def test_the_grid_never_replaces_an_input_or_the_database(white_pair, tmp_path):
    """'calibrate MOD_0000.RAW -o MOD_0000.TXT --overwrite' replaced the white image's metadata with the grid, and
    'calibrate --database DB --for RAW -o DB/index.json --overwrite' the database's index: both are refused naming
    -o before any work, and the files are unchanged."""
    import shutil

    path, _ = white_pair
    for p in (path, path.with_suffix(".TXT")):
        shutil.copy(p, tmp_path / p.name)
    white = tmp_path / path.name
    txt = white.with_suffix(".TXT").read_bytes()
    r = CliRunner().invoke(cli, ["calibrate", str(white), "-o", str(white.with_suffix(".TXT")), "--overwrite"], obj={})
    errors = [line for line in r.output.splitlines() if line.startswith("Error:")]
    assert r.exit_code == 2 and len(errors) == 1, r.output
    assert "would replace the input MOD_0000.TXT, the sidecar of MOD_0000.RAW" in errors[0]
    assert white.with_suffix(".TXT").read_bytes() == txt
    db = tmp_path / "db"
    assert run("calibrate", "--database", db, path.parent).exit_code == 0
    index = (db / "index.json").read_bytes()
    raw, _ = simulate_white("f01-mini", seed=9, shape=SHAPE)
    write_raw_pair(tmp_path / "pic" / "frame.RAW", replace(raw, metadata=replace(raw.metadata, is_white_image=False)))
    r = CliRunner().invoke(cli, ["calibrate", "--database", str(db), "--for", str(tmp_path / "pic" / "frame.RAW"),
                                 "-o", str(db / "index.json"), "--overwrite"], obj={})
    assert r.exit_code == 2 and "is inside the calibration database" in r.output, r.output
    assert (db / "index.json").read_bytes() == index


def test_the_levels_warning_of_a_16_bit_mosaic_prints_its_white_level_whole(tmp_path):
    """'plenodecode depth light_field.png -w radiometry_frame.png ...' (the README's microscope line) warned
    'radiometry_frame.png: black 91, white 6.554e+04 of 65535': the white level in four significant digits.  A
    16-bit mosaic without a sidecar now reads 'white 65535 of 65535'."""
    import shutil
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    shutil.copy(root / "sample_raws" / "square" / "scene_white.png", tmp_path / "white.png")   # no sidecar
    env = {**__import__("os").environ, "PYTHONPATH": str(root)}
    proc = subprocess.run([sys.executable, "-m", "plenodecode", "info", str(tmp_path / "white.png")],
                          capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    line = next(s for s in proc.stderr.splitlines() if "white.png: no JSON sidecar" in s)
    assert ", white 65535 of 65535 (" in line and "e+" not in line, line


@pytest.mark.parametrize("name", ["g.xyz", "grid", "g.mat"])
def test_grid_named_other_than_json_is_refused_before_fitting(tmp_path, monkeypatch, name):
    """'calibrate radiometry_frame.png -o g.xyz' on the real ant-leg frame fitted for seconds and wrote the grid
    JSON under g.xyz; a name that is not .json is refused naming -o, with the name to use, and nothing fitted."""
    from plenodecode import calib
    from tests.conftest import shared_path

    frame = shared_path("lf-microscopy-antleg", "radiometry_frame.png")
    monkeypatch.setattr(calib, "calibrate", lambda *a, **k: pytest.fail("fitted before -o was checked"))
    res = CliRunner().invoke(cli, ["calibrate", str(frame), "-o", str(tmp_path / name)])
    assert res.exit_code == 2, res.output
    stem = name.split(".")[0]
    assert res.output.strip().splitlines()[-1] == ("Error: Invalid value for -o / --output: the grid is written as "
                                                   f"JSON, the one format calibrate writes: name it {stem}.json, not "
                                                   f"{name}")
    assert list(tmp_path.iterdir()) == []


def test_dark_white_hint_names_what_suits_the_camera(tmp_path):
    """A uniformly dark --white was answered 'use a flat-field (MOD_*.RAW) image' for every camera: the ant leg's
    dark frame now names the microscope's radiometry frame beside it (decode, whose reader finds its optics;
    calibrate, which reads no optics, names the frame all the same); a Lytro white still names MOD_NNNN.RAW."""
    from tests.conftest import shared_path

    folder = shared_path("lf-microscopy-antleg")
    r = CliRunner().invoke(cli, ["decode", str(folder / "light_field.png"), "-w", str(folder / "dark_frame.tif"),
                                 "-o", str(tmp_path / "lf.npy")], obj={})
    assert r.exit_code == 1 and not (tmp_path / "lf.npy").exists(), r.output
    assert r.output.strip().endswith(
        f"{folder / 'dark_frame.tif'} is uniformly dark (99.9th percentile 0.0017 of the white level); expected a "
        f"white image: use the microscope's radiometry (flat-field) frame, e.g. {folder / 'radiometry_frame.png'} "
        "beside it, not a dark frame"), r.output
    r = CliRunner().invoke(cli, ["calibrate", str(folder / "dark_frame.tif"), "-o", str(tmp_path / "g.json")], obj={})
    assert r.exit_code == 1 and f"e.g. {folder / 'radiometry_frame.png'} beside it, not a dark frame" in r.output
    raw, _ = simulate_white("f01-mini", seed=4, shape=SHAPE)
    write_raw_pair(tmp_path / "MOD_0001.RAW", replace(raw, mosaic=np.full_like(raw.mosaic, 168)))
    r = CliRunner().invoke(cli, ["calibrate", str(tmp_path / "MOD_0001.RAW"), "-o", str(tmp_path / "g.json")], obj={})
    assert r.exit_code == 1 and r.output.strip().endswith(
        "expected a white image: use a flat-field MOD_NNNN.RAW white image of the camera, not a dark frame"), r.output
    assert not (tmp_path / "g.json").exists()
