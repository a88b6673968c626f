"""Scene raws of the synthetic generator and their ground truth: the radiance kernels against an
independent model, raw / white against the camera radiance, disparity maps, ground-truth light fields."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from plenodecode import synthetic as syn
from plenodecode.synthetic.scene import SUPPORT_EDGE, Plane, Scene, box_radiance
from plenodecode.types import cfa_channel_map


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
