import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.errors import FormatError
from plenodecode.io.images import (IMAGE_FORMATS, quantise, read_image, srgb_encode, write_animation,
                                   write_image)


@pytest.fixture
def rgb():
    return np.random.default_rng(1).random((7, 11, 3)).astype(np.float32)


@pytest.mark.parametrize("ext,bits", [(e, b) for e, bs in IMAGE_FORMATS.items() for b in bs
                                      if e not in (".jpg", ".jpeg", ".tiff")])
def test_round_trip_error_matches_bit_depth(tmp_path, rgb, ext, bits):
    p = write_image(tmp_path / f"a{ext}", rgb, bit_depth=bits)
    back = read_image(p)
    assert back.shape == rgb.shape
    expected_dtype = {8: np.uint8, 16: np.float16 if ext == ".exr" else np.uint16, 32: np.float32}[bits]
    assert back.dtype == expected_dtype
    if back.dtype.kind == "u":
        err = np.abs(back / np.iinfo(back.dtype).max - rgb).max()
        assert err <= 0.5 / (2**bits - 1) + 1e-7
    elif bits == 16:   # half float: 11-bit mantissa
        assert np.abs(back.astype(np.float32) - rgb).max() <= 2.0**-11
    else:
        np.testing.assert_array_equal(back, rgb)


@pytest.mark.parametrize("ext", [".png", ".tif"])
def test_single_channel_uint16_is_bit_exact_and_not_transposed(tmp_path, ext):
    m = np.random.default_rng(2).integers(0, 65536, (13, 29)).astype(np.uint16)
    back = read_image(write_image(tmp_path / f"m{ext}", m, bit_depth=16))
    assert back.shape == (13, 29) and back.dtype == np.uint16
    np.testing.assert_array_equal(back, m)


@pytest.mark.parametrize("channels", [2, 4])
def test_alpha_channel_is_stored_unassociated(tmp_path, channels):
    x = np.random.default_rng(4).random((5, 6, channels)).astype(np.float32)
    x[..., -1] = np.linspace(0, 1, 30).reshape(5, 6)      # includes alpha = 0
    back = read_image(write_image(tmp_path / "a.png", x, bit_depth=16)) / 65535.0
    assert np.abs(back - x).max() <= 0.5 / 65535 + 1e-7


def test_quantise_rounds_and_clips():
    x = np.array([-0.2, 0.0, 0.5 / 255 - 1e-6, 0.5 / 255 + 1e-6, 1.0, 3.0, np.nan], np.float32)
    np.testing.assert_array_equal(quantise(x, 8), [0, 0, 0, 1, 255, 255, 0])
    np.testing.assert_array_equal(quantise(np.array([0, 255], np.uint8), 16), [0, 65535])
    np.testing.assert_array_equal(quantise(np.array([0, 65535], np.uint16), 8), [0, 255])


def test_srgb_encoding_is_applied_before_quantising(tmp_path):
    lin = np.array([[0.0, 0.0031308, 0.18, 1.0]], np.float32)
    back = read_image(write_image(tmp_path / "s.png", lin, bit_depth=16, encode_srgb=True)) / 65535.0
    # IEC 61966-2-1: 12.92 L below 0.0031308, else 1.055 L^(1/2.4) - 0.055
    expected = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(back, expected, atol=1e-5)
    np.testing.assert_allclose(srgb_encode(np.float32(0.18)), 0.46135613, atol=1e-6)


def test_smooth_jpeg_is_close(tmp_path):
    yy, xx = np.mgrid[0:32, 0:48] / 48.0
    img = np.stack([yy, xx, 0.5 * (xx + yy)], -1).astype(np.float32)
    back = read_image(write_image(tmp_path / "a.jpg", img, bit_depth=8)) / 255.0
    assert np.abs(back - img).mean() < 0.01


def test_refusals(tmp_path, rgb):
    with pytest.raises(ValueError, match="bit_depth"):
        write_image(tmp_path / "a.png", rgb, bit_depth=32)
    with pytest.raises(ValueError, match="bit_depth"):
        write_image(tmp_path / "a.jpg", rgb, bit_depth=16)
    with pytest.raises(ValueError, match="bit_depth"):
        write_image(tmp_path / "a.pfm", rgb, bit_depth=16)
    with pytest.raises(ValueError, match="path"):
        write_image(tmp_path / "a.xyz", rgb, bit_depth=8)
    with pytest.raises(ValueError, match="shape"):
        write_image(tmp_path / "a.png", np.zeros((4, 4, 5), np.float32), bit_depth=8)
    p = write_image(tmp_path / "a.png", rgb, bit_depth=8)
    before = p.read_bytes()
    with pytest.raises(FileExistsError):
        write_image(p, 1 - rgb, bit_depth=8)
    assert p.read_bytes() == before
    write_image(p, 1 - rgb, bit_depth=8, overwrite=True)
    assert p.read_bytes() != before
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.png"]   # no temporary files left


def test_read_image_errors(tmp_path):
    with pytest.raises(FormatError):
        read_image(tmp_path / "missing.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(FormatError):
        read_image(bad)


def test_pfm_through_write_image_keeps_row_order(tmp_path):
    img = np.arange(12, dtype=np.float32).reshape(3, 4) - 5.5
    p = write_image(tmp_path / "d.pfm", img, bit_depth=32)
    raw = p.read_bytes()
    assert raw.startswith(b"Pf\n4 3\n-1")
    # first stored row is the bottom image row
    body = np.frombuffer(raw[-48:], "<f4")
    np.testing.assert_array_equal(body[:4], img[-1])
    np.testing.assert_array_equal(read_image(p), img)


def test_hci_pfm_reads_top_down():
    d = read_image(shared_path("hci-antinous", "gt_disp_lowres.pfm"))
    assert d.shape == (512, 512) and d.dtype == np.float32
    assert -3.5 < d.min() < d.max() < 3.0
    import cv2   # the centre view's structure must line up with the disparity map (not upside down)
    view = cv2.imread(str(shared_path("hci-antinous", "input_Cam040.png")), cv2.IMREAD_GRAYSCALE).astype(np.float32)
    gd = np.hypot(*np.gradient(d))
    gv = np.hypot(*np.gradient(view))
    up = np.corrcoef(gd.ravel(), gv.ravel())[0, 1]
    flipped = np.corrcoef(gd[::-1].ravel(), gv.ravel())[0, 1]
    assert up > 0.1 and up > 3 * flipped


def test_gif_and_webp_animations(tmp_path):
    from PIL import Image

    t = np.linspace(0, 1, 5, dtype=np.float32)
    frames = np.broadcast_to(t[:, None, None, None], (5, 8, 10, 3)).copy()
    frames[:, :, :5, 0] = 0.25
    g = write_animation(tmp_path / "a.gif", frames, fps=10)
    w = write_animation(tmp_path / "a.webp", frames, fps=20, loop=False)
    g1 = write_animation(tmp_path / "once.gif", frames, fps=10, loop=False)
    with Image.open(g) as im:
        assert im.n_frames == 5 and im.info.get("loop") == 0 and im.info["duration"] == 100
        im.seek(3)
        px = np.asarray(im.convert("RGB"))
        assert abs(int(px[0, 9, 1]) - round(0.75 * 255)) <= 3 and abs(int(px[0, 0, 0]) - 64) <= 3
    with Image.open(g1) as im:
        assert im.n_frames == 5 and "loop" not in im.info
    with Image.open(w) as im:
        assert im.n_frames == 5 and im.info.get("loop") == 1
        im.seek(4)
        assert abs(int(np.asarray(im.convert("RGB"))[0, 9, 2]) - 255) <= 1
    with pytest.raises(FileExistsError):
        write_animation(g, frames, fps=10)
    with pytest.raises(ValueError, match="fps"):
        write_animation(tmp_path / "b.gif", frames, fps=0)


def test_pfm_round_trip_colour_and_byte_orders(tmp_path):
    """RGB stays RGB, rows top-down, and a big-endian file written by hand reads the same values."""
    from plenodecode.io.pfm import read_pfm, write_pfm

    rng = np.random.default_rng(7)
    rgb = rng.normal(size=(6, 5, 3)).astype(np.float32)
    np.testing.assert_array_equal(read_pfm(write_pfm(tmp_path / "c.pfm", rgb)), rgb)
    grey = rgb[..., 1].copy()
    (tmp_path / "be.pfm").write_bytes(b"Pf\n5 6\n1.0\n" + np.ascontiguousarray(grey[::-1], ">f4").tobytes())
    np.testing.assert_array_equal(read_pfm(tmp_path / "be.pfm"), grey)
    (tmp_path / "short.pfm").write_bytes(b"Pf\n5 6\n-1.0\n" + b"\0" * 20)
    with pytest.raises(FormatError, match="payload"):
        read_pfm(tmp_path / "short.pfm")


@pytest.mark.parametrize("name", ["a.exr", "a.tif", "a.png"])
def test_the_same_image_gives_the_same_bytes(tmp_path, name):
    """No write-time stamp: two writes a second apart are byte-identical."""
    import time

    img = np.random.default_rng(3).random((5, 6, 3)).astype(np.float32)
    bits = 16
    first = write_image(tmp_path / "1" / name, img, bit_depth=bits).read_bytes()
    time.sleep(1.1)
    assert write_image(tmp_path / "2" / name, img, bit_depth=bits).read_bytes() == first


def test_srgb_encode_matches_colour_science():
    """The numpy sRGB encoding equals colour-science's ``cctf_encoding(L, function='sRGB')`` (the reference)."""
    import colour

    lin = np.concatenate([np.linspace(-0.2, 1.5, 2001), [0.0, 0.0031308, 0.0031309, 1.0]]).astype(np.float32)
    lin = lin.reshape(-1, 5)
    expect = np.asarray(colour.cctf_encoding(lin, function="sRGB"), np.float32)
    np.testing.assert_array_equal(srgb_encode(lin), expect)


# ------------------------------------------------------------------------------------------- colour-space tags
def png_chunks(path) -> list[str]:
    """The chunk types of a PNG, in file order."""
    import struct

    b = open(path, "rb").read()
    pos, names = 8, []
    while pos < len(b):
        (n,) = struct.unpack(">I", b[pos:pos + 4])
        names.append(b[pos + 4:pos + 8].decode("ascii"))
        pos += 12 + n
    return names


def stored_colour_space(path) -> str | None:
    """The ``oiio:ColorSpace`` OpenImageIO reads back from ``path``."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    try:
        return inp.spec().getattribute("oiio:ColorSpace")
    finally:
        inp.close()


@pytest.mark.parametrize("colour,encode,chunks", [
    ("linear-srgb", True, {"sRGB", "cHRM", "gAMA"}),          # encoded here: sRGB primaries and curve
    ("srgb", False, {"sRGB", "cHRM", "gAMA"}),                # already encoded: still sRGB
    ("linear-srgb", False, {"gAMA"}),                         # linear: gamma 1.0, no sRGB claim
    ("camera", True, set()),                                  # camera primaries: no sRGB, cHRM or gAMA
    ("camera-srgb-curve", False, set()),
    ("camera", False, set()),
])
def test_png_colour_chunks_say_what_the_pixels_are(tmp_path, rgb, colour, encode, chunks):
    p = write_image(tmp_path / "a.png", rgb, bit_depth=16, encode_srgb=encode, colour=colour)
    assert {"sRGB", "cHRM", "gAMA"} & set(png_chunks(p)) == chunks


def test_untagged_and_encoded_default_keeps_srgb(tmp_path, rgb):
    """Without a colour state, an encoded image is sRGB as before."""
    p = write_image(tmp_path / "a.exr", rgb, bit_depth=32, encode_srgb=True)
    assert stored_colour_space(p) == "srgb_rec709_scene"


@pytest.mark.parametrize("colour,tag", [("camera", "unknown"), ("camera-srgb-curve", "unknown"),
                                        ("linear-srgb", "lin_rec709_scene"), ("srgb", "srgb_rec709_scene")])
def test_exr_colour_space_reads_back(tmp_path, rgb, colour, tag):
    p = write_image(tmp_path / "a.exr", rgb, bit_depth=32, colour=colour)
    assert stored_colour_space(p) == tag


@pytest.mark.parametrize("colour,encode,chunks", [("camera", True, {"sRGB", "cHRM", "gAMA"}),
                                                  ("camera", False, {"gAMA"})])
def test_grey_image_tag_follows_its_curve(tmp_path, colour, encode, chunks):
    """One channel has no primaries: a grey camera image is tagged by its tone curve alone."""
    grey = np.random.default_rng(2).random((6, 9)).astype(np.float32)
    p = write_image(tmp_path / "g.png", grey, bit_depth=16, encode_srgb=encode, colour=colour)
    assert {"sRGB", "cHRM", "gAMA"} & set(png_chunks(p)) == chunks


def test_unknown_colour_state_refused(tmp_path, rgb):
    with pytest.raises(ValueError, match="colour must be one of"):
        write_image(tmp_path / "a.png", rgb, bit_depth=8, colour="xyz")
    assert not (tmp_path / "a.png").exists()


def test_a_jpeg_cut_short_is_refused_not_filled(tmp_path):
    """OpenImageIO returns a truncated JPEG whole, its missing rows mid-grey (128), and only flags the error on the
    reader: a cut copy of a lenslet JPEG then failed self-calibration with 'the image is uniform (no lenslet
    pattern)'.  Now it is refused as truncated; the whole file still reads."""
    img = (np.random.default_rng(3).random((96, 128)) * 255).astype(np.uint8)
    whole = write_image(tmp_path / "whole.jpg", img, bit_depth=8)
    np.testing.assert_allclose(read_image(whole).astype(float).mean(), img.mean(), atol=2)
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    with pytest.raises(FormatError, match="ends early .*truncated"):
        read_image(cut)
