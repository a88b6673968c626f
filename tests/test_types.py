import json
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


# ---------------------------------------------------------------------------------------------------------------
# LightFieldGeometry: the typed metadata of a light field
# ---------------------------------------------------------------------------------------------------------------
def _camera():
    from plenodecode.types import CameraMetadata

    return CameraMetadata(model="ILLUM", serial="B5", focal_length_m=0.0301, f_number=2.0, lens_pitch_m=2.0e-5,
                          pixel_pitch_m=1.4e-6, mla_offset_m=(0.0, 0.0, 3.7e-5), wb_gains={"r": 1.9, "g": 1.0, "b": 1.4},
                          ccm=((1.5, -0.3, -0.2), (-0.2, 1.4, -0.2), (0.0, -0.5, 1.5)),
                          extra={"devices": {"lens": {"infinityLambda": 12.5}}})


def _legacy_decoded_metadata():
    """The free metadata dict decode() wrote before the typed geometry."""
    grid = _hex_grid()
    return {"source": "a.lfr", "calibration": grid.to_dict(), "camera": _camera().to_dict(),
            "spatial_step_px": grid.row_spacing, "view_step_px": 1.0, "colour": "linear-srgb", "demosaic": "malvar",
            "geometry": {"pixel_pitch_m": 1.4e-6, "lens_pitch_m": 2.0e-5, "lens_pitch_px": 14.29,
                         "focal_length_m": 0.0301, "f_number": 2.0, "mla_sensor_gap_m": 3.7e-5}}


def _lf(meta=None, colour="linear-srgb", **kw):
    return LightField(np.zeros((3, 3, 4, 5, 3), np.float32), None, colour, meta, **kw)


def test_legacy_metadata_dict_becomes_the_typed_geometry():
    from plenodecode.types import LightFieldGeometry

    lf = _lf(_legacy_decoded_metadata())
    g = lf.geometry
    assert isinstance(g, LightFieldGeometry)
    assert (g.focal_length_m, g.f_number, g.lens_pitch_m, g.pixel_pitch_m) == (0.0301, 2.0, 2.0e-5, 1.4e-6)
    assert g.spatial_step_px == pytest.approx(14.29 * math.sqrt(3) / 2) and g.view_step_px == 1.0
    assert g.mla_sensor_gap_m == 3.7e-5 and g.infinity_lambda == 12.5
    assert g.source == "a.lfr" and g.calibration == _hex_grid().to_dict() and g.camera == _camera()
    assert g.colour == "linear-srgb" and g.hci is None and g.disparity_range is None
    # provenance stays free-form; the legacy keys are still readable from lf.metadata
    assert lf.provenance == {"demosaic": "malvar"}
    assert lf.metadata["camera"]["serial"] == "B5" and lf.metadata["view_step_px"] == 1.0
    assert lf.metadata["geometry"]["lens_pitch_m"] == 2.0e-5 and lf.metadata["demosaic"] == "malvar"


def test_legacy_fallbacks_lens_pitch_and_spatial_step_from_the_calibration():
    meta = _legacy_decoded_metadata()
    meta["camera"] = dict(meta["camera"], lens_pitch_m=None, mla_offset_m=None)
    del meta["spatial_step_px"], meta["geometry"]
    g = _lf(meta).geometry
    assert g.lens_pitch_m == pytest.approx(14.29 * 1.4e-6, rel=1e-12)
    assert g.spatial_step_px == pytest.approx(_hex_grid().row_spacing)
    assert g.mla_sensor_gap_m is None


def test_synthetic_generator_metadata_converts():
    """The keys plenodecode.synthetic builds (Simulation.lightfield, load_truth)."""
    grid = _hex_grid()
    meta = {"source": "plenodecode.io.synthetic", "preset": "illum-mini", "seed": 3, "spatial_step_px": 12.0,
            "view_step_px": 1.0, "calibration": grid.to_dict(), "camera": _camera().to_dict(),
            "disparity_range": [-0.5, 0.9]}
    lf = _lf(meta)
    assert lf.geometry.disparity_range == (-0.5, 0.9) and lf.geometry.spatial_step_px == 12.0
    assert lf.provenance == {"preset": "illum-mini", "seed": 3}
    assert lf.metadata["disparity_range"] == [-0.5, 0.9] and lf.metadata["calibration"] == grid.to_dict()


def test_legacy_view_round_trips_and_replace_rules():
    from dataclasses import replace

    lf = _lf(_legacy_decoded_metadata())
    # the legacy view read back gives the same geometry
    assert _lf(dict(lf.metadata)).geometry == lf.geometry
    # a copy keeps geometry and provenance; colour follows lf.colour
    enc = lf.replace(colour="srgb")
    assert enc.geometry == replace(lf.geometry, colour="srgb") and enc.geometry.display_encoded
    assert not lf.geometry.display_encoded and enc.provenance == lf.provenance
    cam = lf.replace(colour="camera-srgb-curve")      # camera RGB with the sRGB curve: encoded, not sRGB colours
    assert cam.geometry.colour == "camera-srgb-curve" and cam.geometry.display_encoded
    # metadata= replaces everything (legacy keys included); geometry= keeps the typed part
    assert lf.replace(metadata={}).geometry == _lf({}).geometry
    edited = lf.replace(metadata={**lf.metadata, "disparity_range": [-1.0, 2.0]})
    assert edited.geometry == replace(lf.geometry, disparity_range=(-1.0, 2.0))
    kept = lf.replace(metadata={"note": 1}, geometry=lf.geometry)
    assert kept.geometry == lf.geometry and kept.provenance == {"note": 1}
    # a typed geometry passed with free metadata
    from plenodecode.types import LightFieldGeometry

    typed = _lf({"note": 2}, geometry=LightFieldGeometry(spatial_step_px=2.0, disparity_range=[0, 1]))
    assert typed.geometry.disparity_range == (0.0, 1.0) and typed.metadata["spatial_step_px"] == 2.0


def test_geometry_document_round_trip_and_version():
    from plenodecode.errors import MetadataError
    from plenodecode.types import GEOMETRY_SCHEMA_VERSION, HCIParameters, LightFieldGeometry

    g = _lf(_legacy_decoded_metadata()).geometry
    hci = HCIParameters(baseline_mm=100.0, focal_length_mm=100.0, sensor_size_mm=35.0, resolution_px=(512, 512),
                        focus_distance_m=7.0, disparity_range=(-3.3, 2.8), sections={"meta": {"scene": "x"}})
    for geometry in (g, LightFieldGeometry(), LightFieldGeometry(hci=hci, spatial_step_px=1.0, colour="srgb")):
        doc = json.loads(json.dumps(geometry.to_dict()))
        assert doc["version"] == GEOMETRY_SCHEMA_VERSION
        back = LightFieldGeometry.from_dict(doc)
        assert back == LightFieldGeometry.from_dict(json.loads(json.dumps(back.to_dict())))
        for name in ("spatial_step_px", "focal_length_m", "lens_pitch_m", "mla_sensor_gap_m", "disparity_range",
                     "colour", "source", "calibration", "camera"):
            assert getattr(back, name) == getattr(geometry, name), name
    assert LightFieldGeometry.from_dict(json.loads(json.dumps(LightFieldGeometry(hci=hci).to_dict()))).hci == \
        HCIParameters.from_cfg(hci.to_cfg())
    with pytest.raises(MetadataError, match="newer"):
        LightFieldGeometry.from_dict({"version": GEOMETRY_SCHEMA_VERSION + 1})
    with pytest.raises(ValueError, match="colour"):
        LightFieldGeometry(colour="rgb")


def test_hci_parameters_from_cfg():
    from plenodecode.errors import MetadataError
    from plenodecode.types import HCIParameters

    cfg = {"intrinsics": {"focal_length_mm": 100, "image_resolution_x_px": 512, "image_resolution_y_px": 384,
                          "sensor_size_mm": 35, "fstop": 100},
           "extrinsics": {"baseline_mm": 100, "focus_distance_m": 7, "num_cams_x": 9},
           "meta": {"disp_min": -3.3, "disp_max": 2.8}}
    h = HCIParameters.from_cfg(cfg)
    assert (h.baseline_mm, h.focal_length_mm, h.sensor_size_mm, h.focus_distance_m) == (100.0, 100.0, 35.0, 7.0)
    assert h.resolution_px == (512, 384) and h.image_resolution_px == 512.0 and h.disparity_range == (-3.3, 2.8)
    assert h.to_cfg() == cfg and HCIParameters.from_cfg(h.to_cfg()) == h
    assert HCIParameters.from_cfg({}) is None and HCIParameters.from_cfg(None) is None
    assert HCIParameters.from_cfg({"extrinsics": {"focus_distance_m": 7}}).baseline_mm is None
    with pytest.raises(MetadataError, match="baseline_mm"):
        HCIParameters.from_cfg({"extrinsics": {"baseline_mm": "wide"}})
    # the HCI scene of a legacy dict: metric depth and the search range read it
    lf = _lf({"hci_parameters": cfg})
    assert lf.geometry.hci == h and lf.geometry.disparity_range is None


#: Every public name plenodecode.types had before its metadata types moved to plenodecode.metadata.
TYPES_NAMES = ("CFA_PATTERNS", "COLOUR_STATES", "GRID_JSON_VERSION", "cfa_channel_map", "CameraMetadata", "RawCapture",
               "LensletGrid", "LightField", "LightFieldGeometry", "HCIParameters", "LightFieldMetadata",
               "GEOMETRY_SCHEMA_VERSION", "LINEAR_COLOUR_STATES", "LEGACY_GEOMETRY_KEYS", "MicroscopeOptics")


def test_types_hands_on_the_metadata_types():
    """``from plenodecode.types import X`` keeps working for every public name, and the names moved to
    plenodecode.metadata are the same objects (isinstance checks agree whichever module a caller imports)."""
    import plenodecode.metadata as metadata
    import plenodecode.types as types

    assert set(TYPES_NAMES) <= set(types.__all__)
    for name in TYPES_NAMES:
        assert getattr(types, name) is not None, name
    for name in metadata.__all__:
        assert getattr(types, name) is getattr(metadata, name), name
    lf = LightField(np.zeros((3, 3, 2, 2, 1), np.float32), metadata={"spatial_step_px": 2.0})
    assert isinstance(lf.geometry, metadata.LightFieldGeometry) and lf.geometry.spatial_step_px == 2.0


def test_encoded_and_linear_colour_states_pair_up():
    """Each linear state has one sRGB-encoded state with the same primaries, and back."""
    from plenodecode.types import (COLOUR_STATES, ENCODED_COLOUR_STATES, LINEAR_COLOUR_STATES, encoded_colour_state,
                                   linear_colour_state)

    assert encoded_colour_state("camera") == "camera-srgb-curve" and encoded_colour_state("linear-srgb") == "srgb"
    assert linear_colour_state("camera-srgb-curve") == "camera" and linear_colour_state("srgb") == "linear-srgb"
    assert set(COLOUR_STATES) == set(LINEAR_COLOUR_STATES) | set(ENCODED_COLOUR_STATES.values())
    for state in COLOUR_STATES:
        enc, lin = encoded_colour_state(state), linear_colour_state(state)
        assert enc in ENCODED_COLOUR_STATES.values() and lin in LINEAR_COLOUR_STATES
        assert encoded_colour_state(lin) == enc and linear_colour_state(enc) == lin
