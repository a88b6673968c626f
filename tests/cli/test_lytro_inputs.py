"""``plenodecode info`` on real and generated Lytro files."""

import re

import numpy as np
from click.testing import CliRunner

from tests.conftest import shared_path
from plenodecode.cli.main import cli
from plenodecode.io.lytro import write_lfr, write_raw_pair
from plenodecode.types import CameraMetadata, RawCapture

REAL = ("demo.LFP", "IMG_0001-stk.lfp", "IMG_0002-stk.lfp", "IMG_0002-dm.lfp")


def run(*args):
    return CliRunner().invoke(cli, ["info", *map(str, args)], catch_exceptions=False)


def test_info_on_the_real_containers():
    paths = [shared_path("lytro-containers", n) for n in REAL]
    res = run(*paths)
    assert res.exit_code == 0, res.output
    blocks = dict(zip(REAL, res.output.split("\n\n")))
    demo = blocks["demo.LFP"]
    assert re.search(r"camera\s+ILLUM \(Lytro, Inc\.\)", demo)
    assert re.search(r"serial\s+45142500380", demo)
    assert re.search(r"kind\s+processed", demo)
    assert demo.count("jpeg 704x480") == 10 and "depth float32 88x60" in demo
    assert "sensor   7728 x 5368, 10 bit, GRBG" in demo
    assert re.search(r"LFM\s+16\s+12841\s+8fb0b328e80d\s+table of contents", demo)
    assert re.search(r"LFC\s+12960\s+21120\s+d416c7eddf43\s+views\[0\]\.accelerations\[0\]\.depthMap\.imageRef", demo)
    dm = blocks["IMG_0002-dm.lfp"]
    assert "F01" in dm and "depth float32 330x330" in dm and "confidence float32 330x330" in dm
    assert re.search(r"serial\s+-", dm)
    stk1, stk2 = blocks["IMG_0001-stk.lfp"], blocks["IMG_0002-stk.lfp"]
    assert stk1.count("jpeg 1080x1080") == 12 and "lut float32 20x20" in stk1
    assert "h264 1080x1080 (frames 37)" in stk2 and "h264 1080x1080 (frames 11)" in stk2
    for b in blocks.values():
        assert "kind     processed" in b


def _raw(model="ILLUM", white=False):
    cam = CameraMetadata(make="Lytro, Inc.", model=model, serial="B5143909630", zoom_step=-1040, focus_step=-300,
                         pixel_pitch_m=1.4e-6, lens_pitch_m=2e-5, is_white_image=white)
    m = np.random.default_rng(0).integers(0, 1024, (24, 32), dtype=np.uint16)
    return RawCapture(m, "GRBG", 64, 1023, cam)


def test_info_on_generated_raws(tmp_path):
    lfr = write_lfr(tmp_path / "IMG_0001.LFR", _raw())
    rawp, _ = write_raw_pair(tmp_path / "MOD_0000.RAW", _raw("B01", white=True))
    res = run(lfr, rawp)
    assert res.exit_code == 0, res.output
    a, b = res.output.split("\n\n")
    assert "kind     raw" in a and "raw      32 x 24, 10 bit (little), GRBG, black 64, white 1023" in a
    assert "serial   B5143909630" in a and "lenslet pitch 14.286 px" in a and "zoom step -1040, focus step -300" in a
    assert re.search(r"LFM\s+\d+\s+\d+\s+[0-9a-f]{12}\s+table of contents", a)
    assert "frames[0].frame.imageRef  [frame: raw]" in a
    assert "camera   B01" in b and "kind     raw, white image" in b and "32 x 24, 10 bit" in b


def test_info_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.lfr"
    header = b"\x89LFP\r\n\x1a\n" + (1).to_bytes(4, "big") + bytes(4)
    bad.write_bytes(header + b"\x89LFC\r\n\x1a\n" + bytes(4) + b"\xff\xff\xff\xff")
    res = CliRunner().invoke(cli, ["info", str(bad)])
    assert res.exit_code == 1
    assert res.output.strip().count("\n") == 0 and "declares 4294967295 payload bytes" in res.output
    res = CliRunner().invoke(cli, ["info", str(tmp_path / "missing.lfr")])
    assert res.exit_code == 1 and "no such file" in res.output


def test_info_help_has_an_example():
    res = CliRunner().invoke(cli, ["info", "--help"])
    assert res.exit_code == 0 and "Example" in res.output and "plenodecode info" in res.output


def test_info_on_metadata_files_alone(tmp_path):
    """The .TXT / .json metadata of a headerless raw describes that raw; a JSON that is not Lytro metadata
    gets a one-line error."""
    _, side = write_raw_pair(tmp_path / "MOD_0000.RAW", _raw("B01", white=True))
    res = run(side)
    assert res.exit_code == 0, res.output
    assert "Lytro metadata for a headerless raw (MOD_0000.RAW is beside it)" in res.output
    assert "kind     metadata of a white image" in res.output and "raw      32 x 24, 10 bit (little), GRBG" in res.output
    (tmp_path / "MOD_0000.RAW").unlink()
    assert "no MOD_0000.RAW beside it" in run(side).output
    other = tmp_path / "settings.json"
    other.write_text('{"a": 1}')
    res = CliRunner().invoke(cli, ["info", str(other)])
    assert res.exit_code == 1 and res.output.strip().count("\n") == 0 and "not Lytro frame metadata" in res.output


def test_info_on_the_real_metadata_files():
    res = run(shared_path("lytro-containers", "lenslet_whiteimage.TXT"),
              shared_path("lytro-containers", "IMG_0001__frame.json"))
    assert res.exit_code == 0, res.output
    white, frame = res.output.split("\n\n")
    assert "camera   B01 (Lytro, Inc.)" in white and "serial   B5143909630" in white
    assert "metadata of a white image" in white and "7728 x 5368, 10 bit (little), GRBG, black 64, white 1023" in white
    assert "camera   F01" in frame and "metadata of a raw" in frame and "3280 x 3280, 12 bit (big), BGGR" in frame


def test_a_white_image_without_its_txt_says_the_metadata_is_missing(tmp_path):
    """The bundled MOD_0000.RAW copied without its MOD_0000.TXT: every command said 'not a raw LibRaw can read ...
    expected a DNG or camera raw, or an image mosaic with a JSON sidecar'; now one line names the missing
    MOD_0000.TXT, and with it beside the file it reads again."""
    import shutil
    from pathlib import Path

    bundled = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini"
    white = tmp_path / "MOD_0000.RAW"
    shutil.copy(bundled / "MOD_0000.RAW", white)
    for args in (["info", white], [white, "-o", tmp_path / "p.png"], ["calibrate", white, "-o", tmp_path / "g.json"]):
        res = CliRunner().invoke(cli, list(map(str, args)))
        errors = [line for line in res.output.splitlines() if line.startswith("error:")]
        assert res.exit_code == 1 and len(errors) == 1, res.output
        assert "MOD_0000.TXT or MOD_0000.json, which is missing" in errors[0] and "LibRawFile" not in errors[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["MOD_0000.RAW"]
    shutil.copy(bundled / "MOD_0000.TXT", tmp_path / "MOD_0000.TXT")
    res = run(white)
    assert res.exit_code == 0 and "white image" in res.output, res.output


def test_info_on_a_text_file_that_is_no_metadata_says_so(tmp_path):
    """'plenodecode info notes.txt' said 'the metadata sidecar is not valid JSON ... the file is damaged' of a
    plain text file; it says the file is no Lytro metadata, and a MOD_0000.TXT beside its .RAW keeps the damage
    message."""
    notes = tmp_path / "notes.txt"
    notes.write_text("shot list: the lilies at f/2\n")
    res = CliRunner().invoke(cli, ["info", str(notes)])
    assert res.exit_code == 1 and "not JSON, so not the metadata of a Lytro raw" in res.output, res.output
    assert "damaged" not in res.output
    (tmp_path / "MOD_0000.RAW").write_bytes(b"\0" * 64)
    (tmp_path / "MOD_0000.TXT").write_text("{broken")
    res = CliRunner().invoke(cli, ["info", str(tmp_path / "MOD_0000.TXT")])
    assert res.exit_code == 1 and "the metadata file is damaged" in res.output, res.output


def test_a_truncated_real_lenslet_jpeg_is_refused_as_truncated(tmp_path):
    """A copy of the real F01 IMG_2.jpg cut at 300 kB (an interrupted download) decoded its missing rows as
    mid-grey and failed with 'the image is uniform (no lenslet pattern): expected a white image'; now one line says
    the file is truncated, before any calibration, and nothing is written."""
    import subprocess
    import sys

    src = shared_path("lytro-f01-lenslet-jpg", "IMG_2.jpg")
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(src.read_bytes()[:300_000])
    res = subprocess.run([sys.executable, "-m", "plenodecode", str(cut), "-o", str(tmp_path / "y.png")],
                         capture_output=True, text=True)
    assert res.returncode == 1
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith("error: ") and "truncated" in last and "uniform" not in res.stderr, res.stderr
    assert not (tmp_path / "y.png").exists()
