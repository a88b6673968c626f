"""Depth outputs with their confidence: the confidence map files and the greyed-out colour-mapped PNG."""

import numpy as np
import pytest

from plenodecode.io.depthio import MASK_GREY, colour_map_figure, colour_map_image, write_depth_outputs
from plenodecode.io.images import read_image


def _image_box(rgb: np.ndarray) -> tuple[slice, slice]:
    """Rows and columns of the map in a rendered figure: the first run of mostly non-white columns from the
    left (the colour bar comes after a white gap), and the mostly non-white rows within it."""
    ink = (rgb < 0.98).any(axis=-1)
    cols = np.flatnonzero(ink.mean(axis=0) > 0.5)
    end = np.flatnonzero(np.diff(cols) > 1)
    cols = cols[: end[0] + 1] if end.size else cols
    rows = np.flatnonzero(ink[:, cols].mean(axis=1) > 0.5)
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def _is_grey(rgb: np.ndarray) -> np.ndarray:
    return np.all(np.abs(rgb - np.array(MASK_GREY, np.float32)) < 1.5 / 255, axis=-1)


def test_low_confidence_pixels_are_grey_and_left_out_of_the_colour_range():
    v = np.tile(np.linspace(-1.0, 1.0, 80, dtype=np.float32), (60, 1))
    v[:, :20] = 50.0                              # an outlier region ...
    masked = np.zeros(v.shape, bool)
    masked[:, :20] = True                         # ... that is masked
    rgb = colour_map_image(v, label="disparity (px / view step)", masked=masked)
    ys, xs = _image_box(rgb)
    box = rgb[ys, xs]
    grey = _is_grey(box)
    split = round(box.shape[1] * 20 / 80)
    assert grey[:, : split - 1].mean() > 0.98 and grey[:, split + 1:].mean() < 0.02
    # the colours span the unmasked values (-0.5 .. 1 after the 1st-99th percentiles), not the outlier
    fig = colour_map_figure(v, label="d", masked=masked)
    lo, hi = fig.axes[0].images[0].get_clim()
    assert -0.6 < lo < -0.4 and 0.9 < hi <= 1.0
    plain = colour_map_image(v, label="d")
    assert not _is_grey(plain[_image_box(plain)]).any()


def test_confidence_files_beside_the_depth_outputs(tmp_path):
    v = np.tile(np.linspace(-1.0, 1.0, 80, dtype=np.float32), (60, 1))
    conf = np.full(v.shape, 0.9, np.float32)
    conf[:, :20] = 0.05
    out = write_depth_outputs(tmp_path / "d.pfm", v, label="disparity", confidence=conf, min_confidence=0.2)
    assert [p.name for p in out] == ["d.pfm", "d.exr", "d.png", "d_confidence.exr", "d_confidence.png"]
    np.testing.assert_array_equal(np.squeeze(read_image(out[3])), conf)
    # the confidence PNG: a figure laid out as d.png, in its colour map, greys of d.png where below 0.2
    from tests.cli.test_depth import assert_confidence_png_matches_the_depth_png

    assert_confidence_png_matches_the_depth_png(out[0], conf, 0.2)
    rgb = read_image(out[2])[..., :3] / np.float32(255)
    box = rgb[_image_box(rgb)]
    assert _is_grey(box).mean() == pytest.approx(0.25, abs=0.03)
    # 0 greys out nothing; a value outside [0, 1] is refused before anything is written
    out = write_depth_outputs(tmp_path / "e.pfm", v, label="disparity", confidence=conf, min_confidence=0)
    rgb = read_image(out[2])[..., :3] / np.float32(255)
    assert not _is_grey(rgb[_image_box(rgb)]).any()
    for bad in (1.5, -0.1, float("nan")):
        with pytest.raises(ValueError, match="min_confidence"):
            write_depth_outputs(tmp_path / "f.pfm", v, label="disparity", confidence=conf, min_confidence=bad)
    assert not list(tmp_path.glob("f*"))
    with pytest.raises(ValueError, match="confidence"):
        write_depth_outputs(tmp_path / "g.pfm", v, label="disparity", confidence=conf[:10])
