"""Aggregation: the SGM recurrence and the winner-take-all minimum with its confidence."""

import numpy as np
import pytest

from plenodecode.depth.aggregation import SGM_DIRECTIONS, sgm, winner


def _sgm_reference(cost, guide, p1, p2, sigma, dirs):
    """Direct transcription of Hirschmueller's recurrence with the P2 of :func:`sgm`, pixel by pixel (slow, tiny
    inputs only)."""
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
                # the guide's step, also across the pixel before or after (an edge spread over a mixed pixel)
                steps = [abs(guide[y, x] - guide[py, px])]
                if 0 <= py - dy < Y and 0 <= px - dx < X:
                    steps.append(abs(guide[y, x] - guide[py - dy, px - dx]))
                if 0 <= y + dy < Y and 0 <= x + dx < X:
                    steps.append(abs(guide[y + dy, x + dx] - guide[py, px]))
                q2 = max(p1, p2 / (1 + max(steps) / sigma))
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


@pytest.mark.parametrize("width", [1, 2, 3])
def test_sgm_jump_penalty_falls_at_an_edge_spread_over_a_mixed_pixel(width):
    """A strip of ``width`` px (labels 9 of 0..9) in a background (label 0), one row, so that only the
    horizontal paths carry it across; each label costs 0.05 more than the right one.  Its guide step of 0.3
    is sharp, or spread over a mixed pixel on either side (guide 0.15, costs halfway), as on an oblique edge.
    P2 falls with the step across the mixed pixel (``G`` of :func:`sgm`), so the strip survives there as at
    the sharp edges; with the step between neighbours alone (0.15 twice) it was smoothed away at 0.05."""
    labels = np.arange(10, dtype=np.float64)
    found = {}
    for mixed in (False, True):
        guide = np.zeros((1, 40), np.float32)
        guide[:, 20:20 + width] = 0.3
        cost = np.full((1, 40, 10), 0.05, np.float32)
        cost[0, :, 0] = 0.0
        cost[0, 20:20 + width, 0] = 0.05
        cost[0, 20:20 + width, 9] = 0.0
        if mixed:
            for x in (19, 20 + width):
                guide[0, x] = 0.15
                cost[0, x] = 0.025
                cost[0, x, [0, 9]] = 0.0
        d, _ = winner(sgm(cost, guide, p1=0.1, p2=3.0, sigma=0.02, paths=8), labels)
        found[mixed] = np.mean(np.abs(d[0, 20:20 + width] - 9) < 0.5)
    assert found == {False: 1.0, True: 1.0}
