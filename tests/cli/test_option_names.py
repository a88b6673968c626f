"""Errors about an option's value name the option as typed, never the library's keyword (design.md rule 3)."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from tests.conftest import ROOT, shared_path


def _error(res) -> str:
    assert res.exit_code == 2, res.output
    return res.stderr.strip().splitlines()[-1]


def test_focus_at_outside_the_picture_names_x_y_not_the_keyword_at(tmp_path):
    """'--focus-at 600,10' on the 512 x 512 HCI antinous said 'at = (row 10, column 600) lies outside ...'."""
    hci = shared_path("hci-antinous")
    res = CliRunner().invoke(cli, ["refocus", str(hci), "-o", str(tmp_path / "r.png"), "--focus-at", "600,10"])
    assert _error(res) == ("Error: Invalid value for --focus-at: X,Y = 600,10 lies outside the centre view: "
                           "X (column) 0 to 511, Y (row) 0 to 511, or fractions 0.0-1.0")
    assert not (tmp_path / "r.png").exists()
    ok = CliRunner().invoke(cli, ["refocus", str(hci), "-o", str(tmp_path / "r.png"), "--focus-at", "511,10"])
    assert ok.exit_code == 0 and (tmp_path / "r.png").is_file(), ok.output


@pytest.mark.parametrize("view, said", [(("9", "0"), "V (view row) 9"), (("2", "8.5"), "U (view column) 8.5")])
def test_view_past_the_last_names_v_u_as_the_option_does(tmp_path, view, said):
    """'views --view 9 0' on the 9 x 9 HCI antinous said 'v must be within [0, 8] (view index)'."""
    hci = shared_path("hci-antinous")
    res = CliRunner().invoke(cli, ["views", str(hci), "-o", str(tmp_path / "v.png"), "--view", *view])
    assert _error(res) == (f"Error: Invalid value for --view: {said} is past the last view of this 9 x 9 light "
                           "field: 0 to 8")
    assert not (tmp_path / "v.png").exists()


def test_metric_focus_distance_inside_the_focal_length_is_refused_before_the_depth_estimate(tmp_path, monkeypatch):
    """'depth RAW --metric --focus-distance 0.001' estimated the whole depth map, then ended in a traceback
    'ValueError: focus_distance_m (0.001 m) must exceed the focal length (0.0301 m)'."""
    from plenodecode import pipeline

    raw = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"
    rendered = []
    monkeypatch.setattr(pipeline, "render_product", lambda *a, **k: rendered.append(a))
    res = CliRunner().invoke(cli, ["depth", str(raw), "-o", str(tmp_path / "z.pfm"), "--metric", "--focus-distance",
                                   "0.001", "--database", str(ROOT / "calib")])
    assert _error(res) == ("Error: Invalid value for --focus-distance: 0.001 m is not beyond the main lens's focal "
                           "length (30.1 mm) of scene.lfr: give the distance the camera was focused at, in metres")
    assert rendered == [] and list(tmp_path.iterdir()) == []


def test_summary_files_not_of_a_batch_name_the_option_not_the_keyword(tmp_path):
    """'batch -o OUT' over a foreign summary.json said 'pass --overwrite (overwrite=True)'."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text("{}")
    res = CliRunner().invoke(cli, ["batch", str(ROOT / "sample_raws" / "square"), "-o", str(out), "--database",
                                   str(ROOT / "calib")])
    assert _error(res) == (f"Error: {out / 'summary.json'} exists and was not written by a batch run; pass "
                           "--overwrite or choose another -o folder")
    assert (out / "summary.json").read_text() == "{}"


@pytest.mark.parametrize("view", [("4,4",), ("4", "4")])
def test_view_takes_v_comma_u_as_focus_at_takes_x_comma_y(tmp_path, view):
    """'views --view 4,4' (the form --focus-at X,Y teaches) failed with click's "'4,4' is not a valid float"; it
    and the older 'V U' form both write the HCI antinous centre view, input_Cam040.png, to the sample."""
    import cv2
    import numpy as np

    hci = shared_path("hci-antinous")
    out = tmp_path / "v.png"
    res = CliRunner().invoke(cli, ["views", str(hci), "--view", *view, "-o", str(out)])
    assert res.exit_code == 0, res.output
    written = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    centre = cv2.imread(str(hci / "input_Cam040.png"), cv2.IMREAD_UNCHANGED)
    assert written.dtype == np.uint16 and np.array_equal(written, centre.astype(np.uint16) * 257)


@pytest.mark.parametrize("view, said", [(("4",), "expected V,U (view row, view column, e.g. 4,4 or 7.5,6.25), "
                                                 "got '4'"),
                                        (("4,x",), "expected V,U (view row, view column, e.g. 4,4 or 7.5,6.25), "
                                                   "got '4,x'"),
                                        (("4,-1",), "V and U must be finite and >= 0, got '4,-1'")])
def test_bad_view_is_one_line_naming_view_before_the_input_is_read(tmp_path, view, said):
    res = CliRunner().invoke(cli, ["views", str(ROOT / "sample_raws" / "square" / "scene.png"), "--view", *view,
                                   "-o", str(tmp_path / "v.png")])
    assert _error(res) == f"Error: Invalid value for '--view': {said}"
    assert list(tmp_path.iterdir()) == []


def test_view_past_the_last_of_a_raw_is_refused_before_decoding(tmp_path, monkeypatch):
    """'views IMG_1.jpg --view 20,4' on the real F01 JPEG decoded the whole raw before saying that its 9 x 9 views
    end at 8; the calibration's decoded shape says so before decoding."""
    from plenodecode.pipeline import source

    monkeypatch.setattr(source, "decode_raw", lambda *a, **k: pytest.fail("decoded before --view was checked"))
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    res = CliRunner().invoke(cli, ["views", str(jpeg), "--view", "20,4", "-o", str(tmp_path / "v.png")])
    assert _error(res) == ("Error: Invalid value for --view: V (view row) 20 is past the last view of this 9 x 9 light "
                           "field: 0 to 8")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("view, note", [("8,8", True), ("7.5,7", False)])
def test_view_partly_outside_the_micro_images_says_so(tmp_path, view, note):
    """'views IMG_1.jpg --view 8,8' on the real F01 JPEG wrote a corner view striped by the lenses' edges (data in
    44 % of its samples; the folder of every view writes it black) without a word; now a note on stderr says so.
    A view between whole ones (7.5,7) gets none."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    res = CliRunner().invoke(cli, ["views", str(jpeg), "--view", view, "-o", str(tmp_path / "v.png")])
    assert res.exit_code == 0, res.output
    notes = [line for line in res.stderr.splitlines() if "outside the micro-images" in line]
    assert notes == ([f"note: view {view.replace(',', ', ')} is partly outside the micro-images (data in 44% of its "
                      "samples): it shows the lenses' edges as stripes; 77 of the 81 views are whole, and the folder "
                      "of every view writes the others black"] if note else [])
    assert (tmp_path / "v.png").is_file()
