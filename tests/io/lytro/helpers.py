"""Builders and checks shared by the Lytro tests: random raws, section layout, small containers."""

from __future__ import annotations

import hashlib
import json
import struct
from dataclasses import replace

import numpy as np

from plenodecode.io.lytro import lytro_metadata, write_container
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


def tiny_jpeg(h, w, value):
    import cv2
    ok, buf = cv2.imencode(".jpg", np.full((h, w, 3), value, np.uint8))
    assert ok
    return buf.tobytes()


def make_processed(path):
    """A Desktop-style processed Illum LFP (LFM first): 3 JPEGs 16x8 and a 4x3 float32 depth map."""
    jpegs = [tiny_jpeg(8, 16, 40 * k) for k in range(3)]
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


def container_with_metadata(path, meta_bytes, image):
    sha = lambda b: "sha1-" + hashlib.sha1(b).hexdigest()  # noqa: E731
    toc = {"frames": [{"frame": {"metadataRef": sha(meta_bytes), "imageRef": sha(image)}}]}
    return write_container(path, toc, [image, meta_bytes], lfm_first=False)


def illum_metadata_json(raw, **image_changes):
    meta, _ = lytro_metadata(raw, schema="illum")
    meta["image"].update(image_changes)
    return json.dumps(meta).encode()
