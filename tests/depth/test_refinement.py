"""Refinement: the sub-label offset of a per-pixel cost volume and the weighted median."""

import numpy as np

from plenodecode.depth.refinement import cost_at, cost_gate, refine_disparity, refine_radius_for, weighted_median
from plenodecode.depth.views import prepare_views
from tests.depth.test_methods import planes_lightfield


def test_refinement_moves_a_coarse_map_onto_the_plane():
    d = 0.43
    lf, _ = planes_lightfield(n=5, size=48, d_back=d, d_front=d, square=(0, 0, 0, 0), seed=3)
    views = prepare_views(lf, grey=True)
    coarse = np.full((48, 48), 0.4, np.float32)                  # one label (0.1 px) away at most
    fine = refine_disparity(views, coarse, half_range=0.1, samples=9, radius=3)
    err = np.abs(fine - d)[6:-6, 6:-6]
    assert fine.dtype == np.float32 and np.median(err) < 0.01 and np.abs(coarse - 0.4).max() == 0.0


def test_refine_radius_and_median_off():
    assert refine_radius_for((512, 512), "auto") == 6 and refine_radius_for((64, 48), "auto") == 3
    assert refine_radius_for((64, 48), 2) == 2
    d = np.random.default_rng(0).uniform(0, 1, (10, 12)).astype(np.float32)
    assert weighted_median(np.zeros((10, 12), np.float32), d, 0) is d


def test_cost_at_reads_the_volume_linearly_between_labels():
    labels = np.linspace(-1.0, 1.0, 5)                                  # step 0.5
    cost = np.broadcast_to(np.array([4.0, 3.0, 0.0, 1.0, 2.0], np.float32), (2, 3, 5)).copy()
    d = np.array([[-1.0, -0.75, 0.25], [1.0, 2.0, -3.0]], np.float32)   # off the range: clipped to the ends
    np.testing.assert_allclose(cost_at(cost, labels, d), [[4.0, 3.5, 0.5], [2.0, 2.0, 4.0]], atol=1e-6)


def test_cost_gate_keeps_what_the_views_support():
    """A 1-px slat (label 3) that a median replaced by the background (label 1): its cost there is 10 x its
    own, so it stays; a noisy pixel whose median value costs about the same as its own takes the median."""
    labels = np.arange(5, dtype=np.float64)
    cost = np.ones((1, 3, 5), np.float32)
    cost[0, 0] = [1.0, 1.0, 1.0, 0.1, 1.0]       # the slat matches at 3 only
    cost[0, 1] = [0.5, 0.2, 0.5, 0.25, 0.5]      # ambiguous: 1 and 3 about equal
    cost[0, 2] = [1.0, 0.1, 1.0, 1.0, 1.0]       # the median moves it onto its minimum
    before = np.array([[3.0, 3.0, 3.0]], np.float32)
    after = np.array([[1.0, 1.0, 1.0]], np.float32)
    out = cost_gate(cost, labels, before, after, ratio=2.0, floor=0.05)
    np.testing.assert_array_equal(out, [[3.0, 1.0, 1.0]])
    assert out.dtype == np.float32


def test_cost_gate_subtracts_the_noise_base():
    """On noisy views every label's cost sits on the noise's: a far pixel matching its own label at 1.0 and a
    median's value at 1.3 passes a ratio of 2, but above a base of 0.9 the median's costs 4 x more."""
    labels = np.arange(3, dtype=np.float64)
    cost = np.array([[[1.0, 1.3, 1.3], [1.0, 1.02, 1.3]]], np.float32)
    before = np.zeros((1, 2), np.float32)
    after = np.ones((1, 2), np.float32)
    np.testing.assert_array_equal(cost_gate(cost, labels, before, after, ratio=2.0, floor=0.05), [[1.0, 1.0]])
    # the second pixel's values cost the same above the base too: the median stands
    np.testing.assert_array_equal(cost_gate(cost, labels, before, after, ratio=2.0, floor=0.05, base=0.9),
                                  [[0.0, 1.0]])
