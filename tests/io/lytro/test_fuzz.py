"""Damaged Lytro files: only PlenodecodeError subclasses may escape, and nothing hangs.

Mutations (truncation, byte flips in headers and payloads, rewritten length fields, inserted
and deleted bytes) of a small generated ``.LFR`` and of the real containers (when present),
read with and without SHA-1 verification so that damaged JSON reaches the parsers; plus
structural damage of real and generated metadata fed to :func:`metadata_from_lytro`.
"""

import json
import re
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import shared_path
from plenodecode.errors import FormatError, PlenodecodeError
from plenodecode.io.lytro import (
    extract_contents, lytro_metadata, metadata_from_lytro, read_container, read_lytro, read_raw_pair,
    write_container, write_lfr, write_raw_pair,
)
from plenodecode.types import CameraMetadata, RawCapture

SETTINGS = dict(max_examples=60, deadline=timedelta(seconds=5), suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("lytro-fuzz")


def _small_raw(white=False) -> RawCapture:
    rng = np.random.default_rng(3)
    cam = CameraMetadata(make="Lytro, Inc.", model="ILLUM", serial="B5143909630", zoom_step=12, focus_step=-3,
                         wb_gains={"r": 1.2, "gr": 1, "gb": 1, "b": 1.5}, ccm=((1, 0, 0), (0, 1, 0), (0, 0, 1)),
                         pixel_pitch_m=1.4e-6, lens_pitch_m=2e-5, mla_rotation=1e-4, is_white_image=white)
    return RawCapture(rng.integers(0, 1024, (24, 32), dtype=np.uint16), "GRBG", 64, 1023, cam)


def _base(name: str, work: Path) -> bytes:
    if name == "generated":
        p = work / "base.LFR"
        if not p.exists():
            write_lfr(p, _small_raw())
        return p.read_bytes()
    return shared_path("lytro-containers", name).read_bytes()


def _section_header_offsets(data: bytes) -> list[int]:
    out, pos = [], data.find(b"\x89LF", 1)
    while pos >= 0:
        out.append(pos)
        pos = data.find(b"\x89LF", pos + 1)
    return out


@st.composite
def mutations(draw, data: bytes):
    """A damaged copy of ``data``."""
    b = bytearray(data)
    heads = _section_header_offsets(data)
    for _ in range(draw(st.integers(1, 3))):
        if not b:
            break
        kind = draw(st.sampled_from(["truncate", "flip", "flip_header", "length", "insert", "delete", "json"]))
        if kind == "truncate":
            del b[draw(st.integers(0, len(b) - 1)):]
        elif kind == "flip":
            i = draw(st.integers(0, len(b) - 1))
            b[i] ^= draw(st.integers(1, 255))
        elif kind == "flip_header" and heads:
            i = min(len(b) - 1, draw(st.sampled_from(heads)) + draw(st.integers(0, 95)))
            b[i] ^= draw(st.integers(1, 255))
        elif kind == "length" and heads:
            h = draw(st.sampled_from(heads)) + 12
            if h + 4 <= len(b):
                b[h:h + 4] = draw(st.one_of(st.integers(0, 2**32 - 1), st.integers(0, 256))).to_bytes(4, "big")
        elif kind == "insert":
            i = draw(st.integers(0, len(b)))
            b[i:i] = draw(st.binary(min_size=1, max_size=20))
        elif kind == "delete":
            i = draw(st.integers(0, len(b) - 1))
            del b[i:i + draw(st.integers(1, 40))]
        elif kind == "json":
            # damage the JSON text itself: replace a character inside the LFM / metadata payloads
            starts = [m.start() for m in re.finditer(rb"\{\s", bytes(b))] or [0]
            i = min(len(b) - 1, draw(st.sampled_from(starts)) + draw(st.integers(0, 400)))
            b[i] = draw(st.sampled_from(list(b'{}[]",:0-9e.aZ\x00\xff')))
    return bytes(b)


def _exercise(path: Path, verify: bool) -> None:
    try:
        c = read_container(path, verify=verify)
        for it in c.contents():
            it.describe()
            c.payload(it.sha1)
        if c.kind == "raw":
            read_lytro(path, verify=verify)
    except PlenodecodeError:
        pass


@pytest.mark.parametrize("name", ["generated", "demo.LFP", "IMG_0001-stk.lfp", "IMG_0002-stk.lfp",
                                  "IMG_0002-dm.lfp"])
@settings(**SETTINGS)
@given(data=st.data(), verify=st.booleans())
def test_damaged_containers_raise_only_plenodecode_errors(work, name, data, verify):
    base = _base(name, work)
    damaged = data.draw(mutations(base))
    path = work / f"damaged-{name}"
    path.write_bytes(damaged)
    _exercise(path, verify)


def test_extract_refuses_a_map_whose_size_disagrees_with_the_toc(tmp_path):
    real = read_container(shared_path("lytro-containers", "IMG_0002-dm.lfp"))
    toc = json.loads(json.dumps(real.toc))
    toc["picture"]["accelerationArray"][0]["vendorContent"]["width"] = 331
    payloads = [bytes(real.payload(s.sha1)) for s in real.sections if s.kind == "LFC"]
    path = write_container(tmp_path / "d.lfp", toc, payloads)  # consistent SHA-1s, wrong declared size
    with pytest.raises(FormatError, match=r"d\.lfp: depth_map is 435600 bytes.*331 x 330 float32"):
        extract_contents(path, tmp_path / "out")
    assert not (tmp_path / "out").exists()  # checked before anything is written


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**30, 10**30) | st.just(10**400) | st.floats(allow_nan=True)
    | st.text(max_size=8) | st.sampled_from(["r,gr:gb,b", "gr", "b", "little", "big"]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=10)


def _paths(obj, prefix=()):
    """Every key path of a JSON object."""
    out = [prefix]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, prefix + (i,))
    return out


def _replace_at(obj, path, value):
    if not path:
        return value
    k = path[0]
    if isinstance(obj, dict):
        return {**obj, k: _replace_at(obj[k], path[1:], value)}
    out = list(obj)
    out[k] = _replace_at(obj[k], path[1:], value)
    return out


def _metadata_docs():
    docs = [lytro_metadata(_small_raw(), schema="illum")[0], lytro_metadata(_small_raw(), schema="rawdetails")[0]]
    for name in ("lenslet_whiteimage.TXT", "IMG_0001__frame.json"):
        from tests.conftest import SHARED_DATA
        p = SHARED_DATA / "lytro-containers" / name
        if p.exists():
            docs.append(json.loads(p.read_text()))
    return docs


_DOCS = _metadata_docs()


@settings(max_examples=150, deadline=timedelta(seconds=5))
@given(data=st.data())
def test_damaged_metadata_raises_only_plenodecode_errors(data):
    doc = data.draw(st.sampled_from(_DOCS))
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(_paths(doc)))
        doc = _replace_at(doc, path, data.draw(json_values))
    try:
        cam, cfa, black, white, w, h, bits, endian = metadata_from_lytro(doc)
    except PlenodecodeError:
        return
    assert cfa in ("RGGB", "GRBG", "GBRG", "BGGR") and black.shape == white.shape == (2, 2)
    assert 1 <= w <= 65536 and 1 <= h <= 65536 and bits in (8, 10, 12, 16) and endian in ("little", "big")
    assert isinstance(cam, CameraMetadata)


@settings(max_examples=40, deadline=timedelta(seconds=5))
@given(data=st.data())
def test_damaged_raw_pair_sidecar(work, data):
    d = work / "pair"
    rawp = d / "MOD_0003.RAW"
    if not rawp.exists():
        write_raw_pair(rawp, _small_raw(white=True))
    txt = d / "MOD_0003.TXT"
    good = d / "good.json"
    if not good.exists():
        good.write_bytes(txt.read_bytes())
    doc = json.loads(good.read_text())
    path = data.draw(st.sampled_from(_paths(doc)))
    damaged = _replace_at(doc, path, data.draw(json_values))
    text = json.dumps(damaged).encode()
    if data.draw(st.booleans()):
        cut = data.draw(st.integers(0, len(text)))
        text = text[:cut] + data.draw(st.binary(max_size=8))
    txt.write_bytes(text)
    try:
        raw = read_raw_pair(rawp)
    except PlenodecodeError:
        return
    assert raw.mosaic.shape == (24, 32)
