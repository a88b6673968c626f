"""Depth outputs (PFM, EXR, PNG with legend, PLY) and the ``plenodecode depth`` command."""

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.depthio import (colour_mapped, colour_range, display_colours, read_ply, write_depth_outputs,
                                    write_ply)
from plenodecode.io.images import read_image
from plenodecode.io.pfm import read_pfm
from plenodecode.types import LightField


def test_ply_round_trip_and_no_overwrite(tmp_path):
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(50, 3)).astype(np.float32)
    col = rng.integers(0, 256, (50, 3)).astype(np.uint8)
    p = write_ply(tmp_path / "c.ply", pts, col)
    got, gcol = read_ply(p)
    np.testing.assert_array_equal(got, pts)
    np.testing.assert_array_equal(gcol, col)
    assert p.read_bytes().startswith(b"ply\nformat binary_little_endian 1.0\n")
    with pytest.raises(FileExistsError):
        write_ply(p, pts)
    with pytest.raises(ValueError, match="points"):
        write_ply(tmp_path / "d.ply", pts[:, :2])


def test_colour_mapped_follows_the_percentile_range_and_blacks_out_nan():
    from matplotlib import colormaps

    rng = np.random.default_rng(1)
    d = rng.normal(size=(30, 40))
    d[2:5, 3:6] = np.nan
    d[0, 0] = np.inf
    fin = d[np.isfinite(d)]
    lo, hi = np.percentile(fin, 2), np.percentile(fin, 98)
    assert colour_range(d, percentiles=(2, 98)) == (lo, hi)
    rgb = colour_mapped(d, cmap="viridis", percentiles=(2, 98))
    assert rgb.shape == (30, 40, 3) and rgb.dtype == np.float32
    y, x = 10, 7                                      # one finite pixel, mapped by hand
    t = min(max((d[y, x] - lo) / (hi - lo), 0.0), 1.0)
    np.testing.assert_array_equal(rgb[y, x], np.float32(colormaps["viridis"](t)[:3]))
    assert np.all(rgb[2:5, 3:6] == 0) and np.all(rgb[0, 0] == 0)
    # the depth PNG's defaults: turbo, 1st-99th percentile; an empty range is widened by 1e-6
    assert colour_range(d) == tuple(np.percentile(fin, [1, 99]))
    assert colour_range(np.full((3, 3), 2.0)) == (2.0, 2.0 + 1e-6)
    assert colour_range(np.full((3, 3), np.nan)) == (0.0, 1.0)
    assert colour_range(d, vmin=-1.0, vmax=1.0) == (-1.0, 1.0)


def test_display_colours_are_srgb_encoded_bytes():
    rng = np.random.default_rng(2)
    img = (rng.random((6, 7, 3)) * 1.2 - 0.1).astype(np.float32)
    img[0, 0, 0] = np.nan
    x = np.clip(np.nan_to_num(img.astype(np.float64)), 0, 1)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    np.testing.assert_array_equal(display_colours(img, "linear-srgb"), np.rint(srgb * 255).astype(np.uint8))
    np.testing.assert_array_equal(display_colours(img, "srgb"), np.rint(x * 255).astype(np.uint8))
    assert display_colours(img[..., :1], "srgb").shape == (6, 7, 3)
    # camera RGB: linear gets the curve, already on the curve ('camera-srgb-curve', 8-bit F01 views) is kept:
    # the point cloud's colours of such a light field were encoded a second time (washed out)
    np.testing.assert_array_equal(display_colours(img, "camera"), np.rint(srgb * 255).astype(np.uint8))
    np.testing.assert_array_equal(display_colours(img, "camera-srgb-curve"), np.rint(x * 255).astype(np.uint8))


def test_depth_outputs_are_written_together(tmp_path):
    v = np.linspace(-1, 2, 60 * 80, dtype=np.float32).reshape(60, 80)
    out = write_depth_outputs(tmp_path / "d.pfm", v, label="disparity")
    assert [p.name for p in out] == ["d.pfm", "d.exr", "d.png"]
    np.testing.assert_array_equal(read_pfm(out[0]), v)
    exr = read_image(out[1])
    np.testing.assert_allclose(np.squeeze(exr), v, rtol=0, atol=0)
    png = read_image(out[2])
    assert png.shape[1] > 80 and png.ndim == 3            # rendered figure with a colour bar beside the map
    # one existing output blocks all of them; nothing is half written
    (tmp_path / "e.png").write_bytes(b"x")
    with pytest.raises(FileExistsError):
        write_depth_outputs(tmp_path / "e.pfm", v, label="disparity")
    assert not (tmp_path / "e.pfm").exists() and not (tmp_path / "e.exr").exists()
    with pytest.raises(ValueError, match=r"\.pfm, \.exr or \.png"):
        write_depth_outputs(tmp_path / "e.tif", v, label="x")


def _uniform_lf(d=0.6, n=5, size=40):
    """A textured plane at disparity d (HCI convention), with HCI camera parameters for metric depth."""
    from scipy import ndimage

    rng = np.random.default_rng(7)
    tex = ndimage.gaussian_filter(rng.uniform(0, 1, (size + 20, size + 20)), 1.2)
    tex = (tex - tex.min()) / (tex.max() - tex.min())
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    data = np.empty((n, n, size, size, 1), np.float32)
    for v in range(n):
        for u in range(n):
            data[v, u, :, :, 0] = ndimage.map_coordinates(tex, [yy + d * (v - n // 2) + 10, xx + d * (u - n // 2) + 10],
                                                          order=3)
    params = {"intrinsics": {"focal_length_mm": 100.0, "image_resolution_x_px": size, "image_resolution_y_px": size,
                             "sensor_size_mm": 35.0},
              "extrinsics": {"baseline_mm": 100.0, "focus_distance_m": 7.0}}
    return LightField(data, None, "srgb", {"hci_parameters": params, "disparity_range": [-1.0, 1.0]})


def test_depth_command(tmp_path):
    from plenodecode.io.lightfield import save_lightfield

    src = save_lightfield(_uniform_lf(0.6), tmp_path / "lf.npy", format="npy")
    out = tmp_path / "res" / "d.pfm"
    runner = CliRunner()
    r = runner.invoke(cli, ["depth", str(src), "-o", str(out), "--method", "fast"], obj={})
    assert r.exit_code == 0, r.output
    d = read_pfm(out)
    assert d.shape == (40, 40) and abs(np.median(d[5:-5, 5:-5]) - 0.6) < 0.05
    assert (tmp_path / "res" / "d.exr").exists() and (tmp_path / "res" / "d.png").exists()
    # no overwrite without --overwrite (usage error, exit 2)
    r = runner.invoke(cli, ["depth", str(src), "-o", str(out)], obj={})
    assert r.exit_code == 2 and "--overwrite" in r.output
    # metric depth and a point cloud
    ply = tmp_path / "res" / "cloud.ply"
    r = runner.invoke(cli, ["depth", str(src), "-o", str(out), "--metric", "--ply", str(ply), "--overwrite",
                            "--disparity-range", "-1:1"], obj={})
    assert r.exit_code == 0, r.output
    z = read_pfm(out)
    g = 0.1 * 100.0 / 35.0 * 40
    assert abs(np.median(z[5:-5, 5:-5]) - g / (0.6 + g / 7.0)) < 0.05   # 6.03 m
    pts, col = read_ply(ply)
    assert len(pts) == 40 * 40 and col is not None and np.allclose(np.median(pts[:, 2]), np.median(z), atol=1e-4)
    r = runner.invoke(cli, ["depth", str(src), "-o", str(tmp_path / "x.pfm"), "--disparity-range", "3:1"], obj={})
    assert r.exit_code == 2


def test_depth_command_reports_missing_geometry(tmp_path):
    from plenodecode.io.lightfield import save_lightfield

    lf = _uniform_lf(0.3)
    src = save_lightfield(lf.replace(metadata={}), tmp_path / "bare.npy", format="npy")
    r = CliRunner().invoke(cli, ["depth", str(src), "-o", str(tmp_path / "d.pfm"), "--metric", "--method", "fast"],
                           obj={})
    assert r.exit_code == 2 and "which metric depth needs" in r.output and "--metric" in r.output
    assert "depth (fast)" not in r.output and not (tmp_path / "d.pfm").exists()
