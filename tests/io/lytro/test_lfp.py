"""Picture files (:mod:`plenodecode.io.lytro.lfp`).

F01 ``.lfp`` / Illum ``.lfr`` round trips and layout, payload extraction, real Illum living picture.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError
from plenodecode.io.lytro import (
    ContentItem, LytroContainer, extract_contents, read_container, read_lytro, read_raw_pair,
    write_lfp, write_lfr, write_raw_pair,
)
from plenodecode.io.packing import pack_10bit, pack_12bit
from tests.io.lytro.helpers import (
    CFAS, assert_same_raw, container_with_metadata, illum_metadata_json, make_raw, sections_of,
)


@pytest.mark.parametrize("cfa", CFAS)
def test_lfr_round_trip_bit_exact(tmp_path, cfa):
    raw = make_raw(1, cfa=cfa)
    path = write_lfr(tmp_path / "IMG_0001.LFR", raw)
    back = read_lytro(path)
    assert_same_raw(back, raw)
    assert back.path == str(path)


def test_lfr_structure_is_illum_camera_style(tmp_path):
    raw = make_raw(2)
    path = write_lfr(tmp_path / "a.lfr", raw)
    secs = sections_of(path)
    assert [k for k, _, _ in secs] == ["C", "C", "C", "M"]  # LFC sections first, LFM last
    assert all(off % 16 == 0 for _, off, _ in secs)
    data = path.read_bytes()
    assert data[:16] == b"\x89LFP\r\n\x1a\n" + b"\x00\x00\x00\x01" + b"\x00\x00\x00\x00"
    _, off, n = secs[-1]
    toc = json.loads(data[off + 96:off + 96 + n])
    frame = toc["frames"][0]["frame"]
    assert set(frame) == {"metadataRef", "privateMetadataRef", "imageRef"}
    assert "picture_schema.json" in toc["schema"]
    payloads = {}
    for _, o, n in secs:
        p = data[o + 96:o + 96 + n]
        assert data[o + 16:o + 61] == b"sha1-" + hashlib.sha1(p).hexdigest().encode()
        payloads[data[o + 16:o + 61].decode()] = p
    assert payloads[frame["imageRef"]] == pack_10bit(raw.mosaic)
    meta = json.loads(payloads[frame["metadataRef"]])
    assert meta["image"]["pixelPacking"] == {"endianness": "little", "bitsPerPixel": 10}
    assert meta["image"]["mosaic"] == {"tile": "r,gr:gb,b", "upperLeftPixel": "gr"}
    assert meta["camera"]["model"] == "ILLUM"
    assert len(meta["image"]["color"]["ccm"]) == 9
    assert json.loads(payloads[frame["privateMetadataRef"]])["camera"]["serialNumber"] == "B5143909630"
    c = read_container(path)
    assert (c.kind, c.model, c.serial, c.model_source) == ("raw", "ILLUM", "B5143909630", "metadata")
    raw_items = [it for it in c.contents() if it.type == "raw"]
    assert len(raw_items) == 1 and raw_items[0].shape == (48, 64) and raw_items[0].info["bits"] == 10


def test_lfp_f01_round_trip_and_layout(tmp_path):
    raw = make_raw(3, bits=12, cfa="BGGR", model="F01", shape=(30, 44))
    path = write_lfp(tmp_path / "IMG_0001.lfp", raw)
    assert_same_raw(read_lytro(path), raw)
    secs = sections_of(path)
    assert secs[0][0] == "M" and secs[0][1] == 16 and [k for k, _, _ in secs[1:]] == ["C"] * 3
    c = read_container(path)
    meta = c.metadata
    assert meta["image"]["rawDetails"]["pixelPacking"] == {"endianness": "big", "bitsPerPixel": 12}
    assert meta["image"]["rawDetails"]["mosaic"]["upperLeftPixel"] == "b"
    assert len(meta["image"]["color"]["ccmRgbToSrgbArray"]) == 9
    assert c.toc["version"]["major"] == 1 and c.model == "F01" and c.serial == "A000424242"
    assert c.payload(c.toc["picture"]["frameArray"][0]["frame"]["imageRef"]) == pack_12bit(raw.mosaic)


def test_white_image_flag_round_trips(tmp_path):
    for writer, raw in ((write_lfr, make_raw(4, white_image=True)),
                        (write_lfp, make_raw(4, bits=12, model="F01", white_image=True))):
        path = writer(tmp_path / f"w.{writer.__name__}", raw)
        back = read_lytro(path)
        assert back.metadata.is_white_image and read_container(path).white_image


def test_writers_refuse_to_overwrite_and_leave_no_temp_files(tmp_path):
    raw = make_raw(7)
    path = write_lfr(tmp_path / "a.lfr", raw)
    before = path.read_bytes()
    with pytest.raises(FileExistsError, match="overwrite"):
        write_lfr(path, make_raw(8))
    assert path.read_bytes() == before
    write_lfr(path, make_raw(8), overwrite=True)
    np.testing.assert_array_equal(read_lytro(path).mosaic, make_raw(8).mosaic)
    write_raw_pair(tmp_path / "MOD_0000.RAW", raw)
    (tmp_path / "MOD_0001.TXT").write_text("{}")
    with pytest.raises(FileExistsError):
        write_raw_pair(tmp_path / "MOD_0001.RAW", raw)  # the TXT exists: nothing is written
    assert not (tmp_path / "MOD_0001.RAW").exists()
    with pytest.raises(ValueError, match="fit in 10 bits"):
        write_lfr(tmp_path / "big.lfr", replace(raw, mosaic=np.full((4, 4), 2000, np.uint16)))
    assert not (tmp_path / "big.lfr").exists()
    assert not list(tmp_path.glob(".*.tmp"))


def test_extract_contents_of_a_raw_gives_a_readable_pair(tmp_path):
    raw = make_raw(9)
    path = write_lfr(tmp_path / "a.lfr", raw)
    files = extract_contents(path, tmp_path / "out")
    names = sorted(p.name for p in files)
    assert names == ["frame.json", "frame.raw", "frame_private.json", "toc.json"]
    back = read_raw_pair(tmp_path / "out" / "frame.raw")
    np.testing.assert_array_equal(back.mosaic, raw.mosaic)
    assert back.metadata.model == "ILLUM" and back.cfa == raw.cfa
    with pytest.raises(FileExistsError):
        extract_contents(path, tmp_path / "out")
    assert len(extract_contents(path, tmp_path / "out", overwrite=True)) == 4


def test_real_demo_lfp_illum_living_picture(tmp_path):
    path = shared_path("lytro-containers", "demo.LFP")
    c = read_container(path)
    assert isinstance(c, LytroContainer)
    assert (c.kind, c.model, c.serial) == ("processed", "ILLUM", "45142500380")
    assert c.sections[0].kind == "LFM" and (c.sections[0].offset, c.sections[0].length) == (16, 12841)
    assert c.sections[1].offset == 12960 and all(s.offset % 16 == 0 for s in c.sections)
    items = c.contents()
    assert all(isinstance(it, ContentItem) for it in items)
    jpegs = [it for it in items if it.type == "jpeg"]
    depth = [it for it in items if it.type == "depth"]
    assert len(jpegs) == 10 and all(it.shape == (480, 704) for it in jpegs)
    assert len(depth) == 1 and depth[0].shape == (60, 88) and depth[0].size == 21120
    with pytest.raises(FormatError, match="demo.LFP: holds no raw.*10 x jpeg 704x480.*plenodecode extract .*demo.LFP -o DIR"):
        read_lytro(path)
    files = extract_contents(path, tmp_path)
    d = np.load(tmp_path / "depth_map.npy")
    assert d.shape == (60, 88) and -15 <= d.min() < d.max() <= 12.5  # within the TOC's min/maxLambda
    import cv2
    img = cv2.imread(str(tmp_path / "focus_stack_00.jpg"))
    assert img.shape == (480, 704, 3)
    assert len(files) == 13  # toc + depth + its picture + 10 JPEGs


def test_payload_size_disagrees_with_metadata(tmp_path):
    raw = make_raw(13)
    image = pack_10bit(raw.mosaic[:40])  # 64 x 40 packed, metadata says 64 x 48
    p = container_with_metadata(tmp_path / "s.lfr", illum_metadata_json(raw), image)
    with pytest.raises(FormatError, match=r"s\.lfr.*3200 bytes but the metadata declares 64 x 48 at 10 bit = 3840"):
        read_lytro(p)
