"""``plenodecode extract``: every item embedded in a processed Lytro file written, with its metadata (issue 18,
items 6 and 7), on a generated container and on the real Desktop files in ../shared/data."""

from __future__ import annotations

import json
import re

import numpy as np
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.lytro import read_container
from tests.conftest import shared_path
from tests.io.lytro.helpers import make_processed

SHA1 = re.compile(r"^sha1-[0-9a-fA-F]{40}$")


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def toc_references(toc) -> set[str]:
    """Every ``sha1-<hex>`` string anywhere in a table of contents (lower case): the items it lists."""
    if isinstance(toc, dict):
        return set().union(*(toc_references(v) for v in toc.values())) if toc else set()
    if isinstance(toc, list):
        return set().union(*(toc_references(v) for v in toc)) if toc else set()
    return {toc.lower()} if isinstance(toc, str) and SHA1.match(toc) else set()


def check_extracted(path, out) -> int:
    """Every item the TOC lists (and the file holds) is on disk, non-empty, described in contents.json with
    its size; returns the number of items."""
    c = read_container(path)
    listed = {s for s in toc_references(c.toc) if c.has(s)}
    manifest = json.loads((out / "contents.json").read_text())
    entries = manifest["items"]
    assert {e["sha1"].lower() for e in entries} == listed            # every listed item, nothing else
    assert len(entries) == len(listed)
    for e in entries:
        f = out / e["file"]
        assert f.is_file() and f.stat().st_size > 0, e["file"]
        if e["type"] == "jpeg":
            assert f.read_bytes()[:2] == b"\xff\xd8" and f.stat().st_size == e["size"]
        elif e["type"] in ("depth", "confidence", "lut"):
            arr = np.load(f)
            assert arr.dtype == np.float32 and arr.nbytes == e["size"]
            assert e["shape"] is None or list(arr.shape) == e["shape"]
        else:
            assert f.stat().st_size == e["size"]
    assert json.loads((out / "toc.json").read_text()) == c.toc
    return len(entries)


def test_extract_writes_every_item_with_its_metadata(tmp_path):
    path = make_processed(tmp_path / "p.lfp")
    out = tmp_path / "out"
    res = run("extract", path, "-o", out)
    assert res.exit_code == 0, res.output
    n = check_extracted(path, out)
    assert n == 4                                          # a depth map and three JPEGs (metadata is in the TOC)
    lines = res.output.splitlines()
    assert len(lines) == n + 4 and lines[-1] == f"wrote {n} items of p.lfp to {out}"     # + the depth map's picture
    assert f"{out / 'depth_map.png'}  its picture, colour bar in the file's units" in lines
    assert sum(line.startswith(str(out / "focus_stack_")) and "jpeg 16x8" in line for line in lines) == 3
    depth = json.loads((out / "contents.json").read_text())["items"]
    assert [e for e in depth if e["type"] == "depth"][0]["shape"] == [3, 4]


def test_extract_overwrite_rule_and_atomic_folder(tmp_path):
    path = make_processed(tmp_path / "p.lfp")
    out = tmp_path / "out"
    assert run("extract", path, "-o", out).exit_code == 0
    before = {f.name: f.stat().st_mtime_ns for f in out.iterdir()}
    res = run("extract", path, "-o", out)                   # exists: refused before any work, nothing touched
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1 and "--overwrite" in errors[0] and "overwrite=True" not in res.output
    assert {f.name: f.stat().st_mtime_ns for f in out.iterdir()} == before
    assert run("-q", "extract", path, "-o", out, "--overwrite").exit_code == 0
    # a damaged container (a cut depth map): one error line, exit 1, and no output folder at all
    data = bytearray(path.read_bytes())
    bad = tmp_path / "bad.lfp"
    bad.write_bytes(bytes(data[:-40]))
    res = run("extract", bad, "-o", tmp_path / "bad_out")
    assert res.exit_code == 1 and res.output.count("error:") == 1
    assert not (tmp_path / "bad_out").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]       # no staging left behind


def test_extract_every_real_container():
    folder = shared_path("lytro-containers")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".lfp")
    assert len(files) == 4                               # IMG_0001-stk, IMG_0002-dm, IMG_0002-stk, demo.LFP
    import tempfile
    from pathlib import Path

    counts = {}
    with tempfile.TemporaryDirectory() as tmp:
        for path in files:
            out = Path(tmp) / path.stem
            res = run("-q", "extract", path, "-o", out)
            assert res.exit_code == 0, (path.name, res.output)
            counts[path.name] = check_extracted(path, out)
    # what each file holds (also listed by `plenodecode info`): 12 JPEG refocus slices + a depth LUT; a depth and
    # a confidence map; two H.264 streams + a depth LUT; a depth map + 10 focus-stack JPEGs
    assert counts == {"IMG_0001-stk.lfp": 13, "IMG_0002-dm.lfp": 2, "IMG_0002-stk.lfp": 3, "demo.LFP": 11}


def test_an_extracted_raw_keeps_its_camera_serial(tmp_path):
    """'extract scene.lfr' writes frame.raw, frame.json and frame_private.json (where the Illum keeps its serial);
    the raw read back had no serial, so 'info' printed 'serial -' and the database could not pick its camera's
    white image by serial.  The private metadata beside it is read now."""
    from pathlib import Path

    from plenodecode.io import read_raw

    root = Path(__file__).resolve().parents[2]
    res = CliRunner().invoke(cli, ["extract", str(root / "sample_raws" / "illum-mini" / "scene.lfr"),
                                   "-o", str(tmp_path / "items")])
    assert res.exit_code == 0 and (tmp_path / "items" / "frame_private.json").is_file(), res.output
    raw = read_raw(tmp_path / "items" / "frame.raw")
    assert raw.metadata.serial == read_raw(root / "sample_raws" / "illum-mini" / "scene.lfr").metadata.serial \
        == "B5143909630"
    out = CliRunner().invoke(cli, ["info", str(tmp_path / "items" / "frame.raw")]).output
    assert "serial   B5143909630" in out
    res = CliRunner().invoke(cli, ["decode", str(tmp_path / "items" / "frame.raw"), "--database", str(root / "calib"),
                                   "-o", str(tmp_path / "lf.zarr")])
    assert res.exit_code == 0, res.output


def test_extracted_depth_and_confidence_maps_come_with_pictures(tmp_path):
    """'extract IMG_0002-dm.lfp' wrote the depth and confidence maps as .npy only, which no picture viewer opens.
    Each 2-D map now also gets a PNG with a colour bar in the file's units; the picture follows the map (its grey
    level, over the image part, rises with the confidence it shows: correlation above 0.9) and the .npy stays as
    it was.  A depth LUT (1-D) gets none."""
    from plenodecode.io.images import read_image

    path = shared_path("lytro-containers", "IMG_0002-dm.lfp")
    res = run("extract", path, "-o", tmp_path / "dm")
    assert res.exit_code == 0, res.output
    assert check_extracted(path, tmp_path / "dm") == 2
    for name in ("depth_map", "confidence_map"):
        assert f"{name}.png  its picture" in res.output
    confidence = np.load(tmp_path / "dm" / "confidence_map.npy")
    picture = np.asarray(read_image(tmp_path / "dm" / "confidence_map.png"), np.float64)
    assert picture.shape[0] >= confidence.shape[0] and picture.shape[2] == 3
    # the image part: the largest block of the figure whose rows and columns are not the white margin
    grey = picture.mean(axis=-1)
    rows = np.flatnonzero((grey < grey.max()).mean(axis=1) > 0.5)
    cols = np.flatnonzero((grey[rows] < grey.max()).mean(axis=0) > 0.9)
    shown = grey[rows[0]:rows[-1] + 1, cols[0]:cols[0] + len(rows)]
    import cv2

    resized = cv2.resize(confidence, (shown.shape[1], shown.shape[0]), interpolation=cv2.INTER_AREA)
    assert np.corrcoef(resized.ravel(), shown.ravel())[0, 1] > 0.9
    res = run("-q", "extract", shared_path("lytro-containers", "IMG_0002-stk.lfp"), "-o", tmp_path / "stk")
    assert res.exit_code == 0 and not list((tmp_path / "stk").glob("*.png")), res.output
