"""Geometric calibrations on disk: this project's JSON and the toolbox's CalInfo.json."""

import json

import numpy as np
import pytest

from plenodecode import raymodel as model
from plenodecode.errors import FormatError
from plenodecode.io.calinfo import load_geometric_calibration, save_geometric_calibration
from tests.conftest import shared_path


def test_real_toolbox_calinfo_loads_with_zero_based_indices(tmp_path):
    path = shared_path("lytro-f01-gridmodel", "CalInfo.json")
    doc = json.loads(path.read_text())
    cal = load_geometric_calibration(path)
    assert cal.lf_shape == (11, 11, 379, 379)
    assert cal.poses.shape == (9, 6)
    assert np.allclose(cal.distortion, doc["EstCamDistortionV"])
    # sample (0,0,0,0) here is the toolbox's (1,1,1,1)
    h_tb = np.asarray(doc["EstCamIntrinsicsH"])
    assert np.allclose(model.measured_rays(cal.intrinsics, np.zeros(4)), (h_tb @ [1, 1, 1, 1, 1])[:4])
    # round trip through the toolbox layout and through this project's own
    for toolbox in (True, False):
        out = save_geometric_calibration(cal, tmp_path / f"cal{toolbox}.json", toolbox=toolbox)
        back = load_geometric_calibration(out)
        assert np.allclose(back.intrinsics, cal.intrinsics, rtol=1e-12, atol=1e-15)
        assert np.allclose(back.distortion, cal.distortion) and back.lf_shape == cal.lf_shape
        assert np.allclose(back.poses, cal.poses)


def test_not_a_calibration_is_a_format_error(tmp_path):
    bad = tmp_path / "x.json"
    bad.write_text('{"hello": 1}')
    with pytest.raises(FormatError, match="x.json"):
        load_geometric_calibration(bad)
    bad.write_text("not json")
    with pytest.raises(FormatError, match="x.json"):
        load_geometric_calibration(bad)
