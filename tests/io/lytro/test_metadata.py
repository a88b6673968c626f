"""Lytro metadata schemas (:mod:`plenodecode.io.lytro.metadata`): real documents, implausible sizes, damaged entries."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError, MetadataError, PlenodecodeError
from plenodecode.io.lytro import lytro_metadata, metadata_from_lytro, read_lytro
from plenodecode.io.packing import pack_10bit
from tests.io.lytro.helpers import container_with_metadata, illum_metadata_json, make_raw


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


def test_absurd_image_size_refused_before_allocating(tmp_path):
    raw = make_raw(14)
    p = container_with_metadata(tmp_path / "huge.lfr", illum_metadata_json(raw, width=10**6, height=10**6),
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
    p = container_with_metadata(tmp_path / "big.lfr", illum_metadata_json(raw, width=60000, height=60000),
                                 pack_10bit(raw.mosaic))
    with pytest.raises(FormatError, match="60000 x 60000"):
        read_lytro(p)


def test_metadata_errors_are_plenodecode_errors():
    raw = make_raw(16)
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
