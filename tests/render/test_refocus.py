"""Refocusing: shift-sum against a direct reference, Fourier slice against shift-sum, sharpest slope = disparity,
slope 0 = mean of the views, apertures, upsampling, and the error paths."""

import functools

import numpy as np
import pytest
import scipy.ndimage as ndi

from plenodecode.errors import MetadataError
import plenodecode.render.shiftsum as shiftsum
import plenodecode.render.shiftsum_tiles as shiftsum_tiles
from plenodecode.render import REFOCUS_METHODS, focal_stack, refocus, sharpest_slope, shift_sum
from plenodecode.render.focalstack import gradient_energy
from plenodecode.render.fourier import FourierRefocuser
from plenodecode.types import LightField

# ----------------------------------------------------------------------------------------------------------
# analytic test scenes
# ----------------------------------------------------------------------------------------------------------


def _texture(shape, seed, sigma):
    """Band-limited random colour texture: spectrum of white noise times a Gaussian (blur sigma px)."""
    rng = np.random.default_rng(seed)
    spec = np.fft.fft2(rng.standard_normal((*shape, 3)), axes=(0, 1))
    ky = np.fft.fftfreq(shape[0])[:, None, None]
    kx = np.fft.fftfreq(shape[1])[None, :, None]
    return spec * np.exp(-2 * (np.pi * sigma) ** 2 * (ky**2 + kx**2)), ky, kx


def _shift(spec, ky, kx, dy, dx):
    """Exact sub-pixel translation of a periodic band-limited image: out(y, x) = img(y + dy, x + dx)."""
    return np.real(np.fft.ifft2(spec * np.exp(2j * np.pi * (ky * dy + kx * dx)), axes=(0, 1)))


@functools.lru_cache(maxsize=8)
def two_planes(n=9, shape=(64, 88), d_bg=-0.6, d_fg=0.8, rect=(18, 46, 48, 80), seed=0, sigma=1.5, weight=False):
    """Views of a textured background plane (disparity d_bg) behind a textured rectangle (d_fg).

    ``view[v, u](y, x) = plane(y + d (v - vc), x + d (u - uc))`` (design.md), with the rectangle (given in
    centre-view coordinates y0, y1, x0, x1) occluding the background.  Returns (LightField, disparity map);
    cached, so callers must not modify the arrays.
    """
    margin = 24
    big = (shape[0] + 2 * margin, shape[1] + 2 * margin)
    bg, ky, kx = _texture(big, seed, sigma)
    fg, _, _ = _texture(big, seed + 1, sigma)
    c = n // 2
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    data = np.empty((n, n, *shape, 3), np.float64)
    crop = (slice(margin, margin + shape[0]), slice(margin, margin + shape[1]))
    for v in range(n):
        for u in range(n):
            a, b = v - c, u - c
            back = _shift(bg, ky, kx, d_bg * a, d_bg * b)[crop]
            front = _shift(fg, ky, kx, d_fg * a, d_fg * b)[crop]
            ys, xs = yy + d_fg * a, xx + d_fg * b
            inside = (ys >= rect[0]) & (ys < rect[1]) & (xs >= rect[2]) & (xs < rect[3])
            data[v, u] = np.where(inside[..., None], front, back)
    data = (data - data.min()) / (data.max() - data.min())
    inside = (yy >= rect[0]) & (yy < rect[1]) & (xx >= rect[2]) & (xx < rect[3])
    disp = np.where(inside, d_fg, d_bg).astype(np.float32)
    w = None
    if weight:
        rng = np.random.default_rng(seed + 7)
        w = (0.3 + 0.7 * rng.random((n, n, *shape))).astype(np.float32)
    meta = {"spatial_step_px": 1.0, "view_step_px": 1.0, "disparity_range": [d_bg, d_fg]}
    return LightField(data.astype(np.float32), w, "linear-srgb", meta), disp


def psnr(a, b, border=0):
    sl = (slice(border, a.shape[0] - border), slice(border, a.shape[1] - border))
    err = np.mean((a[sl].astype(np.float64) - b[sl]) ** 2)
    return 10 * np.log10(1.0 / err)


def reference_shift_sum(lf, s, order=1, mask=None):
    """Direct weight-normalised shift-and-add with scipy.ndimage.shift (linear, edge values outside), views
    weighted by ``mask`` (V, U)."""
    nv, nu, ny, nx, nc = lf.shape
    vc, uc = lf.centre_index
    num = np.zeros((ny, nx, nc))
    den = np.zeros((ny, nx))
    for v in range(nv):
        for u in range(nu):
            m = 1.0 if mask is None else float(mask[v, u])
            if m == 0:
                continue
            sh = (s * (v - vc), s * (u - uc))
            w = np.ones((ny, nx)) if lf.weight is None else lf.weight[v, u].astype(np.float64)
            den += m * ndi.shift(w, sh, order=order, mode="nearest")
            for c in range(nc):
                num[..., c] += m * ndi.shift(lf.data[v, u, ..., c] * w, sh, order=order, mode="nearest")
    return num / den[..., None]


def keys_reference(lf, s, mask=None):
    """Weight-normalised shift-sum with Keys' cubic (a = -0.5), separable, edge values outside, views weighted by
    ``mask`` (V, U): an independent implementation."""
    nv, nu, ny, nx, nc = lf.shape
    vc, uc = lf.centre_index

    def keys(x):
        x = np.abs(x)
        return np.where(x <= 1, 1.5 * x**3 - 2.5 * x**2 + 1,
                        np.where(x < 2, -0.5 * x**3 + 2.5 * x**2 - 4 * x + 2, 0.0))

    def shift_axis(img, t, axis):
        n = img.shape[axis]
        pos = np.arange(n) - t                         # out[x] = img(x - t)
        out = 0
        for k in range(int(np.floor(pos.min())) - 2, int(np.ceil(pos.max())) + 3):
            w = keys(pos - k)
            if not np.any(w):
                continue
            idx = np.clip(np.full(n, k), 0, n - 1)
            shape = [1] * img.ndim
            shape[axis] = n
            out = out + np.take(img, idx, axis=axis) * w.reshape(shape)
        return out

    # the taps of one output pixel are the integers within 2 of its source position
    num = np.zeros((ny, nx, nc))
    den = np.zeros((ny, nx, 1))
    for v in range(nv):
        for u in range(nu):
            m = 1.0 if mask is None else float(mask[v, u])
            if m == 0:
                continue
            w = np.ones((ny, nx, 1)) if lf.weight is None else lf.weight[v, u, ..., None].astype(np.float64)
            img = shift_axis(np.concatenate([lf.data[v, u] * w, w], axis=-1), s * (u - uc), 1)
            img = shift_axis(img, s * (v - vc), 0)
            num += m * img[..., :nc]
            den += m * img[..., nc:]
    return num / den


# ----------------------------------------------------------------------------------------------------------
# shift-sum
# ----------------------------------------------------------------------------------------------------------


def test_registry_lists_both_methods_and_rejects_unknown():
    assert set(REFOCUS_METHODS) == {"shift-sum", "fourier-slice"}
    lf, _ = two_planes(n=3, shape=(12, 14))
    with pytest.raises(ValueError, match="method must be one of 'shift-sum', 'fourier-slice'"):
        refocus(lf, slope=0.0, method="nope")


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
def test_slope_zero_is_the_mean_of_the_views(method):
    lf, _ = two_planes(n=5, shape=(30, 40))
    mean = lf.data.mean(axis=(0, 1))
    out = refocus(lf, slope=0.0, method=method)
    tol = 1e-6 if method == "shift-sum" else 2e-3      # Fourier: gridding accuracy (~70 dB)
    np.testing.assert_allclose(out, mean, atol=tol)


def test_slope_zero_with_weights_is_the_weighted_mean():
    lf, _ = two_planes(n=5, shape=(30, 40), weight=True)
    w = lf.weight[..., None]
    expect = (lf.data * w).sum((0, 1)) / w.sum((0, 1))
    np.testing.assert_allclose(refocus(lf, slope=0.0), expect, atol=1e-6)
    np.testing.assert_allclose(refocus(lf, slope=0.0, method="fourier-slice"), expect, atol=3e-3)


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
def test_pixels_no_view_has_data_for_take_their_nearest_neighbour(method):
    """A decode's edge gaps (weight 0 in every view: the hex -> rect grid's alternate edge pixels) were written
    0, black dots along the photograph's edge; a pixel with less than MIN_APERTURE_SHARE of the aperture's
    weight takes its nearest neighbour's value, the others keep the weighted mean."""
    lf, _ = two_planes(n=5, shape=(30, 40), weight=True)
    weight = lf.weight.copy()
    weight[:, :, 0, ::2] = 0.0                 # top row: alternate pixels without data in every view
    weight[:, :, :, -1] *= 0.05                # right column: 5 % of the weight (a lens half off the sensor)
    holed = lf.replace(data=lf.data * (weight[..., None] > 0), weight=weight)
    out = refocus(holed, slope=0.0, method=method)
    w = weight[..., None]
    expect = (lf.data * w).sum((0, 1)) / np.maximum(w.sum((0, 1)), 1e-12)
    tol = 1e-6 if method == "shift-sum" else 3e-3
    np.testing.assert_allclose(out[1:, :-1], expect[1:, :-1], atol=tol)
    for x in range(2, 38, 2):                  # each gap: one of its nearest neighbours (left, right, below)
        assert min(np.abs(out[0, x] - expect[y, xx]).max() for y, xx in ((0, x - 1), (0, x + 1), (1, x))) < tol
    np.testing.assert_allclose(out[1:, -1], expect[1:, -2], atol=tol)


@pytest.mark.parametrize("s", [0.45, -1.3, 2.6, 7.0])
@pytest.mark.parametrize("weighted", [False, True])
def test_linear_shift_sum_equals_direct_reference(s, weighted):
    rng = np.random.default_rng(1)
    data = rng.random((5, 7, 18, 23, 3), dtype=np.float32)
    w = rng.random((5, 7, 18, 23), dtype=np.float32) + 0.1 if weighted else None
    lf = LightField(data, w)
    out = shift_sum(lf, [s], interp="linear")[0]
    np.testing.assert_allclose(out, reference_shift_sum(lf, s), atol=2e-6)


@pytest.mark.parametrize("s", [0.3, -1.7])
def test_cubic_shift_sum_equals_keys_reference(s):
    data = np.random.default_rng(2).random((5, 5, 16, 21, 3), dtype=np.float32)
    lf = LightField(data)
    np.testing.assert_allclose(shift_sum(lf, s)[0], keys_reference(lf, s), atol=2e-6)


def test_many_slopes_in_one_pass_equal_one_at_a_time():
    lf, _ = two_planes(n=5, shape=(24, 30), weight=True)
    slopes = [-1.1, 0.0, 0.37, 1.9]
    stack = shift_sum(lf, slopes)
    for i, s in enumerate(slopes):
        np.testing.assert_array_equal(stack[i], shift_sum(lf, s)[0])


@pytest.mark.parametrize("interp", ["linear", "cubic"])
@pytest.mark.parametrize("weighted", [False, True])
@pytest.mark.parametrize("slopes", [[-2.3, -0.45, 0.0, 0.8, 3.1], [-0.3, 0.2, 0.25]])
def test_tiles_and_slope_groups_do_not_change_the_photographs(monkeypatch, interp, weighted, slopes):
    """The compiled kernel: tiny tiles (partial ones at the borders, shifts reaching across several tiles; with small slopes, inner
    tiles read the light field in place) and groups of 2 slopes give the reference photographs, and exactly the
    same numbers as one tile."""
    rng = np.random.default_rng(5)
    data = rng.random((5, 7, 33, 38, 3), dtype=np.float32)
    w = rng.random((5, 7, 33, 38), dtype=np.float32) + 0.1 if weighted else None
    lf = LightField(data, w)
    monkeypatch.setattr(shiftsum, "_TILED_MIN_SLOPES", 1)             # the compiled tiled kernel
    whole = shift_sum(lf, slopes, interp=interp)
    monkeypatch.setattr(shiftsum_tiles, "_ROWS", 5)
    monkeypatch.setattr(shiftsum_tiles, "_COLS", 7)
    monkeypatch.setattr(shiftsum_tiles, "_EDGE_COLS", 3)
    monkeypatch.setattr(shiftsum_tiles, "_ACC_BYTES", 2 * 4 * 5 * 12 * 4)   # two slopes per group
    tiled = shift_sum(lf, slopes, interp=interp)
    np.testing.assert_array_equal(tiled, whole)
    for i, s in enumerate(slopes):
        ref = reference_shift_sum(lf, s) if interp == "linear" else keys_reference(lf, s)
        np.testing.assert_allclose(tiled[i], ref, atol=2e-6)


@pytest.mark.parametrize("interp", ["linear", "cubic"])
@pytest.mark.parametrize("weighted", [False, True])
def test_opencv_photographs_equal_the_compiled_focal_stack(monkeypatch, interp, weighted):
    """A focal stack (compiled tiled kernel) and the same slopes one photograph at a time (OpenCV) agree to float32
    rounding, with large shifts, a fractional aperture mask and a weight; a one-pixel shift error or a tap applied
    to the wrong view would differ by ~0.1."""
    rng = np.random.default_rng(9)
    data = rng.random((5, 7, 29, 41, 3), dtype=np.float32)
    w = rng.random((5, 7, 29, 41), dtype=np.float32) + 0.1 if weighted else None
    lf = LightField(data, w)
    mask = np.ones((5, 7), np.float32)
    mask[:, 2] = 0
    mask[1, 5] = 0.25
    slopes = np.array([-3.4, -1.25, -0.5, 0.0, 0.3, 0.77, 1.6, 4.2])
    assert len(slopes) >= shiftsum._TILED_MIN_SLOPES
    stack = shift_sum(lf, slopes, aperture=mask, interp=interp)
    for i, s in enumerate(slopes):
        one = shift_sum(lf, s, aperture=mask, interp=interp)[0]
        np.testing.assert_allclose(one, stack[i], atol=1e-6)
    monkeypatch.setattr(shiftsum, "_TILED_MIN_SLOPES", 100)
    np.testing.assert_allclose(shift_sum(lf, slopes, aperture=mask, interp=interp), stack, atol=1e-6)
    # a light field of _TILED_MIN_SAMPLES samples or more: one photograph through the kernel, as in the stack
    monkeypatch.setattr(shiftsum, "_TILED_MIN_SAMPLES", data[..., 0].size)
    np.testing.assert_array_equal(shift_sum(lf, slopes[2], aperture=mask, interp=interp)[0], stack[2])


@pytest.mark.parametrize("interp", ["linear", "cubic"])
def test_aperture_masks_with_empty_view_columns(interp):
    """Views are processed in pairs per view column: odd counts, empty columns and fractional weights."""
    data = np.random.default_rng(6).random((5, 6, 17, 19, 3), dtype=np.float32)
    lf = LightField(data)
    mask = np.ones((5, 6), np.float32)
    mask[:, 1] = 0                        # an empty view column
    mask[1:4, 4] = 0                      # a column with 2 views
    mask[0, 0] = 0                        # a column with 4 views
    mask[2, 5] = 0.5                      # a fractional weight
    for s in (-1.3, 0.6):
        out = shift_sum(lf, s, aperture=mask, interp=interp)[0]
        ref = reference_shift_sum(lf, s, mask=mask) if interp == "linear" else keys_reference(lf, s, mask=mask)
        np.testing.assert_allclose(out, ref, atol=2e-6)


def test_default_bicubic_keeps_the_focus_accurate():
    """The default (Keys bicubic) shift-sum finds the disparity of both planes of the analytic scenes within
    0.01 px/view (measured <= 0.0072); bilinear interpolation is off by up to 0.13 on the same regions."""
    bg = (slice(4, 14), slice(6, 40))
    fg = (slice(24, 40), slice(54, 74))
    for d_bg, d_fg in [(-0.6, 0.8), (0.13, 1.37)]:
        lf, _ = two_planes(d_bg=d_bg, d_fg=d_fg)
        assert abs(sharpest_slope(lf, region=bg) - d_bg) < 0.01
        assert abs(sharpest_slope(lf, region=fg) - d_fg) < 0.01


def test_render_modules_do_not_shadow_the_refocus_function():
    import importlib
    import types

    import plenodecode.render as render

    assert isinstance(render.refocus, types.FunctionType)
    for name in ("refocus_methods", "shiftsum", "fourier", "alpha", "focalstack", "viewpoints"):
        assert isinstance(importlib.import_module(f"plenodecode.render.{name}"), types.ModuleType)
    assert importlib.import_module("plenodecode.render.refocus_methods").refocus is render.refocus
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("plenodecode.render.refocus")


def test_upsampling_samples_the_photograph_between_pixels():
    rng = np.random.default_rng(3)
    lf = LightField(rng.random((3, 5, 12, 15, 1), dtype=np.float32))
    k, s = 3, 0.6
    up = shift_sum(lf, s, upsample=k, interp="linear")[0]
    assert up.shape == (36, 45, 1)
    np.testing.assert_array_equal(up[::k, ::k], shift_sum(lf, s, interp="linear")[0])
    # phase (1, 2): the photograph at (y + 1/3, x + 2/3) = mean of views shifted by (s a - 1/3, s b - 2/3)
    expect = np.zeros((12, 15))
    for v in range(3):
        for u in range(5):
            expect += ndi.shift(lf.data[v, u, ..., 0].astype(np.float64), (s * (v - 1) - 1 / 3, s * (u - 2) - 2 / 3),
                                order=1, mode="nearest")
    np.testing.assert_allclose(up[1::k, 2::k, 0], expect / 15, atol=2e-6)


def test_input_is_not_modified():
    lf, _ = two_planes(n=5, shape=(20, 24), weight=True)
    before, wbefore = lf.data.copy(), lf.weight.copy()
    refocus(lf, slope=0.7)
    refocus(lf, slope=0.7, method="fourier-slice")
    np.testing.assert_array_equal(lf.data, before)
    np.testing.assert_array_equal(lf.weight, wbefore)


# ----------------------------------------------------------------------------------------------------------
# accuracy on the analytic scene
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
@pytest.mark.parametrize("d_bg, d_fg", [(-0.6, 0.8), (0.13, 1.37)])
def test_sharpest_slope_is_the_disparity(method, d_bg, d_fg):
    lf, _ = two_planes(d_bg=d_bg, d_fg=d_fg)
    bg = (slice(4, 14), slice(6, 40))          # background only (and clear of the front rectangle's shifts)
    fg = (slice(24, 40), slice(54, 74))        # inside the front rectangle
    assert abs(sharpest_slope(lf, region=bg, method=method) - d_bg) < 0.05
    assert abs(sharpest_slope(lf, region=fg, method=method) - d_fg) < 0.05


def test_photograph_at_the_disparity_reproduces_the_centre_view():
    lf, disp = two_planes(d_bg=-0.45, d_fg=0.8)
    centre = lf.centre_view()
    photo = refocus(lf, slope=-0.45)
    bg = ndi.binary_erosion(disp == np.float32(-0.45), iterations=7)   # clear of the front plane in every view
    inner = np.zeros_like(bg)
    inner[6:-6, 6:-6] = True
    err = np.abs(photo - centre)[bg & inner]
    assert np.sqrt(np.mean(err**2)) < 0.01                       # sharp where in focus
    assert np.sqrt(np.mean((refocus(lf, slope=0.8) - centre)[bg & inner] ** 2)) > 0.05   # blurred where not


@pytest.mark.parametrize("s", [-0.6, 0.1, 0.55, 0.8, 1.2])
def test_fourier_slice_agrees_with_shift_sum(s):
    lf, _ = two_planes()
    ref = FourierRefocuser(lf, max_slope=1.5)
    assert psnr(ref.photograph(s), refocus(lf, slope=s), border=6) >= 35.0


def test_fourier_slice_has_no_wraparound_ghosts():
    # a bright block at the right edge only; a large slope shifts outer views' content across the border.
    data = np.zeros((7, 7, 40, 48, 1), np.float32)
    data[:, :, 12:28, 40:48] = 1.0
    lf = LightField(data)
    for s in (2.0, -2.0):
        photo = FourierRefocuser(lf, max_slope=2.0).photograph(s)
        assert np.abs(photo[:, :12]).max() < 2e-3                # nothing appears at the opposite edge
        assert psnr(photo, refocus(lf, slope=s), border=0) >= 35.0


def test_fourier_transform_is_reused_when_passed(monkeypatch):
    """No module cache: a transform built once is passed explicitly (refocuser=) and checked against the call."""
    from plenodecode.render import fourier

    lf, _ = two_planes(n=5, shape=(24, 30))
    a = FourierRefocuser(lf)
    built = []
    monkeypatch.setattr(fourier, "FourierRefocuser", lambda *args, **kw: built.append(1) or a)
    stack = focal_stack(lf, [-0.5, 0.5], method="fourier-slice", refocuser=a)
    photo = refocus(lf, slope=0.5, method="fourier-slice", refocuser=a)
    assert built == []                                           # the focal stack and refocus used the same transform
    np.testing.assert_array_equal(stack[1], photo)
    focal_stack(lf, [-0.5, 0.5], method="fourier-slice")
    assert built == [1]                                          # without it, one transform per call
    other = LightField(lf.data[:, :, :20].copy())
    with pytest.raises(ValueError, match="refocuser was built for a light field of shape"):
        refocus(other, slope=0.5, method="fourier-slice", refocuser=a)
    with pytest.raises(ValueError, match="refocuser covers"):
        refocus(lf, slope=a.max_slope + 1, method="fourier-slice", refocuser=a)
    with pytest.raises(ValueError, match="aperture"):
        refocus(lf, slope=0.5, method="fourier-slice", refocuser=a, aperture=0.5)
    with pytest.raises(ValueError, match="oversample"):
        refocus(lf, slope=0.5, method="fourier-slice", refocuser=a, oversample=2.0)


def test_fourier_weighted_matches_shift_sum():
    lf, _ = two_planes(weight=True)
    for s in (-0.6, 0.8):
        assert psnr(refocus(lf, slope=s, method="fourier-slice"), refocus(lf, slope=s), border=6) >= 35.0


def test_fourier_upsampling_matches_shift_sum_upsampling():
    lf, _ = two_planes(n=5, shape=(32, 40), sigma=2.0)
    a = refocus(lf, slope=0.4, method="fourier-slice", upsample=2)
    b = refocus(lf, slope=0.4, upsample=2)
    assert a.shape == b.shape == (64, 80, 3)
    assert psnr(a, b, border=10) >= 35.0


# ----------------------------------------------------------------------------------------------------------
# synthetic aperture
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["shift-sum", "fourier-slice"])
def test_smaller_aperture_sharpens_a_defocused_region(method):
    lf, _ = two_planes()
    bg = (slice(4, 14), slice(6, 40))
    energy = [gradient_energy(refocus(lf, slope=0.8, method=method, aperture=r))[bg].mean() for r in (1.0, 0.5, 0.2)]
    assert energy[0] < 0.8 * energy[1] and energy[1] < 0.8 * energy[2]
    # a mask with only the centre view is the centre view at any slope
    mask = np.zeros(lf.shape[:2], bool)
    mask[4, 4] = True
    one_view = refocus(lf, slope=0.8, method=method, aperture=mask)
    if method == "shift-sum":
        np.testing.assert_allclose(one_view, lf.centre_view(), atol=1e-6)
    else:                                     # the gridding error of a single view is not averaged out
        assert psnr(one_view, lf.centre_view()) > 50.0


def test_aperture_arguments_are_checked():
    lf, _ = two_planes(n=3, shape=(10, 12))
    for bad in (0.0, 1.5, -0.2, True):
        with pytest.raises(ValueError, match="aperture"):
            refocus(lf, slope=0.0, aperture=bad)
    with pytest.raises(ValueError, match="aperture mask"):
        refocus(lf, slope=0.0, aperture=np.ones((2, 2), bool))


# ----------------------------------------------------------------------------------------------------------
# arguments and errors
# ----------------------------------------------------------------------------------------------------------


def test_exactly_one_of_slope_and_alpha():
    lf, _ = two_planes(n=3, shape=(10, 12))
    with pytest.raises(ValueError, match="exactly one"):
        refocus(lf)
    with pytest.raises(ValueError, match="exactly one"):
        refocus(lf, slope=0.1, alpha=1.0)


def test_alpha_without_camera_metadata_names_the_missing_constant():
    lf, _ = two_planes(n=3, shape=(10, 12))
    with pytest.raises(MetadataError, match="focal_length_m"):
        refocus(lf, alpha=1.01)


def test_bad_arguments_name_the_parameter():
    lf, _ = two_planes(n=3, shape=(10, 12))
    with pytest.raises(ValueError, match="upsample"):
        refocus(lf, slope=0.1, upsample=0)
    with pytest.raises(ValueError, match="interp"):
        refocus(lf, slope=0.1, interp="sinc")
    with pytest.raises(ValueError, match="lf"):
        refocus(lf.data, slope=0.1)


# ----------------------------------------------------------------------------------------------------------
# focus at a point of the picture, or at a distance
# ----------------------------------------------------------------------------------------------------------
#: Three fronto-parallel planes of a generated Illum scene (57 x 72 decoded): (a point inside, disparity).
PLANES = (((28, 14), 0.3), ((28, 57), 0.8), ((28, 40), -0.6))


@functools.lru_cache(maxsize=1)
def generated_scene():
    """The generator's exact light field and the decoded raw of background (-0.6), rectangle (0.3), disk (0.8)."""
    import plenodecode as pd
    from plenodecode.synthetic.scene import Plane

    scene = [Plane(d0=-0.6, support=("all",), depth_order=2, texture_seed=1),
             Plane(d0=0.3, support=("rect", 8, 4, 48, 24), depth_order=1, texture_seed=2),
             Plane(d0=0.8, support=("disk", 28, 57, 10), depth_order=0, texture_seed=3)]
    sim = pd.simulate("illum-mini", seed=0, noise=False, shape=(700, 900), scene=scene)
    return sim.ground_truth_lightfield(), pd.decode(sim.raw, sim.grid, white=sim.white)


@pytest.mark.parametrize("which", ["truth", "decoded"])
def test_focus_at_a_point_of_each_plane_chooses_its_disparity(which):
    from plenodecode.render.refocus_methods import slope_at

    lf = generated_scene()[which == "decoded"]
    for point, disparity in PLANES:
        assert slope_at(lf, point) == pytest.approx(disparity, abs=0.03), point        # depth map, 7 x 7 median
        # without depth: the sharpest slice of a small focal stack (biased a little by the neighbouring planes)
        assert slope_at(lf, point, at_method="sharpness") == pytest.approx(disparity, abs=0.06), point
    y, x = PLANES[1][0]
    np.testing.assert_array_equal(refocus(lf, at=(y, x)), refocus(lf, slope=slope_at(lf, (y, x))))


def test_focus_distance_gives_the_plane_at_that_distance():
    from dataclasses import replace

    from plenodecode.render.alpha import slope_to_distance
    from plenodecode.render.refocus_methods import focus_slope

    truth, _ = generated_scene()
    lf = truth.replace(geometry=replace(truth.geometry, focus_distance_m=1.5))
    for _, disparity in PLANES:
        z = slope_to_distance(disparity, lf)
        assert focus_slope(lf, distance_m=z) == pytest.approx(disparity, abs=1e-9)
    disk_z = slope_to_distance(0.8, lf)
    assert disk_z < 1.5                                   # the front disk is nearer than the focus plane
    np.testing.assert_array_equal(refocus(lf, distance_m=disk_z), refocus(lf, slope=focus_slope(lf, distance_m=disk_z)))
    with pytest.raises(MetadataError, match="focus"):
        refocus(truth, distance_m=1.0)                    # no focus distance in its geometry


def test_focus_arguments_are_checked():
    lf, _ = two_planes(n=3, shape=(10, 12))
    with pytest.raises(ValueError, match="exactly one"):
        refocus(lf, slope=0.1, at=(2, 3))
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ValueError, match="slope"):
            refocus(lf, slope=bad)
    with pytest.raises(ValueError, match="at = "):
        refocus(lf, at=(20, 3))
    with pytest.raises(ValueError, match="at_method"):
        refocus(lf, at=(2, 3), at_method="guess")


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("slopes", [0.3, np.linspace(-1, 1, 9)])
def test_progress_counts_up_to_its_total_on_both_paths(monkeypatch, threads, slopes):
    """OpenCV path (one slope; one or two threads) and compiled focal stack (9 slopes): steps 1..total, upsampled
    too, and the photographs do not depend on OpenCV's thread count beyond float32 rounding."""
    import cv2

    lf, _ = two_planes(n=5, shape=(20, 26))
    before = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    try:
        for k in (1, 2):
            calls = []
            out = shift_sum(lf, slopes, upsample=k, progress=lambda d, t: calls.append((d, t)))
            total = calls[-1][1]
            assert [d for d, _ in calls] == list(range(1, total + 1)) and total == 4 * k * k
        cv2.setNumThreads(1)
        np.testing.assert_allclose(out, shift_sum(lf, slopes, upsample=2), atol=1e-6)
    finally:
        cv2.setNumThreads(before)


def test_photograph_does_not_depend_on_the_opencv_thread_count():
    """Batch workers run with one OpenCV thread, the command line with all: the same photograph, bit for bit."""
    import cv2

    from plenodecode.render import refocus

    rng = np.random.default_rng(0)
    lf = LightField(data=rng.random((9, 9, 40, 50, 3), dtype=np.float32))
    before = cv2.getNumThreads()
    try:
        images = []
        for threads in (1, 2, 3):
            cv2.setNumThreads(threads)
            images.append(np.asarray(refocus(lf, slope=0.37)))
    finally:
        cv2.setNumThreads(before)
    assert all(np.array_equal(images[0], image) for image in images[1:])
