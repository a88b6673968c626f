"""Building blocks of the depth methods: metrics, shifts, SGM recurrence, sub-label minimum, confidence."""

import numpy as np
import pytest

from plenodecode.depth import _core, badpix, mse100


# ---------------------------------------------------------------------------------------------- metrics
def test_badpix_and_mse_follow_the_benchmark_definition():
    gt = np.zeros((40, 40), np.float32)
    est = gt.copy()
    est[15:25, 15:20] = 0.08          # 50 bad pixels inside the 10 x 10 evaluated area ...
    est[0:15, :] = 5.0                # ... and garbage in the border, which is ignored
    assert badpix(est, gt, border=15) == pytest.approx(50.0)
    assert badpix(est, gt, t=0.1, border=15) == 0.0
    assert mse100(est, gt, border=15) == pytest.approx(100 * 50 * 0.08 ** 2 / 100, rel=1e-5)
    assert badpix(est, gt, border=0) == pytest.approx(100 * (15 * 40 + 50) / 1600)


def test_metrics_mask_nonfinite_and_errors():
    gt = np.zeros((10, 10))
    gt[0, 0] = np.nan                   # not evaluated
    est = np.zeros((10, 10))
    est[5, 5] = np.nan                  # counts as bad, MSE infinite
    assert badpix(est, gt, border=0) == pytest.approx(100 / 99)
    assert mse100(est, gt, border=0) == np.inf
    mask = np.zeros((10, 10), bool)
    mask[:3] = True
    assert badpix(est, gt, border=0, mask=mask) == 0.0
    with pytest.raises(ValueError, match="same shape"):
        badpix(np.zeros((4, 4)), np.zeros((5, 5)))
    with pytest.raises(ValueError, match="border"):
        badpix(np.zeros((10, 10)), np.zeros((10, 10)), border=5)


# ---------------------------------------------------------------------------------------------- shifts
def test_shift_view_convention():
    rng = np.random.default_rng(0)
    img = rng.uniform(0, 1, (20, 30, 3)).astype(np.float32)
    out = _core.shift_view(img, 2.0, dv=1.0, du=-1.0)    # out(y, x) = img(y - 2, x + 2)
    np.testing.assert_allclose(out[5:15, 5:20], img[3:13, 7:22], atol=1e-6)
    grid = tuple(np.mgrid[0:20, 0:30].astype(np.float32))
    d = np.full((20, 30), 2.0, np.float32)
    np.testing.assert_allclose(_core.remap_view(img, d, 1.0, -1.0, grid), out, atol=1e-5)


def test_view_pattern_and_sectors():
    star = _core.view_pattern(9, 9, "star")
    assert star.sum() == 33 and star[4].all() and star[:, 4].all() and star[0, 0] and not star[0, 1]
    # 8 sectors, each holding one arm of the star (4 views each)
    sectors = [_core.sector_of(v - 4, u - 4) for v in range(9) for u in range(9) if star[v, u] and (v, u) != (4, 4)]
    assert np.bincount(sectors, minlength=8).tolist() == [4] * 8
    with pytest.raises(ValueError, match="pattern"):
        _core.view_pattern(3, 3, "ring")


# ---------------------------------------------------------------------------------------------- SGM
def _sgm_reference(cost, guide, p1, p2, sigma, dirs):
    """Direct transcription of Hirschmueller's recurrence, pixel by pixel (slow, tiny inputs only)."""
    Y, X, D = cost.shape
    total = np.zeros_like(cost, dtype=np.float64)
    for dy, dx in dirs:
        L = np.zeros_like(cost, dtype=np.float64)
        ys = range(Y) if dy >= 0 else range(Y - 1, -1, -1)
        xs = range(X) if dx >= 0 else range(X - 1, -1, -1)
        for y in ys:
            for x in xs:
                py, px = y - dy, x - dx
                if not (0 <= py < Y and 0 <= px < X):
                    L[y, x] = cost[y, x]
                    continue
                prev = L[py, px]
                m = prev.min()
                q2 = max(p1, p2 / (1 + abs(guide[y, x] - guide[py, px]) / sigma))
                for d in range(D):
                    cands = [prev[d], m + q2]
                    if d > 0:
                        cands.append(prev[d - 1] + p1)
                    if d < D - 1:
                        cands.append(prev[d + 1] + p1)
                    L[y, x, d] = cost[y, x, d] + min(cands) - m
        total += L
    return total


def test_sgm_matches_the_recurrence():
    rng = np.random.default_rng(4)
    cost = rng.uniform(0, 1, (7, 9, 6)).astype(np.float32)
    guide = rng.uniform(0, 1, (7, 9)).astype(np.float32)
    out = _core.sgm(cost, guide, p1=0.1, p2=0.8, sigma=0.2, paths=8)
    ref = _sgm_reference(cost, guide, 0.1, 0.8, 0.2, _core.SGM_DIRECTIONS)
    np.testing.assert_allclose(out, ref, rtol=1e-5, atol=1e-5)
    out4 = _core.sgm(cost, guide, p1=0.1, p2=0.8, sigma=0.2, paths=4)
    np.testing.assert_allclose(out4, _sgm_reference(cost, guide, 0.1, 0.8, 0.2, _core.SGM_DIRECTIONS[:4]),
                               rtol=1e-5, atol=1e-5)


def test_sgm_removes_noise_from_a_piecewise_constant_labeling():
    rng = np.random.default_rng(5)
    Y, X, D = 40, 50, 12
    truth = np.where(np.arange(X)[None, :] < 25, 3, 8) * np.ones((Y, 1), int)
    cost = np.abs(np.arange(D)[None, None, :] - truth[..., None]).astype(np.float32) * 0.1
    cost += rng.uniform(0, 0.6, cost.shape).astype(np.float32)
    guide = np.where(np.arange(X)[None, :] < 25, 0.2, 0.8) * np.ones((Y, 1), np.float32)
    raw_ok = np.mean(np.argmin(cost, -1) == truth)
    agg_ok = np.mean(np.argmin(_core.sgm(cost, guide, p1=1.0, p2=5.0, sigma=0.1), -1) == truth)
    assert raw_ok < 0.6 and agg_ok > 0.98


# ---------------------------------------------------------------------------------------------- winner
def test_winner_subpixel_and_confidence():
    labels = np.linspace(-2, 2, 41)                       # step 0.1
    true = np.array([[0.337, -1.512], [1.05, 0.0]])
    cost = ((labels[None, None, :] - true[..., None]) ** 2).astype(np.float32) + 0.5
    d, conf = _core.winner(cost, labels)
    np.testing.assert_allclose(d, true, atol=1e-4)          # a parabola is exact on a quadratic cost
    flat = np.ones((1, 1, 41), np.float32)
    two = np.ones((1, 1, 41), np.float32)
    two[0, 0, [5, 30]] = 0.2
    assert _core.winner(flat, labels)[1][0, 0] == 0.0
    assert _core.winner(two, labels)[1][0, 0] == 0.0        # two equal minima: ambiguous
    k = np.argmin(cost, -1)
    idx = np.arange(41)
    c2 = np.array([[cost[i, j][np.abs(idx - k[i, j]) > 3].min() for j in range(2)] for i in range(2)])
    c1 = cost.min(-1)
    np.testing.assert_allclose(conf, (c2 - c1) / c2, rtol=1e-5)


def test_make_labels_and_range_errors():
    lab = _core.make_labels(-1.0, 1.0, 0.3, pad=0.1)
    assert lab[0] == -1.1 and lab[-1] == pytest.approx(1.1) and np.diff(lab).max() <= 0.3 + 1e-12
    with pytest.raises(ValueError, match="label_step"):
        _core.make_labels(0, 1, 0)
    with pytest.raises(ValueError, match="disparity_range"):
        _core._check_range((2, 1), "disparity_range")
