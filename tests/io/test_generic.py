import json
import logging
import struct

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError, MetadataError
from plenodecode.io.generic import ccm_from_xyz_to_camera, read_generic, write_mosaic
from plenodecode.io.images import write_image
from plenodecode.types import CameraMetadata, RawCapture

XYZ_TO_CAM = np.array([[0.9, -0.3, -0.1], [-0.4, 1.2, 0.2], [-0.05, 0.15, 0.6]])


def make_dng(mosaic, *, cfa=(0, 1, 1, 2), black=(60, 62, 64, 66), white=4095, xyz_to_cam=XYZ_TO_CAM,
             neutral=(0.5, 1.0, 0.8), make=b"Plenodecode", model=b"TestCam"):
    """A minimal little-endian DNG 1.4 (TIFF 6.0 + DNG tags), one uncompressed 16-bit CFA strip.

    cfa: CFAPattern codes (0 = R, 1 = G, 2 = B) of the 2x2 tile, row-major; black: BlackLevel
    per tile position (BlackLevelRepeatDim 2x2); ColorMatrix1 = xyz_to_cam (illuminant D65).
    """
    h, w = mosaic.shape
    pixels = mosaic.astype("<u2").tobytes()
    entries = []

    def add(tag, typ, values):
        if typ == 2:                                    # ASCII
            data, count = values + b"\0", len(values) + 1
        elif typ in (5, 10):                            # (S)RATIONAL
            code = "<II" if typ == 5 else "<ii"
            data = b"".join(struct.pack(code, int(round(v * 10000)), 10000) for v in np.ravel(values))
            count = np.size(values)
        else:
            code = {1: "B", 3: "H", 4: "I"}[typ]
            data, count = struct.pack(f"<{len(values)}{code}", *values), len(values)
        entries.append((tag, typ, count, data))

    add(254, 4, [0]); add(256, 4, [w]); add(257, 4, [h]); add(258, 3, [16]); add(259, 3, [1])
    add(262, 3, [32803]); add(271, 2, make); add(272, 2, model); add(273, 4, [0]); add(277, 3, [1])
    add(278, 4, [h]); add(279, 4, [len(pixels)]); add(284, 3, [1]); add(33421, 3, [2, 2])
    add(33422, 1, list(cfa)); add(50706, 1, [1, 4, 0, 0]); add(50708, 2, make + b" " + model)
    add(50713, 3, [2, 2]); add(50714, 3, list(black)); add(50717, 4, [white])
    add(50721, 10, xyz_to_cam); add(50728, 5, neutral); add(50778, 3, [21])
    entries.sort()
    data_start = 8 + 2 + 12 * len(entries) + 4
    ifd, blob = struct.pack("<H", len(entries)), b""
    pix_offset = data_start + sum(len(d) + len(d) % 2 for _, _, _, d in entries if len(d) > 4)
    for tag, typ, count, data in entries:
        if tag == 273:
            data = struct.pack("<I", pix_offset)
        if len(data) <= 4:
            field = data.ljust(4, b"\0")
        else:
            field = struct.pack("<I", data_start + len(blob))
            blob += data + b"\0" * (len(data) % 2)
        ifd += struct.pack("<HHI", tag, typ, count) + field
    return b"II*\0" + struct.pack("<I", 8) + ifd + struct.pack("<I", 0) + blob + pixels


@pytest.fixture
def mosaic():
    return np.random.default_rng(0).integers(64, 4096, (24, 38)).astype(np.uint16)


@pytest.mark.parametrize("codes,name", [((0, 1, 1, 2), "RGGB"), ((1, 0, 2, 1), "GRBG"),
                                        ((1, 2, 0, 1), "GBRG"), ((2, 1, 1, 0), "BGGR")])
def test_dng_through_rawpy(tmp_path, mosaic, codes, name):
    p = tmp_path / "x.dng"
    p.write_bytes(make_dng(mosaic, cfa=codes))
    raw = read_generic(p)
    np.testing.assert_array_equal(raw.mosaic, mosaic)
    assert raw.cfa == name
    np.testing.assert_array_equal(raw.black, [[60, 62], [64, 66]])   # per tile position, as written
    np.testing.assert_array_equal(raw.white, np.full((2, 2), 4095))
    # camera_whitebalance = 1 / AsShotNeutral, normalised to green
    assert raw.metadata.wb_gains == pytest.approx({"r": 2.0, "gr": 1.0, "gb": 1.0, "b": 1.25}, abs=1e-3)
    np.testing.assert_allclose(raw.metadata.ccm, ccm_from_xyz_to_camera(XYZ_TO_CAM), atol=1e-3)
    np.testing.assert_allclose(np.sum(raw.metadata.ccm, axis=1), 1.0, atol=1e-9)
    assert (raw.metadata.make, raw.metadata.model) == ("Plenodecode", "TestCam")
    assert raw.path == str(p)


def test_ccm_from_srgb_camera_is_identity():
    import colour

    xyz_to_srgb = np.linalg.inv(colour.models.RGB_COLOURSPACE_sRGB.matrix_RGB_to_XYZ)
    np.testing.assert_allclose(ccm_from_xyz_to_camera(xyz_to_srgb), np.eye(3), atol=1e-6)
    # a camera with channel gains: rows re-normalised -> still identity up to white balance
    np.testing.assert_allclose(ccm_from_xyz_to_camera(np.diag([2.0, 1.0, 0.5]) @ xyz_to_srgb), np.eye(3), atol=1e-6)


def test_non_bayer_and_non_raw_refused(tmp_path, mosaic):
    p = tmp_path / "x.dng"
    p.write_bytes(make_dng(mosaic, cfa=(0, 1, 2, 1)))
    with pytest.raises(FormatError, match="Bayer"):
        read_generic(p)
    q = tmp_path / "notes.cr2"
    q.write_bytes(b"certainly not a raw file" * 10)
    with pytest.raises(FormatError, match="notes.cr2"):
        read_generic(q)
    with pytest.raises(FormatError):
        read_generic(tmp_path / "missing.dng")


@pytest.mark.parametrize("ext", [".png", ".tif"])
def test_write_mosaic_round_trip(tmp_path, mosaic, ext):
    meta = CameraMetadata(make="Synth", model="square", serial="S1", zoom_step=3.0, exposure_s=0.01,
                          wb_gains={"r": 2.0, "gr": 1.0, "gb": 1.0, "b": 1.5},
                          ccm=((1.2, -0.1, -0.1), (-0.2, 1.3, -0.1), (0.0, -0.3, 1.3)),
                          pixel_pitch_m=1.4e-6, lens_pitch_m=2e-5, mla_offset_m=(1e-6, -2e-6, 3e-5),
                          extra={"preset": "square", "seed": [1, 2]})
    raw = RawCapture(mosaic, "GRBG", np.array([[60, 61], [62, 63]]), 4095, meta)
    p = write_mosaic(tmp_path / f"m{ext}", raw)
    assert p.with_suffix(".json").is_file()
    back = read_generic(p)
    np.testing.assert_array_equal(back.mosaic, raw.mosaic)
    assert back.mosaic.dtype == np.uint16 and back.cfa == "GRBG"
    np.testing.assert_array_equal(back.black, raw.black)
    np.testing.assert_array_equal(back.white, raw.white)
    assert back.metadata == raw.metadata
    with pytest.raises(FileExistsError):
        write_mosaic(p, raw)
    write_mosaic(p, raw.__class__(mosaic[::-1].copy(), None, 0, 65535), overwrite=True)
    again = read_generic(p)
    assert again.cfa is None and again.metadata == CameraMetadata()
    np.testing.assert_array_equal(again.mosaic, mosaic[::-1])
    assert not [x for x in tmp_path.iterdir() if x.name.startswith(".")]


def test_mosaic_without_sidecar_is_monochrome(tmp_path, mosaic, caplog):
    p = write_image(tmp_path / "plain.png", mosaic, bit_depth=16)
    with caplog.at_level(logging.WARNING):
        raw = read_generic(p)
    assert "no JSON sidecar" in caplog.text
    assert raw.cfa is None
    np.testing.assert_array_equal(raw.black, 0)
    np.testing.assert_array_equal(raw.white, 65535)
    np.testing.assert_array_equal(raw.mosaic, mosaic)


def test_sidecar_variants(tmp_path, mosaic):
    p = write_image(tmp_path / "s.png", mosaic, bit_depth=16)
    (tmp_path / "s.png.json").write_text(json.dumps({"cfa": "BGGR", "black": 64, "white": [4095, 4000, 4001, 4002]}))
    raw = read_generic(p)
    assert raw.cfa == "BGGR"
    np.testing.assert_array_equal(raw.black, 64)
    np.testing.assert_array_equal(raw.white, [[4095, 4000], [4001, 4002]])
    (tmp_path / "s.png.json").write_text('{"cfa": "RGBW"}')
    with pytest.raises(MetadataError, match="cfa"):
        read_generic(p)
    (tmp_path / "s.png.json").write_text("{not json")
    with pytest.raises(MetadataError):
        read_generic(p)


def test_float_exr_mosaic_scaled_to_uint16(tmp_path, mosaic):
    x = mosaic / 65535.0
    p = write_image(tmp_path / "f.exr", x, bit_depth=32)
    (tmp_path / "f.json").write_text(json.dumps({"cfa": "RGGB", "black": 0.01, "white": 0.9}))
    raw = read_generic(p)
    np.testing.assert_array_equal(raw.mosaic, mosaic)
    np.testing.assert_allclose(raw.black, 0.01 * 65535)
    np.testing.assert_allclose(raw.white, 0.9 * 65535)


def test_multichannel_image_refused(tmp_path):
    p = write_image(tmp_path / "rgb.png", np.zeros((4, 6, 3), np.uint16), bit_depth=16)
    with pytest.raises(FormatError, match="mosaic"):
        read_generic(p)


def test_real_microscope_frames_read_as_monochrome():
    raw = read_generic(shared_path("lf-microscopy-antleg", "light_field.png"))
    assert raw.shape == (2160, 2592) and raw.cfa is None and raw.mosaic.dtype == np.uint16
    dark = read_generic(shared_path("lf-microscopy-antleg", "dark_frame.tif"))
    # ImageJ says min=42, max=199 for the dark frame
    assert int(dark.mosaic.min()) == 42 and int(dark.mosaic.max()) == 199
    assert raw.mosaic.mean() > dark.mosaic.mean()


def test_read_raw_dispatches_to_generic_and_raytrix(tmp_path, mosaic):
    from plenodecode.io import read_raw
    from plenodecode.io.raytrix import RaytrixCalibration

    raw = RawCapture(mosaic, "RGGB", 64, 4095, CameraMetadata(model="m"))
    write_mosaic(tmp_path / "a.png", raw)
    assert read_raw(tmp_path / "a.png").cfa == "RGGB"
    (tmp_path / "x.dng").write_bytes(make_dng(mosaic))
    assert read_raw(tmp_path / "x.dng").metadata.model == "TestCam"
    (tmp_path / "a.xml").write_text(RaytrixCalibration(offset=(0.0, 0.0), diameter=9.0).to_xml())
    r = read_raw(tmp_path / "a.png")
    assert r.metadata.extra["raytrix"]["diameter"] == 9.0 and r.cfa == "RGGB"   # sidecar levels kept


def test_pgm_mosaic(tmp_path, mosaic):
    h, w = mosaic.shape
    (tmp_path / "m.pgm").write_bytes(f"P5\n{w} {h}\n4095\n".encode() + mosaic.astype(">u2").tobytes())
    raw = read_generic(tmp_path / "m.pgm")
    np.testing.assert_array_equal(raw.mosaic, mosaic)
    assert raw.white[0, 0] == 4095 and raw.cfa is None
    (tmp_path / "c.pgm").write_bytes(b"P5 # comment\n4 2\n# another\n200\n" + bytes(range(8)))
    np.testing.assert_array_equal(read_generic(tmp_path / "c.pgm").mosaic, np.arange(8).reshape(2, 4))
    (tmp_path / "t.pgm").write_bytes(b"P5\n4 2\n200\n" + bytes(3))
    with pytest.raises(FormatError, match="bytes"):
        read_generic(tmp_path / "t.pgm")
