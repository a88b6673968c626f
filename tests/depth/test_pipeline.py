"""The pipeline's parameter checking and the choice of the disparity range."""

import pytest

from plenodecode.depth.pipeline import _check_range, metadata_disparity_range


def test_range_errors():
    with pytest.raises(ValueError, match="disparity_range"):
        _check_range((2, 1), "disparity_range")


def test_metadata_disparity_range():
    assert metadata_disparity_range({"disparity_range": [-1, 2]}) == (-1.0, 2.0)
    assert metadata_disparity_range({"hci_parameters": {"meta": {"disp_min": -1.5, "disp_max": 1.5}}}) == (-1.5, 1.5)
    assert metadata_disparity_range({}) is None
    with pytest.raises(ValueError, match="disparity_range"):
        metadata_disparity_range({"disparity_range": [3, 1]})
