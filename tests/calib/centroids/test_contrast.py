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
