"""The synthetic forward model: grid truth, white images, scene raws, ground-truth light fields."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from plenodecode.io import synthetic as syn
from plenodecode.types import LensletGrid, cfa_channel_map

SMALL = (240, 320)


def _centroids(img: np.ndarray, grid: LensletGrid) -> tuple[np.ndarray, np.ndarray]:
    """Intensity-weighted centroid of each lens's Voronoi cell, for lenses whose disk is fully on the sensor."""
    h, w = img.shape
    rr, cc = np.mgrid[:h, :w]
    lens = syn.assign_pixels(grid, rr, cc)
    label = (lens.i + 10) * 100000 + (lens.j + 10)
    centres = grid.centres()
    i, j = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
    m = grid.radius + 2
    inside = ((centres[:, 0] > m) & (centres[:, 0] < h - 1 - m) & (centres[:, 1] > m) & (centres[:, 1] < w - 1 - m))
    ids = ((i.ravel() + 10) * 100000 + (j.ravel() + 10))[inside]
    mass = ndimage.sum(img, label, ids)
    cy = ndimage.sum(img * rr, label, ids) / mass
    cx = ndimage.sum(img * cc, label, ids) / mass
    return np.stack([cy, cx], -1), centres[inside]


# ---------------------------------------------------------------------------------------- grid
@pytest.mark.parametrize("name", sorted(syn.PRESETS))
def test_grid_covers_every_lens_on_the_sensor(name):
    grid = syn.make_grid(name, shape=SMALL, rotation=0.01 if name != "raytrix" else None, offset=(0.3, -0.6))
    h, w = SMALL
    # every lens of an extended block that lies on the sensor must be in the grid
    big = grid.replace(origin=tuple(grid.lattice_to_sensor(-4 * grid.row_spacing, -4 * grid.pitch)),
                       shape=(grid.shape[0] + 8, grid.shape[1] + 8), lens_type=None)
    c = big.centres()
    on = (c[:, 0] >= -0.5) & (c[:, 0] <= h - 0.5) & (c[:, 1] >= -0.5) & (c[:, 1] <= w - 0.5)
    ib, jb = np.divmod(np.arange(c.shape[0]), big.shape[1])
    assert ib[on].min() == 4 and jb[on].min() == 4
    assert ib[on].max() == grid.shape[0] + 3 and jb[on].max() == grid.shape[1] + 3
    assert grid.sensor_shape == SMALL
    assert 0.44 * grid.pitch < grid.radius < 0.49 * grid.pitch
    if syn.PRESETS[name].lattice == "hex":
        assert grid.row_spacing == pytest.approx(grid.pitch * np.sqrt(3) / 2)
        assert abs(grid.odd_row_shift) == 0.5
    else:
        assert grid.row_spacing == grid.pitch and grid.odd_row_shift == 0.0
    assert (grid.lens_type is not None) == (name == "raytrix")


def test_offset_moves_the_lattice_by_sub_pixels():
    g0 = syn.make_grid("f01-mini", offset=(0.0, 0.0), shape=SMALL)
    g1 = syn.make_grid("f01-mini", offset=(0.25, -0.4), shape=SMALL)
    moved = g1.centres() - [0.25, -0.4]
    lens = syn.assign_pixels(g0, moved[:, 0], moved[:, 1])   # every moved lens is a lens of g0's lattice
    np.testing.assert_allclose(np.hypot(lens.oa, lens.ob), 0.0, atol=1e-9)
    anchor = syn.assign_pixels(g1, np.array([(SMALL[0] - 1) / 2 + 0.25]), np.array([(SMALL[1] - 1) / 2 - 0.4]))
    np.testing.assert_allclose([anchor.oa[0], anchor.ob[0]], 0.0, atol=1e-9)


def test_raytrix_lens_types_are_a_three_colouring():
    grid = syn.make_grid("raytrix")
    t = grid.lens_type
    assert set(np.unique(t)) == {0, 1, 2}
    c = grid.centres_2d()
    # each lens's 6 nearest neighbours have other types; lenses sqrt(3) pitch apart share a type
    flat_c, flat_t = c.reshape(-1, 2), t.ravel()
    d = np.hypot(*(flat_c[:, None, :] - flat_c[None, :, :]).transpose(2, 0, 1)) / grid.pitch
    near = (d > 0.5) & (d < 1.2)
    same = flat_t[:, None] == flat_t[None, :]
    assert near.sum() > 0 and not (near & same).any()
    second = (d > 1.6) & (d < 1.9)
    assert (second & same).sum() == second.sum()


def test_assign_pixels_picks_the_nearest_lens():
    grid = syn.make_grid("illum-mini", shape=SMALL, rotation=0.008)
    rng = np.random.default_rng(1)
    pts = rng.uniform([0, 0], SMALL, size=(5000, 2))
    lens = syn.assign_pixels(grid, pts[:, 0], pts[:, 1])
    big = grid.replace(origin=tuple(grid.lattice_to_sensor(-2 * grid.row_spacing, -2 * grid.pitch)),
                       shape=(grid.shape[0] + 4, grid.shape[1] + 4))
    if big.odd_row_shift != grid.odd_row_shift:  # pragma: no cover - two rows keeps parity
        raise AssertionError
    c = big.centres()
    d = np.hypot(pts[:, None, 0] - c[None, :, 0], pts[:, None, 1] - c[None, :, 1])
    near = np.argmin(d, axis=1)
    np.testing.assert_array_equal(lens.i + 2, near // big.shape[1])
    np.testing.assert_array_equal(lens.j + 2, near % big.shape[1])
    np.testing.assert_allclose(np.hypot(lens.oa, lens.ob), d.min(axis=1), atol=1e-9)


# ---------------------------------------------------------------------------------------- white
def test_white_is_deterministic_and_seeded():
    a, ga = syn.simulate_white("f01-mini", seed=3, shape=SMALL)
    b, _ = syn.simulate_white("f01-mini", seed=3, shape=SMALL)
    c, _ = syn.simulate_white("f01-mini", seed=4, shape=SMALL)
    np.testing.assert_array_equal(a.mosaic, b.mosaic)
    assert (a.mosaic != c.mosaic).mean() > 0.5
    assert ga.to_dict() == syn.make_grid("f01-mini", shape=SMALL).to_dict()


@pytest.mark.parametrize("name", ["illum-mini", "f01-mini", "square", "raytrix"])
def test_white_disk_centroids_match_the_true_centres(name):
    raw, grid = syn.simulate_white(name, noise=False, shape=SMALL, offset=(0.3, 0.7),
                                   rotation=0.01 if name != "raytrix" else None)
    got, true = _centroids(raw.normalised().astype(np.float64), grid)
    assert len(true) >= 20
    err = np.hypot(*(got - true).T)
    assert err.max() < 0.05, err.max()
    # without the vignetting slope the disks are symmetric to the sampling error only
    h, w = SMALL
    rr, cc = np.mgrid[:h, :w]
    p = syn.PRESETS[name]
    flat = raw.normalised() / syn.vignetting(rr, cc, SMALL, p.vignette_corner, p.sensor_shape)
    got2, _ = _centroids(flat, grid)
    assert np.hypot(*(got2 - true).T).max() < 0.04


def test_white_disk_profile_radius_and_vignetting():
    raw, grid = syn.simulate_white("illum-mini", noise=False)
    img = raw.normalised()
    h, w = raw.shape
    rr, cc = np.mgrid[:h, :w]
    lens = syn.assign_pixels(grid, rr, cc)
    r = np.hypot(lens.oa, lens.ob)
    vig = syn.vignetting(rr, cc, (h, w), 0.5)
    centre = (np.abs(rr - h / 2) < 60) & (np.abs(cc - w / 2) < 60)
    # bright near the lens centre, dark beyond the soft edge
    assert img[centre & (r < 1.0)].min() > 0.75
    assert img[centre & (r > grid.radius + 0.75 + 0.41)].max() == 0.0   # edge + box reach
    # corners at ~50 % of the centre
    corner = (rr < 60) & (cc < 60) & (r < 1.0)
    ratio = img[corner].mean() / img[centre & (r < 1.0)].mean()
    assert 0.45 < ratio < 0.6
    np.testing.assert_allclose(vig[0, 0], 0.5, rtol=1e-9)
    np.testing.assert_allclose(syn.disk_profile(np.array([0.0, grid.radius, grid.radius + 0.75]), grid.radius),
                               [1.0, 0.5 * (1 - 0.12), 0.0], atol=1e-12)


@pytest.mark.parametrize("name,cfa,black,white,bits", [
    ("illum", "GRBG", 64, 1023, 10), ("illum-mini", "GRBG", 64, 1023, 10), ("f01", "BGGR", 168, 4095, 12),
    ("f01-mini", "BGGR", 168, 4095, 12), ("square", None, 100, 4095, 12), ("raytrix", None, 0, 4095, 12)])
def test_levels_cfa_and_metadata_per_preset(name, cfa, black, white, bits):
    p = syn.PRESETS[name]
    assert (p.cfa, p.black, p.white, p.bits) == (cfa, black, white, bits)
    raw, grid = syn.simulate_white(name, shape=(64, 96))
    assert raw.cfa == cfa and raw.mosaic.dtype == np.uint16
    np.testing.assert_array_equal(raw.black, np.full((2, 2), black))
    np.testing.assert_array_equal(raw.white, np.full((2, 2), white))
    assert raw.mosaic.max() < 2 ** bits
    md = raw.metadata
    assert md.is_white_image and md.serial == p.serial and md.model == p.model
    assert md.lenslet_pitch_px() == pytest.approx(grid.pitch)
    assert md.mla_rotation == grid.rotation
    if cfa is not None:
        assert md.wb_gains == {"r": 1.0, "gr": 1.0, "gb": 1.0, "b": 1.0}
        ccm = np.asarray(md.ccm)
        np.testing.assert_allclose(ccm.sum(axis=1), 1.0, atol=1e-12)
    if name == "illum":
        assert p.sensor_shape == (5368, 7728) and p.pitch_px == pytest.approx(14.2857, abs=1e-4)
        assert p.wb_gains == (1.379, 1.0, 1.0, 1.148)
    if name == "f01":
        assert p.sensor_shape == (3280, 3280) and p.pitch_px == pytest.approx(9.9276, abs=1e-4)
        assert p.rotation == 0.00193


@pytest.mark.parametrize("name", ["illum-mini", "f01-mini"])
def test_white_noise_matches_poisson_gaussian_model(name):
    p = syn.PRESETS[name]
    clean, _ = syn.simulate_white(name, noise=False, shape=SMALL, seed=5)
    noisy, _ = syn.simulate_white(name, noise=True, shape=SMALL, seed=5)
    h, w = SMALL
    rr, cc = np.mgrid[:h, :w]
    grid = syn.make_grid(name, shape=SMALL)
    lens = syn.assign_pixels(grid, rr, cc)
    span = p.white - p.black
    sig = (syn.disk_response(lens.oa, lens.ob, grid.radius) * p.exposure
           * syn.vignetting(rr, cc, SMALL, p.vignette_corner, p.sensor_shape))
    res = noisy.mosaic.astype(np.float64) - (p.black + sig * span)
    model_var = sig * span ** 2 / p.full_well + p.read_noise_dn ** 2 + 1 / 12
    ok = np.abs(res) < 8 * np.sqrt(model_var)   # hot pixels out
    assert (~ok).mean() < 1e-3
    for lo, hi in ((0.0, 0.01), (0.3, 0.6), (0.6, 1.0)):
        sel = ok & (sig >= lo) & (sig < hi)
        assert sel.sum() > 150
        ratio = np.sqrt(np.mean(res[sel] ** 2) / np.mean(model_var[sel]))
        assert 0.9 < ratio < 1.1, (lo, hi, ratio)
    # the noise-free image is the rounded signal
    np.testing.assert_array_equal(clean.mosaic, np.rint(p.black + sig * span).astype(np.uint16))


def test_hot_pixels_only_with_noise():
    p = dataclasses.replace(syn.PRESETS["square"], hot_fraction=2e-3)
    noisy, grid = syn.simulate_white(p, shape=SMALL, seed=2)
    clean, _ = syn.simulate_white(p, shape=SMALL, seed=2, noise=False)
    h, w = SMALL
    rr, cc = np.mgrid[:h, :w]
    lens = syn.assign_pixels(grid, rr, cc)
    dark = np.hypot(lens.oa, lens.ob) > grid.radius + 1.25   # edge half-width + half a pixel diagonal
    hot = dark & (noisy.mosaic > p.black + 0.25 * (p.white - p.black))
    assert 0.3 * 2e-3 * dark.sum() < hot.sum() < 2.0 * 2e-3 * dark.sum()
    assert not (dark & (clean.mosaic > p.black + 1)).any()


def test_bad_arguments_raise_value_error():
    with pytest.raises(ValueError, match="preset"):
        syn.simulate_white("nope")
    with pytest.raises(ValueError, match="shape"):
        syn.simulate_white("f01-mini", shape=(8, 8))
    with pytest.raises(ValueError, match="seed"):
        syn.simulate_white("f01-mini", seed=-1, shape=SMALL)
    with pytest.raises(ValueError, match="pitch"):
        syn.simulate_white("f01-mini", pitch=1.0, shape=SMALL)


# ---------------------------------------------------------------------------------------- scene
from plenodecode.io._scene import SUPPORT_EDGE, Plane, Scene, box_radiance  # noqa: E402


def _reference_radiance(tex, y, x, oa, ob, ch, space="camera"):
    """Independent numpy model of one ray per element: 2x2 solve, support alpha, bilinear texture,
    front-to-back compositing."""
    raster = tex.camera if space == "camera" else tex.srgb
    out = np.zeros(len(y))
    trans = np.ones(len(y))
    for k in range(tex.d0.size):
        g = np.array([tex.gy[k], tex.gx[k]])
        o = np.stack([oa, ob], -1)
        a_mat = np.eye(2)[None] - o[:, :, None] * g[None, None, :]
        rhs = np.stack([y, x], -1) + tex.d0[k] * o
        p = np.linalg.solve(a_mat, rhs[..., None])[..., 0]
        kind, prm = tex.kind[k], tex.prm[k]
        if kind == 0:
            sd = np.full(len(y), -np.inf)
        elif kind == 1:
            dy = np.maximum(prm[0] - p[:, 0], p[:, 0] - prm[2])
            dx = np.maximum(prm[1] - p[:, 1], p[:, 1] - prm[3])
            sd = np.where((dy > 0) & (dx > 0), np.hypot(dy, dx), np.maximum(dy, dx))
        else:
            sd = np.hypot(p[:, 0] - prm[0], p[:, 1] - prm[1]) - prm[2]
        t = np.clip(0.5 - sd / SUPPORT_EDGE, 0, 1)
        alpha = t * t * (3 - 2 * t)
        coords = [(p[:, 0] - tex.y0) * tex.scale, (p[:, 1] - tex.x0) * tex.scale]
        val = np.zeros(len(y))
        for c in np.unique(ch):
            sel = ch == c
            val[sel] = ndimage.map_coordinates(raster[k, c].astype(np.float64), [coords[0][sel], coords[1][sel]],
                                               order=1, mode="nearest")
        out += trans * alpha * val
        trans *= 1 - alpha
    return out


def _box_reference(tex, y, x, oa, ob, ch, space="camera"):
    acc = np.zeros(len(y))
    for da in syn.SUBSAMPLES:
        for db in syn.SUBSAMPLES:
            acc += _reference_radiance(tex, y, x, oa + da, ob + db, ch, space)
    return acc / syn.SUBSAMPLES.size ** 2


@pytest.fixture(scope="module")
def sim_clean():
    return syn.simulate("illum-mini", seed=11, noise=False, shape=(480, 640))


def test_simulate_is_deterministic_and_seeded():
    a = syn.simulate("f01-mini", seed=7, shape=(96, 128))
    b = syn.simulate("f01-mini", seed=7, shape=(96, 128))
    c = syn.simulate("f01-mini", seed=8, shape=(96, 128))
    np.testing.assert_array_equal(a.raw.mosaic, b.raw.mosaic)
    np.testing.assert_array_equal(a.white.mosaic, b.white.mosaic)
    assert (a.raw.mosaic != c.raw.mosaic).mean() > 0.5
    assert (a.raw.mosaic != a.white.mosaic).mean() > 0.5
    assert a.grid.to_dict() == c.grid.to_dict()
    # the simulation's white is the white image of simulate_white for the same seed
    np.testing.assert_array_equal(a.white.mosaic, syn.simulate_white("f01-mini", seed=7, shape=(96, 128))[0].mosaic)
    assert not a.raw.metadata.is_white_image and a.white.metadata.is_white_image
    assert a.raw.metadata.wb_gains == {"r": 1.0, "gr": 1.117, "gb": 1.117, "b": 1.723}


def test_kernel_radiance_matches_an_independent_model(sim_clean):
    tex = sim_clean.textures
    rng = np.random.default_rng(0)
    n = 4000
    y, x = rng.uniform(-2, 21, n), rng.uniform(-2, 27, n)
    oa, ob = rng.uniform(-7, 7, n), rng.uniform(-7, 7, n)
    ch = rng.integers(0, 3, n)
    got = box_radiance(tex, y, x, oa, ob, ch)
    ref = _box_reference(tex, y, x, oa, ob, ch)
    np.testing.assert_allclose(got, ref, atol=2e-6)
    got = box_radiance(tex, y, x, oa, ob, ch, space="srgb")
    np.testing.assert_allclose(got, _box_reference(tex, y, x, oa, ob, ch, "srgb"), atol=2e-6)


def test_raw_over_white_is_the_camera_radiance(sim_clean):
    sim = sim_clean
    p, grid = sim.preset, sim.grid
    raw, white = sim.raw.normalised().astype(np.float64), sim.white.normalised().astype(np.float64)
    h, w = raw.shape
    rr, cc = np.mgrid[:h, :w]
    lens = syn.assign_pixels(grid, rr, cc)
    ch = cfa_channel_map(p.cfa)[rr % 2, cc % 2]
    lit = white > 0.3
    sel = np.flatnonzero(lit)
    want = box_radiance(sim.textures, lens.y.ravel()[sel], lens.x.ravel()[sel], lens.oa.ravel()[sel],
                        lens.ob.ravel()[sel], ch.ravel()[sel])
    got = raw.ravel()[sel] / white.ravel()[sel]
    # both images are rounded to whole DN: bound the ratio error by half a DN on each
    span = p.white - p.black
    bound = 0.5 / span * (1 + want) / white.ravel()[sel] + 1e-9
    assert np.all(np.abs(got - want) <= bound), np.max(np.abs(got - want) / bound)
    # the camera radiance is diag(1/wb) inv(ccm) of the linear-sRGB texture
    srgb = np.stack([box_radiance(sim.textures, lens.y.ravel()[sel][:50], lens.x.ravel()[sel][:50],
                                  lens.oa.ravel()[sel][:50], lens.ob.ravel()[sel][:50], c, space="srgb")
                     for c in range(3)])
    cam = p.camera_matrix() @ srgb
    np.testing.assert_allclose(cam[ch.ravel()[sel][:50], np.arange(50)], want[:50], atol=1e-5)
    wb = np.array([p.wb_gains[0], p.wb_gains[1], p.wb_gains[3]])
    np.testing.assert_allclose(np.asarray(p.ccm) @ (wb[:, None] * cam), srgb, atol=1e-5)


@pytest.mark.parametrize("name", ["illum-mini", "f01-mini"])
def test_bayer_pure_red_scene_lights_only_red_sites(name):
    p = syn.PRESETS[name]
    wb = np.array([p.wb_gains[0], p.wb_gains[1], p.wb_gains[3]])
    srgb = np.asarray(p.ccm) @ (wb * np.array([0.6, 0.0, 0.0]))     # camera RGB (0.6, 0, 0)
    sim = syn.simulate(name, noise=False, shape=(64, 96), scene=[Plane(0.0, colour=tuple(srgb))])
    chan = cfa_channel_map(p.cfa)
    h, w = sim.raw.shape
    rr, cc = np.mgrid[:h, :w]
    is_red = chan[rr % 2, cc % 2] == 0
    assert is_red.mean() == pytest.approx(0.25)
    assert np.all(sim.raw.mosaic[~is_red] == p.black)
    lit = sim.white.normalised() > 0.3
    assert np.all(sim.raw.mosaic[is_red & lit] > p.black + 50)
    ratio = sim.raw.normalised()[is_red & lit] / sim.white.normalised()[is_red & lit]
    np.testing.assert_allclose(ratio, 0.6, atol=4e-3)


def test_monochrome_square_preset_is_grey():
    sim = syn.simulate("square", noise=False, shape=(110, 165))
    assert sim.raw.cfa is None and sim.textures.srgb.shape[1] == 1
    lf = sim.ground_truth_lightfield(n_views=3)
    assert lf.shape[-1] == 1 and lf.shape[:2] == (3, 3)
    assert sim.grid.lattice == "square"


def test_default_scene_disparity_map(sim_clean):
    sim = sim_clean
    smp = sim.grid.decoded_sampling()
    assert sim.disparity.shape == (smp["Y"], smp["X"]) and sim.disparity.dtype == np.float32
    lo, hi = sim.disparity_range
    assert -0.51 < lo < -0.49 and 0.89 < hi < 0.91
    assert np.all(np.abs(sim.disparity) <= 1.0)
    # three surfaces: background -0.5, slanted 0 .. 0.6, front 0.9
    d = sim.disparity
    assert (d == np.float32(-0.5)).mean() > 0.3 and (d == np.float32(0.9)).mean() > 0.05
    slanted = (d > -0.4) & (d < 0.7)
    assert slanted.mean() > 0.1
    assert d[slanted].min() < 0.1 and d[slanted].max() > 0.45


def test_ground_truth_views_shift_by_the_disparity_exactly():
    # two fronto-parallel planes with disparities that make integer shifts for even view offsets
    scene = Scene((Plane(0.5, texture_seed=1, depth_order=1),
                   Plane(-1.0, support=("rect", 4.0, 4.0, 12.0, 14.0), texture_seed=2, depth_order=0)))
    sim = syn.simulate("f01-mini", noise=False, shape=(320, 400), scene=scene)
    lf = sim.ground_truth_lightfield(n_views=9)
    vc = uc = 4
    centre = lf.data[vc, uc]
    d = sim.disparity
    for v, u in ((vc + 2, uc - 4), (vc - 4, uc + 2), (vc + 4, uc + 4)):
        for dval in (0.5, -1.0):
            sy, sx = int(dval * (v - vc)), int(dval * (u - uc))
            # HCI: view[v,u](y - d*(v-vc), x - d*(u-uc)) = centre(y, x)
            ys, xs = np.nonzero(d == dval)
            ok = (ys - sy >= 0) & (ys - sy < d.shape[0]) & (xs - sx >= 0) & (xs - sx < d.shape[1])
            ys, xs = ys[ok], xs[ok]
            # away from the occlusion edges (relative shift 1.5 px per view step, 4 steps, the box
            # and the soft rim of the support)
            if dval == 0.5:
                far = ~((ys > 4 - 8) & (ys < 12 + 8) & (xs > 4 - 8) & (xs < 14 + 8))
            else:   # its box rays stay on the fully opaque part of the rect
                far = (ys >= 6) & (ys <= 10) & (xs >= 6) & (xs <= 12)
            view = lf.data[v, u]
            assert far.sum() > 30
            np.testing.assert_allclose(view[ys[far] - sy, xs[far] - sx], centre[ys[far], xs[far]], atol=2e-6)
    # and the centre view of a d = 0 plane is the texture sampled at the decoded grid, exactly
    sim0 = syn.simulate("f01-mini", noise=False, shape=(96, 128), scene=[Plane(0.0, texture_seed=3)])
    lf0 = sim0.ground_truth_lightfield(n_views=3)
    tex = sim0.textures
    yy, xx = np.mgrid[: lf0.shape[2], : lf0.shape[3]]
    for c in range(3):
        samp = tex.srgb[0, c][((yy - tex.y0) * tex.scale).astype(int), ((xx - tex.x0) * tex.scale).astype(int)]
        np.testing.assert_allclose(lf0.data[1, 1, :, :, c], samp, atol=2e-6)


def test_ground_truth_views_of_the_default_scene_follow_the_disparity_map(sim_clean):
    sim = sim_clean
    lf = sim.ground_truth_lightfield(n_views=7)
    vc, uc = lf.centre_index
    centre = lf.data[vc, uc]
    d = sim.disparity.astype(np.float64)
    ny, nx = d.shape
    yy, xx = np.mgrid[:ny, :nx].astype(np.float64)
    # interior of each surface: no occlusion edge (disparity jump) within 7 px
    jump = np.zeros(d.shape, bool)
    jump[1:] |= np.abs(np.diff(d, axis=0)) > 0.1
    jump[:, 1:] |= np.abs(np.diff(d, axis=1)) > 0.1
    smooth = ~ndimage.binary_dilation(jump, iterations=7)
    smooth[:4] = smooth[-4:] = False
    smooth[:, :4] = smooth[:, -4:] = False
    assert smooth.sum() > 150
    assert (smooth & (d > -0.4) & (d < 0.7)).sum() > 100          # the slanted plane is tested too
    for v, u in ((vc + 3, uc), (vc, uc - 3), (vc - 2, uc + 3)):
        ys = yy - d * (v - vc)
        xs = xx - d * (u - uc)
        for c in range(3):
            shifted = ndimage.map_coordinates(lf.data[v, u, :, :, c].astype(np.float64), [ys, xs], order=3,
                                              mode="nearest")
            err = np.abs(shifted - centre[..., c])[smooth]
            assert err.max() < 0.03 and err.mean() < 0.002, (v, u, c, err.max(), err.mean())
            # the continuous model at the shifted positions: exact up to the slant inside the box
            model = box_radiance(sim.textures, ys[smooth], xs[smooth], float(v - vc), float(u - uc), c,
                                 space="srgb")
            np.testing.assert_allclose(model, centre[..., c][smooth], atol=1e-3)


def test_default_texture_is_band_limited_for_a_38_db_decoder(sim_clean):
    # samples halfway between decoded samples, predicted by cubic interpolation of the
    # integer samples, reach > 38 dB on the centre view (what a good resampler can do)
    sim = sim_clean
    tex = sim.textures
    ny, nx = sim.disparity.shape
    yy, xx = np.mgrid[:ny, :nx].astype(np.float64)
    half_y, half_x = yy[1:-2, 1:-2] + 0.5, xx[1:-2, 1:-2] + 0.5
    err2 = []
    for c in range(3):
        grid_vals = box_radiance(tex, yy, xx, 0.0, 0.0, c, space="srgb")
        truth = box_radiance(tex, half_y, half_x, 0.0, 0.0, c, space="srgb")
        pred = ndimage.map_coordinates(grid_vals, [half_y, half_x], order=3, mode="nearest")
        err2.append((pred - truth) ** 2)
    psnr = 10 * np.log10(1.0 / np.mean(err2))
    assert psnr > 38, psnr
    cv = box_radiance(tex, yy, xx, 0.0, 0.0, 1, space="srgb")
    assert 0.05 < cv.std() < 0.3 and cv.min() >= 0.0 and cv.max() <= 0.95


def test_ground_truth_lightfield_metadata_and_weight(sim_clean):
    lf = sim_clean.ground_truth_lightfield()
    grid = sim_clean.grid
    smp = grid.decoded_sampling()
    n = grid.n_views()
    assert lf.shape == (n, n, smp["Y"], smp["X"], 3) and lf.data.dtype == np.float32
    assert lf.colour == "linear-srgb"
    assert lf.metadata["view_step_px"] == 1.0 and lf.metadata["spatial_step_px"] == pytest.approx(smp["step"])
    assert lf.metadata["calibration"] == grid.to_dict()
    assert lf.metadata["disparity_range"] == pytest.approx([-0.5, 0.9], abs=1e-6)
    vc, uc = lf.centre_index
    w = lf.weight[:, :, 0, 0]
    assert w[vc, uc] == w.max() and w[vc, uc] > 0.99 and w[0, 0] == 0.0
    np.testing.assert_allclose(w, w[::-1, ::-1])
    with pytest.raises(ValueError, match="n_views"):
        sim_clean.ground_truth_lightfield(n_views=4)


# ---------------------------------------------------------------------------------------- focused (raytrix)
def test_focused_micro_images_are_inverted_reduced_views_of_the_virtual_image():
    # one plane at virtual depth 4 and every lens type focused there: no blur, so
    # raw / white is the box-averaged radiance of the VI point c_k - v * o
    p = dataclasses.replace(syn.PRESETS["raytrix"], type_focus=(4.0, 4.0, 4.0))
    sim = syn.simulate(p, noise=False, shape=(280, 350), scene=[Plane(4.0, texture_seed=5)])
    grid = sim.grid
    assert np.all(sim.truth["blur_sigma"] == 0)
    np.testing.assert_allclose(sim.truth["virtual_depth"], 4.0)
    np.testing.assert_allclose(sim.disparity, grid.pitch / 4.0, rtol=1e-6)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = sim.raw.normalised().astype(np.float64) / sim.white.normalised()
    h, w = sim.raw.shape
    rr, cc = np.mgrid[:h, :w].astype(np.float64)
    lens = syn.assign_pixels(grid, rr, cc)
    c = grid.lattice_to_sensor(lens.i * grid.row_spacing,
                               lens.j * grid.pitch + grid.odd_row_shift * grid.pitch * np.mod(lens.i, 2))
    vy, vx = c[..., 0] - 4.0 * (rr - c[..., 0]), c[..., 1] - 4.0 * (cc - c[..., 1])   # X = c_k - v o
    inside = (sim.white.normalised() > 0.3) & (vy > 2) & (vy < h - 3) & (vx > 2) & (vx < w - 3)
    assert inside.sum() > 5000
    tf = sim.truth["total_focus"][..., 0].astype(np.float64)
    want = ndimage.map_coordinates(tf, [vy[inside], vx[inside]], order=1)
    span = p.white - p.black
    err = np.abs(ratio[inside] - want)
    # the pixel box (1 px in o = 4 px in the VI) and bilinear reading of total_focus
    assert err.mean() < 2e-3 and err.max() < 0.02 + 2 / span, (err.mean(), err.max())


def test_focused_lens_types_blur_by_virtual_depth():
    sim = syn.simulate("raytrix", noise=False, scene=[Plane(5.0, texture_seed=1)])
    grid, p = sim.grid, sim.preset
    h, w = sim.raw.shape
    rr, cc = np.mgrid[:h, :w]
    lens = syn.assign_pixels(grid, rr, cc)
    wn = sim.white.normalised()
    ratio = np.where(wn > 0.5, sim.raw.normalised() / np.maximum(wn, 1e-3), np.nan)
    types = np.asarray(syn.raytrix_lens_types(grid))
    sharp_type = int(np.argmin(np.abs(1 / 5.0 - 1 / np.asarray(p.type_focus))))
    assert sharp_type == 2
    # spread of raw/white inside each micro-image, averaged per lens type
    ok = np.isfinite(ratio) & (lens.i >= 0) & (lens.i < grid.shape[0]) & (lens.j >= 0) & (lens.j < grid.shape[1])
    label = np.where(ok, lens.i * grid.shape[1] + lens.j + 1, 0)
    ids = np.arange(1, grid.shape[0] * grid.shape[1] + 1)
    count = ndimage.sum(ok, label, ids)
    with np.errstate(invalid="ignore", divide="ignore"):
        spread = ndimage.standard_deviation(np.nan_to_num(ratio), label, ids)
    full = count > 400
    contrast = {t: spread[full & (types.ravel() == t)].mean() for t in range(3)}
    assert contrast[2] > 1.5 * contrast[0] and contrast[1] > contrast[0]
    # blur sigma: D |1/v - 1/v_f| / 4 per type
    sig = sim.truth["blur_sigma"]
    for t in range(3):
        want = grid.pitch * abs(1 / 5.0 - 1 / p.type_focus[t]) / 4
        sel = (lens.i >= 0) & (lens.i < grid.shape[0]) & (lens.j >= 0) & (lens.j < grid.shape[1])
        sel &= types[np.clip(lens.i, 0, grid.shape[0] - 1), np.clip(lens.j, 0, grid.shape[1] - 1)] == t
        np.testing.assert_allclose(sig[sel], want, rtol=1e-5)


def test_focused_default_scene_truth():
    sim = syn.simulate("raytrix", seed=1, shape=(350, 500))
    t = sim.truth
    assert t["lens_type"].shape == sim.grid.shape
    np.testing.assert_array_equal(t["lens_type"], sim.grid.lens_type)
    v = t["virtual_depth"]
    assert v.shape == (350, 500) and 2.1 < v.min() < 2.3 and 4.9 < v.max() < 5.1
    assert t["total_focus"].shape == (350, 500, 1)
    with pytest.raises(ValueError, match="focused"):
        sim.ground_truth_lightfield()


# ---------------------------------------------------------------------------------------- writing
@pytest.mark.parametrize("name,shape", [("illum-mini", (96, 128)), ("f01-mini", (96, 128)), ("square", (110, 138)),
                                        ("raytrix", (140, 175))])
def test_write_simulation_round_trips_through_read_raw(tmp_path, name, shape):
    from plenodecode.io import read_raw

    sim = syn.simulate(name, seed=4, shape=shape)
    paths = syn.write_simulation(sim, tmp_path, name="cap")
    assert set(paths) == set(syn.simulation_files(name, "cap"))
    assert all(q.is_file() for q in paths.values())
    raw, white = read_raw(paths["raw"]), read_raw(paths["white"])
    np.testing.assert_array_equal(raw.mosaic, sim.raw.mosaic)
    np.testing.assert_array_equal(white.mosaic, sim.white.mosaic)
    for got, want in ((raw, sim.raw), (white, sim.white)):
        assert got.cfa == want.cfa
        np.testing.assert_array_equal(got.black, want.black)
        np.testing.assert_array_equal(got.white, want.white)
        assert got.metadata.serial == want.metadata.serial
    assert white.metadata.is_white_image and not raw.metadata.is_white_image
    if sim.raw.cfa is not None:
        assert raw.metadata.wb_gains == pytest.approx(dict(sim.raw.metadata.wb_gains))
        np.testing.assert_allclose(np.asarray(raw.metadata.ccm), np.asarray(sim.raw.metadata.ccm), atol=1e-6)
    truth = syn.load_truth(paths["truth_json"])
    assert truth.grid.to_dict() == sim.grid.to_dict()
    np.testing.assert_array_equal(truth.centres, sim.grid.centres())
    np.testing.assert_array_equal(truth.disparity, sim.disparity)
    assert truth.preset == name and truth.seed == 4
    if name == "raytrix":
        assert truth.lightfield is None
        np.testing.assert_array_equal(truth.arrays["lens_type"], sim.grid.lens_type)
        np.testing.assert_array_equal(truth.arrays["total_focus"], sim.truth["total_focus"])
    else:
        assert truth.scene == sim.scene
        lf = sim.ground_truth_lightfield()
        np.testing.assert_array_equal(truth.lightfield.data, lf.data)
        np.testing.assert_array_equal(truth.lightfield.weight, lf.weight)
    # never overwrite silently; nothing half-written
    before = {k: q.stat().st_mtime_ns for k, q in paths.items()}
    with pytest.raises(FileExistsError):
        syn.write_simulation(sim, tmp_path, name="cap")
    assert {k: q.stat().st_mtime_ns for k, q in paths.items()} == before
    syn.write_simulation(sim, tmp_path, name="cap", overwrite=True, lightfield=False)
    assert not [q for q in tmp_path.iterdir() if q.name.endswith(".tmp")]


def test_load_truth_rejects_foreign_files(tmp_path):
    from plenodecode.errors import FormatError

    bad = tmp_path / "x.truth.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(FormatError, match="format"):
        syn.load_truth(bad)
    with pytest.raises(FormatError):
        syn.load_truth(tmp_path / "missing.truth.json")


def test_cli_synth_writes_files_and_refuses_to_overwrite(tmp_path):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.cli.synth import PRESET_NAMES

    assert set(PRESET_NAMES) == set(syn.PRESETS)
    args = ["synth", "f01-mini", "-o", str(tmp_path), "--seed", "3", "--offset", "0.25", "-0.4",
            "--shape", "96", "128", "--no-noise"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert "scene.lfp" in res.output and "MOD_0000.RAW" in res.output
    truth = syn.load_truth(tmp_path / "scene.truth.json")
    assert truth.grid.to_dict() == syn.make_grid("f01-mini", offset=(0.25, -0.4), shape=(96, 128)).to_dict()
    assert truth.document["noise"] is False and truth.seed == 3
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = CliRunner().invoke(cli, [*args, "--overwrite"])
    assert res.exit_code == 0, res.output
