"""Local mean and the contrast image (:mod:`plenodecode.calib.centroids.contrast`)."""

from __future__ import annotations

import numpy as np

from plenodecode.calib import centroids as C


def test_local_mean_reproduces_a_plane_up_to_the_borders():
    yy, xx = np.mgrid[0:300, 0:410]
    plane = (0.3 + 0.002 * yy - 0.0013 * xx).astype(np.float32)
    for sigma in (6.0, 21.0):
        lm = C.local_mean(plane, sigma)
        assert lm.shape == plane.shape
        np.testing.assert_allclose(lm, plane, atol=2e-3)


def test_devignette_is_the_image_over_its_local_mean_minus_one_and_zero_where_dark():
    rng = np.random.default_rng(2)
    yy, xx = np.mgrid[0:120, 0:150]
    img = ((0.2 + 0.8 * (xx > 40)) * (1 + 0.3 * np.cos(yy / 1.7) * np.cos(xx / 1.9))).astype(np.float32)
    img[:, :40] *= 1e-3                                          # a dark band below the floor
    img += 1e-4 * rng.random(img.shape).astype(np.float32)
    pitch = 6.0
    got = C.devignette(img, pitch, floor=0.02)
    lm = C.local_mean(img, 1.5 * pitch)
    lo = 0.02 * np.percentile(lm[::4, ::4], 99)
    want = np.where(lm >= lo, img / lm - 1, 0)
    assert got.dtype == np.float32 and (got == 0).sum() >= 120 * 15     # most of the dark band is cleared
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)


def test_local_mean_is_the_weighted_least_squares_plane_at_every_pixel():
    """Against a direct solve: at each pixel, the plane ``b0 + b . (x' - x)`` minimising the Gaussian-weighted
    (sigma 3, taps within 4 sigma, zero outside the image) squared error of a non-linear image; its ``b0``."""
    rng = np.random.default_rng(4)
    yy, xx = np.mgrid[0:37, 0:45]
    img = (0.5 + 0.3 * np.sin(yy / 2.3) * np.cos(xx / 3.1) + 0.05 * rng.random(yy.shape)).astype(np.float32)
    sigma, half = 3.0, 12
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    k /= k.sum()
    lm = C.local_mean(img, sigma)
    want = np.empty(img.shape)
    for y in range(img.shape[0]):
        for x in range(img.shape[1]):
            ys = np.arange(max(0, y - half), min(img.shape[0], y + half + 1))
            xs = np.arange(max(0, x - half), min(img.shape[1], x + half + 1))
            w = np.sqrt(np.outer(k[ys - y + half], k[xs - x + half])).ravel()
            dy, dx = np.meshgrid(ys - y, xs - x, indexing="ij")
            a = np.stack([np.ones(dy.size), dy.ravel(), dx.ravel()], 1) * w[:, None]
            want[y, x] = np.linalg.lstsq(a, img[np.ix_(ys, xs)].ravel() * w, rcond=None)[0][0]
    np.testing.assert_allclose(lm, want, atol=2e-5)
