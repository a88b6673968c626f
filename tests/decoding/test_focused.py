"""Focused-plenoptic (Raytrix) rendering: patch tiling, per-lens patch size, total focus."""

from __future__ import annotations

import numpy as np
import pytest
from tests.conftest import shared_path

from plenodecode.decoding.focused import estimate_patch_sizes, render_focused, render_total_focus
from plenodecode.types import LensletGrid

TEXEL = 1.0


def texture(qy: np.ndarray, qx: np.ndarray) -> np.ndarray:
    return 0.5 + 0.2 * np.sin(qy * 0.45 + 0.3) * np.cos(qx * 0.37) + 0.1 * np.sin(0.23 * qx + 0.11 * qy)


def focused_raw(grid: LensletGrid, v: float, *, keplerian: bool) -> np.ndarray:
    """Micro-images of a plane at virtual depth v: pixel c + m shows virtual-image point c -+ v m.

    Returns the sensor image (H, W, 1) and the rendered image is ``texture(X / v)`` at output
    position ``q = X / v`` (output spacing P = D / v).
    """
    h, w = grid.sensor_shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    cen = grid.centres()
    from scipy.spatial import cKDTree

    d, k = cKDTree(cen).query(np.stack([yy.ravel(), xx.ravel()], 1))
    c = cen[k]
    m = np.stack([yy.ravel(), xx.ravel()], 1) - c
    sign = -1.0 if keplerian else 1.0
    x_vi = c + sign * v * m                       # virtual-image point seen by the pixel
    val = texture(x_vi[:, 0] / v, x_vi[:, 1] / v)
    val[d > grid.radius] = 0.0
    return val.reshape(h, w).astype(np.float32)[..., None]


@pytest.fixture(scope="module")
def hex_grid():
    from plenodecode.synthetic import make_grid

    return make_grid("raytrix", shape=(330, 460))


@pytest.mark.parametrize("keplerian", [True, False])
def test_render_with_true_patch_reproduces_the_virtual_image(hex_grid, keplerian):
    v = 3.0
    img = focused_raw(hex_grid, v, keplerian=keplerian)
    p = hex_grid.pitch / v
    r = render_focused(img, hex_grid, patch=p, keplerian=keplerian)
    qy, qx = np.mgrid[0:r.image.shape[0], 0:r.image.shape[1]].astype(np.float64)
    gt = texture(qy, qx)
    m = r.weight > 0.5
    m[:8], m[-8:], m[:, :8], m[:, -8:] = False, False, False, False
    err = r.image[..., 0][m] - gt[m]
    psnr = -10 * np.log10(np.mean(err ** 2))
    assert psnr > 45.0
    assert r.spread[m].mean() < 0.01
    # a wrong patch size (refocus to another depth) duplicates or drops content
    for f in (0.8, 1.25):
        bad = render_focused(img, hex_grid, patch=p * f, spacing=p, keplerian=keplerian)
        assert np.sqrt(np.mean((bad.image[..., 0][m] - gt[m]) ** 2)) > 5 * np.sqrt(np.mean(err ** 2))
        assert bad.spread[m].mean() > 3 * r.spread[m].mean()


def test_patch_size_and_orientation_are_estimated(hex_grid):
    v = 2.6
    img = focused_raw(hex_grid, v, keplerian=False)
    p, score = estimate_patch_sizes(img, hex_grid)                     # orientation detected
    assert np.median(p) == pytest.approx(hex_grid.pitch / v, rel=0.01)
    assert np.nanmedian(score) > 0.95
    tf = render_total_focus(img, hex_grid)
    assert tf.keplerian is False
    with pytest.raises(ValueError, match="p_range"):
        estimate_patch_sizes(img, hex_grid, keplerian=True, p_range=(5.0, 2.0))


def test_total_focus_on_synthetic_raytrix_preset():
    from plenodecode import synthetic
    import cv2

    sim = synthetic.simulate("raytrix", noise=False, seed=2)
    truth = sim.truth
    true_p = sim.grid.pitch / truth["lens_virtual_depth"]
    r = render_total_focus(sim.raw, sim.grid, white=sim.white)
    ok = np.isfinite(true_p)
    rel = np.abs(r.patch[ok] - true_p[ok]) / true_p[ok]
    assert np.median(rel) < 0.03                              # per-lens depth (patch size) recovered
    # compare with the ground-truth total-focus image at the rendering's scale
    ho, wo = r.image.shape[:2]
    qy, qx = np.mgrid[0:ho, 0:wo].astype(np.float32)
    ref = cv2.remap(truth["total_focus"][..., 0], qx / r.scale, qy / r.scale, cv2.INTER_LINEAR)
    m = r.weight > 0.3
    b = int(2 * r.spacing)
    m[:b], m[-b:], m[:, :b], m[:, -b:] = False, False, False, False

    def psnr(img):
        return -10 * np.log10(np.mean((img[..., 0][m] - ref[m]) ** 2))

    p_tf = psnr(r.image)
    p_fixed = psnr(render_focused(sim.raw, sim.grid, patch=float(np.median(true_p[ok])), spacing=r.spacing,
                                  white=sim.white, keplerian=r.keplerian).image)
    p_plain = psnr(render_total_focus(sim.raw, sim.grid, white=sim.white, sharpness=0.0, spacing=r.spacing,
                                      keplerian=r.keplerian).image)
    print(f"\nraytrix total focus {p_tf:.1f} dB, fixed P {p_fixed:.1f} dB, without focus weights {p_plain:.1f} dB")
    assert p_tf > 30.0
    assert p_tf > p_fixed + 2.0
    assert p_tf > p_plain + 1.0


@pytest.mark.realdata
def test_total_focus_on_real_raytrix_r42():
    png = shared_path("raytrix-r42", "sc2_klein.png")
    from plenodecode.io.raytrix import grid_from_raycalib, parse_raycalib, read_raytrix_rgb

    rgb = read_raytrix_rgb(png).astype(np.float32) / 255.0
    grid = grid_from_raycalib(parse_raycalib(png.with_suffix(".xml")), rgb.shape[:2])
    r = render_total_focus(rgb, grid)
    m = r.weight > 0.5
    assert m.mean() > 0.8
    assert np.isfinite(r.image).all() and r.image[m].std() > 0.1        # not degenerate
    assert r.keplerian is False                                         # the R42 micro-images are upright
    assert 0.1 * grid.pitch < np.median(r.patch) < 0.5 * grid.pitch
    # sharp: neighbouring patches agree much better than at a wrong depth or orientation
    for f in (0.7, 1.3):
        wrong = render_focused(rgb, grid, patch=r.patch * f, spacing=r.spacing, keplerian=False)
        assert wrong.spread[m].mean() > 1.5 * r.spread[m].mean()
    flipped = render_focused(rgb, grid, patch=r.patch, spacing=r.spacing, keplerian=True)
    assert flipped.spread[m].mean() > 3 * r.spread[m].mean()
    plain = render_total_focus(rgb, grid, sharpness=0.0, spacing=r.spacing, keplerian=False)

    def grad_energy(img):
        g = img.mean(-1)
        gy, gx = np.gradient(g)
        return float(np.mean((gy ** 2 + gx ** 2)[m]))

    assert grad_energy(r.image) > 1.1 * grad_energy(plain.image)      # focus weights pick the sharp lenses


def test_focused_bad_inputs(hex_grid):
    from plenodecode.errors import CalibrationError, DecodeError
    from plenodecode.types import RawCapture

    img = np.zeros((*hex_grid.sensor_shape, 1), np.float32)
    with pytest.raises(ValueError, match="patch"):
        render_focused(img, hex_grid, patch=-1.0)
    with pytest.raises(ValueError, match="feather"):
        render_focused(img, hex_grid, patch=5.0, feather=0)
    with pytest.raises(DecodeError, match="330x460"):
        render_focused(img[:-1], hex_grid, patch=5.0)
    raw = RawCapture(np.zeros((100, 100), np.uint16), None, 0, 4095)
    with pytest.raises(CalibrationError, match="100x100"):
        render_total_focus(raw, hex_grid)
