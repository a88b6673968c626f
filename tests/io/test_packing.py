"""Bit packing of Lytro raws: known bit vectors (formats.md §2-3) and exact inverses."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from plenodecode.errors import FormatError
from plenodecode.io.packing import (
    pack, pack_10bit, pack_12bit, packed_size, unpack, unpack_10bit, unpack_12bit,
)


def test_12bit_known_vector():
    # formats.md §2: bytes 12 34 56 give 0x123 and 0x456 (big-endian bit stream, not MIPI RAW12)
    out = unpack_12bit(bytes([0x12, 0x34, 0x56]), 1, 2)
    assert out.dtype == np.uint16 and out.tolist() == [[0x123, 0x456]]
    assert pack_12bit(np.array([[0x123, 0x456]], np.uint16)) == bytes([0x12, 0x34, 0x56])


def test_10bit_known_group_with_distinct_lsbs():
    # p_k = (b_k << 2) | ((b4 >> 2k) & 3): b4 = 0b00_11_10_01 gives LSBs 1, 2, 3, 0 to p0..p3.
    group = bytes([0xFF, 0x00, 0xA8, 0x40, 0b00111001])
    out = unpack_10bit(group, 1, 4)
    assert out.tolist() == [[0x3FD, 0x002, 0x2A3, 0x100]]
    # the reversed LSB order (LightFieldLab's bug) would give [0x3FC, 0x003, 0x2A2, 0x101]
    assert pack_10bit(out) == group


def test_10bit_groups_are_row_major_consecutive_pixels():
    # two groups -> a 2 x 4 image: the first group is row 0, the second row 1
    buf = bytes([1, 2, 3, 4, 0b11100100, 10, 20, 30, 40, 0])
    out = unpack_10bit(buf, 2, 4)
    assert out.tolist() == [[4 | 0, 8 | 1, 12 | 2, 16 | 3], [40, 80, 120, 160]]


def test_12bit_multi_row_layout():
    buf = bytes([0xAB, 0xCD, 0xEF, 0x01, 0x23, 0x45])
    assert unpack_12bit(buf, 2, 2).tolist() == [[0xABC, 0xDEF], [0x012, 0x345]]


mosaics10 = hnp.arrays(np.uint16, st.tuples(st.integers(1, 6), st.integers(1, 5).map(lambda k: 4 * k)),
                       elements=st.integers(0, 1023))
mosaics12 = hnp.arrays(np.uint16, st.tuples(st.integers(1, 6), st.integers(1, 6).map(lambda k: 2 * k)),
                       elements=st.integers(0, 4095))


@settings(max_examples=60, deadline=None)
@given(mosaics10)
def test_10bit_round_trip(m):
    buf = pack_10bit(m)
    assert len(buf) == m.size * 10 // 8 == packed_size(*m.shape, 10)
    np.testing.assert_array_equal(unpack_10bit(buf, *m.shape), m)
    # pack is the inverse the other way round too: arbitrary bytes survive unpack + pack
    raw = bytes(np.random.default_rng(m.size).integers(0, 256, len(buf), dtype=np.uint8))
    assert pack_10bit(unpack_10bit(raw, *m.shape)) == raw


@settings(max_examples=60, deadline=None)
@given(mosaics12)
def test_12bit_round_trip(m):
    buf = pack_12bit(m)
    assert len(buf) == m.size * 3 // 2
    np.testing.assert_array_equal(unpack_12bit(buf, *m.shape), m)
    raw = bytes(np.random.default_rng(m.size).integers(0, 256, len(buf), dtype=np.uint8))
    assert pack_12bit(unpack_12bit(raw, *m.shape)) == raw


def test_random_full_width_rows_round_trip():
    rng = np.random.default_rng(7)
    # an Illum row stride is 9660 B; 40 rows = 77,280 groups, more than one unpacking block of 65,536
    m10 = rng.integers(0, 1024, (40, 7728), dtype=np.uint16)
    b10 = pack_10bit(m10)
    assert len(b10) == 40 * 9660
    np.testing.assert_array_equal(unpack_10bit(memoryview(b10), 40, 7728), m10)
    assert unpack_10bit(b"", 0, 8).shape == (0, 8)
    m12 = rng.integers(0, 4096, (8, 3280), dtype=np.uint16)  # an F01 row stride is 4920 B
    b12 = pack_12bit(m12)
    assert len(b12) == 8 * 4920
    np.testing.assert_array_equal(unpack_12bit(np.frombuffer(b12, np.uint8), 8, 3280), m12)


def test_dispatch_and_16bit():
    rng = np.random.default_rng(1)
    m = rng.integers(0, 1024, (4, 8), dtype=np.uint16)
    np.testing.assert_array_equal(unpack(pack(m, 10), 4, 8, 10, "little"), m)
    np.testing.assert_array_equal(unpack(pack(m, 12), 4, 8, 12, "big"), m)
    np.testing.assert_array_equal(unpack(m.astype(">u2").tobytes(), 4, 8, 16, "big"), m)
    np.testing.assert_array_equal(unpack(m.astype("<u2").tobytes(), 4, 8, 16, "little"), m)
    with pytest.raises(FormatError, match="unsupported pixel packing"):
        unpack(pack(m, 10), 4, 8, 10, "big")
    with pytest.raises(ValueError, match="bits"):
        pack(m, 14)


def test_bad_sizes_and_values():
    with pytest.raises(FormatError, match="should be 5 bytes, found 4"):
        unpack_10bit(b"\x00" * 4, 1, 4)
    with pytest.raises(FormatError, match="should be 3 bytes"):
        unpack_12bit(b"\x00" * 4, 1, 2)
    with pytest.raises(ValueError, match="divisible by 4"):
        pack_10bit(np.zeros((1, 3), np.uint16))
    with pytest.raises(ValueError, match="fit in 10 bits"):
        pack_10bit(np.full((1, 4), 1024, np.uint16))
    with pytest.raises(ValueError, match="fit in 12 bits"):
        pack_12bit(np.full((1, 2), 4096, np.uint16))
    with pytest.raises(ValueError, match="uint16"):
        pack_12bit(np.zeros((1, 2), np.int32))
    with pytest.raises(ValueError, match="height and width"):
        packed_size(-1, 4, 10)
