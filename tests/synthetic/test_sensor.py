"""The sensor model of the synthetic generator, seen through white images: disks, vignetting, levels, noise."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from plenodecode import synthetic as syn
from plenodecode.types import LensletGrid

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
