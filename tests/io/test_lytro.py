"""Lytro containers, raw pairs and metadata: synthetic round trips, real files, bad input."""

import hashlib
import json
import struct
import tracemalloc
from dataclasses import replace

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError, MetadataError, PlenodecodeError
from plenodecode.io import read_raw
from plenodecode.io.lytro import (
    ContentItem, LytroContainer, extract_contents, find_sidecar, metadata_from_lytro, read_container,
    read_lytro, read_raw_pair, write_container, write_lfp, write_lfr, write_raw_pair,
)
from plenodecode.io.packing import pack_10bit, pack_12bit
from plenodecode.types import CameraMetadata, RawCapture

CFAS = ("RGGB", "GRBG", "GBRG", "BGGR")


def make_raw(seed=0, *, shape=(48, 64), bits=10, cfa="GRBG", model="ILLUM", white_image=False):
    rng = np.random.default_rng(seed)
    cam = CameraMetadata(
        make="Lytro, Inc.", model=model, serial="B5143909630" if model != "F01" else "A000424242",
        zoom_step=float(rng.integers(-1040, 124)), focus_step=float(rng.integers(-300, 815)),
        exposure_s=float(rng.uniform(1e-3, 0.1)), iso=float(rng.integers(80, 3200)),
        wb_gains={"r": float(rng.uniform(1, 2)), "gr": 1.0, "gb": 1.0, "b": float(rng.uniform(1, 2))},
        ccm=tuple(tuple(float(x) for x in row) for row in rng.normal(0, 0.3, (3, 3)) + np.eye(3)),
        pixel_pitch_m=1.4e-6, lens_pitch_m=float(rng.uniform(1.3e-5, 2.1e-5)),
        mla_rotation=float(rng.uniform(-1e-3, 1e-3)), mla_offset_m=(1.44e-6, -6.26e-6, 3.7e-5),
        mla_scale=(1.0, float(rng.uniform(0.999, 1.001))), focal_length_m=float(rng.uniform(0.01, 0.08)),
        f_number=2.08, is_white_image=white_image,
    )
    top = (1 << bits) - 1
    black = rng.integers(60, 70, (2, 2)).astype(float) * (4 if bits == 12 else 1)
    return RawCapture(mosaic=rng.integers(0, top + 1, shape, dtype=np.uint16), cfa=cfa, black=black,
                      white=np.full((2, 2), float(top)), metadata=cam)


def assert_same_raw(got: RawCapture, want: RawCapture, *, model=None):
    np.testing.assert_array_equal(got.mosaic, want.mosaic)
    assert got.mosaic.dtype == np.uint16
    assert got.cfa == want.cfa
    np.testing.assert_array_equal(got.black, want.black)
    np.testing.assert_array_equal(got.white, want.white)
    expected = want.metadata if model is None else replace(want.metadata, model=model)
    assert replace(got.metadata, extra={}) == expected
    assert "lytro" in got.metadata.extra


def sections_of(path):
    """(kind, offset, N) of every section, parsed independently of the library."""
    b = path.read_bytes()
    out, pos = [], 16
    while pos < len(b):
        if b[pos] == 0:
            pos += 1
            continue
        n = struct.unpack(">I", b[pos + 12:pos + 16])[0]
        out.append((b[pos + 3:pos + 4].decode(), pos, n))
        pos += 96 + n
    return out


# ---------------------------------------------------------------------------------------------
# synthetic round trips
# ---------------------------------------------------------------------------------------------
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


def _tiny_jpeg(h, w, value):
    import cv2
    ok, buf = cv2.imencode(".jpg", np.full((h, w, 3), value, np.uint8))
    assert ok
    return buf.tobytes()


def make_processed(path):
    """A Desktop-style processed Illum LFP (LFM first): 3 JPEGs 16x8 and a 4x3 float32 depth map."""
    jpegs = [_tiny_jpeg(8, 16, 40 * k) for k in range(3)]
    depth = (np.arange(12, dtype="<f4").reshape(3, 4) - 5).tobytes()
    sha = lambda b: "sha1-" + hashlib.sha1(b).hexdigest()  # noqa: E731
    acc = {"kind": "focusStack", "width": 16, "height": 8, "representation": "jpeg",
           "depthMap": {"width": 4, "height": 3, "imageRef": sha(depth), "representation": "packedFloat",
                        "minLambda": -5, "maxLambda": 6},
           "perImage": [{"imageRef": sha(j), "focus": float(k)} for k, j in enumerate(jpegs)]}
    toc = {"schema": "http://schema.lytro.com/lfp/picture/2.1.4/picture_schema.json", "thumbnails": [],
           "frames": [{"frame": {"metadata": {"camera": {"model": "ILLUM"}},
                                 "privateMetadata": {"camera": {"serialNumber": "B1"}}}}],
           "views": [{"accelerations": [acc]}]}
    return write_container(path, toc, [depth, *jpegs], lfm_first=True)


def test_processed_container_contents_and_extraction(tmp_path):
    path = make_processed(tmp_path / "p.lfp")
    c = read_container(path)
    assert (c.kind, c.model, c.serial) == ("processed", "ILLUM", "B1")
    items = {it.name: it for it in c.contents()}
    assert items["depth_map"].type == "depth" and items["depth_map"].shape == (3, 4)
    assert items["depth_map"].dtype == "float32"
    assert [items[f"focus_stack_{k:02d}"].shape for k in range(3)] == [(8, 16)] * 3
    with pytest.raises(FormatError, match="no raw image.*3 x jpeg 16x8.*plenodecode info"):
        read_lytro(path)
    files = extract_contents(path, tmp_path / "x")
    depth = np.load(tmp_path / "x" / "depth_map.npy")
    assert depth.dtype == np.float32 and depth.shape == (3, 4)
    np.testing.assert_array_equal(depth, np.arange(12, dtype=np.float32).reshape(3, 4) - 5)
    import cv2
    img = cv2.imread(str(tmp_path / "x" / "focus_stack_02.jpg"))
    assert img.shape == (8, 16, 3) and abs(float(img.mean()) - 80) < 3
    assert len(files) == 5


# ---------------------------------------------------------------------------------------------
# real files (skipped without ../shared/data)
# ---------------------------------------------------------------------------------------------
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
    with pytest.raises(FormatError, match="demo.LFP: holds no raw.*10 x jpeg 704x480.*plenodecode info"):
        read_lytro(path)
    files = extract_contents(path, tmp_path)
    d = np.load(tmp_path / "depth_map.npy")
    assert d.shape == (60, 88) and -15 <= d.min() < d.max() <= 12.5  # within the TOC's min/maxLambda
    import cv2
    img = cv2.imread(str(tmp_path / "focus_stack_00.jpg"))
    assert img.shape == (480, 704, 3)
    assert len(files) == 12  # toc + depth + 10 JPEGs


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


def test_real_illum_white_image_txt_maps():
    path = shared_path("lytro-containers", "lenslet_whiteimage.TXT")
    doc = json.loads(path.read_text())
    cam, cfa, black, white, w, h, bits, endian = metadata_from_lytro(doc, None, path)
    assert (cam.model, cam.make, cam.serial) == ("B01", "Lytro, Inc.", "B5143909630")
    assert (cam.zoom_step, cam.focus_step) == (-1040, -300)
    assert cam.is_white_image
    assert (cfa, w, h, bits, endian) == ("GRBG", 7728, 5368, 10, "little")
    assert np.all(black == 64) and np.all(white == 1023)
    assert cam.lenslet_pitch_px() == pytest.approx(14.286, abs=1e-3)
    assert cam.wb_gains == {"r": 1, "gr": 1, "gb": 1, "b": 1}
    assert cam.mla_rotation == pytest.approx(-0.00055235880427062511, rel=1e-12)
    assert cam.mla_offset_m[2] == pytest.approx(4.06e-5, rel=1e-6)
    assert np.allclose(np.sum(cam.ccm, axis=1), 1, atol=1e-5)
    assert cam.extra["lytro"]["document"]["compressedFrame"]["metadata"]["representation"] == "jpeg"


def test_real_f01_frame_json_maps():
    path = shared_path("lytro-containers", "IMG_0001__frame.json")
    cam, cfa, black, white, w, h, bits, endian = metadata_from_lytro(json.loads(path.read_text()), None, path)
    assert (cam.model, cfa, w, h, bits, endian) == ("F01", "BGGR", 3280, 3280, 12, "big")
    assert np.all(black == 168) and np.all(white == 4095)
    assert cam.wb_gains == {"r": 1, "gr": 1.1171875, "gb": 1.1171875, "b": 1.72265625}
    assert np.allclose(np.sum(cam.ccm, axis=1), 1, atol=1e-5)
    assert cam.ccm[0][0] == pytest.approx(3.1115827560424805, rel=1e-12)
    assert cam.pixel_pitch_m == pytest.approx(1.4e-6, rel=1e-6)
    assert cam.lens_pitch_m == pytest.approx(1.38986e-5, rel=1e-5)
    assert cam.lenslet_pitch_px() == pytest.approx(9.928, abs=1e-3)
    assert (cam.zoom_step, cam.focus_step, cam.iso) == (981, 582, 200)
    assert cam.exposure_s == pytest.approx(0.01433531753718853)
    assert cam.focal_length_m == pytest.approx(0.00645, rel=1e-6) and cam.f_number == pytest.approx(1.91, rel=1e-6)
    assert cam.mla_scale == pytest.approx((1, 1.0004994869232178))
    assert not cam.is_white_image


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


# ---------------------------------------------------------------------------------------------
# bad input: FormatError naming the file and the problem
# ---------------------------------------------------------------------------------------------
@pytest.fixture
def lfr(tmp_path):
    return write_lfr(tmp_path / "ok.lfr", make_raw(11))


def test_truncated_file(lfr, tmp_path):
    bad = tmp_path / "cut.lfr"
    bad.write_bytes(lfr.read_bytes()[:2000])
    with pytest.raises(FormatError, match=r"cut\.lfr.*truncated"):
        read_lytro(bad)
    bad.write_bytes(lfr.read_bytes()[:10])
    with pytest.raises(FormatError, match="too short"):
        read_container(bad)
    bad.write_bytes(b"")
    with pytest.raises(FormatError, match="too short"):
        read_container(bad)


def test_wrong_magic(lfr, tmp_path):
    bad = tmp_path / "x.lfr"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + lfr.read_bytes()[8:])
    with pytest.raises(FormatError, match=r"x\.lfr.*not an LFP/LFR"):
        read_lytro(bad)
    data = bytearray(lfr.read_bytes())
    data[16 + 3] = ord("X")  # first section's magic
    bad.write_bytes(bytes(data))
    with pytest.raises(FormatError, match=r"expected a section magic .* at offset 16"):
        read_container(bad)


def test_section_length_beyond_eof(lfr, tmp_path):
    data = bytearray(lfr.read_bytes())
    data[16 + 12:16 + 16] = (10**9).to_bytes(4, "big")
    bad = tmp_path / "len.lfr"
    bad.write_bytes(bytes(data))
    with pytest.raises(FormatError, match=r"len\.lfr.*declares 1000000000 payload bytes"):
        read_container(bad)


def test_sha1_mismatch(lfr, tmp_path):
    data = bytearray(lfr.read_bytes())
    data[16 + 96 + 5] ^= 0x01  # a raw pixel byte
    bad = tmp_path / "sha.lfr"
    bad.write_bytes(bytes(data))
    with pytest.raises(FormatError, match=r"sha\.lfr.*SHA-1 mismatch"):
        read_lytro(bad)
    assert read_lytro(bad, verify=False).mosaic.shape == (48, 64)  # the check can be turned off


def _container_with_metadata(path, meta_bytes, image):
    sha = lambda b: "sha1-" + hashlib.sha1(b).hexdigest()  # noqa: E731
    toc = {"frames": [{"frame": {"metadataRef": sha(meta_bytes), "imageRef": sha(image)}}]}
    return write_container(path, toc, [image, meta_bytes], lfm_first=False)


def _meta(raw, **image_changes):
    from plenodecode.io.lytro import lytro_metadata
    meta, _ = lytro_metadata(raw, schema="illum")
    meta["image"].update(image_changes)
    return json.dumps(meta).encode()


def test_unparsable_metadata_and_toc(tmp_path):
    raw = make_raw(12)
    image = pack_10bit(raw.mosaic)
    p = _container_with_metadata(tmp_path / "m.lfr", _meta(raw)[:-40], image)
    with pytest.raises(FormatError, match=r"m\.lfr.*frame metadata.*not valid JSON"):
        read_lytro(p)
    p = _container_with_metadata(tmp_path / "n.lfr", b'\xff\xfe{"a": 1}', image)
    with pytest.raises(FormatError, match="not valid JSON"):
        read_lytro(p)
    # a TOC that is not JSON
    toc = b"{not json"
    sec = b"\x89LFM\r\n\x1a\n" + b"\0" * 4 + len(toc).to_bytes(4, "big")
    sec += (b"sha1-" + hashlib.sha1(toc).hexdigest().encode()).ljust(80, b"\0") + toc
    (tmp_path / "t.lfp").write_bytes(b"\x89LFP\r\n\x1a\n\0\0\0\x01\0\0\0\0" + sec)
    with pytest.raises(FormatError, match="table of contents.*not valid JSON"):
        read_container(tmp_path / "t.lfp")


def test_payload_size_disagrees_with_metadata(tmp_path):
    raw = make_raw(13)
    image = pack_10bit(raw.mosaic[:40])  # 64 x 40 packed, metadata says 64 x 48
    p = _container_with_metadata(tmp_path / "s.lfr", _meta(raw), image)
    with pytest.raises(FormatError, match=r"s\.lfr.*3200 bytes but the metadata declares 64 x 48 at 10 bit = 3840"):
        read_lytro(p)


def test_absurd_image_size_refused_before_allocating(tmp_path):
    raw = make_raw(14)
    p = _container_with_metadata(tmp_path / "huge.lfr", _meta(raw, width=10**6, height=10**6),
                                 pack_10bit(raw.mosaic))
    tracemalloc.start()
    try:
        with pytest.raises(FormatError, match=r"huge\.lfr.*1000000 is not a plausible sensor size"):
            read_lytro(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6
    # within the plausible range but not matching the payload: refused by the size check
    p = _container_with_metadata(tmp_path / "big.lfr", _meta(raw, width=60000, height=60000),
                                 pack_10bit(raw.mosaic))
    with pytest.raises(FormatError, match="60000 x 60000"):
        read_lytro(p)


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


def test_metadata_errors_are_plenodecode_errors():
    raw = make_raw(16)
    from plenodecode.io.lytro import lytro_metadata
    meta, _ = lytro_metadata(raw, schema="illum")
    for change in ({"mosaic": {"tile": "r,g:b", "upperLeftPixel": "r"}}, {"mosaic": {"tile": 3}},
                   {"pixelFormat": {"black": {"r": "x"}, "white": 1023}}, {"pixelPacking": {"bitsPerPixel": 11}},
                   {"width": -3}, {"width": 2.5}, {"pixelFormat": None}):
        bad = {**meta, "image": {**meta["image"], **change}}
        with pytest.raises(PlenodecodeError):
            metadata_from_lytro(bad)
    with pytest.raises(MetadataError):
        metadata_from_lytro([1, 2])
    # the input is not modified
    snapshot = json.dumps(meta, sort_keys=True)
    metadata_from_lytro(meta)
    assert json.dumps(meta, sort_keys=True) == snapshot


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
