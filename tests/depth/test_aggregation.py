"""Aggregation: the SGM recurrence and the winner-take-all minimum with its confidence."""

import numpy as np

from plenodecode.depth.aggregation import SGM_DIRECTIONS, sgm, winner


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
    out = sgm(cost, guide, p1=0.1, p2=0.8, sigma=0.2, paths=8)
    ref = _sgm_reference(cost, guide, 0.1, 0.8, 0.2, SGM_DIRECTIONS)
    np.testing.assert_allclose(out, ref, rtol=1e-5, atol=1e-5)
    out4 = sgm(cost, guide, p1=0.1, p2=0.8, sigma=0.2, paths=4)
    np.testing.assert_allclose(out4, _sgm_reference(cost, guide, 0.1, 0.8, 0.2, SGM_DIRECTIONS[:4]),
                               rtol=1e-5, atol=1e-5)


def test_sgm_removes_noise_from_a_piecewise_constant_labeling():
    rng = np.random.default_rng(5)
    Y, X, D = 40, 50, 12
    truth = np.where(np.arange(X)[None, :] < 25, 3, 8) * np.ones((Y, 1), int)
    cost = np.abs(np.arange(D)[None, None, :] - truth[..., None]).astype(np.float32) * 0.1
    cost += rng.uniform(0, 0.6, cost.shape).astype(np.float32)
    guide = np.where(np.arange(X)[None, :] < 25, 0.2, 0.8) * np.ones((Y, 1), np.float32)
    raw_ok = np.mean(np.argmin(cost, -1) == truth)
    agg_ok = np.mean(np.argmin(sgm(cost, guide, p1=1.0, p2=5.0, sigma=0.1), -1) == truth)
    assert raw_ok < 0.6 and agg_ok > 0.98


def test_winner_subpixel_and_confidence():
    labels = np.linspace(-2, 2, 41)                       # step 0.1
    true = np.array([[0.337, -1.512], [1.05, 0.0]])
    cost = ((labels[None, None, :] - true[..., None]) ** 2).astype(np.float32) + 0.5
    d, conf = winner(cost, labels)
    np.testing.assert_allclose(d, true, atol=1e-4)          # a parabola is exact on a quadratic cost
    flat = np.ones((1, 1, 41), np.float32)
    two = np.ones((1, 1, 41), np.float32)
    two[0, 0, [5, 30]] = 0.2
    assert winner(flat, labels)[1][0, 0] == 0.0
    assert winner(two, labels)[1][0, 0] == 0.0        # two equal minima: ambiguous
    k = np.argmin(cost, -1)
    idx = np.arange(41)
    c2 = np.array([[cost[i, j][np.abs(idx - k[i, j]) > 3].min() for j in range(2)] for i in range(2)])
    c1 = cost.min(-1)
    np.testing.assert_allclose(conf, (c2 - c1) / c2, rtol=1e-5)
