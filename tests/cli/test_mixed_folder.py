"""Folders a user assembles from real captures: the Raytrix R42 crop and its RayCalibData XML beside a Lytro F01 JPEG
(the XML is the R42 crop's; the JPEG is read as the F01 mosaic it is), and raws linked into a folder with files of
the user's beside the links."""

from __future__ import annotations

import shutil

import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from tests.conftest import ROOT, shared_path


def _beside_r42(tmp_path, *files, xmls=("sc2_klein.xml",)):
    """A folder holding the R42 crop, its XML under each name of ``xmls``, and copies of ``files``."""
    folder = tmp_path / "shoot"
    folder.mkdir()
    shutil.copy(shared_path("raytrix-r42", "sc2_klein.png"), folder)
    for name in xmls:
        shutil.copy(shared_path("raytrix-r42", "sc2_klein.xml"), folder / name)
    for f in files:
        shutil.copy(f, folder)
    return folder


@pytest.mark.parametrize("xmls", [("sc2_klein.xml",), ("sc2_klein.xml", "calib_2.xml")], ids=["one-xml", "two-xmls"])
def test_f01_jpeg_beside_a_raytrix_xml_is_read_as_the_f01_mosaic(tmp_path, xmls):
    """A real F01 JPEG copied beside the R42 crop and its XML was read as a Raytrix image with that XML (the only
    RayCalibData in the folder): 'info' said 'Raytrix', '3280 x 3280, monochrome, black 0, white 255', and batch wrote
    its 'total focus', a grey picture patterned by the wrong lens grid; with a second XML it failed 'say which one
    with --raytrix-xml'.  An XML named for another image no longer claims an image of a Lytro sensor's size."""
    folder = _beside_r42(tmp_path, shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), xmls=xmls)
    res = CliRunner().invoke(cli, ["info", str(folder / "IMG_1.jpg")])
    assert res.exit_code == 0, res.output
    assert "camera   Lytro F01 (by its 3280 x 3280 sensor" in res.output
    assert "raw      3280 x 3280, BGGR, black 15.6887, white 255" in res.output
    res = CliRunner().invoke(cli, ["info", str(folder / "sc2_klein.png")])
    assert res.exit_code == 0 and "(Raytrix)" in res.output, res.output        # its own XML still applies
    from plenodecode import pipeline

    raw = pipeline.open_raw(folder / "IMG_1.jpg")          # as batch and the decoding commands read it
    assert raw.cfa == "BGGR" and "raytrix" not in raw.metadata.extra


def test_batch_of_an_f01_jpeg_beside_a_raytrix_image_serves_its_views(tmp_path, monkeypatch):
    """'batch FOLDER --outputs centre' over the real F01 JPEG beside the R42 crop and its XML was refused up front:
    'all 2 raws here are focused-plenoptic (Raytrix) raws'; only the R42 crop is, and the batch starts."""
    from plenodecode import batch

    folder = _beside_r42(tmp_path, shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"))
    ran = []

    def first_task(files, *args, **kwargs):       # the checks passed: the batch starts
        ran.append([f.name for f in files])
        raise SystemExit(0)

    monkeypatch.setattr(batch, "run_batch", first_task)
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(tmp_path / "out"), "--outputs", "centre",
                                   "--database", str(ROOT / "calib")])
    assert res.exit_code == 0 and ran == [["IMG_1.jpg", "sc2_klein.png"]], res.output


def test_batch_reads_a_linked_raw_with_the_sidecar_beside_the_link(tmp_path):
    """The real F01 JPEG linked into a folder (the data stay where they are) beside a sidecar written for it: 'info'
    and the single commands read it with that sidecar, but batch followed the link and read the JPEG beside its
    target, without it ('no JSON sidecar; CFA BGGR ...'), so the sidecar's monochrome reading (cfa null) gave a colour
    photo.  The batch reads the raw at the link: a grey photo, and no 'no JSON sidecar' warning."""
    import json

    from plenodecode.io.images import read_image

    folder = tmp_path / "linked"
    folder.mkdir()
    try:
        (folder / "IMG_1.jpg").symlink_to(shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"))
    except OSError as exc:                  # a file system without links
        pytest.skip(f"cannot make a symbolic link here: {exc}")
    (folder / "IMG_1.json").write_text(json.dumps({
        "format": "plenodecode.mosaic", "version": 1, "cfa": None, "black": [[16, 16], [16, 16]],
        "white": [[255, 255], [255, 255]], "metadata": {"make": "Lytro", "model": "F01"}}))
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(folder), "-o", str(out), "--self-calibrate", "--jobs", "1"])
    assert res.exit_code == 0, res.output
    assert "no JSON sidecar" not in res.output
    photo = read_image(out / "IMG_1" / "refocus_s+0.00.png")
    assert photo.shape == (383, 382)            # one channel: the sidecar's monochrome reading (colour: (383, 382, 3))
