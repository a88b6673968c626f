"""The occlusion-edge fix (visibility check, colour-guided weighted median, per-pixel visibility relabel, coverage
relabel)."""

import numpy as np
import pytest
from scipy import ndimage

from plenodecode.depth.confidence import image_noise
from plenodecode.depth.occlusion import (coverage_relabel, fix_occlusion_edges, mixing_agrees, nearest_surface,
                                         two_colour_edge, visibility_relabel)
from plenodecode.depth.views import colour_guide, prepare_views
from plenodecode.types import LightField
from tests.depth.test_methods import _texture, planes_lightfield


def test_foreground_fattening_is_removed(scene):
    """A map whose square is fattened by 3 px (the error SGM makes beside an occluder) is repaired: the
    fattened background fails the all-view visibility test and goes back to the far disparity."""
    lf, gt, views = scene
    front = gt > 0
    fat = np.where(ndimage.binary_dilation(front, iterations=3), 1.0, -0.6).astype(np.float32)
    before = fat.copy()
    wrong_before = np.count_nonzero(np.abs(fat - gt) > 0.5)            # 3-px ring of the square: 324 px
    fixed = fix_occlusion_edges(views, fat, colour_guide(lf))
    wrong_after = np.count_nonzero(np.abs(fixed - gt) > 0.5)
    assert wrong_before > 300
    assert wrong_after < 0.33 * wrong_before                             # measured 77 px (24 %)
    np.testing.assert_array_equal(fat, before)                          # input not modified


def test_visibility_check_alone_and_a_correct_map(scene):
    lf, gt, views = scene
    front = gt > 0
    fat = np.where(ndimage.binary_dilation(front, iterations=2), 1.0, -0.6).astype(np.float32)
    only_check = fix_occlusion_edges(views, fat, colour_guide(lf), median_radius=0)
    # measured 212 -> 59 wrong pixels
    assert np.count_nonzero(np.abs(only_check - gt) > 0.5) < 0.33 * np.count_nonzero(np.abs(fat - gt) > 0.5)
    # the true map is kept: the occluder passes the all-view test (measured 5 px changed)
    same = fix_occlusion_edges(views, gt, colour_guide(lf), median_radius=0)
    assert np.count_nonzero(np.abs(same - gt) > 0.5) <= 8
    flat = np.full_like(gt, 0.3)                                        # no edge: returned unchanged
    np.testing.assert_array_equal(fix_occlusion_edges(views, flat, colour_guide(lf)), flat)


def test_edge_fix_is_deterministic(scene):
    """OpenCV's colour-guided weighted median clusters colours from random seeds; the fix seeds it, so the
    same input gives the same map (the batch compares its depth products with a direct run)."""
    lf, gt, views = scene
    front = gt > 0
    fat = np.where(ndimage.binary_dilation(front, iterations=2), 1.0, -0.6).astype(np.float32)
    noisy = fat + np.random.default_rng(1).normal(0.0, 0.05, fat.shape).astype(np.float32)
    guide = colour_guide(lf)
    runs = [fix_occlusion_edges(views, noisy, guide) for _ in range(3)]
    for r in runs[1:]:
        np.testing.assert_array_equal(r, runs[0])


def test_wedge_sees_into_a_concave_pocket():
    """Background at the bottom of a pocket in the occluder's outline (a U) is hidden from the views on
    both sides, so a half-plane of views looks past the arms while a 90 degree wedge does not: the
    visibility check with the wedge moves more of the fattened pocket back to the background."""
    wrong = {2: 0, 4: 0}
    for seed in range(3):
        u_shape = [(14, 50, 16, 27), (14, 50, 37, 48), (40, 50, 16, 48)]      # a 10 px wide pocket
        lf, gt = planes_lightfield(n=7, size=64, d_back=-0.6, d_front=1.0, square=u_shape, seed=seed)
        views = prepare_views(lf, grey=True, contrast_sigma=1.5, contrast_eps=0.005, contrast_weight=0.07)
        fat = np.where(ndimage.binary_dilation(gt > 0, iterations=3), 1.0, -0.6).astype(np.float32)
        pocket = np.zeros(gt.shape, bool)
        pocket[14:40, 27:37] = True
        for wedge in wrong:
            fixed = fix_occlusion_edges(views, fat, colour_guide(lf), wedge=wedge, median_radius=0)
            wrong[wedge] += np.count_nonzero((np.abs(fixed - gt) > 0.5) & pocket)
    # the fattening fills 3 x 168 pocket pixels; measured 47 left wrong with the wedge, 65 with half-planes
    assert wrong[2] < 60 and wrong[2] < 0.8 * wrong[4]


def rimmed_square_lightfield(n=7, size=64, d_back=-1.5, d_front=1.0, rim=2, seed=0):
    """A bright textured square with a dark ``rim`` px border, in front of a dim textured background whose
    mean is the rim's: the silhouette rim of a lit statue against a shadowed wall (hci-antinous), which the
    colour-guided median cuts off.  Exact occlusion, HCI convention (see ``planes_lightfield``)."""
    rng = np.random.default_rng(seed)
    pad = 16
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    back = 0.27 + 0.05 * (_texture(rng, (size + 2 * pad,) * 2) - 0.5)
    front = _texture(rng, (size + 2 * pad,) * 2)
    y0, y1, x0, x1 = 20, 44, 18, 46
    fy, fx = np.mgrid[-pad:size + pad, -pad:size + pad].astype(np.float64)
    edge_dist = np.minimum.reduce([fy - y0, y1 - 1 - fy, fx - x0, x1 - 1 - fx])
    front = np.where(edge_dist < rim, 0.25 + 0.05 * (front - 0.5), 0.5 + 0.5 * front)
    data = np.empty((n, n, size, size, 1), np.float32)
    c = n // 2
    for v in range(n):
        for u in range(n):
            sy, sx = yy + d_front * (v - c), xx + d_front * (u - c)
            inside = (sy >= y0) & (sy < y1) & (sx >= x0) & (sx < x1)
            f = ndimage.map_coordinates(front, [sy + pad, sx + pad], order=1, mode="nearest")
            b = ndimage.map_coordinates(back, [yy + d_back * (v - c) + pad, xx + d_back * (u - c) + pad],
                                        order=3, mode="nearest")
            data[v, u, :, :, 0] = np.where(inside, f, b)
    inside_c = (yy >= y0) & (yy < y1) & (xx >= x0) & (xx < x1)
    gt = np.where(inside_c, d_front, d_back).astype(np.float32)
    return LightField(data, None, "srgb", {"disparity_range": [-2.0, 1.5]}), gt, inside_c


def test_visibility_relabel_restores_a_dark_rim_and_removes_fattening():
    """Per-pixel visibility puts the silhouette rim back on the occluder (the median of step 2 gives it to
    the background, whose colour it has) and a fattened ring back on the background."""
    lf, gt, front = rimmed_square_lightfield()
    plain = prepare_views(lf, grey=True)
    eroded = np.where(ndimage.binary_erosion(front, iterations=2), 1.0, -1.5).astype(np.float32)
    fattened = np.where(ndimage.binary_dilation(front, iterations=1), 1.0, -1.5).astype(np.float32)
    for wrong_map in (eroded, fattened):
        before = np.count_nonzero(np.abs(wrong_map - gt) > 0.5)        # 176 and 96 px
        after = np.count_nonzero(np.abs(visibility_relabel(plain, wrong_map) - gt) > 0.5)
        assert before > 90 and after < 0.2 * before, (before, after)
    kept = visibility_relabel(plain, gt)                           # a correct map stays correct
    assert np.count_nonzero(np.abs(kept - gt) > 0.5) <= 4
    flat = np.full_like(gt, 0.3)
    np.testing.assert_array_equal(visibility_relabel(plain, flat), flat)


def test_visibility_relabel_reopens_narrowed_oblique_slits():
    """A far plane seen through oblique 3 and 5 px slits is visible in few views (the strip along the slit):
    with the slits narrowed by 1 px of fattening, the relabel reopens about half of that ring (no fewer
    than 35 %; with a minimum visible view weight of 0.25, the old default, under 2 %) and puts few other
    pixels wrong."""
    from plenodecode.synthetic import simulate_ideal
    from plenodecode.synthetic.thin import THIN_SCENES

    lf, gt = simulate_ideal("illum-mini", seed=1, scene=THIN_SCENES["slits-o-j1-tex"])
    plain = prepare_views(lf, grey=True)
    near = gt > 0
    fat = np.where(ndimage.binary_dilation(near, np.ones((3, 3), bool)), gt.max(), gt.min()).astype(np.float32)
    judged = np.zeros_like(near)
    judged[gt.shape[0] // 2:-5, 5:-5] = True                        # the panels of 3 and 5 px slits
    ring = judged & (fat != gt)
    for min_visible, lowest, highest in ((None, 0.35, 1.0), (0.25, 0.0, 0.02)):     # None: the default, 0.05
        out = visibility_relabel(plain, fat, **({} if min_visible is None else {"min_visible": min_visible}))
        restored = np.count_nonzero(ring & (np.abs(out - gt) <= 0.07)) / np.count_nonzero(ring)
        newly_wrong = np.count_nonzero(judged & ~ring & (np.abs(out - gt) > 0.07))
        assert lowest <= restored <= highest, (min_visible, restored)
        assert newly_wrong < 0.1 * np.count_nonzero(ring), (min_visible, newly_wrong)


def test_nearest_surface_is_a_z_buffer():
    """Every centre pixel lands at p - d (dv, du); the nearer of two surfaces landing on a pixel wins."""
    d = np.full((8, 8), -1.0, np.float32)
    d[3:5, 3:5] = 2.0
    z = nearest_surface(d, 0.0, 1.0)                               # the view one step to the right
    # the square (x 3..4) lands at x - 2 = 1..2, over the background that lands at x + 1
    assert np.all(z[3:5, 1:4] == 2.0) and z[3, 4] == -1.0 and z[0, 5] == -1.0
    assert np.all(np.isneginf(z[:, 0]))                                 # nothing lands at x = 0 (x + 1 >= 1)


@pytest.mark.parametrize("method", ["costvolume", "fast"])
def test_methods_keep_the_dark_rim_on_the_occluder(method):
    """End to end: without the relabel the methods give the whole 2 px rim to the background (measured 192
    wrong pixels for both methods, without the thin-structure strips and cost gate); with it none is wrong.
    (The coverage relabel after it, off here, alone puts back about half of the rim: no background moves
    through the rim's pixels.)  The strips and the gate alone keep about half of the rim (97 wrong)."""
    from plenodecode.depth import estimate_depth
    lf, gt, _ = rimmed_square_lightfield(seed=1)
    no_thin = {"strips": 0, "gate_ratio": 0.0}
    wrong = {v: np.count_nonzero(np.abs(estimate_depth(lf, method=method, edge_visibility=v, edge_coverage=False,
                                                       **no_thin).disparity - gt) > 0.5)
             for v in (False, True)}
    assert wrong[False] > 150 and wrong[True] <= 10, wrong
    default = np.count_nonzero(np.abs(estimate_depth(lf, method=method, edge_coverage=False).disparity - gt) > 0.5)
    assert default <= 10, default


def disc_lightfield(n=7, size=64, radius=20.3, centre=(31.6, 32.4), d_front=1.0, d_back=-1.5, ss=4, seed=0,
                    flat_back=False):
    """A textured disc in front of a textured (or flat) background, every view box-filtered over ``ss x ss``
    samples per pixel: pixels on the outline mix both surfaces by their exact coverage, as a rendered or
    photographed edge does.  Ground truth at the pixel centres; also returns the disc's coverage (Y, X)."""
    rng = np.random.default_rng(seed)
    pad = 16
    front = 0.55 + 0.4 * _texture(rng, (size + 2 * pad,) * 2)
    back = (np.full((size + 2 * pad,) * 2, 0.3) if flat_back
            else 0.1 + 0.4 * _texture(rng, (size + 2 * pad,) * 2))
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    data = np.zeros((n, n, size, size, 1), np.float32)
    cover = np.zeros((size, size))
    c = n // 2
    for oy in sub:
        for ox in sub:
            cover += (np.hypot(yy + oy - centre[0], xx + ox - centre[1]) < radius) / ss ** 2
            for v in range(n):
                for u in range(n):
                    fy, fx = yy + oy + d_front * (v - c), xx + ox + d_front * (u - c)
                    inside = np.hypot(fy - centre[0], fx - centre[1]) < radius
                    f = ndimage.map_coordinates(front, [fy + pad, fx + pad], order=1)
                    b = ndimage.map_coordinates(back, [yy + oy + d_back * (v - c) + pad,
                                                       xx + ox + d_back * (u - c) + pad], order=1)
                    data[v, u, :, :, 0] += np.where(inside, f, b) / ss ** 2
    gt = np.where(np.hypot(yy - centre[0], xx - centre[1]) < radius, d_front, d_back).astype(np.float32)
    return LightField(data, None, "srgb", {"disparity_range": [-2.0, 1.5]}), gt, cover


def test_coverage_relabel_gives_mixed_pixels_to_the_surface_at_their_centre():
    """Maps that give the disc every pixel it touches, or only the pixels it covers whole, are both moved to
    the pixel-centre outline; a correct map stays, but for pixels covered by exactly half (their centre is
    on the outline: either side is right).  Over a flat background (no slope to measure) the centre view's
    clean two-colour edge does most of it."""
    lf, gt, cover = disc_lightfield()
    plain = prepare_views(lf, grey=True)
    touched = np.where(cover > 0, 1.0, -1.5).astype(np.float32)
    covered = np.where(cover >= 1, 1.0, -1.5).astype(np.float32)
    for wrong_map in (touched, covered):
        before = np.count_nonzero(np.abs(wrong_map - gt) > 0.5)        # 74 and 54 px
        kept = wrong_map.copy()
        after = np.count_nonzero(np.abs(coverage_relabel(plain, wrong_map) - gt) > 0.5)   # 6 and 4
        assert before > 50 and after < 0.2 * before, (before, after)
        np.testing.assert_array_equal(wrong_map, kept)                  # input not modified
    # 2 px, both covered by 8/16 samples (the others may take their side's hypothesis, a Gaussian mean of
    # the side's equal values: the same up to float rounding)
    moved = np.abs(coverage_relabel(plain, gt) - gt) > 1e-4
    assert moved.sum() <= 3 and np.all(np.abs(cover[moved] - 0.5) < 0.07), cover[moved]
    flat_lf, _, _ = disc_lightfield(flat_back=True)
    flat = prepare_views(flat_lf, grey=True)
    for wrong_map in (touched, covered):
        before = np.count_nonzero(np.abs(wrong_map - gt) > 0.5)
        after = np.count_nonzero(np.abs(coverage_relabel(flat, wrong_map) - gt) > 0.5)   # 14 and 9
        assert after < 0.25 * before, (before, after)


def test_views_give_the_light_back_for_the_mixing_models():
    """Views of a linear light field are display-encoded for matching; ``Views.linear`` undoes that (up to the
    views' common scale), as the coverage models need; stored sRGB values are used as they are."""
    rng = np.random.default_rng(0)
    data = rng.uniform(0.05, 1.0, (3, 3, 6, 7, 3)).astype(np.float32)
    for colour, gamma in (("linear-srgb", 2.2), ("srgb", 1.0)):
        views = prepare_views(LightField(data, None, colour, {}))
        assert views.encoding_gamma == gamma
        ratio = views.linear((0, 2)) / data[0, 2]
        np.testing.assert_allclose(ratio, ratio.flat[0], rtol=1e-4)


def test_two_colour_edge_gives_the_coverage_and_the_flatness_of_the_sides():
    """Across a vertical edge at x = 10.3 between two flat colours, box-filtered, each pixel's position between
    its neighbours one pixel either side is the fraction the right side covers; the flatness is 0 where both
    neighbours and the pixels beyond them are pure, and measures the mixed pixel otherwise; equal
    neighbours give NaN."""
    back, front = np.array([0.2, 0.5, 0.1]), np.array([0.7, 0.3, 0.6])
    x = np.arange(24, dtype=np.float64)
    cover = np.clip(x + 0.5 - 10.3, 0.0, 1.0)                            # of the right side (front)
    row = back + cover[:, None] * (front - back)
    image = np.repeat(row[None], 8, axis=0).astype(np.float32)          # (8, 24, 3)
    xs = np.array([9, 10, 11, 3])
    ys = np.full(4, 4)
    normal = np.tile([0.0, 1.0], (4, 1))                                 # (y, x): towards the front
    m, flatness = two_colour_edge(image, ys, xs, normal)
    np.testing.assert_allclose(m[:3], [0.0, 0.2, 1.0], atol=1e-5)
    # x = 9: |I(11) - I(10)| / |I(10) - I(8)| = 0.8 / 0.2; x = 11: |I(9) - I(10)| / |I(12) - I(10)| = 0.2 / 0.8
    np.testing.assert_allclose(flatness[:3], [4.0, 0.0, 0.25], atol=1e-5)
    assert np.isnan(m[3]) and np.isnan(flatness[3])                     # flat: no estimate


def test_only_a_mix_backs_the_coverage_estimate():
    """The colour mixing agrees with a coverage estimate on the same side of 1/2 only when it is a mix: a
    pixel darker than both its neighbours (mixing < 0) or brighter (> 1), or without contrast, does not."""
    mixed = np.array([0.2, 0.8, 0.2, -0.4, 1.3, np.nan, 0.7])
    covered = np.array([0.1, 0.9, 0.9, 0.1, 0.9, 0.1, 0.3])
    np.testing.assert_array_equal(mixing_agrees(mixed, covered),
                                  [True, True, False, False, False, False, False])


@pytest.mark.parametrize("method", ["costvolume", "fast"])
def test_methods_put_the_outline_at_the_pixel_centres(method):
    """End to end on the box-filtered disc: photo-consistency gives the disc the pixels it covers by about
    15 % or more (measured 57 and 58 wrong pixels); the coverage relabel leaves 6 and 7."""
    from plenodecode.depth import estimate_depth
    lf, gt, _ = disc_lightfield(seed=1)
    wrong = {v: np.count_nonzero(np.abs(estimate_depth(lf, method=method, edge_coverage=v).disparity - gt) > 0.5)
             for v in (False, True)}
    assert wrong[False] > 40 and wrong[True] < 0.25 * wrong[False], wrong


def noisy_step_lightfield(back_amp, n=9, size=40, edge=20.5, d_near=0.0, d_far=-0.5, noise=0.015, seed=0):
    """A textured surface at ``d_near`` right of x = ``edge`` in front of a background at ``d_far`` whose texture
    has amplitude ``back_amp``, every view with white noise ``noise`` (a decoded light field's); point-sampled,
    so the pixels at x = 20 and 21 are pure.  Ground truth (Y, X) float32."""
    rng = np.random.default_rng(seed)
    pad = 12
    front = 0.5 + 0.4 * _texture(rng, (size + 2 * pad,) * 2)
    back = 0.3 + back_amp * _texture(rng, (size + 2 * pad,) * 2)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    c = n // 2
    data = np.zeros((n, n, size, size, 1), np.float32)
    for v in range(n):
        for u in range(n):
            f = ndimage.map_coordinates(front, [yy + d_near * (v - c) + pad, xx + d_near * (u - c) + pad], order=1)
            b = ndimage.map_coordinates(back, [yy + d_far * (v - c) + pad, xx + d_far * (u - c) + pad], order=1)
            data[v, u, :, :, 0] = np.where(xx + d_near * (u - c) > edge, f, b) + rng.normal(0.0, noise, (size, size))
    gt = np.where(xx > edge, d_near, d_far).astype(np.float32)
    return LightField(data, None, "srgb", {"disparity_range": [-2.0, 1.5]}), gt


def test_coverage_relabel_does_not_read_noise_as_coverage():
    """Beside a 0.5 px jump the background point clears the occluder in the views on one side only, where it
    moves by 1.5-2 px: over a weak texture the centre view's samples of it are mostly noise, which shrinks the
    regression's background coefficient towards 0 (regression dilution) and read as 'covered'.  The correct
    map stays (without the reliability test 8 and 13 far pixels went to the near side, seeds 0 and 1;
    measured 0); with a textured background a map whose edge is 1 px off is still put right (40 -> 20 wrong
    pixels, 25 without the test)."""
    for seed in (0, 1):
        lf, gt = noisy_step_lightfield(back_amp=0.003, seed=seed)
        moved = coverage_relabel(prepare_views(lf, grey=True), gt, jump=0.3) != gt
        assert moved.sum() <= 2, (seed, moved.sum())
    lf, gt = noisy_step_lightfield(back_amp=0.4)
    wrong = gt.copy()
    wrong[:, 20] = 0.0
    after = np.count_nonzero(coverage_relabel(prepare_views(lf, grey=True), wrong, jump=0.3) != gt)
    assert after <= 0.6 * np.count_nonzero(wrong != gt), after


def test_white_noise_variance_of_a_textured_image():
    """White noise of standard deviation 0.015 on a ramp with a smooth texture (no noise: estimate ~0) is
    found within 10 % by the robust estimate the coverage relabel uses (measured 0.0152 and 0.0145 for the
    two seeds)."""
    yy, xx = np.mgrid[0:80, 0:90].astype(np.float64)
    clean = 0.2 + 0.004 * xx + 0.1 * np.sin(xx / 5.0) * np.cos(yy / 7.0)
    assert image_noise(clean, robust=True) ** 2 < 1e-6
    for seed in (0, 1):
        noisy = clean + np.random.default_rng(seed).normal(0.0, 0.015, clean.shape)
        assert abs(image_noise(noisy, robust=True) - 0.015) < 0.0015


def test_despeckling_median_is_gated_so_thin_slats_survive(monkeypatch):
    """The 3 x 3 median that despeckles the relabelled band is gated by the matching cost (as the other
    clean-ups): on the ideal slats-v-j1-tex scene the quarter of the 1 and 2 px slats is 1.2 % wrong (the
    whole map 1.4 %); with the plain median it was 7.2 % (4.5 %), so the bound 3 % catches it."""
    from plenodecode.depth import estimate_depth
    from plenodecode.depth import occlusion
    from plenodecode.synthetic import simulate_ideal
    from plenodecode.synthetic.thin import THIN_SCENES

    lf, gt = simulate_ideal("illum-mini", seed=1, scene=THIN_SCENES["slats-v-j1-tex"])

    def thinnest_quarter_wrong() -> tuple[float, float]:
        bad = (np.abs(estimate_depth(lf, method="costvolume").disparity - gt) > 0.07)[5:-5, 5:-5]
        return float(bad[:, :bad.shape[1] // 4].mean()), float(bad.mean())

    quarter, whole = thinnest_quarter_wrong()
    assert quarter < 0.03 and whole < 0.025, (quarter, whole)
    plain = occlusion.visibility_relabel
    monkeypatch.setattr(occlusion, "visibility_relabel", lambda *a, **kw: plain(*a, **{**kw, "despeckle": True}))
    assert thinnest_quarter_wrong()[0] > 0.05


def _near_coverage(scene, shape: tuple[int, int], n: int = 8) -> np.ndarray:
    """Fraction of each centre-view pixel that the stripes supports of ``scene`` cover, from ``n x n``
    point samples per pixel: (Y, X) float64."""
    from plenodecode.synthetic.scene import stripes_signed_distance

    offsets = (np.arange(n) + 0.5) / n - 0.5
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    prms = [np.array([np.cos(np.radians(p.support[1])), np.sin(np.radians(p.support[1])), *p.support[2:]])
            for p in scene.planes if p.support[0] == "stripes"]
    cover = np.zeros(shape)
    for oy in offsets:
        for ox in offsets:
            inside = np.zeros(shape, bool)
            for prm in prms:
                inside |= stripes_signed_distance(prm, yy + oy, xx + ox) <= 0.0
            cover += inside
    return cover / (n * n)


def test_coverage_relabel_finds_the_background_beside_oblique_slats(monkeypatch):
    """Oblique 1-5 px slats 1 px nearer than a textured plane (slats-o-j1-tex): a map that gives the slats
    every pixel they touch is moved to the pixel-centre outline, 1240 wrong pixels -> 133 (bound: a fifth).
    The fit needs the background clear of the occluder by BACKGROUND_MARGIN px; at 2 px, between slats 6 px
    apart whose mixed pixels the map gives the slats, few views' background points are clear: 1100 stayed
    wrong (bound: more than 60 %)."""
    from plenodecode.depth import occlusion
    from plenodecode.synthetic import simulate_ideal
    from plenodecode.synthetic.thin import THIN_SCENES

    build = THIN_SCENES["slats-o-j1-tex"]
    lf, gt = simulate_ideal("illum-mini", seed=1, scene=build)
    cover = _near_coverage(build(*gt.shape, seed=1), gt.shape)
    assert np.mean((cover > 0.5) == (gt > 0)) > 0.99               # pixel centre inside <=> covered by > 1/2
    plain = prepare_views(lf, grey=True)
    touched = np.where(cover > 0, gt.max(), gt.min()).astype(np.float32)

    def wrong(m: np.ndarray) -> int:
        return int(np.count_nonzero((np.abs(m - gt) > 0.07)[5:-5, 5:-5]))

    before = wrong(touched)
    after = wrong(coverage_relabel(plain, touched, jump=0.3))
    assert before > 1000 and after < 0.2 * before, (before, after)
    monkeypatch.setattr(occlusion, "BACKGROUND_MARGIN", 2)
    assert wrong(coverage_relabel(plain, touched, jump=0.3)) > 0.6 * before


def test_coverage_relabel_gives_a_decided_pixel_its_surface():
    """A pixel the coverage relabel gives to a surface takes that surface's disparity also where the map had it
    on that side already: a matched value between the two surfaces (a mix, a ramp left by the window) was kept.
    End to end, BadPix0.07 3.4 % on slats-o-j2-weak and 0.6 % on slats-v-j2-tex (4.2 and 1.3 % before)."""
    from plenodecode.depth import estimate_depth
    from plenodecode.depth.scores import badpix
    from plenodecode.synthetic import simulate_ideal
    from plenodecode.synthetic.thin import THIN_SCENES

    for name, bound in (("slats-o-j2-weak", 3.8), ("slats-v-j2-tex", 1.0)):
        lf, gt = simulate_ideal("illum-mini", seed=1, scene=THIN_SCENES[name])
        assert badpix(estimate_depth(lf, method="costvolume"), gt, 0.07, border=5) <= bound, name


def _badpix_with_and_without(monkeypatch, scene: str, step: str) -> tuple[float, float]:
    """BadPix0.07 (%) of the costvolume method on the ideal light field of thin scene ``scene``, as it is and with
    ``visibility_relabel``'s ``step`` switched off."""
    from plenodecode.depth import estimate_depth
    from plenodecode.depth import occlusion
    from plenodecode.depth.scores import badpix
    from plenodecode.synthetic import simulate_ideal
    from plenodecode.synthetic.thin import THIN_SCENES

    lf, gt = simulate_ideal("illum-mini", seed=1, scene=THIN_SCENES[scene])

    def wrong() -> float:
        return badpix(estimate_depth(lf, method="costvolume"), gt, 0.07, border=5)

    with_it = wrong()
    plain = occlusion.visibility_relabel
    monkeypatch.setattr(occlusion, "visibility_relabel", lambda *a, **kw: plain(*a, **{**kw, step: False}))
    return with_it, wrong()


def test_visibility_relabel_settles_values_between_the_surfaces(monkeypatch):
    """Oblique slats 0.5 px nearer than a textured plane (slats-o-j0.5-tex): their mixed pixels, and the windows
    across their edges, leave values between the two surfaces.  A band pixel whose side the views prefer takes
    that side's hypothesis where it explains the pixel's colour at least as well as the pixel's value does:
    BadPix0.07 14.0 % end to end, 16.8 % without; with the gates' floors scaled by each pixel's cost span 9.9 %
    against 14.4 % (bound 12 %)."""
    with_it, without = _badpix_with_and_without(monkeypatch, "slats-o-j0.5-tex", "settle")
    assert with_it <= 12.0 < without


def test_visibility_relabel_refits_the_far_hypothesis_to_the_views(monkeypatch):
    """A weakly textured plane between oblique slats 0.5 px nearer (slats-o-j0.5-weak): the box costs pull the
    plane's values towards the slats, and the far hypothesis, their mean, with them.  Fitted again to the
    offsets the far pixels' own views prefer, BadPix0.07 is 12.2 % end to end, 25.5 % without; with the gates'
    floors scaled by each pixel's cost span 8.1 % against 16.3 % (bound 12 %)."""
    with_it, without = _badpix_with_and_without(monkeypatch, "slats-o-j0.5-weak", "refit")
    assert with_it <= 12.0 < without


def test_gates_keep_a_weakly_textured_slit():
    """The clean-up gates' floors scale with the pixel's own cost span (``gate_span_min``): a floor in units of
    the median span alone exceeded the whole span of the weakly textured far plane seen through 1-5 px slits, so
    the weighted median and the edge pass filled the slits with the near surface.  On the ideal slits-h-j1-weak
    scene 2.7 % of the map is wrong; with the floor unscaled (the old gate_floor 0.05) 6.7 %."""
    from plenodecode.depth import estimate_depth
    from plenodecode.synthetic import simulate_ideal
    from plenodecode.synthetic.thin import THIN_SCENES

    lf, gt = simulate_ideal("illum-mini", seed=1, scene=THIN_SCENES["slits-h-j1-weak"])

    def wrong(**kw) -> float:
        return float((np.abs(estimate_depth(lf, method="costvolume", **kw).disparity - gt) > 0.07)[5:-5, 5:-5].mean())

    assert wrong() < 0.04
    assert wrong(gate_span_min=0.0, gate_floor=0.05) > 0.055
