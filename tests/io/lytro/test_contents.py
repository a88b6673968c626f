"""What a container holds (:mod:`plenodecode.io.lytro.contents`).

Processed Desktop files, depth maps, focal stacks, calibration archives.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError
from plenodecode.io.lytro import (
    extract_contents, read_container, read_lytro, read_raw_pair, write_container, write_raw_pair,
)
from tests.io.lytro.helpers import assert_same_raw, make_processed, make_raw


def test_processed_container_contents_and_extraction(tmp_path):
    path = make_processed(tmp_path / "p.lfp")
    c = read_container(path)
    assert (c.kind, c.model, c.serial) == ("processed", "ILLUM", "B1")
    items = {it.name: it for it in c.contents()}
    assert items["depth_map"].type == "depth" and items["depth_map"].shape == (3, 4)
    assert items["depth_map"].dtype == "float32"
    assert [items[f"focus_stack_{k:02d}"].shape for k in range(3)] == [(8, 16)] * 3
    with pytest.raises(FormatError, match="no raw image.*3 x jpeg 16x8.*plenodecode extract .* -o DIR"):
        read_lytro(path)
    files = extract_contents(path, tmp_path / "x")
    depth = np.load(tmp_path / "x" / "depth_map.npy")
    assert depth.dtype == np.float32 and depth.shape == (3, 4)
    np.testing.assert_array_equal(depth, np.arange(12, dtype=np.float32).reshape(3, 4) - 5)
    import cv2
    img = cv2.imread(str(tmp_path / "x" / "focus_stack_02.jpg"))
    assert img.shape == (8, 16, 3) and abs(float(img.mean()) - 80) < 3
    assert len(files) == 6                           # toc, the depth map and its picture, three JPEGs


def test_real_f01_depth_map_file(tmp_path):
    c = read_container(shared_path("lytro-containers", "IMG_0002-dm.lfp"))
    assert (c.kind, c.model, c.model_source) == ("processed", "F01", "toc layout")
    kinds = {it.type: it for it in c.contents()}
    assert kinds["depth"].shape == kinds["confidence"].shape == (330, 330)
    assert kinds["depth"].size == kinds["confidence"].size == 435600
    extract_contents(c.path, tmp_path)
    depth, conf = np.load(tmp_path / "depth_map.npy"), np.load(tmp_path / "confidence_map.npy")
    assert depth.dtype == np.float32 and depth.shape == (330, 330)
    assert -20 <= depth.min() < depth.max() <= 11 and 0 <= conf.min() < conf.max() <= 1


def test_real_f01_focal_stacks():
    c1 = read_container(shared_path("lytro-containers", "IMG_0001-stk.lfp"))
    t1 = [it.type for it in c1.contents()]
    assert c1.model == "F01" and t1.count("jpeg") == 12 and t1.count("lut") == 1
    assert [it.shape for it in c1.contents() if it.type == "lut"] == [(20, 20)]
    c2 = read_container(shared_path("lytro-containers", "IMG_0002-stk.lfp"))
    h264 = [it for it in c2.contents() if it.type == "h264"]
    assert sorted(it.info["frames"] for it in h264) == [11, 37]
    assert all(it.shape == (1080, 1080) for it in h264)
    assert [it.shape for it in c2.contents() if it.type == "lut"] == [(330, 330)]
    for c in (c1, c2):
        assert c.kind == "processed" and c.sections[0].kind == "LFM"
        with pytest.raises(FormatError, match="holds no raw"):
            read_lytro(c.path)


def test_calibration_archive(tmp_path):
    raw = make_raw(17, model="B01", white_image=True)
    rawp, txt = write_raw_pair(tmp_path / "MOD_0000.RAW", raw)
    files = [rawp.read_bytes(), txt.read_bytes()]
    sha = ["sha1-" + hashlib.sha1(b).hexdigest() for b in files]
    toc = {"files": [{"name": "C:\\T1CALIB\\MOD_0000.RAW", "dataRef": sha[0]},
                     {"name": "C:\\T1CALIB\\MOD_0000.TXT", "dataRef": sha[1]}], "nextFile": "data.C.1"}
    arch = write_container(tmp_path / "data.C.0", toc, files)
    c = read_container(arch)
    assert c.kind == "calibration" and [it.type for it in c.contents()] == ["raw", "json"]
    with pytest.raises(FormatError, match="calibration archive"):
        read_lytro(arch)
    out = extract_contents(arch, tmp_path / "cal")
    assert sorted(p.name for p in out) == ["T1CALIB__MOD_0000.json", "T1CALIB__MOD_0000.raw", "toc.json"]
    assert_same_raw(read_raw_pair(tmp_path / "cal" / "T1CALIB__MOD_0000.raw"), raw)
