"""The shared low-level image operations against simple references."""

import cv2
import numpy as np
import pytest

from plenodecode.imaging import INTERPOLATION_TAPS, interpolation_taps, remap_view, shift_view


def _keys_reference(s: float, a: float = -0.5) -> float:
    """Keys (1981) eq. (15), written directly from the paper for one scalar."""
    s = abs(s)
    if s <= 1:
        return (a + 2) * s**3 - (a + 3) * s**2 + 1
    if s < 2:
        return a * s**3 - 5 * a * s**2 + 8 * a * s - 4 * a
    return 0.0


@pytest.mark.parametrize("interp", list(INTERPOLATION_TAPS))
def test_interpolation_taps_match_the_kernel(interp):
    rng = np.random.default_rng(3)
    t = np.concatenate([rng.uniform(-20, 20, 500), np.arange(-3, 3, 0.5)])
    first, w = interpolation_taps(t, interp)
    assert w.shape == (len(t), INTERPOLATION_TAPS[interp]) and w.dtype == np.float32
    for k in range(len(t)):
        for j in range(w.shape[1]):
            pos = first[k] + j                        # tap position relative to x
            ref = _keys_reference(t[k] - pos) if interp == "cubic" else max(0.0, 1.0 - abs(t[k] - pos))
            assert w[k, j] == pytest.approx(ref, abs=1e-7)
    np.testing.assert_allclose(w.sum(-1), 1.0, atol=1e-6)


@pytest.mark.parametrize("interp", list(INTERPOLATION_TAPS))
def test_interpolation_taps_are_exact_at_integers_and_reproduce_quadratics(interp):
    first, w = interpolation_taps(np.arange(-4.0, 5.0), interp)
    rows = np.arange(len(first))
    hit = first - np.arange(-4, 5)                   # tap index that falls on the sample itself
    assert np.all(w[rows, -hit] == 1.0) and np.all(np.abs(w).sum(-1) == 1.0)
    # sampling x**2 at x + t: linear is exact for lines, cubic (a = -0.5) for quadratics
    t = np.linspace(-2, 2, 41)
    first, w = interpolation_taps(t, interp)
    pos = first[:, None] + np.arange(w.shape[1])
    f = (lambda x: 3 * x - 1) if interp == "linear" else (lambda x: x**2 - 2 * x)
    np.testing.assert_allclose((w * f(pos)).sum(-1), f(t), atol=1e-5)


def test_interpolation_taps_reject_unknown_kernels():
    with pytest.raises(ValueError, match="interp must be one of linear, cubic"):
        interpolation_taps(np.zeros(2), "lanczos")


def test_shift_view_follows_the_disparity_convention():
    rng = np.random.default_rng(4)
    img = rng.random((20, 24, 3)).astype(np.float32)
    # d = 2, view offset (1, -1): out(y, x) = img(y - 2, x + 2), edge values outside
    out = shift_view(img, 2.0, 1.0, -1.0)
    ys = np.clip(np.arange(20) - 2, 0, 19)
    xs = np.clip(np.arange(24) + 2, 0, 23)
    np.testing.assert_array_equal(out, img[ys][:, xs])
    # a fractional shift is the bilinear mix of its two integer neighbours
    half = shift_view(img, 0.5, 0.0, 1.0)
    ref = 0.5 * (img + img[:, np.clip(np.arange(24) - 1, 0, 23)])
    np.testing.assert_allclose(half, ref, atol=2e-3)     # OpenCV's 5-bit fixed-point weights


def test_remap_view_is_shift_view_for_a_constant_disparity():
    rng = np.random.default_rng(5)
    img = rng.random((16, 18)).astype(np.float32)
    grid = np.mgrid[0:16, 0:18].astype(np.float32)
    d = np.full((16, 18), 1.25, np.float32)
    for flag in (cv2.INTER_LINEAR, cv2.INTER_CUBIC):
        np.testing.assert_allclose(remap_view(img, d, -1.0, 2.0, grid, flag), shift_view(img, 1.25, -1.0, 2.0, flag),
                                   atol=1e-5)


def test_fill_gaps_takes_the_nearest_known_pixel_up_to_the_depth_and_leaves_deeper_holes():
    from plenodecode.imaging import fill_gaps

    image = np.arange(8 * 10 * 2, dtype=np.float32).reshape(8, 10, 2)
    known = np.ones((8, 10), bool)
    known[0, ::2] = False                      # a 1 px edge gap (the hex -> rect grid's alternate pixels)
    known[:, 0] = False                        # a column with no lens
    known[3:8, 6:10] = False                   # a 5 x 4 hole: its inner pixels are more than 2 px from data
    out = fill_gaps(image, known, depth=2.0)
    np.testing.assert_array_equal(out[known], image[known])
    assert any(np.array_equal(out[0, 4], image[y, x]) for y, x in ((0, 3), (0, 5), (1, 4)))   # 1 px away
    np.testing.assert_array_equal(out[5, 0], image[5, 1])        # nearest known: to the right
    np.testing.assert_array_equal(out[5, 7], image[5, 5])        # 2 px right of the hole's left edge
    np.testing.assert_array_equal(out[7, 9], image[7, 9])        # 4 px deep: left as it was
    assert fill_gaps(image, np.zeros((8, 10), bool)) is image and fill_gaps(image, np.ones((8, 10), bool)) is image


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
@pytest.mark.parametrize("channels", [6, 7])
def test_warps_of_more_than_four_channels_equal_the_warps_of_each_channel(interpolation, channels):
    """OpenCV refuses cubic warps of more than 4 channels ('Unknown interpolation method': the colour depth views
    with their contrast channels beside them, 6, crashed the refinement of estimate_depth(grey=False)) and rounds
    the positions of bilinear ones to 1/32 px (up to 0.02 off here).  Both warps now give each channel what it gets
    alone, and the bilinear shift is the exact interpolation."""
    import cv2

    from plenodecode.imaging import remap_view, shift_view

    flag = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC}[interpolation]
    rng = np.random.default_rng(3)
    img = rng.random((17, 23, channels), dtype=np.float32)
    disparity = rng.uniform(-1.5, 1.5, (17, 23)).astype(np.float32)
    grid = tuple(np.mgrid[0:17, 0:23].astype(np.float32))
    shifted = shift_view(img, 0.7, -2.0, 1.0, flag)
    remapped = remap_view(img, disparity, 1.0, -3.0, grid, flag)
    assert shifted.shape == remapped.shape == img.shape
    if interpolation == "linear":      # out(y, x) = img(y + 1.4, x - 0.7), exactly
        from scipy import ndimage

        yy, xx = np.mgrid[0:17, 0:23].astype(float)
        for c in range(channels):
            exact = ndimage.map_coordinates(img[..., c].astype(float), [yy + 1.4, xx - 0.7], order=1, mode="nearest")
            assert np.abs(shifted[:15, 1:, c] - exact[:15, 1:]).max() < 1e-5
    for c in range(channels):
        np.testing.assert_array_equal(shifted[..., c], shift_view(np.ascontiguousarray(img[..., c]), 0.7, -2.0, 1.0,
                                                                  flag))
        np.testing.assert_array_equal(remapped[..., c], remap_view(np.ascontiguousarray(img[..., c]), disparity, 1.0,
                                                                   -3.0, grid, flag))
