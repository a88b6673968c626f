"""Metric depth from disparity: HCI camera arrays and unfocused plenoptic cameras."""

import math

import numpy as np
import pytest

from tests.conftest import shared_path
from plenodecode.depth import disparity_to_depth
from plenodecode.depth.metric import depth_to_disparity, depth_to_points, focal_length_px
from plenodecode.errors import MetadataError
from plenodecode.optics import MicroscopeOptics
from plenodecode.types import LightField, LightFieldGeometry

#: parameters.cfg of the HCI 'antinous' scene (the values every HCI scene shares for the camera)
ANTINOUS = {
    "intrinsics": {"focal_length_mm": 100.0, "image_resolution_x_px": 512, "image_resolution_y_px": 512,
                   "sensor_size_mm": 35.0, "fstop": 100.0},
    "extrinsics": {"num_cams_x": 9, "num_cams_y": 9, "baseline_mm": 100.0, "focus_distance_m": 7.0,
                   "offset": 20.89795918367347},
    "meta": {"disp_min": -3.3, "disp_max": 2.8},
}


def _lf(meta, shape=(3, 3, 4, 6, 1)):
    return LightField(np.zeros(shape, np.float32), None, "srgb", meta)


def test_hci_depth_formula():
    lf = _lf({"hci_parameters": ANTINOUS})
    d = np.array([[0.0, 2.8, -3.3, 1.0]], np.float32)
    z = disparity_to_depth(d, lf)
    f_px = 100.0 / 35.0 * 512
    g = 0.1 * f_px
    # the cfg's own 'offset' is B f_px / Z_f: the disparity of infinity is -offset
    assert g / 7.0 == pytest.approx(ANTINOUS["extrinsics"]["offset"], rel=1e-9)
    assert z[0, 0] == pytest.approx(7.0, rel=1e-6)                       # d = 0 is the focus plane
    np.testing.assert_allclose(z[0], g / (d[0] + g / 7.0), rtol=1e-6)
    assert z[0, 1] < 7.0 < z[0, 2]                                        # positive disparity = closer
    np.testing.assert_allclose(depth_to_disparity(z, lf), d, atol=1e-5)
    # the scene's range 6.17 m .. 8.31 m around the statue at 7 m
    assert 6.1 < z[0, 1] < 6.3 and 8.2 < z[0, 2] < 8.4
    inf = disparity_to_depth(np.array([[-g / 7.0 - 0.1, np.nan]], np.float32), lf)
    assert np.isinf(inf[0, 0]) and np.isnan(inf[0, 1])
    dd = np.linspace(-3.3, 2.8, 50, dtype=np.float32)[None]
    assert np.all(np.diff(disparity_to_depth(dd, lf)[0]) < 0)             # monotonic


def test_hci_overrides_and_missing_values():
    lf = _lf({"hci_parameters": ANTINOUS})
    assert disparity_to_depth(np.zeros((1, 1)), lf, focus_distance_m=3.0)[0, 0] == pytest.approx(3.0)
    broken = {"intrinsics": dict(ANTINOUS["intrinsics"]), "extrinsics": {"focus_distance_m": 7.0}}
    with pytest.raises(MetadataError, match="baseline_mm"):
        disparity_to_depth(np.zeros((1, 1)), _lf({"hci_parameters": broken}))
    with pytest.raises(ValueError, match="unknown override"):
        disparity_to_depth(np.zeros((1, 1)), lf, f_number=2)


def test_hci_points_back_project_through_the_pinhole():
    lf = _lf({"hci_parameters": ANTINOUS}, shape=(3, 3, 512, 512, 1))
    z = np.full((512, 512), 7.0, np.float32)
    pts = depth_to_points(z, lf)
    f_px = 100.0 / 35.0 * 512
    assert focal_length_px(lf) == pytest.approx(f_px)
    # the image edge lies at half the sensor width (17.5 mm) scaled by Z / f
    assert pts[256, 511, 0] == pytest.approx(255.5 * 7.0 / f_px, rel=1e-5)
    assert pts[0, 256, 1] < 0 and pts[511, 256, 1] > 0 and np.all(pts[..., 2] == 7.0)


def test_hci_real_parameters_file():
    from plenodecode.io.hci import read_parameters

    params = read_parameters(shared_path("hci-antinous", "parameters.cfg"))
    lf = _lf({"hci_parameters": params})
    z_inf_disp = depth_to_disparity(np.array([[1e12]]), lf)[0, 0]
    assert z_inf_disp == pytest.approx(-params["extrinsics"]["offset"], rel=1e-6)
    z = disparity_to_depth(np.array([[params["meta"]["disp_min"], params["meta"]["disp_max"]]]), lf)
    assert z[0, 0] > params["extrinsics"]["focus_distance_m"] > z[0, 1] > 0


# ------------------------------------------------------------------------------------------ plenoptic
CAM = {"focal_length_m": 0.03, "f_number": 2.0, "lens_pitch_m": 2.0e-5, "pixel_pitch_m": 1.4e-6}
PITCH_PX = 2.0e-5 / 1.4e-6


def _plenoptic(meta_extra=None, camera_extra=None):
    meta = {"camera": {**CAM, **(camera_extra or {})}, "calibration": {"pitch": PITCH_PX, "row_spacing": 12.37},
            "spatial_step_px": 12.37, "view_step_px": 1.0, **(meta_extra or {})}
    return _lf(meta)


def _ray_traced_disparity(z, zf, f=0.03, n=2.0, pitch_px=PITCH_PX, step_px=12.37):
    """Disparity of a point at depth z by tracing two rays of a thin lens to the MLA plane."""
    b = 1 / (1 / f - 1 / zf)                 # MLA at the image of the focus plane
    bp = 1 / (1 / f - 1 / z)                 # image of the point
    aperture = f / n
    du = aperture / pitch_px                 # aperture step of one view (1 sensor px under a lens)
    dx = 2.0e-5 * step_px / pitch_px         # one spatial sample on the MLA
    x_img = 0.37e-3                          # lateral position of the point's image (any)

    def hit(a):                              # ray from aperture point a through the image point, at z = b
        return a + (x_img - a) * b / bp

    # view u + 1 looks through aperture position -du (the lenslets invert the aperture); the point
    # appears at x_u = x_c - d (u - uc) in view u
    return -(hit(-du) - hit(0.0)) / dx


@pytest.mark.parametrize("z", [0.4, 1.0, 1.5, 3.0, 40.0])
def test_plenoptic_depth_matches_ray_tracing(z):
    lf = _plenoptic({"focus_distance_m": 1.5})
    d = _ray_traced_disparity(z, 1.5)
    assert (d > 0) == (z < 1.5)
    assert disparity_to_depth(np.array([[d]]), lf)[0, 0] == pytest.approx(z, rel=1e-5)


def test_plenoptic_focus_from_infinity_lambda_and_errors():
    gap = 3.9e-5
    lam = 15.409461826381098959
    lf = _plenoptic({"geometry": {"mla_sensor_gap_m": gap}},
                    {"extra": {"devices": {"lens": {"infinityLambda": lam}}}})
    b = 0.03 + lam * gap
    zf = 0.03 * b / (b - 0.03)
    assert disparity_to_depth(np.zeros((1, 1)), lf)[0, 0] == pytest.approx(zf, rel=1e-6)
    assert 1.0 < zf < 2.0
    # an explicit focus distance wins
    assert disparity_to_depth(np.zeros((1, 1)), lf, focus_distance_m=0.8)[0, 0] == pytest.approx(0.8)
    with pytest.raises(MetadataError, match="focus_distance_m"):
        disparity_to_depth(np.zeros((1, 1)), _plenoptic())
    no_fnum = _lf({"camera": {"focal_length_m": 0.03, "lens_pitch_m": 2e-5}, "spatial_step_px": 12.0,
                   "view_step_px": 1.0, "focus_distance_m": 1.0})
    with pytest.raises(MetadataError, match="f_number"):
        disparity_to_depth(np.zeros((1, 1)), no_fnum)
    with pytest.raises(ValueError, match="focus_distance_m"):
        disparity_to_depth(np.zeros((1, 1)), _plenoptic(), focus_distance_m=-1.0)


def test_plenoptic_points_scale():
    lf = _plenoptic({"focus_distance_m": 1.5})
    f = focal_length_px(lf)
    b = 1 / (1 / 0.03 - 1 / 1.5)
    dx = 2.0e-5 * 12.37 / PITCH_PX
    assert f == pytest.approx(b / dx)
    assert math.isfinite(f) and f > 0


# ------------------------------------------------------------------------------------------- light-field microscope
def _microscope(**optics):
    values = dict(lens_pitch_m=125e-6, pixel_pitch_m=4.55e-6, magnification=20.0, numerical_aperture=0.5,
                  medium_index=1.33, microlens_focal_length_m=2433e-6)
    values.update(optics)
    geometry = LightFieldGeometry(spatial_step_px=125 / 4.55, view_step_px=1.0, calibration={"pitch": 125 / 4.55},
                                  microscope=MicroscopeOptics(**{k: v for k, v in values.items() if v is not None}))
    return LightField(np.zeros((3, 3, 2, 2, 1), np.float32), geometry=geometry)


def _traced_microscope_disparity(z_m: float) -> float:
    """Disparity (samples per view step) of a point ``z_m`` from the native plane, by following two rays: the
    centre view's (along the axis) and the next view's, whose pixel 4.55 um off the micro-image centre sees the
    image-side angle 4.55 / 2433 rad, i.e. n sin(theta) = 20 * 4.55 / 2433 in the specimen (sine condition)."""
    theta = math.asin(20 * 4.55e-6 / 2433e-6 / 1.33)
    lateral = z_m * math.tan(theta)                 # where the tilted ray crosses the native plane
    return -lateral / (125e-6 / 20)                 # in lenslets of 6.25 um; farther = negative disparity


@pytest.mark.parametrize("z_um", [-80.0, -5.0, 0.0, 30.0, 150.0])
def test_microscope_depth_matches_ray_geometry(z_um):
    lf = _microscope()
    d = _traced_microscope_disparity(z_um * 1e-6)
    z = disparity_to_depth(np.array([[d, np.nan]]), lf)
    assert z[0, 0] * 1e6 == pytest.approx(z_um, abs=1e-3) and np.isnan(z[0, 1])
    assert depth_to_disparity(z[:, :1], lf)[0, 0] == pytest.approx(d, abs=1e-6)
    # the sign: positive disparity (closer to the objective, as for a camera) is negative z
    assert (d > 0) == (z_um < 0) or z_um == 0


def test_microscope_constants_and_units():
    from plenodecode.depth.metric import depth_constants, depth_unit, microscope_constants

    k, dx = microscope_constants(_microscope())
    assert dx == pytest.approx(6.25e-6)
    assert k == pytest.approx(6.25e-6 / math.tan(math.asin(20 * 4.55 / 2433 / 1.33)))      # 222 um per px/view
    assert depth_constants(_microscope())[1:] == (0.0, "microscope")
    assert depth_unit(_microscope()) == ("um", 1e6) and depth_unit(_plenoptic()) == ("m", 1.0)
    # without the micro-lens focal length the micro-images fill the pitch: NA step = 2 NA pixel / pitch
    k_matched, _ = microscope_constants(_microscope(microlens_focal_length_m=None))
    assert k_matched == pytest.approx(6.25e-6 / math.tan(math.asin(2 * 0.5 * 4.55 / 125 / 1.33)))
    # orthographic points (telecentric in the specimen)
    pts = depth_to_points(np.full((2, 3), 10e-6, np.float32), _microscope())
    assert pts[0, 2, 0] - pts[0, 0, 0] == pytest.approx(2 * 6.25e-6) and np.allclose(pts[..., 2], 10e-6)
    with pytest.raises(ValueError, match="focus-distance"):
        disparity_to_depth(np.zeros((1, 1)), _microscope(), focus_distance_m=1.0)


@pytest.mark.parametrize("missing", ["magnification", "medium_index", "numerical_aperture"])
def test_microscope_missing_constant_names_the_python_field(missing):
    """Raised from Python, the error names the MicroscopeOptics field (and keyword) a Python caller passes, not
    the command line's option (``--na``); the CLI rewrites it (tests/cli/test_microscope.py)."""
    kw = {missing: None}
    if missing == "numerical_aperture":
        kw["microlens_focal_length_m"] = None           # the NA is needed only without the micro-lens focal length
    with pytest.raises(MetadataError, match=f"needs {missing},") as info:
        disparity_to_depth(np.zeros((1, 1)), _microscope(**kw))
    assert "--" not in str(info.value) and "MicroscopeOptics" in str(info.value)


def test_microscope_optics_values_are_refused_naming_the_field():
    with pytest.raises(ValueError, match=r"^numerical_aperture 1\.4 must be below medium_index 1\.33 "):
        MicroscopeOptics(numerical_aperture=1.4, medium_index=1.33)
    with pytest.raises(ValueError, match="^medium_index must be at least 1"):
        MicroscopeOptics(medium_index=0.9)
    with pytest.raises(ValueError, match="^lens_pitch_m must be a positive number"):
        MicroscopeOptics(lens_pitch_m=-1.0)


def test_camera_errors_name_the_microscope_fields_for_python():
    with pytest.raises(MetadataError) as info:
        disparity_to_depth(np.zeros((1, 1)), _lf({"spatial_step_px": 10.0, "view_step_px": 1.0}))
    msg = str(info.value)
    assert "focal_length_m" in msg and "=..." not in msg and "numerical_aperture" in msg and "--na" not in msg
    with pytest.raises(MetadataError, match="--focus-distance"):
        disparity_to_depth(np.zeros((1, 1)), _plenoptic())


# ------------------------------------------------------------------ calibrated (rectified) light fields
def _rectified_geometry_lf(shape=(5, 5, 8, 10)):
    """A light field carrying the rectified ray model of the skewed test camera (data unused)."""
    from plenodecode.decoding.rectify import rectified_intrinsics
    from plenodecode.types import LightFieldGeometry
    from tests.geometry_scenes import skewed_calibration

    rect = rectified_intrinsics(skewed_calibration(shape))
    geometry = LightFieldGeometry(ray_model={"intrinsics": rect, "rectified": True})
    return LightField(np.zeros((*shape, 1), np.float32), geometry=geometry), rect


def test_calibrated_depth_is_the_ray_model_closed_form():
    """d = (a + c z) / (b + e z) of H_rect inverts exactly; 3-D points lie on the centre view's rays."""
    from plenodecode.depth.metric import calibrated_constants, depth_constants

    lf, rect = _rectified_geometry_lf()
    a, b, c, e = rect[0, 0], rect[0, 2], rect[2, 0], rect[2, 2]
    z = np.linspace(0.15, 2.0, 80).reshape(8, 10)
    d = (a + c * z) / (b + e * z)
    np.testing.assert_allclose(disparity_to_depth(d, lf), z, rtol=1e-6)
    np.testing.assert_allclose(depth_to_disparity(z, lf), d, rtol=1e-5, atol=1e-6)
    g, zf, model = depth_constants(lf)
    assert model == "calibrated"
    assert calibrated_constants(lf)[2] == pytest.approx(-b / e)
    assert zf - b / e == pytest.approx(-a / c)                     # d = 0 at z = -a / c
    points = depth_to_points(z.astype(np.float32), lf).astype(np.float64)
    n = np.stack(np.broadcast_arrays(2.0, 2.0, np.arange(10.0)[None, :], np.arange(8.0)[:, None]), axis=-1)
    rays = n @ rect[:4, :4].T + rect[:4, 4]
    np.testing.assert_allclose(points[..., 0], rays[..., 0] + rays[..., 2] * z, atol=1e-6)
    np.testing.assert_allclose(points[..., 1], rays[..., 1] + rays[..., 3] * z, atol=1e-6)
    with pytest.raises(ValueError, match="--geometry"):
        disparity_to_depth(d, lf, focus_distance_m=0.5)


def test_generated_planes_metric_depth_within_one_percent():
    """Boards facing the camera at 0.3, 0.4 and 0.5 m, rendered through the distorted skewed camera and
    rectified: the depth of each plane from its corners' disparity is its distance within 1 %; at 0.5 m the
    depth estimator's median over the board too."""
    from plenodecode.decoding.rectify import rectify
    from plenodecode.depth import estimate_depth
    from plenodecode.synthetic.checkerboard import board_lightfield
    from tests.geometry_scenes import corner_disparities, facing_board, skewed_calibration

    cal = skewed_calibration()
    for z in (0.3, 0.4, 0.5):
        board, pose = facing_board(z, corners=7)
        lf = rectify(board_lightfield(cal, board, pose, supersample=2), cal)
        d = np.median(corner_disparities(lf.data, board, (-1, 0, 1)))
        assert disparity_to_depth(np.array([[d]]), lf)[0, 0] == pytest.approx(z, rel=0.01)
        if z == 0.5:
            depth = disparity_to_depth(estimate_depth(lf), lf)[24:72, 24:72]
            assert np.median(depth) == pytest.approx(z, rel=0.01)
