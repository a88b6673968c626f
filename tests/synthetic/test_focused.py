"""The focused (Raytrix-like) camera of the synthetic generator: micro-images, lens types, truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from plenodecode import synthetic as syn
from plenodecode.synthetic import Plane


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
