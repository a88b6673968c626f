"""Lattice fit, grid extent, refit and per-lens deviations on exact synthetic point sets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plenodecode.calib import grid as G
from plenodecode.errors import CalibrationError
from plenodecode.types import LensletGrid


def lattice_points(lattice, pitch, rotation, origin, shift, n_rows=40, n_cols=50, rs=None):
    """Points of an exact lattice block in the LensletGrid model and the model grid."""
    rs = rs if rs is not None else (pitch * math.sqrt(3) / 2 if lattice == "hex" else pitch)
    g = LensletGrid(lattice, pitch, rs, rotation, origin, (n_rows, n_cols), shift, (2000, 2000), 0.46 * pitch)
    return g.centres(), g


def basis(grid: LensletGrid, *, perturb: float = 0.0):
    e_row, e_col = grid.axes()
    v1 = grid.pitch * (1 + perturb) * e_col
    v2 = grid.row_spacing * (1 + perturb) * e_row + (0.5 if grid.lattice == "hex" else 0.0) * grid.pitch * e_col
    return v1, v2


@pytest.mark.parametrize("lattice,rotation,shift", [("hex", 0.004, 0.5), ("hex", -0.009, -0.5),
                                                    ("square", 0.003, 0.0), ("hex", math.pi / 2 + 0.002, 0.5)])
def test_fit_recovers_parameters_with_noise_outliers_and_gaps(lattice, rotation, shift):
    rng = np.random.default_rng(1)
    pts, truth = lattice_points(lattice, 14.2857, rotation, (30.3, 41.7), shift, rs=14.2857 * (0.8661 if lattice == "hex" else 1.0003))
    keep = rng.random(len(pts)) > 0.1                               # 10 % missing lenses
    noisy = pts[keep] + rng.normal(0, 0.05, (keep.sum(), 2))         # 0.05 px centre noise
    outliers = rng.uniform(pts.min(0), pts.max(0), (60, 2))          # spurious detections
    shifted = pts[rng.choice(len(pts), 40, replace=False)] + rng.normal(0, 2.0, (40, 2))  # badly biased ones
    allp = np.vstack([noisy, outliers, shifted])
    v1, v2 = basis(truth, perturb=0.004)                              # initial basis 0.4 % off
    if lattice == "hex" and shift < 0:
        pass  # the fit is in its own (n, m) basis; the block's shift sign is decided later
    fit = G.fit_lattice(allp, v1, v2, lattice)
    assert abs(fit.pitch - truth.pitch) < 2e-4
    assert abs(fit.row_spacing - truth.row_spacing) < 2e-4
    assert abs(fit.rotation - truth.rotation) < 2e-5
    assert fit.sigma == pytest.approx(0.05, rel=0.2)
    assert fit.inlier.sum() >= keep.sum() * 0.98
    assert not fit.inlier[len(noisy):len(noisy) + 60].any()          # no random outlier used


def test_lens_block_covers_every_lens_on_the_sensor_and_matches_the_model():
    rng = np.random.default_rng(3)
    for rotation in (0.0, 0.0093, -0.0071):
        truth_pts, truth = lattice_points("hex", 9.93, rotation, (-20.0, -15.0), 0.5, n_rows=60, n_cols=55)
        H, W = 420, 470
        on = ((truth_pts[:, 0] >= -0.5) & (truth_pts[:, 0] <= H - 0.5)
              & (truth_pts[:, 1] >= -0.5) & (truth_pts[:, 1] <= W - 0.5))
        pts = truth_pts[on] + rng.normal(0, 0.02, (on.sum(), 2))
        v1, v2 = basis(truth)
        fit = G.fit_lattice(pts, v1, v2, "hex")
        grid = G.grid_from_fit(fit, pts, (H, W), refine=False)
        c = grid.centres()
        from scipy.spatial import cKDTree
        d, _ = cKDTree(c).query(truth_pts[on])
        assert d.max() < 0.05
        # the block is minimal: its first/last rows and columns hold lenses on the sensor
        c2 = grid.centres_2d()
        ins = (c2[..., 0] >= -0.5) & (c2[..., 0] <= H - 0.5) & (c2[..., 1] >= -0.5) & (c2[..., 1] <= W - 0.5)
        assert ins[0].any() and ins[-1].any() and ins[:, 0].any() and ins[:, -1].any()
        assert abs(grid.odd_row_shift) == 0.5


def test_refit_grid_recovers_a_perturbed_grid_and_keeps_indices():
    pts, truth = lattice_points("hex", 34.86, 0.0008, (17.3, 29.2), 0.5, n_rows=23, n_cols=29)
    truth = truth.replace(lens_type=(np.arange(23 * 29).reshape(23, 29) % 3).astype(np.int8))
    rng = np.random.default_rng(0)
    noisy = pts + rng.normal(0, 0.03, pts.shape)
    start = truth.replace(origin=(truth.origin[0] + 1.5, truth.origin[1] - 1.1), rotation=truth.rotation + 0.003,
                          pitch=truth.pitch * 1.002, row_spacing=truth.row_spacing * 0.998)
    out = G.refit_grid(start, noisy)
    np.testing.assert_allclose(out.centres(), truth.centres(), atol=0.02)
    assert out.shape == truth.shape
    np.testing.assert_array_equal(out.lens_type, truth.lens_type)
    assert out.info["refit"]["n_points"] == len(pts)
    with pytest.raises(CalibrationError):
        G.refit_grid(start, noisy[:5])


def test_smooth_deviations_keep_distortion_and_drop_noise():
    rows, cols = 40, 50
    ii, jj = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    ij = np.stack([ii.ravel(), jj.ravel()], 1)
    rng = np.random.default_rng(2)
    noise = rng.normal(0, 0.05, (len(ij), 2))
    dev = G.smooth_deviations((rows, cols), ij, noise, 0.05)
    assert np.isnan(dev).all()                                     # pure noise: nothing kept
    # a smooth radial distortion up to 0.6 px at the corners
    r = np.stack([(ii - rows / 2) / rows, (jj - cols / 2) / cols], -1).reshape(-1, 2)
    distortion = 1.2 * r * np.hypot(r[:, :1], r[:, 1:2])
    dev = G.smooth_deviations((rows, cols), ij, distortion + noise, 0.05)
    kept = np.isfinite(dev[..., 0])
    assert kept.mean() > 0.3
    err = dev[kept] - distortion.reshape(rows, cols, 2)[kept]
    assert np.sqrt(np.mean(err ** 2)) < 0.06


def test_too_few_points_raise():
    pts, truth = lattice_points("hex", 10.0, 0.0, (5.0, 5.0), 0.5, n_rows=2, n_cols=2)
    v1, v2 = basis(truth)
    with pytest.raises(CalibrationError):
        G.fit_lattice(pts, v1, v2, "hex")
    with pytest.raises(ValueError, match="lattice"):
        G.fit_lattice(pts, v1, v2, "tri")
