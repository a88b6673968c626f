"""The pipeline's parameter checking and the choice of the disparity range."""

import cv2
import numpy as np
import pytest

from plenodecode.depth.pipeline import _check_range, disparity_range, metadata_disparity_range
from plenodecode.depth.views import prepare_views
from plenodecode.types import LightField, LightFieldGeometry


def test_range_errors():
    with pytest.raises(ValueError, match="disparity_range"):
        _check_range((2, 1), "disparity_range")


def test_metadata_disparity_range():
    assert metadata_disparity_range({"disparity_range": [-1, 2]}) == (-1.0, 2.0)
    assert metadata_disparity_range({"hci_parameters": {"meta": {"disp_min": -1.5, "disp_max": 1.5}}}) == (-1.5, 1.5)
    assert metadata_disparity_range({}) is None
    with pytest.raises(ValueError, match="disparity_range"):
        metadata_disparity_range({"disparity_range": [3, 1]})


@pytest.mark.parametrize("name, value", [("strips", -1), ("strip_width", 0.0), ("strip_penalty", 0.0),
                                         ("strip_radius", -2), ("gate_ratio", -1.0), ("gate_floor", -0.1)])
def test_strip_and_gate_parameters_are_checked(name, value):
    from plenodecode.depth.methods import COSTVOLUME
    from plenodecode.depth.pipeline import check_params, preset_defaults

    assert check_params("costvolume", preset_defaults(COSTVOLUME), {})["strips"] == 12
    with pytest.raises(ValueError, match=name):
        check_params("costvolume", preset_defaults(COSTVOLUME), {name: value})


def test_refine_strip_penalty_falls_with_the_noise():
    from plenodecode.depth.pipeline import strip_penalty_for

    # full penalty on clean views, 1 / sigma above the reference: a noise floor 2 sigma^2 under the costs
    assert strip_penalty_for(16.0, 0.002, 0.0) == 16.0
    assert strip_penalty_for(16.0, 0.002, 0.0017) == 16.0
    assert strip_penalty_for(16.0, 0.002, 0.008) == pytest.approx(4.0)
    assert strip_penalty_for(16.0, 0.0, 0.008) == 16.0


def test_refine_penalty_noise_is_checked():
    from plenodecode.depth.methods import COSTVOLUME
    from plenodecode.depth.pipeline import check_params, preset_defaults

    with pytest.raises(ValueError, match="refine_penalty_noise"):
        check_params("costvolume", preset_defaults(COSTVOLUME), {"refine_penalty_noise": -0.001})


def test_refine_strip_penalty_keeps_a_floor_on_strong_noise():
    from plenodecode.depth.pipeline import MIN_PENALTY_FRACTION, strip_penalty_for

    assert strip_penalty_for(16.0, 0.002, 0.03) == pytest.approx(16.0 * MIN_PENALTY_FRACTION)
    assert strip_penalty_for(16.0, 0.002, 0.01) == pytest.approx(3.2)      # 1 / noise above the reference


def test_edge_floor_is_the_strip_floor_less_two_standard_errors():
    """The visibility check's noise floor: the strips' floor less FLOOR_MARGIN standard errors of a wedge's
    3 x 3 mean (a quarter of 176 views: 1 - 2 sqrt((1 + 3 / 44) / 18) = 0.513 of it); none without a floor,
    less with fewer views, never negative."""
    from plenodecode.depth.pipeline import edge_floor_for

    assert edge_floor_for(1.0, 176, 2) == pytest.approx(1 - 2 * ((1 + 3 / 44) / 18) ** 0.5)
    assert edge_floor_for(0.0, 176, 2) == 0.0 and edge_floor_for(1.0, 0, 2) == 0.0
    assert 0.0 <= edge_floor_for(1.0, 8, 2) < edge_floor_for(1.0, 48, 2) < edge_floor_for(1.0, 176, 2)


def _mesh_over_texture(d_mesh: float = 0.8, d_back: float = -0.3, period: float = 9.0, n: int = 9,
                       size: int = 160) -> LightField:
    """n x n views, size x size px: a periodic mesh (``cos x cos`` dots, ``period`` px) at disparity ``d_mesh`` over
    the left two thirds, a random texture at ``d_back`` on the rest; ``view(v, u)(y, x) = layer(y + d (v - c),
    x + d (u - c))``; the geometry of a decoded F01 (lens footprint 9.93 / 8.6 samples: refocusable +-1.15)."""
    rng = np.random.default_rng(0)
    big = size + 64
    yy, xx = np.mgrid[0:big, 0:big].astype(np.float32)
    mesh = 0.5 + 0.4 * np.cos(2 * np.pi * xx / period) * np.cos(2 * np.pi * yy / period)
    back = cv2.GaussianBlur(rng.random((big, big)).astype(np.float32), (0, 0), 1.2)
    back = 0.5 + 0.15 * (back - back.mean()) / back.std()
    c = n // 2
    data = np.empty((n, n, size, size, 1), np.float32)
    left = np.arange(size)[None, :] < 2 * size // 3
    for v in range(n):
        for u in range(n):
            layers = [cv2.warpAffine(img, np.float32([[1, 0, d * (u - c) + 32], [0, 1, d * (v - c) + 32]]),
                                     (size, size), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP)
                      for img, d in ((mesh, d_mesh), (back, d_back))]
            data[v, u, :, :, 0] = np.where(left, *layers)
    return LightField(data, geometry=LightFieldGeometry(spatial_step_px=8.6, view_step_px=1.0,
                                                        calibration={"pitch": 9.93}))


def test_estimated_range_of_a_periodic_texture_stays_near_the_scene():
    """A periodic mesh matches itself one period away: searched over a quarter of the picture per view step
    (+-10 px/view here) its repeats set the range to -9.2 .. 1.1 (truth -0.3 .. 0.8).  A decoded plenoptic light
    field's search spans 3x its refocusable range, and minima on the search's first or last label are left out."""
    lf = _mesh_over_texture()
    (lo, hi), source = disparity_range(lf, lambda: prepare_views(lf, grey=True))
    assert source == "estimated"
    assert -0.9 < lo < -0.3 and 0.8 < hi < 1.4, (lo, hi)
