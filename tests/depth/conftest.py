"""Fixtures shared by the depth tests."""

import pytest

from plenodecode.depth.views import prepare_views
from tests.depth.test_methods import planes_lightfield


@pytest.fixture(scope="module")
def scene():
    lf, gt = planes_lightfield(n=7, size=64, d_back=-0.6, d_front=1.0, seed=4)
    views = prepare_views(lf, grey=True, contrast_sigma=1.5, contrast_eps=0.005, contrast_weight=0.07)
    return lf, gt, views


@pytest.fixture(scope="module")
def planes():
    return planes_lightfield()
