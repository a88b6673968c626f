"""Unit tests of the decoding steps on small hand-made inputs with exact answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plenodecode.decoding import devignette as dv
from plenodecode.decoding.demosaic import DEMOSAIC_METHODS, demosaic
from plenodecode.decoding.resample import hex_taps, hex_to_rect, output_shape, row_taps
from plenodecode.decoding.slice import lens_labels, plan_bands, safe_radius, sample_lenses, view_offsets
from plenodecode.types import LensletGrid, cfa_channel_map


def hex_grid(h=120, w=160, pitch=10.0, rotation=0.0, origin=(5.3, 4.7)) -> LensletGrid:
    rs = pitch * math.sqrt(3) / 2
    rows = int((h - origin[0]) // rs) + 1
    cols = int((w - origin[1] - pitch / 2) // pitch) + 1
    return LensletGrid("hex", pitch, rs, rotation, origin, (rows, cols), 0.5, (h, w), 0.46 * pitch)


# -- levels, hot pixels, devignetting ---------------------------------------------------------
def test_normalise_per_cfa_position_and_dark():
    black = np.array([[10.0, 20.0], [30.0, 40.0]])
    white = np.array([[110.0, 220.0], [330.0, 440.0]])
    m = np.tile((black + 0.5 * (white - black)).astype(np.uint16), (3, 4))
    out = dv.normalise(m, black, white)
    np.testing.assert_allclose(out, 0.5, atol=1e-6)
    dark = np.full(m.shape, 5.0)
    out2 = dv.normalise(m, black, white, dark=dark)
    np.testing.assert_allclose(out2, (m - 5.0) / np.tile(white - black, (3, 4)), rtol=1e-6)


def test_normalise_is_the_level_formula_and_matches_raw_capture():
    from plenodecode.types import RawCapture

    rng = np.random.default_rng(11)
    m = rng.integers(0, 4096, (13, 17)).astype(np.uint16)
    black = np.array([[64.25, 65.0], [63.5, 64.0]])
    white = np.array([[4095.0, 4000.5], [3999.75, 4095.0]])
    gains = np.array([[1.0, 0.9], [1.1, 1.25]])
    got = dv.normalise(m, black, white)
    np.testing.assert_array_equal(got, RawCapture(m, "RGGB", black, white).normalised())
    tile = np.tile(gains / (white - black), (7, 9))[:13, :17]
    ref = (m - np.tile(black, (7, 9))[:13, :17]) * tile
    np.testing.assert_allclose(dv.normalise(m, black, white, gains=gains), ref, rtol=1e-6)


def test_hot_pixels_found_and_repaired_without_touching_structure():
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:64, 0:80]
    # lenslet-like structure: bright disks on a dark background, smooth inside
    img = (0.6 + 0.2 * np.sin(xx / 7.0)) * ((((yy % 10) - 4.5) ** 2 + ((xx % 10) - 4.5) ** 2) < 16)
    img = img.astype(np.float32) + rng.normal(0, 0.005, img.shape).astype(np.float32)
    hot = img.copy()
    # inside the disks, where the decoder reads (gap pixels are masked out by the white anyway)
    cand = np.argwhere(img > 0.3)
    picked: list = []
    for k in rng.permutation(len(cand)):              # 30 pixels, no two within 2 px
        if all(np.abs(cand[k] - q).max() > 2 for q in picked):
            picked.append(cand[k])
        if len(picked) == 30:
            break
    ys, xs = np.array(picked).T
    hot[ys, xs] += 0.8
    found = dv.find_hot_pixels(hot)
    assert found[ys, xs].all()
    assert found.sum() == len(set(zip(ys.tolist(), xs.tolist())))
    fixed, n = dv.repair_hot_pixels(hot)
    assert n == found.sum()
    assert np.abs(fixed[ys, xs] - img[ys, xs]).max() < 0.3          # back to the neighbourhood level
    untouched = ~found
    np.testing.assert_array_equal(fixed[untouched], hot[untouched])
    assert dv.repair_hot_pixels(img)[1] == 0                           # clean data: nothing changed


def _repair_reference(x, flags):
    """The repair rule written out with np.median, pixel by pixel (the kernel's specification)."""
    out = x.copy()
    counts = set()
    h, w = x.shape
    for y, xx in zip(*np.nonzero(flags)):
        vals = [x[y + dy, xx + dx] for dy in (-2, 0, 2) for dx in (-2, 0, 2)
                if (dy or dx) and 0 <= y + dy < h and 0 <= xx + dx < w and not flags[y + dy, xx + dx]]
        lit = [v for v in vals if v >= 0.5 * max(vals)] if vals else []
        out[y, xx] = np.float32(np.median(np.array(lit, np.float32))) if lit else 0.0
        counts.add(len(lit))
    return out, counts


def test_hot_pixel_repair_is_the_median_of_the_lit_neighbours():
    # dense hot pixels and dark patches: every count of lit neighbours (0..8, even and odd), image borders
    rng = np.random.default_rng(3)
    x = rng.random((48, 56)).astype(np.float32)
    x[rng.random(x.shape) < 0.15] *= np.float32(0.1)            # dark neighbours, left out by the half rule
    x[rng.random(x.shape) < 0.02] = 0.37                        # ties
    flags = rng.random(x.shape) < 0.2
    flags[20:25, 30:35] = True                                  # (22, 32): no neighbour left
    out = np.empty_like(x)
    dv._repair(x, flags, out)
    expected, counts = _repair_reference(x, flags)
    np.testing.assert_array_equal(out, expected)
    assert {0, 1, 2, 3, 4, 5, 6} <= counts


def _hot_reference(x, threshold=0.1, relative=0.5):
    """find_hot_pixels' rule pixel by pixel: x > m + max(threshold, relative m), m = max of the same-colour ring."""
    h, w = x.shape
    flags = np.zeros(x.shape, bool)
    for y in range(h):
        for xx in range(w):
            ring = [x[y + dy, xx + dx] for dy in (-2, 0, 2) for dx in (-2, 0, 2)
                    if (dy or dx) and 0 <= y + dy < h and 0 <= xx + dx < w]
            if ring:
                m = np.float32(max(ring))
                flags[y, xx] = x[y, xx] > m + max(np.float32(threshold), np.float32(relative) * m)
    return flags


@pytest.mark.parametrize("shape", [(1, 1), (2, 3), (3, 3), (1, 9), (4, 4), (23, 31)])
def test_hot_pixel_rule_at_borders_and_in_tiny_images(shape):
    # the ring maximum is taken over the neighbours inside the image; a pixel without any is never hot
    rng = np.random.default_rng(5)
    x = (rng.random(shape) * 0.5).astype(np.float32)
    x[rng.random(shape) < 0.3] += np.float32(0.9)               # hot candidates, many on the border
    expected = _hot_reference(x)
    np.testing.assert_array_equal(dv.find_hot_pixels(x), expected)
    assert dv.repair_hot_pixels(x)[1] == expected.sum()
    if shape == (23, 31):
        assert expected[[0, -1]].any() and expected[:, [0, -1]].any() and expected.sum() > 10


def test_relative_white_and_devignette_exact():
    yy, xx = np.mgrid[0:60, 0:60]
    disk = np.clip(5.0 - np.hypot((yy % 12) - 5.5, (xx % 12) - 5.5), 0, 1)
    vignette = 1.0 - 0.3 * ((yy - 30) ** 2 + (xx - 30) ** 2) / 1800.0
    gains = np.tile(np.array([[0.9, 0.7], [0.5, 0.8]]), (30, 30))     # channel scales of a real white
    white = (disk * vignette * gains).astype(np.float32)
    scene = (0.2 + 0.5 * np.cos(xx / 9.0) ** 2).astype(np.float32)
    raw = scene * white
    rel = dv.relative_white(white, "RGGB", window=14)
    assert rel.max() <= 1.0 and rel[disk > 0.99].min() > 0.9      # peak of each lens ~1, channel scale removed
    out = dv.devignette(raw, white, rel, floor=0.05)
    ok = rel >= 0.05
    np.testing.assert_allclose(out[ok], scene[ok], rtol=1e-5)
    assert np.isnan(out[~ok]).all()


# -- demosaicing ---------------------------------------------------------------------------------
@pytest.mark.parametrize("method", sorted(DEMOSAIC_METHODS))
@pytest.mark.parametrize("cfa", ["RGGB", "GRBG", "GBRG", "BGGR"])
def test_demosaic_exact_on_linear_colour_ramps(method, cfa):
    yy, xx = np.mgrid[0:40, 0:50].astype(np.float64)
    truth = np.stack([0.1 + 0.01 * yy + 0.004 * xx, 0.5 - 0.003 * yy + 0.006 * xx, 0.3 + 0.002 * yy - 0.001 * xx], -1)
    ch = np.tile(cfa_channel_map(cfa), (20, 25))
    mosaic = np.take_along_axis(truth, ch[..., None].astype(np.int64), axis=-1)[..., 0].astype(np.float32)
    out = demosaic(mosaic, cfa, method=method)
    inner = (slice(2, -2), slice(2, -2))
    np.testing.assert_allclose(out[inner], truth[inner], atol=2e-6)


def test_malvar_beats_bilinear_on_correlated_detail():
    yy, xx = np.mgrid[0:96, 0:96].astype(np.float64)
    lum = 0.5 + 0.3 * np.sin(xx / 2.3) * np.cos(yy / 3.1)
    truth = np.stack([0.9 * lum, lum, 0.7 * lum + 0.05], -1)
    ch = np.tile(cfa_channel_map("GRBG"), (48, 48))
    mosaic = np.take_along_axis(truth, ch[..., None].astype(np.int64), -1)[..., 0].astype(np.float32)
    err = {m: np.sqrt(np.mean((demosaic(mosaic, "GRBG", method=m)[4:-4, 4:-4] - truth[4:-4, 4:-4]) ** 2))
           for m in ("bilinear", "malvar")}
    assert err["malvar"] < 0.75 * err["bilinear"]


def test_malvar_matches_the_papers_5x5_filters():
    """Interior pixels equal the filters of Malvar, He & Cutler (ICASSP 2004, Fig. 2), applied by convolution."""
    from scipy.ndimage import correlate

    g_at_rb = np.array([[0, 0, -1, 0, 0], [0, 0, 2, 0, 0], [-1, 2, 4, 2, -1], [0, 0, 2, 0, 0], [0, 0, -1, 0, 0]]) / 8
    rb_at_g_row = np.array([[0, 0, .5, 0, 0], [0, -1, 0, -1, 0], [-1, 4, 5, 4, -1], [0, -1, 0, -1, 0],
                            [0, 0, .5, 0, 0]]) / 8          # R/B neighbours along the row
    rb_at_g_col = rb_at_g_row.T
    rb_at_br = np.array([[0, 0, -1.5, 0, 0], [0, 2, 0, 2, 0], [-1.5, 0, 6, 0, -1.5], [0, 2, 0, 2, 0],
                         [0, 0, -1.5, 0, 0]]) / 8
    rng = np.random.default_rng(4)
    mosaic = rng.random((24, 24)).astype(np.float32)
    out = demosaic(mosaic, "RGGB", method="malvar")
    conv = {name: correlate(mosaic.astype(np.float64), k, mode="reflect")
            for name, k in [("g", g_at_rb), ("row", rb_at_g_row), ("col", rb_at_g_col), ("x", rb_at_br)]}
    ch = np.tile(cfa_channel_map("RGGB"), (12, 12))
    ys, xs = np.mgrid[2:22, 2:22]
    for y, x in zip(ys.ravel(), xs.ravel()):
        c = ch[y, x]
        if c == 1:                      # G site: R along the row on R rows (even y), along the column on B rows
            r_exp = conv["row"][y, x] if y % 2 == 0 else conv["col"][y, x]
            b_exp = conv["col"][y, x] if y % 2 == 0 else conv["row"][y, x]
            np.testing.assert_allclose(out[y, x], [r_exp, mosaic[y, x], b_exp], atol=2e-6)
        else:
            other = conv["x"][y, x]
            exp = [mosaic[y, x], conv["g"][y, x], other] if c == 0 else [other, conv["g"][y, x], mosaic[y, x]]
            np.testing.assert_allclose(out[y, x], exp, atol=2e-6)


@pytest.mark.parametrize("method", sorted(DEMOSAIC_METHODS))
def test_demosaic_does_not_mix_across_labels(method):
    labels = np.zeros((30, 30), np.int32)
    labels[:, 15:] = 1
    truth = np.where(labels[..., None] == 0, [0.2, 0.4, 0.6], [0.9, 0.1, 0.5]).astype(np.float32)
    ch = np.tile(cfa_channel_map("BGGR"), (15, 15))
    mosaic = np.take_along_axis(truth, ch[..., None].astype(np.int64), -1)[..., 0]
    mixed = demosaic(mosaic, "BGGR", method=method)
    kept = demosaic(mosaic, "BGGR", method=method, labels=labels)
    np.testing.assert_allclose(kept, truth, atol=1e-6)          # constant per label: exact everywhere
    assert np.abs(mixed[:, 14:16] - truth[:, 14:16]).max() > 0.1  # without labels the border mixes


def test_demosaic_missing_pixels_and_monochrome():
    rng = np.random.default_rng(1)
    m = np.full((20, 20), 0.5, np.float32)
    m[rng.random(m.shape) < 0.15] = np.nan
    out = demosaic(m, "RGGB", method="malvar")
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out, 0.5, atol=1e-6)
    labels = np.full((20, 20), -1, np.int32)
    labels[5:15, 5:15] = 3
    mono = demosaic(m, None, labels=labels)
    assert mono.shape == (20, 20, 1)
    assert np.isnan(mono[labels < 0]).all() and np.isfinite(mono[labels >= 0]).all()
    with pytest.raises(ValueError, match="malvar"):
        demosaic(m, "RGGB", method="menon")


def test_demosaic_wide_search_for_a_channel_missing_in_the_3x3_window():
    # RGGB: (6, 7) is a G site; its B neighbours (5, 7), (7, 7) are missing, so B comes from the B sites of
    # the 5x5 window, weighted by inverse squared distance (all at 1/5 here), within the pixel's label only
    rng = np.random.default_rng(5)
    m = rng.uniform(0.2, 1.0, (14, 14)).astype(np.float32)
    m[5, 7] = m[7, 7] = np.nan
    labels = np.zeros(m.shape, np.int32)
    labels[7, 9] = 1                                                   # another micro-image: left out
    out = demosaic(m, "RGGB", method="bilinear", labels=labels)
    expected_b = np.mean([m[5, 5], m[5, 9], m[7, 5]], dtype=np.float32)
    np.testing.assert_allclose(out[6, 7], [0.5 * (m[6, 6] + m[6, 8]), m[6, 7], expected_b], rtol=1e-6)
    # R unknown in the whole 5x5 window: the pixel ends all-NaN although its own G is known
    m2 = m.copy()
    m2[4:9:2, 6:9:2] = np.nan
    out2 = demosaic(m2, "RGGB", method="bilinear", labels=labels)
    assert np.isnan(out2[6, 7]).all()
    assert np.isfinite(out2[6, 11]).all()


# -- geometry: labels, slicing, hex -> rect ------------------------------------------------------
def test_labels_are_the_voronoi_cells():
    g = hex_grid()
    labels, dist = lens_labels(g.centres_2d(), g.sensor_shape, 0.6 * g.pitch + 1)
    c = g.centres()
    rng = np.random.default_rng(2)
    pts = np.stack([rng.integers(10, 110, 300), rng.integers(10, 150, 300)], 1)
    d = np.linalg.norm(pts[:, None, :] - c[None], axis=-1)
    np.testing.assert_array_equal(labels[pts[:, 0], pts[:, 1]], d.argmin(1))
    np.testing.assert_allclose(dist[pts[:, 0], pts[:, 1]], d.min(1), atol=1e-4)


@pytest.mark.parametrize("rotation", [0.0, 0.01])
def test_sample_lenses_hits_centre_plus_offset(rotation):
    g = hex_grid(rotation=rotation)
    h, w = g.sensor_shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    f = lambda y, x: 0.3 + 0.002 * y + 0.001 * x          # linear: bilinear sampling is exact
    img = f(yy, xx).astype(np.float32)[..., None]
    labels, _ = lens_labels(g.centres_2d(), (h, w), 0.6 * g.pitch + 1)
    offs = view_offsets(g, 7)
    s, wt = sample_lenses(img, np.ones((h, w), np.float32), labels, g.centres_2d(), offs,
                          safe_radius=safe_radius(g))
    p = g.centres_2d()[None, None] + offs[:, :, None, None]
    inside = wt > 0.999
    assert inside.mean() > 0.7
    np.testing.assert_allclose(s[..., 0][inside], f(p[..., 0], p[..., 1])[inside], atol=1e-5)
    # the offsets follow the lattice axes: view (v, u) - centre = (v-3) e_row + (u-3) e_col
    e_row, e_col = g.axes()
    np.testing.assert_allclose(offs[5, 1], 2 * e_row - 2 * e_col)


def test_hex_to_rect_exact_for_quadratics_and_square_pixels():
    g = hex_grid(h=200, w=300)
    rows, cols = g.shape
    s = g.decoded_sampling()
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    b = j * g.pitch + g.odd_row_shift * g.pitch * (i % 2)            # lattice position along each row
    val = lambda a, bb: 0.2 + 0.01 * a + 0.003 * bb - 2e-5 * bb ** 2
    samples = val(i * g.row_spacing, b).astype(np.float32)[None, None, ..., None]
    ones = np.ones(samples.shape[:4], np.float32)
    ny, nx = output_shape(g)
    yy, xx = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    expect = val(yy * s["step"] + s["a0"], xx * s["step"] + s["b0"])
    cub, wc = hex_to_rect(samples, ones, g, method="cubic")
    lin, _ = hex_to_rect(samples, ones, g, method="linear")
    assert cub.shape == (1, 1, ny, nx, 1)
    inner = (slice(None), slice(2, -2))
    np.testing.assert_allclose(cub[0, 0, ..., 0][inner], expect[inner], atol=1e-5)   # Keys reproduces quadratics
    assert np.abs(lin[0, 0, ..., 0][inner] - expect[inner]).max() > 1e-4             # linear does not
    np.testing.assert_allclose(wc, 1.0, atol=1e-6)
    # square output pixels: X spans the common row range at the row spacing
    assert nx == int(math.floor(((cols - 1 - 0.5) * g.pitch) / g.row_spacing + 1e-9)) + 1
    idx, wts = row_taps(g, method="cubic")
    np.testing.assert_allclose(wts.sum(-1), 1.0, atol=1e-6)
    with pytest.raises(ValueError, match="cubic"):
        row_taps(g, method="sinc")


def test_hex_to_rect_skips_missing_lenses():
    g = hex_grid()
    rows, cols = g.shape
    samples = np.full((1, 1, rows, cols, 1), 0.7, np.float32)
    weight = np.ones((1, 1, rows, cols), np.float32)
    samples[..., 3, 4, 0] = 0.0
    weight[..., 3, 4] = 0.0                                     # lens without a sample
    out, w = hex_to_rect(samples, weight, g)
    np.testing.assert_allclose(out[0, 0, 3], 0.7, atol=1e-6)    # no dark hole where the lens is missing
    assert w[0, 0, 3].min() < 0.6


def test_bands_cover_all_rows_with_even_starts():
    g = hex_grid(h=400, w=300, rotation=0.01)
    bands = plan_bands(g, max_pixels=20_000)
    assert len(bands) > 3
    assert bands[0].i0 == 0 and bands[-1].i1 == g.shape[0]
    assert all(a.i1 == b.i0 for a, b in zip(bands, bands[1:]))
    assert all(b.r0 % 2 == 0 for b in bands)
    c = g.centres_2d()
    for b in bands:   # every decoded lens's cell lies inside the band's sensor rows
        rr = c[b.i0:b.i1, :, 0]
        assert rr.min() - 0.6 * g.pitch >= b.r0 or b.r0 == 0
        assert rr.max() + 0.6 * g.pitch <= b.r1 or b.r1 == g.sensor_shape[0]


def test_reference_output_sizes_from_pitch_and_sensor():
    from plenodecode.synthetic import make_grid

    illum = make_grid("illum")
    f01 = make_grid("f01")
    assert illum.n_views() == 15 and f01.n_views() == 9
    iy, ix = output_shape(illum)
    fy, fx = output_shape(f01)
    assert abs(iy - 434) <= 1 and abs(ix - 625) <= 2           # LFToolbox: 15x15x434x625
    assert abs(fy - 381) <= 2 and abs(fx - 380) <= 2           # LFToolbox: about 9x9x380x380


@pytest.mark.parametrize("method", sorted(DEMOSAIC_METHODS))
def test_interior_hint_does_not_change_the_result(method):
    g = hex_grid()
    labels, dist = lens_labels(g.centres_2d(), g.sensor_shape, 0.6 * g.pitch + 1)
    rng = np.random.default_rng(7)
    m = rng.random(g.sensor_shape).astype(np.float32)
    m[dist > 0.42 * g.pitch] = np.nan                     # dark rims between the disks
    interior = dist < safe_radius(g) - 3.0
    interior[:2], interior[-2:], interior[:, :2], interior[:, -2:] = False, False, False, False
    assert interior.mean() > 0.1
    a = demosaic(m, "GRBG", method=method, labels=labels)
    b = demosaic(m, "GRBG", method=method, labels=labels, interior=interior)
    np.testing.assert_array_equal(a, b)


# -- the 2-D 'hex' resampling kernel ------------------------------------------------------------

def _lattice_and_output(g):
    rows, cols = g.shape
    s = g.decoded_sampling()
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a, b = i * g.row_spacing, j * g.pitch + g.odd_row_shift * g.pitch * (i % 2)
    ny, nx = output_shape(g)
    yy, xx = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    return (a, b), (yy * s["step"] + s["a0"], xx * s["step"] + s["b0"])


def _resample_fn(g, fn, method):
    (a, b), (ao, bo) = _lattice_and_output(g)
    samples = fn(a, b).astype(np.float32)[None, None, ..., None]
    out, w = hex_to_rect(samples, np.ones(samples.shape[:4], np.float32), g, method=method)
    return out[0, 0, ..., 0], fn(ao, bo), w


def test_hex_kernel_exact_for_cubics_and_for_any_function_of_the_row():
    g = hex_grid(h=200, w=300)
    drow, col, w = hex_taps(g)
    assert w.shape == (2, output_shape(g)[1], 20) and drow.tolist() == np.repeat(np.arange(-2, 3), 4).tolist()
    rowsum = w.reshape(*w.shape[:2], 5, 4).sum(-1)
    np.testing.assert_allclose(rowsum, np.broadcast_to([0, 0, 1, 0, 0], rowsum.shape), atol=1e-5)
    inner = (slice(2, -2), slice(2, -2))         # the 2 first / last rows and frame ends fall back to 'cubic'
    cubic = lambda a, b: 0.3 + 2e-3 * a - 1e-3 * b + 1e-5 * a * b - 2e-6 * b ** 2 + 3e-8 * b ** 3 - 1e-8 * a ** 2 * b
    out, expect, wt = _resample_fn(g, cubic, "hex")
    np.testing.assert_allclose(out[inner], expect[inner], atol=2e-5)
    np.testing.assert_allclose(wt, 1.0, atol=1e-6)
    # a function of a alone (horizontal structure, even at the row Nyquist): exact, as along the lens row
    rows_only = lambda a, b: np.cos(np.pi * a / g.row_spacing + 0.3)
    out, expect, _ = _resample_fn(g, rows_only, "hex")
    np.testing.assert_allclose(out, expect, atol=2e-5)


def test_hex_kernel_removes_the_row_alternating_error_on_vertical_structure():
    # a function of b alone at 0.4 cycles per pitch: the row kernels alias it with the sign of the
    # half-pitch row shift (a zipper); the lattice resolves it from the rows above and below
    g = hex_grid(h=200, w=300)
    wave = lambda a, b: np.cos(2 * np.pi * 0.4 * b / g.pitch + 0.3)
    inner = (slice(2, -2), slice(2, -2))
    err = {}
    for method in ("cubic", "hex"):
        out, expect, _ = _resample_fn(g, wave, method)
        r = (out - expect)[inner]
        alt = r[1:-1] - 0.5 * (r[:-2] + r[2:])      # row-alternating part of the error
        err[method] = (np.sqrt(np.mean(r ** 2)), np.sqrt(np.mean(alt ** 2)))
    assert err["cubic"][0] > 0.2 and err["cubic"][1] > 0.2                    # measured 0.28 / 0.39
    assert err["hex"][0] < 0.25 * err["cubic"][0] and err["hex"][1] < 0.25 * err["cubic"][1]


def test_hex_kernel_falls_back_to_cubic_at_missing_lenses_and_reads_context_rows():
    g = hex_grid(h=200, w=300)
    rows, cols = g.shape
    rng = np.random.default_rng(0)
    samples = rng.random((1, 2, rows, cols, 3), dtype=np.float32)
    weight = np.ones((1, 2, rows, cols), np.float32)
    weight[0, 1, 10, 12] = 0.0                                  # view 1 misses one lens
    cub, wc = hex_to_rect(samples, weight, g, method="cubic")
    hx, wh = hex_to_rect(samples, weight, g, method="hex")
    np.testing.assert_array_equal(wh, wc)                       # weights are the row kernel's
    same = np.all(hx == cub, axis=-1)
    assert same[0, 0, [0, 1, -2, -1]].all() and not same[0, 0, 2:-2, 3:-3].any()   # no 2 rows above/below
    near = same[0, 1, 8:13, 3:-3]                               # rows 8..12 read lens row 10
    assert 5 <= near.sum() <= 5 * 5 and not same[0, 1, 14:20, 3:-3].any()
    # a band of rows with 2 context rows on each side gives the rows of the whole-array result
    assert rows >= 20
    part, _ = hex_to_rect(np.ascontiguousarray(samples[:, :, 5:17]), np.ascontiguousarray(weight[:, :, 5:17]), g,
                          first_row=5, method="hex", context=(2, 2))
    np.testing.assert_array_equal(part, hx[:, :, 7:15])
    with pytest.raises(ValueError, match="context"):
        hex_to_rect(samples, weight, g, method="hex", context=(rows, 1))
