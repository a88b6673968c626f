"""Headerless raws with a sidecar (:mod:`plenodecode.io.lytro.rawpair`).

Round trips, real white images and F01 frames, bad pairs.
"""

from __future__ import annotations

import json

import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError, MetadataError
from plenodecode.io import read_raw
from plenodecode.io.lytro import find_sidecar, read_raw_pair, write_raw_pair
from tests.io.lytro.helpers import assert_same_raw, make_raw


@pytest.mark.parametrize("model,bits", [("B01", 10), ("F01", 12)])
def test_raw_pair_round_trip(tmp_path, model, bits):
    raw = make_raw(5, bits=bits, model=model, cfa="GRBG" if bits == 10 else "BGGR", white_image=True)
    rawp, txt = write_raw_pair(tmp_path / "MOD_0007.RAW", raw)
    assert txt.name == "MOD_0007.TXT" and find_sidecar(rawp) == txt
    assert rawp.stat().st_size == raw.mosaic.size * bits // 8
    back = read_raw_pair(rawp)
    assert_same_raw(back, raw)
    doc = json.loads(txt.read_text())
    fr = doc["master"]["picture"]["frameArray"][0]
    assert fr["parameters"]["vendorContent"]["com.lytro.tags"]["modulationFrame"] is True
    assert fr["frame"]["metadata"]["camera"]["model"] == model
    assert fr["frame"]["privateMetadata"]["camera"]["serialNumber"] == raw.metadata.serial
    assert fr["frame"]["metadata"]["image"]["rawDetails"]["pixelPacking"]["bitsPerPixel"] == bits
    # the dispatcher of plenodecode.io finds the pair too
    assert_same_raw(read_raw(rawp), raw)


def test_raw_pair_of_an_illum_capture_is_written_as_b01(tmp_path):
    raw = make_raw(6, model="ILLUM", white_image=True)
    rawp, _ = write_raw_pair(tmp_path / "MOD_0001.RAW", raw)
    assert_same_raw(read_raw_pair(rawp), raw, model="B01")


def test_real_txt_with_full_size_raw_and_trailing_bytes(tmp_path):
    txt = shared_path("lytro-containers", "lenslet_whiteimage.TXT")
    (tmp_path / "MOD_0000.TXT").write_bytes(txt.read_bytes() + b"\r\n\x00\x00garbage\x1a")
    with open(tmp_path / "MOD_0000.RAW", "wb") as fh:  # sparse full-size Illum raw: 51,854,880 B
        fh.seek(51_854_880 - 5)
        fh.write(bytes([0xFF, 0, 0, 0, 0b11]))
    raw = read_raw_pair(tmp_path / "MOD_0000.RAW")
    assert raw.shape == (5368, 7728) and raw.cfa == "GRBG" and raw.metadata.is_white_image
    assert raw.mosaic[-1, -4] == 0x3FF and raw.mosaic[-1, -3] == 0 and raw.mosaic.sum() == 0x3FF


def test_real_f01_frame_pair(tmp_path):
    js = shared_path("lytro-containers", "IMG_0001__frame.json")
    (tmp_path / "IMG_0001__frame.json").write_bytes(js.read_bytes())
    with open(tmp_path / "IMG_0001__frame.raw", "wb") as fh:
        fh.write(bytes([0x12, 0x34, 0x56]))
        fh.truncate(16_137_600)
    assert find_sidecar(tmp_path / "IMG_0001__frame.raw").name == "IMG_0001__frame.json"
    raw = read_raw_pair(tmp_path / "IMG_0001__frame.raw")
    assert raw.shape == (3280, 3280) and raw.cfa == "BGGR" and raw.mosaic[0, :3].tolist() == [0x123, 0x456, 0]


def test_raw_pair_errors(tmp_path):
    raw = make_raw(15)
    rawp, txt = write_raw_pair(tmp_path / "MOD_0001.RAW", raw)
    rawp.write_bytes(rawp.read_bytes()[:-5])
    with pytest.raises(FormatError, match=r"MOD_0001\.RAW.*3835 bytes but MOD_0001\.TXT declares 64 x 48"):
        read_raw_pair(rawp)
    (tmp_path / "lonely.RAW").write_bytes(b"\0" * 16)
    assert find_sidecar(tmp_path / "lonely.RAW") is None
    with pytest.raises(FormatError, match="no metadata sidecar"):
        read_raw_pair(tmp_path / "lonely.RAW")
    (tmp_path / "bad.RAW").write_bytes(b"\0" * 16)
    (tmp_path / "bad.txt").write_text('{"master": {"picture": ')
    with pytest.raises(FormatError, match=r"bad\.txt.*(not valid JSON|no '\}')"):
        read_raw_pair(tmp_path / "bad.RAW")
    (tmp_path / "bad.txt").write_text('{"image": {"width": 4}}')
    with pytest.raises(MetadataError):
        read_raw_pair(tmp_path / "bad.RAW")
    with pytest.raises(FormatError, match="no such file"):
        read_raw_pair(tmp_path / "missing.RAW")
