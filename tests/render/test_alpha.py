"""alpha (Ng's relative film depth) <-> refocus slope: the formula, a thin-lens ray trace, metadata look-up."""

import math

import numpy as np
import pytest

from plenodecode.errors import MetadataError
from plenodecode.render import alpha_to_slope, refocus, refocus_constants, slope_per_alpha_unit, slope_to_alpha
from plenodecode.types import CameraMetadata, LightField

# An Illum-like camera: 30.1 mm at f/2, 20 um lenslets over 1.4 um pixels, hex grid (row spacing = pitch*sqrt(3)/2).
FOCAL, FNUM, LENS_PITCH, PIXEL = 0.0301, 2.0, 2.0e-5, 1.4e-6
PITCH_PX = LENS_PITCH / PIXEL
ROW_SPACING = PITCH_PX * math.sqrt(3) / 2


def camera_lf(**meta_changes):
    cam = CameraMetadata(focal_length_m=FOCAL, f_number=FNUM, lens_pitch_m=LENS_PITCH, pixel_pitch_m=PIXEL)
    meta = {"camera": cam.to_dict(), "spatial_step_px": ROW_SPACING, "view_step_px": 1.0,
            "calibration": {"pitch": PITCH_PX, "row_spacing": ROW_SPACING}}
    meta.update(meta_changes)
    data = np.random.default_rng(0).random((5, 5, 16, 18, 3), dtype=np.float32)
    return LightField(data, None, "linear-srgb", meta)


def test_constant_is_aperture_over_lens_pitch_per_spatial_step():
    # K = (f / N) * view_step / (lens_pitch * spatial_step) = (15.05 mm / 20 um) / 12.372 = 60.82
    k = slope_per_alpha_unit(camera_lf())
    assert k == pytest.approx((FOCAL / FNUM) / LENS_PITCH / ROW_SPACING, rel=1e-12)
    assert k == pytest.approx(60.82, abs=0.01)
    assert alpha_to_slope(1.0, camera_lf()) == 0.0
    assert alpha_to_slope(1.01, camera_lf()) == pytest.approx(k * (1 - 1 / 1.01), rel=1e-12)


def test_alpha_matches_a_thin_lens_ray_trace():
    """Trace rays of a point through a thin main lens to the microlens plane and read its disparity."""
    lf = camera_lf()
    z0 = 1.2                                      # focused object distance (m)
    F = 1 / (1 / FOCAL - 1 / z0)                  # main lens -> microlens plane
    D = FOCAL / FNUM
    f_m = LENS_PITCH * F / D                      # f-number matched lenslets: the aperture image fills a pitch
    sample_m = LENS_PITCH * ROW_SPACING / PITCH_PX   # one decoded spatial sample on the microlens plane
    for z in (0.5, 0.9, 1.2, 3.0, 50.0):
        zi = 1 / (1 / FOCAL - 1 / z)              # image distance of the point
        alpha = zi / F                            # the film plane where the point is in focus
        x_img = -0.004 * zi / z                   # an off-axis point, 4 mm from the axis, images here

        def position(a):
            # view a sees, through each lenslet, the rays from aperture point u = -(a * pixel) * F / f_m
            u = -(a * 1.0 * PIXEL) * F / f_m
            x_mla = u + (x_img - u) * F / zi      # where the ray from u towards the image point crosses the MLA
            return x_mla / sample_m

        d = -(position(3) - position(-3)) / 6     # view[a](y - d a) = centre(y)
        assert alpha_to_slope(alpha, lf) == pytest.approx(d, rel=1e-9, abs=1e-12)
        if z < z0:
            assert alpha > 1 and d > 0            # nearer than the focus: alpha > 1, positive disparity


def test_round_trip_and_arrays():
    lf = camera_lf()
    alphas = np.array([0.97, 0.995, 1.0, 1.004, 1.03])
    s = alpha_to_slope(alphas, lf)
    assert isinstance(s, np.ndarray) and s.shape == (5,)
    np.testing.assert_allclose(slope_to_alpha(s, lf), alphas, rtol=1e-12)
    assert np.all(np.diff(s) > 0)


def test_fallbacks_and_keyword_overrides():
    # lens pitch from calibration pitch x pixel pitch, spatial step from the calibration's row spacing
    lf = camera_lf(spatial_step_px=None)
    cam = dict(lf.metadata["camera"], lens_pitch_m=None)
    lf = lf.replace(metadata={**lf.metadata, "camera": cam})
    c = refocus_constants(lf)
    assert c["lens_pitch_m"] == pytest.approx(LENS_PITCH, rel=1e-12)
    assert c["spatial_step_px"] == pytest.approx(ROW_SPACING)
    # keywords win over metadata
    assert alpha_to_slope(1.02, lf, f_number=4.0) == pytest.approx(alpha_to_slope(1.02, lf) / 2, rel=1e-12)
    # no light field at all: every constant by keyword
    kw = dict(focal_length_m=FOCAL, f_number=FNUM, lens_pitch_m=LENS_PITCH, spatial_step_px=ROW_SPACING,
              view_step_px=1.0)
    assert alpha_to_slope(1.02, **kw) == pytest.approx(alpha_to_slope(1.02, camera_lf()), rel=1e-12)


def test_missing_constants_raise_metadata_error_naming_them():
    lf = camera_lf()
    cam = dict(lf.metadata["camera"], f_number=None)
    with pytest.raises(MetadataError, match="f_number"):
        alpha_to_slope(1.01, lf.replace(metadata={**lf.metadata, "camera": cam}))
    with pytest.raises(MetadataError, match="view_step_px"):
        alpha_to_slope(1.01, camera_lf(view_step_px=None))
    with pytest.raises(ValueError, match="unknown refocus constant"):
        alpha_to_slope(1.01, lf, focal=0.03)


def test_bad_values():
    lf = camera_lf()
    with pytest.raises(ValueError, match="alpha"):
        alpha_to_slope(0.0, lf)
    with pytest.raises(ValueError, match="slope"):
        slope_to_alpha(slope_per_alpha_unit(lf) + 1, lf)
    with pytest.raises(ValueError, match="f_number"):
        alpha_to_slope(1.01, lf, f_number=-2.0)


def test_refocus_by_alpha_is_refocus_by_the_converted_slope():
    lf = camera_lf()
    a = 1.012
    np.testing.assert_array_equal(refocus(lf, alpha=a), refocus(lf, slope=alpha_to_slope(a, lf)))
    with pytest.raises(ValueError, match="only apply with alpha"):
        refocus(lf, slope=0.3, f_number=2.0)


# ----------------------------------------------------------------------------------------------------------
# the refocusable range
# ----------------------------------------------------------------------------------------------------------
def test_refocusable_range_is_the_lens_footprint_over_the_pixel_footprint():
    from plenodecode.render.alpha import refocus_range, refocus_range_units

    lf = camera_lf()
    lo, hi = refocus_range(lf)
    # hex grid: pitch / row spacing = 2 / sqrt(3) samples per view step (view step = 1 sensor pixel)
    assert hi == pytest.approx(2 / math.sqrt(3), rel=1e-9) and lo == -hi
    r = refocus_range_units(lf)
    np.testing.assert_allclose(r.alpha, slope_to_alpha(np.array([lo, hi]), lf), rtol=1e-12)
    assert 0.981 < r.alpha[0] < 0.982 and 1.019 < r.alpha[1] < 1.020
    assert r.distance_m is None                         # no focus distance in the metadata
    assert r.contains(1.0) and not r.contains(alpha_to_slope(1.2, lf))
    # a square grid (pitch = spatial step) with two views per sensor pixel: view_step_px * 1
    square = camera_lf(spatial_step_px=PITCH_PX, view_step_px=0.5, calibration={"pitch": PITCH_PX})
    assert refocus_range(square) == pytest.approx((-0.5, 0.5))
    # no sampling metadata: the decoder's default of one sample per view step
    bare = LightField(np.zeros((3, 3, 4, 4, 1), np.float32))
    assert refocus_range(bare) == (-1.0, 1.0)


def test_refocusable_range_in_metres_and_distance_round_trip():
    from plenodecode.render.alpha import distance_to_slope, refocus_range_units, slope_to_distance

    lf = camera_lf(focus_distance_m=1.2)
    r = refocus_range_units(lf)
    near, far = r.distance_m
    assert near < 1.2 < far
    assert slope_to_distance(r.slope[1], lf) == pytest.approx(near) and "m" in r.describe()
    for z in (0.6, 1.2, 3.0):
        assert slope_to_distance(distance_to_slope(z, lf), lf) == pytest.approx(z, rel=1e-9)
    assert distance_to_slope(1.2, lf) == pytest.approx(0.0, abs=1e-12)
    assert distance_to_slope(0.8, lf) > 0                  # nearer than the focus: positive disparity
    with pytest.raises(ValueError, match="distance_m"):
        distance_to_slope(float("nan"), lf)


def test_hci_pinhole_views_use_the_scene_disparities():
    from plenodecode.render.alpha import refocus_range
    from plenodecode.types import HCIParameters, LightFieldGeometry

    def scene(hci):
        return LightField(np.zeros((9, 9, 40, 60, 3), np.float32), None, "srgb", geometry=LightFieldGeometry(hci=hci))

    assert refocus_range(scene(HCIParameters(baseline_mm=100.0, disparity_range=(-1.5, 2.5)))) == (-1.5, 2.5)
    without = scene(HCIParameters(baseline_mm=100.0))
    assert refocus_range(without) == pytest.approx((-40 / 16, 40 / 16))   # min(Y, X) / (4 * 4 views)


def test_alpha_must_be_finite_and_positive():
    lf = camera_lf()
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="alpha"):
            alpha_to_slope(bad, lf)
