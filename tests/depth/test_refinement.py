"""Refinement: the sub-label offset of a per-pixel cost volume and the weighted median."""

import numpy as np

from plenodecode.depth.refinement import refine_disparity, refine_radius_for, weighted_median
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
