"""Colour helpers of plenodecode.decoding.colour against direct float64 references."""

import numpy as np
import pytest

from plenodecode.decoding.colour import apply_matrix
from plenodecode.imaging import LUMA_WEIGHTS, luma


@pytest.mark.parametrize("shape", [(3,), (7, 3), (3, 2, 5, 6, 3), (2, 2, 300, 120, 3)])
def test_apply_matrix_is_the_matrix_product_per_pixel(shape):
    rng = np.random.default_rng(7)
    data = (rng.random(shape) * 1.5).astype(np.float32)
    ccm = np.array([[1.7013, -0.5646, -0.1367], [-0.2994, 1.5633, -0.2639], [-0.0139, -0.6742, 1.6881]])
    m = ccm @ np.diag([2.1, 1.0, 1.6])
    out = apply_matrix(data, m)
    ref = np.einsum("ij,...j->...i", m, data.astype(np.float64))
    assert out.shape == data.shape and out.dtype == np.float32
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(apply_matrix(data.astype(np.float64), m), ref, rtol=0, atol=1e-6)
    # a non-contiguous input gives the same result
    wide = np.zeros(shape[:-1] + (6,), np.float32)
    wide[..., ::2] = data
    np.testing.assert_array_equal(apply_matrix(wide[..., ::2], m), out)


def test_apply_matrix_checks_shapes():
    with pytest.raises(ValueError, match="3 channels"):
        apply_matrix(np.zeros((4, 2), np.float32), np.eye(3))
    with pytest.raises(ValueError, match=r"\(3, 3\)"):
        apply_matrix(np.zeros((4, 3), np.float32), np.eye(2))


def test_luma_is_the_rec601_weighted_sum():
    rng = np.random.default_rng(8)
    img = rng.random((9, 11, 3)).astype(np.float32)
    ref = 0.299 * img[..., 0].astype(np.float64) + 0.587 * img[..., 1] + 0.114 * img[..., 2]
    got = luma(img)
    assert got.shape == (9, 11) and got.dtype == np.float32 and got.flags.c_contiguous
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(LUMA_WEIGHTS.sum(), 1.0, atol=1e-6)
    np.testing.assert_array_equal(luma(img[..., 1:2]), img[..., 1])
    with pytest.raises(ValueError, match="1 or 3 channels"):
        luma(np.zeros((2, 2, 2), np.float32))
