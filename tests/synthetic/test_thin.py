"""Thin-structure scenes (issue 20): the stripes support and the per-plane rim in the kernels against the
numpy model, the layout of the named scenes, and their ground truth in the ideal light field."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode import synthetic as syn
from plenodecode.synthetic.scene import (
    Plane, Scene, box_radiance, build_textures, front_disparity, stripes_signed_distance)
from plenodecode.synthetic.thin import (
    SPACING, THIN_BACKGROUNDS, THIN_JUMPS, THIN_KINDS, THIN_ORIENTATIONS, THIN_RIM, THIN_SCENES, THIN_WIDTHS,
    WEAK_CONTRAST, thin_scene)

EYE = np.eye(3)


def _textures(scene, ny, nx):
    return build_textures(scene, ny, nx, mono=False, cam_matrix=EYE)


@pytest.mark.parametrize("rim", [0.0, 0.5, 2.0])
def test_stripes_coverage_in_the_kernel_is_the_smoothstep_of_the_numpy_signed_distance(rim):
    # a white stripes plane (oblique, bounded) over a black plane: the single ray's radiance is the coverage
    sup = ("stripes", 30.0, 1.5, 5.0, 0.3, 4.0, 6.0, 30.0, 25.0)
    scene = Scene((Plane(0.0, support=sup, colour=(1, 1, 1), rim=rim), Plane(0.0, colour=(0, 0, 0), depth_order=1)))
    tex = _textures(scene, 36, 32)
    rng = np.random.default_rng(0)
    y, x = rng.uniform(-2, 38, 4000), rng.uniform(-2, 34, 4000)
    got = box_radiance(tex, y, x, 0.0, 0.0, 0, space="srgb", box=0)
    sd = stripes_signed_distance(tex.prm[0], y, x)
    if rim == 0:
        want = (sd < 0).astype(float)
    else:
        t = np.clip(0.5 - sd / rim, 0, 1)
        want = t * t * (3 - 2 * t)
    assert np.abs(got - want).max() < 1e-6
    assert 0.1 < want.mean() < 0.5                      # both sides sampled
    assert np.array_equal(front_disparity(tex, y, x) == 0, np.isfinite(sd))   # one plane covers everything


def test_stripes_geometry_widths_period_and_box():
    prm = build_textures(Scene((Plane(0.0, support=("stripes", 90.0, 2.0, 7.0, -0.5)),)), 4, 4,
                         mono=True, cam_matrix=EYE).prm[0]
    x = np.arange(-7, 14, dtype=float)
    inside = stripes_signed_distance(prm, np.zeros_like(x), x) <= 0
    assert x[inside].tolist() == [-7, -6, 0, 1, 7, 8]        # slats on [-0.5, 1.5] + 7 m: vertical, 2 px wide
    boxed = build_textures(Scene((Plane(0.0, support=("stripes", 0.0, 2.0, 7.0, -0.5, 0, 0, 10, 3)),)), 4, 4,
                           mono=True, cam_matrix=EYE).prm[0]
    y = np.arange(-3, 12, dtype=float)
    assert y[stripes_signed_distance(boxed, y, np.full_like(y, 2.0)) <= 0].tolist() == [0, 1, 7, 8]
    assert not (stripes_signed_distance(boxed, y, np.full_like(y, 3.5)) <= 0).any()     # right of the box
    with pytest.raises(ValueError, match="width < period"):
        Plane(0.0, support=("stripes", 0.0, 3.0, 3.0, 0.0))
    with pytest.raises(ValueError, match="4 or 8"):
        Plane(0.0, support=("stripes", 0.0, 1.0, 3.0))
    with pytest.raises(ValueError, match="rim"):
        Plane(0.0, rim=-1.0)
    with pytest.raises(ValueError, match="contrast"):
        Plane(0.0, contrast=0.0)
    p = Plane(0.5, support=("stripes", 30.0, 1.0, 7.0, 0.0), rim=0.5, contrast=0.2)
    assert Plane.from_dict(p.to_dict()) == p
    assert set(Plane(0.5).to_dict()) == {"d0", "gradient", "support", "depth_order", "texture_seed", "colour"}


def test_registry_holds_every_combination():
    assert len(THIN_SCENES) == len(THIN_KINDS) * len(THIN_ORIENTATIONS) * len(THIN_JUMPS) * len(THIN_BACKGROUNDS) == 36
    assert {"slats-h-j0.5-tex", "slits-o-j2-weak", "slats-v-j1-weak"} <= set(THIN_SCENES)
    sc = THIN_SCENES["slits-o-j2-weak"](40, 60, 3)
    assert sc.name == "slits-o-j2-weak" and len(sc.planes) == 5
    far, *near = sc.ordered()[::-1]
    assert far.d0 == -1.0 and far.contrast == WEAK_CONTRAST and far.support == ("all",)
    assert all(p.d0 == 1.0 and p.rim == THIN_RIM and p.support[1] == 30.0 for p in near)
    with pytest.raises(ValueError, match="orientation"):
        thin_scene(40, 60, orientation="x")


def _runs(line: np.ndarray) -> tuple[list[int], list[int]]:
    """Lengths of the complete runs of True and of False in a 1-D bool array (the first and last runs dropped)."""
    edges = np.flatnonzero(np.diff(line.astype(int))) + 1
    parts = np.split(line, edges)[1:-1]
    return [len(p) for p in parts if p[0]], [len(p) for p in parts if not p[0]]


@pytest.mark.parametrize("kind", THIN_KINDS)
@pytest.mark.parametrize("orientation", ["h", "v"])
def test_truth_has_the_asked_widths_in_each_panel(kind, orientation):
    ny, nx = 80, 100
    sc = thin_scene(ny, nx, kind=kind, orientation=orientation, jump=1.0)
    truth = front_disparity(_textures(sc, ny, nx), *np.mgrid[0:ny, 0:nx].astype(float))
    near = truth == 0.5
    assert set(np.unique(truth)) == {-0.5, 0.5}
    panels = [(slice(0, 40), slice(0, 50)), (slice(0, 40), slice(50, 100)),
              (slice(40, 80), slice(0, 50)), (slice(40, 80), slice(50, 100))]
    for width, (rows, cols) in zip(THIN_WIDTHS, panels):
        block = near[rows, cols][1:-1, 1:-1]       # slit panels overlap their neighbours by 1 px
        line = block[block.shape[0] // 2] if orientation == "v" else block[:, block.shape[1] // 2]
        slats, gaps = _runs(line)
        thin, wide = (slats, gaps) if kind == "slats" else (gaps, slats)
        assert set(thin) == {int(width)} and set(wide) == {int(SPACING)}, (width, slats, gaps)
        # slats run across the whole panel: constant along their direction
        assert (block == (block[:1] if orientation == "v" else block[:, :1])).all()


@pytest.mark.parametrize("orientation", ["h", "v", "o"])
def test_slat_angle_from_the_spectrum_of_the_truth(orientation):
    ny = nx = 128
    sc = thin_scene(ny, nx, kind="slats", orientation=orientation, jump=1.0)
    near = front_disparity(_textures(sc, ny, nx), *np.mgrid[0:ny, 0:nx].astype(float)) > 0
    block = near[64:, 64:] - near[64:, 64:].mean()                         # the 5 px panel
    spec = np.abs(np.fft.fft2(block))
    spec[0, 0] = 0
    fy, fx = np.unravel_index(np.argmax(spec), spec.shape)
    fy, fx = (np.array([fy, fx]) + 32) % 64 - 32                            # signed frequencies
    angle = np.degrees(np.arctan2(abs(fx), abs(fy)))                        # slat normal from the y axis
    assert angle == pytest.approx(THIN_ORIENTATIONS[orientation], abs=4.0)
    assert near[64:, 64:].mean() == pytest.approx(5 / 11, abs=0.03)


def test_weak_background_has_the_reduced_contrast():
    tex = _textures(Scene((Plane(0.0, texture_seed=5), Plane(0.0, texture_seed=5, contrast=WEAK_CONTRAST))), 30, 30)
    full, weak = tex.srgb[0], tex.srgb[1]
    assert weak.std(axis=(1, 2)) == pytest.approx(WEAK_CONTRAST * full.std(axis=(1, 2)), rel=0.05)


@pytest.mark.parametrize("name", ["slats-v-j1-tex", "slits-o-j1-weak", "slats-h-j0.5-tex"])
def test_truth_disparity_aligns_the_views_in_slats_and_gaps(name):
    """view(v, u) at (y, x) - d (v - vc, u - uc) equals the centre view at (y, x) for the truth d, wherever the
    surface is seen whole (every sub-ray of the view's pixel box hits it, by the numpy model)."""
    ny, nx = 40, 56
    sc = THIN_SCENES[name](ny, nx, 2)
    tex = _textures(sc, ny, nx)
    yy, xx = np.mgrid[4:ny - 4, 4:nx - 4].astype(float)
    d = front_disparity(tex, yy, xx).astype(np.float64)
    near_d, far_d = d.max(), d.min()
    centre = box_radiance(tex, yy, xx, 0.0, 0.0, 1, space="srgb")
    sub = syn.SUBSAMPLES

    def near_sd(py, px):
        return np.min([stripes_signed_distance(tex.prm[k], py, px) for k in range(4)], axis=0)

    def sds(a, b):      # near planes' signed distances at the hit points of the sub-rays of view (a, b)
        return [near_sd(yy - d * a + near_d * (a + da), xx - d * b + near_d * (b + db)) for da in sub for db in sub]

    checked = {"near": 0, "far": 0}
    for a in (-2, 1, 3):
        for b in (-3, 0, 2):
            view = box_radiance(tex, yy - d * a, xx - d * b, float(a), float(b), 1, space="srgb")
            both = sds(0, 0) + sds(a, b)        # the surface must be seen whole in the centre view and in this one
            whole_near = (d == near_d) & (np.max(both, axis=0) <= -0.5 * THIN_RIM)
            clear_far = (d == far_d) & (np.min(both, axis=0) >= 0.5 * THIN_RIM)
            for mask, key in ((whole_near, "near"), (clear_far, "far")):
                assert np.abs(view[mask] - centre[mask]).max(initial=0) < 1e-5, (a, b, key)
                checked[key] += int(mask.sum())
    n = yy.size * 9
    assert checked["near"] > 0.15 * n and checked["far"] > 0.03 * n, checked


def test_named_scene_renders_through_simulate():
    sim = syn.simulate("illum-mini", seed=1, noise=False, shape=(420, 560), scene=THIN_SCENES["slats-v-j2-tex"])
    ny, nx = sim.disparity.shape
    assert sim.scene.name == "slats-v-j2-tex" and sim.disparity_range == (-1.0, 1.0)
    assert set(np.unique(sim.disparity)) == {-1.0, 1.0}
    assert sim.raw.mosaic.std() > 100                                        # a scene, not a flat field
    lf = sim.ground_truth_lightfield(n_views=3)
    assert lf.data.shape == (3, 3, ny, nx, 3) and np.isfinite(lf.data).all()
    with pytest.raises(ValueError, match="unfocused"):
        syn.simulate("raytrix", scene=THIN_SCENES["slats-v-j2-tex"])


def test_simulate_ideal_is_the_simulations_ground_truth_without_the_raw():
    kw = dict(seed=4, shape=(300, 400), scene=THIN_SCENES["slits-v-j0.5-tex"])
    sim = syn.simulate("illum-mini", noise=False, **kw)
    lf, disp = syn.simulate_ideal("illum-mini", n_views=5, **kw)
    ref = sim.ground_truth_lightfield(n_views=5)
    assert np.array_equal(lf.data, ref.data) and np.array_equal(lf.weight, ref.weight)
    assert np.array_equal(disp, sim.disparity)
    assert lf.metadata["disparity_range"] == list(sim.disparity_range) == [-0.25, 0.25]
    with pytest.raises(ValueError, match="unfocused"):
        syn.simulate_ideal("raytrix")
