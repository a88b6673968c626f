"""``plenodecode depth``: the confidence map beside the disparity, --min-confidence, and the real light-field
microscope capture (featureless background masked, the two structures' parallax; skipped without
``../shared/data``)."""

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.depthio import DEFAULT_MIN_CONFIDENCE, MASK_GREY
from plenodecode.io.images import read_image
from plenodecode.io.pfm import read_pfm
from tests.cli.test_microscope import antleg  # noqa: F401  (the decoded ant-leg capture, a module fixture)
from tests.depth.test_confidence import half_featureless_scene


def _grey_share(png) -> float:
    """Share of the pixels of a rendered depth PNG that are the mask grey."""
    rgb = read_image(png)[..., :3].astype(np.int16)
    return float(np.mean(np.all(np.abs(rgb - np.rint(255 * np.array(MASK_GREY))) <= 1, axis=-1)))


def _map_pixels(png, shape) -> tuple[np.ndarray, np.ndarray]:
    """The RGB (uint8) of a depth figure (:func:`colour_map_figure` of a map of ``shape`` with a title) at the
    centres of the map's samples: (Y, X, 3), and the figure's size."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from plenodecode.io.depthio import colour_map_figure

    fig = colour_map_figure(np.zeros(shape), label="x", title="t")
    FigureCanvasAgg(fig).draw()
    x0, y0, x1, y1 = fig.axes[0].images[0].get_window_extent().extents
    rgb = read_image(png)[..., :3]
    h = rgb.shape[0]
    rows = np.clip((h - y1 + (np.arange(shape[0]) + 0.5) * (y1 - y0) / shape[0]).astype(int), 0, h - 1)
    cols = np.clip((x0 + (np.arange(shape[1]) + 0.5) * (x1 - x0) / shape[1]).astype(int), 0, rgb.shape[1] - 1)
    return rgb[np.ix_(rows, cols)], np.array(rgb.shape[:2])


def _confidence_shown(png, shape) -> np.ndarray:
    """The confidence the confidence PNG shows at each sample: the nearest colour of its colour map over 0 .. 1."""
    from matplotlib import colormaps

    from plenodecode.io.depthio import CONFIDENCE_CMAP

    rgb, _ = _map_pixels(png, shape)
    table = np.rint(255 * colormaps[CONFIDENCE_CMAP](np.linspace(0, 1, 256))[:, :3])
    dist = np.abs(rgb.reshape(-1, 1, 3).astype(np.float64) - table[None]).sum(-1)
    return (np.argmin(dist, axis=1) / 255.0).reshape(shape)


def assert_confidence_png_matches_the_depth_png(out, conf, threshold) -> None:
    """X_confidence.png is laid out as X.png (same size, the map at the same pixels), shows the EXR's confidence
    in its colour map, and X.png's grey pixels are those it shows below ``threshold``."""
    shown = _confidence_shown(out.with_name(f"{out.stem}_confidence.png"), conf.shape)
    depth_rgb, depth_size = _map_pixels(out.with_suffix(".png"), conf.shape)
    _, conf_size = _map_pixels(out.with_name(f"{out.stem}_confidence.png"), conf.shape)
    assert tuple(depth_size) == tuple(conf_size)
    assert np.max(np.abs(shown - conf)) < 0.02          # neighbouring colours of the map are alike (measured 0.007)
    grey = np.all(np.abs(depth_rgb.astype(np.int16) - np.rint(255 * np.array(MASK_GREY))) <= 1, axis=-1)
    np.testing.assert_array_equal(grey, conf < threshold)


def test_depth_writes_the_confidence_and_greys_out_the_featureless_half(tmp_path):
    from plenodecode.io.lightfield import save_lightfield

    lf, gt, square = half_featureless_scene()
    src = save_lightfield(lf, tmp_path / "lf.npy", format="npy")
    out = tmp_path / "d.pfm"
    r = CliRunner().invoke(cli, ["depth", str(src), "-o", str(out), "--method", "fast"], obj={})
    assert r.exit_code == 0, r.output
    assert f"% below {DEFAULT_MIN_CONFIDENCE:g}" in r.output
    conf = read_image(tmp_path / "d_confidence.exr").squeeze()
    assert conf.shape == (64, 64)
    assert_confidence_png_matches_the_depth_png(out, conf, DEFAULT_MIN_CONFIDENCE)
    # the uniform right half of the background (away from the square) is below the default threshold, the
    # textured left half above it
    assert np.median(conf[4:18, 40:60]) < DEFAULT_MIN_CONFIDENCE and np.median(conf[4:18, 4:20]) > 0.4
    greyed = _grey_share(tmp_path / "d.png")
    r = CliRunner().invoke(cli, ["depth", str(src), "-o", str(out), "--method", "fast", "--overwrite",
                                 "--min-confidence", "0"], obj={})
    assert r.exit_code == 0, r.output
    assert greyed > 0.1 and _grey_share(tmp_path / "d.png") < 0.001     # (anti-aliased text aside)


@pytest.mark.parametrize("bad", ["nan", "-0.1", "1.5", "x"])
def test_min_confidence_outside_the_unit_interval_is_a_usage_error(tmp_path, bad):
    out = tmp_path / "d.pfm"
    r = CliRunner().invoke(cli, ["depth", str(tmp_path), "-o", str(out), "--min-confidence", bad], obj={})
    assert r.exit_code == 2 and "--min-confidence" in r.output
    assert len([ln for ln in r.output.splitlines() if ln.startswith("Error")]) == 1
    assert not list(tmp_path.glob("d*"))


def _parallax(lf, ys, xs, k=8):
    """Disparity (px per view step, HCI sign) between the views k steps left and right of the centre, by
    phase correlation over a window, and the correlation's response."""
    import cv2

    V, U = lf.shape[:2]
    a = np.nan_to_num(lf.data[V // 2, U // 2 - k, ys, xs, 0]).astype(np.float64)
    b = np.nan_to_num(lf.data[V // 2, U // 2 + k, ys, xs, 0]).astype(np.float64)
    (shift_x, _), response = cv2.phaseCorrelate(a, b, cv2.createHanningWindow(a.shape[::-1], cv2.CV_64F))
    return -shift_x / (2 * k), response          # view u sees the centre shifted by -d (u - uc)


def test_antleg_background_is_masked_and_the_structures_have_the_parallax_sign(antleg, tmp_path):  # noqa: F811
    from scipy import ndimage

    _, zarr, lf = antleg
    out = tmp_path / "antleg.pfm"
    r = CliRunner().invoke(cli, ["depth", str(zarr), "-o", str(out)], obj={})
    assert r.exit_code == 0, r.output
    d = read_pfm(out)
    conf = read_image(tmp_path / "antleg_confidence.exr").squeeze()
    # the confidence PNG was the raw 94 x 79 map beside a 760 x 554 depth figure: now a figure laid out as it
    assert read_image(tmp_path / "antleg_confidence.png").shape == read_image(out.with_suffix(".png")).shape
    assert_confidence_png_matches_the_depth_png(out, conf, DEFAULT_MIN_CONFIDENCE)
    V, U = lf.shape[:2]
    centre = ndimage.gaussian_filter(np.nan_to_num(lf.data[V // 2, U // 2, :, :, 0]), 2.0)
    # the structures: the two largest bright blobs of the smoothed centre view; the background: far from both
    bright = centre > np.percentile(centre, 80)
    blobs, n = ndimage.label(bright)
    assert n >= 2
    sizes = ndimage.sum(bright, blobs, range(1, n + 1))
    structures = [blobs == 1 + i for i in np.argsort(sizes)[::-1][:2]]
    near = ndimage.binary_dilation(structures[0] | structures[1], iterations=8)
    background = ~near
    assert background.mean() > 0.15
    low = DEFAULT_MIN_CONFIDENCE
    # the frame's edge: lens rows half off the sensor leave outer views without samples there (confident blobs
    # of made-up texture before their gaps were filled for the matching: 114 pixels in the top 4 rows)
    frame = np.ones_like(background)
    frame[4:-4, 4:-4] = False
    print(f"background {background.mean():.2f} of the map, {np.mean(conf[background] < low):.3f} below {low}, "
          f"{np.mean(conf[background & frame] < low):.3f} at the frame's edge; grey share of the PNG "
          f"{_grey_share(out.with_suffix('.png')):.3f}, of the map {np.mean(conf < low):.3f}")
    assert np.mean(conf[background] < low) > 0.9             # featureless: below the default --min-confidence
    assert np.mean(conf[background & frame] < low) > 0.99
    # and greyed in the PNG (the map fills about half of the figure)
    assert _grey_share(out.with_suffix(".png")) > 0.3 * np.mean(conf < low)
    medians = []
    for blob in structures:
        rows, cols = np.flatnonzero(blob.any(axis=1)), np.flatnonzero(blob.any(axis=0))
        ys = slice(max(0, rows[0] - 4), rows[-1] + 5)
        # the window along the structure with the strongest parallax (the structures are tilted in depth)
        best = None
        for x0 in range(cols[0], max(cols[0] + 1, cols[-1] - 30), 6):
            xs = slice(x0, x0 + 32)
            p, response = _parallax(lf, ys, xs)
            if response > 0.4 and (best is None or abs(p) > abs(best[0])):
                best = (p, xs)
        assert best is not None
        p, xs = best
        keep = (conf[ys, xs] >= 0.2) & blob[ys, xs]
        est = float(np.median(d[ys, xs][keep]))
        print(f"structure rows {ys}, cols {xs}: parallax {p:+.3f}, estimate {est:+.3f} px/view")
        assert abs(p) > 0.05 and np.sign(est) == np.sign(p) and abs(est - p) < 0.2, (p, est)
        medians.append(est)
    # the two structures lie on opposite sides of the focal plane: distinct disparities
    assert abs(medians[0] - medians[1]) > 0.3


def test_a_disparity_range_past_the_picture_is_refused_before_estimating(tmp_path, monkeypatch):
    """'--disparity-range -100:100' on the illum-mini light field (15 x 15 views of 87 x 125) searched for 27 s
    over disparities at which no view overlaps the centre one; now a range past |d| = max(Y, X) / 7 = 17.9 px/view
    (here 64 / half the view grid) is a usage error naming --disparity-range and the bound, before any estimation,
    and writes nothing; a range inside it still runs."""
    from plenodecode import depth
    from plenodecode.io.lightfield import save_lightfield

    lf, _, _ = half_featureless_scene()
    src = save_lightfield(lf, tmp_path / "lf.npy", format="npy")
    V, U, Y, X = lf.shape[:4]
    reach = max(Y, X) / max(V // 2, U // 2)
    estimated = []
    real = depth.estimate_depth
    monkeypatch.setattr(depth, "estimate_depth", lambda *a, **k: estimated.append(1) or real(*a, **k))
    out = tmp_path / "d.pfm"
    for bad in (f"-{reach * 1.01:.3f}:1", f"0:{reach * 5:.3f}"):
        r = CliRunner().invoke(cli, ["depth", str(src), "-o", str(out), "--disparity-range", bad], obj={})
        errors = [ln for ln in r.output.splitlines() if ln.startswith("Error")]
        assert r.exit_code == 2 and len(errors) == 1 and "--disparity-range" in errors[0], r.output
        assert f"|disparity| <= {reach:.3g} here" in errors[0]
    assert estimated == [] and not list(tmp_path.glob("d*"))
    r = CliRunner().invoke(cli, ["depth", str(src), "-o", str(out), "--method", "fast", "--disparity-range",
                                 f"-{reach * 0.5:.3f}:{reach * 0.5:.3f}"], obj={})
    assert r.exit_code == 0, r.output
    assert np.isfinite(read_pfm(out)).all()


def test_min_confidence_0_says_no_share_below_it_and_the_default_says_the_measured_share(tmp_path):
    """'depth ... --min-confidence 0' printed '(0 % below 0)'; with 0 nothing is greyed and the line says nothing
    of it.  With the default the share matches the confidence map written beside the depth."""
    import re

    from tests.conftest import shared_path

    r42 = shared_path("raytrix-r42", "sc2_klein.png")
    res = CliRunner().invoke(cli, ["depth", str(r42), "-o", str(tmp_path / "a.pfm"), "--min-confidence", "0"])
    assert res.exit_code == 0, res.output
    first = res.stdout.splitlines()[0]
    assert "below" not in first and re.search(r"mean confidence \d\.\d\d, \d+\.\d s$", first), first
    res = CliRunner().invoke(cli, ["depth", str(r42), "-o", str(tmp_path / "b.pfm")])
    conf = read_image(tmp_path / "b_confidence.exr")
    share = 100 * float(np.mean(conf < np.float32(DEFAULT_MIN_CONFIDENCE)))
    assert share > 1 and f"({share:.0f} % below {DEFAULT_MIN_CONFIDENCE:g})" in res.stdout.splitlines()[0], \
        (share, res.stdout)


def test_disparity_and_metric_depth_pngs_colour_near_the_same_way(tmp_path):
    """The metric-depth PNG coloured near as blue (small depth, the cold end of the map) while the disparity PNG
    coloured near as red.  On HCI antinous (the bust in front of a far wall) the nearest tenth of the confident
    pixels is warm and the farthest tenth cold in both PNGs, and both colour bars say near at the top."""
    from plenodecode.io.depthio import colour_map_figure
    from tests.conftest import shared_path

    hci = shared_path("hci-antinous")
    shown = {}
    for name, extra in (("d", []), ("z", ["--metric"])):
        res = CliRunner().invoke(cli, ["depth", str(hci), "-o", str(tmp_path / f"{name}.pfm"), "--method", "fast",
                                       *extra])
        assert res.exit_code == 0, res.output
    d = read_pfm(tmp_path / "d.pfm")
    conf = read_image(tmp_path / "d_confidence.exr")
    ok = np.isfinite(d) & (conf >= DEFAULT_MIN_CONFIDENCE)
    near = ok & (d >= np.quantile(d[ok], 0.9))
    far = ok & (d <= np.quantile(d[ok], 0.1))
    for name in ("d", "z"):
        rgb, _ = _map_pixels(tmp_path / f"{name}.png", d.shape)
        warmth = rgb[..., 0].astype(np.float64) - rgb[..., 2]
        shown[name] = (float(np.mean(warmth[near])), float(np.mean(warmth[far])))
    for name, (near_warmth, far_warmth) in shown.items():
        assert near_warmth > 100 and far_warmth < -15, shown       # red - blue, 0-255 (measured 174, -28)
    z = read_pfm(tmp_path / "z.pfm")
    assert np.nanmedian(z[near]) < np.nanmedian(z[far])             # the near pixels are near in metres too
    for values, near_end in ((d, "high"), (z, "low")):
        fig = colour_map_figure(values, label="x", near=near_end)
        bar = fig.axes[1]
        top = max(bar.texts, key=lambda t: t.get_position()[1])
        warm_at_top = bar.get_ylim()[1] == (np.nanmax if near_end == "high" else np.nanmin)(bar.get_ylim())
        assert top.get_text() == "near" and {t.get_text() for t in bar.texts} == {"near", "far"}
        assert warm_at_top


def test_f01_shoe_mesh_depth_keeps_to_the_scene_range(tmp_path):
    """'plenodecode depth IMG_2.jpg' (the real F01 shoe: a periodic mesh) searched -8.6 .. 12.4 px/view, 211
    labels, because the mesh matched itself a period away in the coarse search over +-24 px/view; the map it wrote
    ran from -8.7 to 12.5 (5th percentile -2.8).  The search now spans 3x the refocusable range (+-1.15 here) and
    the map keeps to what the scene holds: the shoe's toe at about +1.7 px/view, the carpet behind below +0.2."""
    import re

    from tests.conftest import shared_path

    jpg = shared_path("lytro-f01-lenslet-jpg", "IMG_2.jpg")
    res = CliRunner().invoke(cli, ["depth", str(jpg), "-o", str(tmp_path / "d.pfm")])
    assert res.exit_code == 0, res.output
    lo, hi = map(float, re.search(r"disparity (\S+) \.\. (\S+) px/view", res.output).groups())
    assert -1.5 < lo and hi < 3.5, res.output
    disparity = read_pfm(tmp_path / "d.pfm")
    near, far = np.nanpercentile(disparity, [95, 5])
    assert 1.2 < near < 2.5 and -1.0 < far < 0.5, (near, far)


@pytest.mark.parametrize("suffix", [".png", ".exr"])
def test_an_output_named_as_the_picture_writes_the_whole_depth_set(tmp_path, suffix):
    """'depth RAW -o depth.png' (what a user asking for a depth picture types) was refused ('must end in .pfm');
    .png and .exr now name the same files as .pfm: the PFM, EXR and PNG of the map with its confidence beside,
    the PNG a colour-mapped figure and the PFM the values the EXR holds."""
    from tests.conftest import shared_path

    r42 = shared_path("raytrix-r42", "sc2_klein.png")
    res = CliRunner().invoke(cli, ["depth", str(r42), "-o", str(tmp_path / f"d{suffix}")])
    assert res.exit_code == 0, res.output
    names = {"d.pfm", "d.exr", "d.png", "d_confidence.exr", "d_confidence.png"}
    assert {p.name for p in tmp_path.iterdir()} == names
    assert {line.split("/")[-1] for line in res.stdout.splitlines() if line.startswith("wrote ")} == names
    values = read_pfm(tmp_path / "d.pfm")
    assert values.shape == (122, 176) and np.nanstd(values) > 0
    np.testing.assert_array_equal(read_image(tmp_path / "d.exr").reshape(values.shape), values)
    assert read_image(tmp_path / "d.png").shape[0] > values.shape[0]     # a figure with its colour bar


def test_a_depth_output_of_another_kind_is_refused_naming_the_option(tmp_path):
    res = CliRunner().invoke(cli, ["depth", "sample_raws/illum-mini/scene.lfr", "-o", str(tmp_path / "d.jpg")])
    assert res.exit_code == 2 and "--output" in res.output and ".pfm, .exr or .png" in res.output, res.output
    assert not any(tmp_path.iterdir())
