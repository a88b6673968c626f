"""The frame's edge in written photographs and views: pixels that no lens sample reaches (the hex -> rect grid's
alternate edge pixels, a lens row or column half off the sensor) take their nearest neighbour's value instead of
black dots and lines, and a microscope's border column lit by 1-5 % of the aperture is not 2-25x too bright."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.images import read_image
from tests.conftest import shared_path


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def edge_ratios(img: np.ndarray) -> dict[str, np.ndarray]:
    """Each edge row / column over the row / column next to it, pixel by pixel (grey, float64)."""
    g = np.asarray(img, np.float64)
    g = g.mean(axis=-1) if g.ndim == 3 else g
    with np.errstate(divide="ignore", invalid="ignore"):
        return {"top": g[0] / g[1], "bottom": g[-1] / g[-2], "left": g[:, 0] / g[:, 1], "right": g[:, -1] / g[:, -2]}


def test_real_f01_jpeg_photograph_has_no_black_edge_pixels(tmp_path):
    # before: 73 % of the top row, 62 % of the bottom row and every other pixel of the left column were 0
    res = run(shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), "-o", tmp_path / "photo.png")
    assert res.exit_code == 0, res.output
    photo = read_image(tmp_path / "photo.png")
    grey = photo.astype(np.float64).mean(axis=-1)
    for name, edge in {"top": grey[0], "bottom": grey[-1], "left": grey[:, 0], "right": grey[:, -1]}.items():
        assert np.count_nonzero(edge == 0) == 0, name
    for name, ratio in edge_ratios(photo).items():
        assert 0.8 < np.median(ratio) < 1.25, name


def test_real_antleg_centre_view_and_photograph_edges_match_their_neighbours(tmp_path, caplog):
    folder = shared_path("lf-microscopy-antleg")
    res = run("batch", folder / "light_field.png", "-w", folder / "radiometry_frame.png", "--dark",
              folder / "dark_frame.tif", "--outputs", "centre,refocus", "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    # the dark frame's own levels are not used: no guess at them is shown; the raw's line names the dark frame
    logged = caplog.text
    assert "light_field.png: no JSON sidecar" in logged and "dark_frame.tif: no JSON sidecar" not in logged
    assert "black from the dark frame dark_frame.tif" in logged
    # before: the centre view's left column and half its top row were 0, one left pixel 4.8x its neighbour; the
    # photograph's left column up to 7.8x its neighbour.  The noisy specimen itself gives 0.72-1.64 on the right
    for name in ("centre.png", "refocus_s+0.00.png"):
        img = read_image(tmp_path / "out" / "light_field" / name)
        assert np.count_nonzero(img == 0) == 0, name
        for edge, ratio in edge_ratios(img).items():
            assert 0.5 < ratio.min() and ratio.max() < 2.0, (name, edge, ratio.min(), ratio.max())


def test_real_f01_jpeg_parallax_frames_and_views_have_no_black_edges(tmp_path):
    # before: every frame had 400-800 black pixels along its edges (weight-0 samples blended in), the views 1 px
    # black dots along the top row and the left column
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    res = run("parallax", jpeg, "--frames", 8, "-o", tmp_path / "par.gif")
    assert res.exit_code == 0, res.output
    frames = sorted((tmp_path / "par_frames").glob("*.png"))
    assert len(frames) == 8
    views = run("views", jpeg, "-o", tmp_path / "views")
    assert views.exit_code == 0, views.output
    for path in frames + [tmp_path / "views" / f"view_{v:02d}_{u:02d}.png" for v, u in ((4, 4), (2, 6), (6, 3))]:
        grey = read_image(path).astype(np.float64).mean(axis=-1)
        edges = np.concatenate([grey[0], grey[-1], grey[:, 0], grey[:, -1]])
        assert np.count_nonzero(edges == 0) == 0, path.name
    # the corner views lie outside the micro-images (data in 44 % of their samples; before: diagonal stripes of
    # the lenses' edges): black, and the command names them; the views beside them are pictures
    corners = [f"view_{v:02d}_{u:02d}" for v in (0, 8) for u in (0, 8)]
    assert "4 partly outside the micro-images" in views.output and corners[0] in views.output
    for name in corners:
        assert read_image(tmp_path / "views" / f"{name}.png").max() == 0, name
    for v, u in ((0, 1), (1, 0), (1, 1), (0, 4)):
        assert np.median(read_image(tmp_path / "views" / f"view_{v:02d}_{u:02d}.png")) > 20, (v, u)


def test_real_f01_jpeg_all_in_focus_has_no_black_edge_pixels(tmp_path):
    # before: 363 black pixels on its edges (the centre view's gaps where it fell back to it, and views' zeros
    # interpolated in elsewhere)
    res = run("batch", shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg"), "--outputs", "all-in-focus",
              "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    image = read_image(tmp_path / "out" / "IMG_1" / "all_in_focus.png")
    grey = image.astype(np.float64).mean(axis=-1)
    edges = np.concatenate([grey[0], grey[-1], grey[:, 0], grey[:, -1]])
    assert np.count_nonzero(edges == 0) == 0
    for name, ratio in edge_ratios(image).items():
        assert 0.8 < np.median(ratio) < 1.25, name
