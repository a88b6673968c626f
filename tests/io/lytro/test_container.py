"""The container grammar (:mod:`plenodecode.io.lytro.container`).

Damaged files give a FormatError naming the file and the problem.
"""

from __future__ import annotations

import hashlib

import pytest

from plenodecode.errors import FormatError
from plenodecode.io.lytro import read_container, read_lytro, write_lfr
from plenodecode.io.packing import pack_10bit
from tests.io.lytro.helpers import container_with_metadata, illum_metadata_json, make_raw


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


def test_unparsable_metadata_and_toc(tmp_path):
    raw = make_raw(12)
    image = pack_10bit(raw.mosaic)
    p = container_with_metadata(tmp_path / "m.lfr", illum_metadata_json(raw)[:-40], image)
    with pytest.raises(FormatError, match=r"m\.lfr.*frame metadata.*not valid JSON"):
        read_lytro(p)
    p = container_with_metadata(tmp_path / "n.lfr", b'\xff\xfe{"a": 1}', image)
    with pytest.raises(FormatError, match="not valid JSON"):
        read_lytro(p)
    # a TOC that is not JSON
    toc = b"{not json"
    sec = b"\x89LFM\r\n\x1a\n" + b"\0" * 4 + len(toc).to_bytes(4, "big")
    sec += (b"sha1-" + hashlib.sha1(toc).hexdigest().encode()).ljust(80, b"\0") + toc
    (tmp_path / "t.lfp").write_bytes(b"\x89LFP\r\n\x1a\n\0\0\0\x01\0\0\0\0" + sec)
    with pytest.raises(FormatError, match="table of contents.*not valid JSON"):
        read_container(tmp_path / "t.lfp")
