import math

import numpy as np
import pytest

from plenodecode.errors import CalibrationError
from plenodecode.types import LensletGrid, LightField, RawCapture, cfa_channel_map


def _hex_grid(rotation=0.003, refined=False):
    shape = (7, 9)
    ref = None
    if refined:
        ref = np.full((*shape, 2), np.nan)
        ref[3, 4] = (40.25, 60.5)
    return LensletGrid("hex", 14.29, 14.29 * math.sqrt(3) / 2, rotation, (10.5, 12.25), shape, 0.5,
                       (120, 160), 7.0, refined=ref, residual_rms=0.01, info={"serial": "B123"})


def test_grid_lattice_geometry_matches_model():
    g = _hex_grid(rotation=0.0)
    c = g.centres_2d()
    assert c.shape == (7, 9, 2)
    np.testing.assert_allclose(c[0, 0], (10.5, 12.25))
    np.testing.assert_allclose(c[0, 1], (10.5, 12.25 + 14.29))
    np.testing.assert_allclose(c[1, 0], (10.5 + g.row_spacing, 12.25 + 0.5 * 14.29))


def test_grid_rotation_turns_rows_towards_plus_row():
    g = _hex_grid(rotation=0.01)
    c = g.centres_2d()
    d = c[0, 8] - c[0, 0]
    assert math.isclose(math.atan2(d[0], d[1]), 0.01, abs_tol=1e-12)
    a, b = g.sensor_to_lattice(c)
    np.testing.assert_allclose(g.lattice_to_sensor(a, b), c, atol=1e-9)


def test_grid_json_round_trip_keeps_refined_and_nan():
    g = _hex_grid(refined=True)
    h = LensletGrid.from_json(g.to_json())
    np.testing.assert_array_equal(h.centres(), g.centres())
    assert np.isnan(h.refined[0, 0, 0]) and h.refined[3, 4, 1] == 60.5
    assert (h.pitch, h.rotation, h.origin, h.shape, h.info) == (g.pitch, g.rotation, g.origin, g.shape, g.info)


def test_grid_json_rejects_foreign_and_newer():
    with pytest.raises(CalibrationError):
        LensletGrid.from_json('{"format": "x"}')
    d = _hex_grid().to_dict()
    d["version"] = 99
    with pytest.raises(CalibrationError, match="newer"):
        LensletGrid.from_dict(d)


def test_decoded_sampling_illum_size():
    pitch = 20e-6 / 1.4e-6
    g = LensletGrid("hex", pitch, pitch * math.sqrt(3) / 2, 0.0, (7, 7), (434, 541), 0.5, (5368, 7728), 7.0)
    s = g.decoded_sampling()
    assert g.n_views() == 15
    assert s["Y"] == 434 and 620 <= s["X"] <= 626


def test_raw_capture_normalised_per_cfa_position():
    m = np.array([[100, 200], [300, 400]], np.uint16)
    raw = RawCapture(m, "GRBG", black=[[0, 100], [100, 0]], white=1100.0)
    np.testing.assert_allclose(raw.normalised(), [[100 / 1100, 100 / 1000], [200 / 1000, 400 / 1100]], rtol=1e-6)
    assert cfa_channel_map("GRBG").tolist() == [[1, 0], [2, 1]]


def test_light_field_validates_shape_and_dtype():
    with pytest.raises(ValueError, match="5-D"):
        LightField(np.zeros((3, 3, 4, 4), np.float32))
    with pytest.raises(ValueError, match="float32"):
        LightField(np.zeros((3, 3, 4, 4, 3)))
    lf = LightField(np.zeros((3, 5, 4, 4, 3), np.float32))
    assert lf.centre_index == (1, 2)


def test_public_api_names_are_callables_even_after_subpackage_imports():
    """Importing a subpackage never replaces a public function of the same name (no module is named like one)."""
    import importlib
    import types

    import plenodecode as pd

    for sub in ("io", "calib", "decoding", "render", "depth"):
        importlib.import_module(f"plenodecode.{sub}")
    for name in ("read_raw", "simulate", "calibrate", "decode", "refocus", "focal_stack", "all_in_focus",
                 "perspective", "estimate_depth", "disparity_to_depth", "save_lightfield", "load_lightfield"):
        assert callable(getattr(pd, name)), name
        assert not isinstance(getattr(pd, name), types.ModuleType), name
