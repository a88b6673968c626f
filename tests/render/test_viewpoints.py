"""Perspective views at fractional positions and parallax paths."""

import numpy as np
import pytest

from plenodecode.render import parallax_path, perspective, render_parallax
from plenodecode.types import LightField


def random_lf(nv=7, nu=9, seed=0):
    return LightField(np.random.default_rng(seed).random((nv, nu, 12, 14, 3), dtype=np.float32))


@pytest.mark.parametrize("interp", ["linear", "cubic"])
def test_integer_positions_return_the_views_exactly(interp):
    lf = random_lf()
    for v, u in [(0, 0), (3, 4), (6, 8), (2, 7)]:
        out = perspective(lf, float(v), float(u), interp=interp)
        np.testing.assert_array_equal(out, lf.data[v, u])
        assert out is not lf.data[v, u] and not np.shares_memory(out, lf.data)


def test_bilinear_between_four_views():
    lf = random_lf()
    v, u = 2.25, 5.6
    expect = (0.75 * 0.4 * lf.data[2, 5] + 0.75 * 0.6 * lf.data[2, 6]
              + 0.25 * 0.4 * lf.data[3, 5] + 0.25 * 0.6 * lf.data[3, 6])
    np.testing.assert_allclose(perspective(lf, v, u), expect, atol=1e-6)


@pytest.mark.parametrize("interp", ["linear", "cubic"])
def test_views_varying_linearly_are_interpolated_exactly(interp):
    # L[v, u] = A + v B + u C: both kernels reproduce linear functions (cubic away from the border views)
    rng = np.random.default_rng(4)
    a, b, c = (rng.random((12, 14, 3), dtype=np.float32) for _ in range(3))
    v_idx = np.arange(7, dtype=np.float32)[:, None, None, None, None]
    u_idx = np.arange(9, dtype=np.float32)[None, :, None, None, None]
    lf = LightField((a + v_idx * b + u_idx * c).astype(np.float32))
    for v, u in [(1.3, 2.7), (3.5, 4.5), (4.9, 6.1)]:
        np.testing.assert_allclose(perspective(lf, v, u, interp=interp), a + v * b + u * c, atol=1e-4)


def test_cubic_differs_from_linear_on_curved_data():
    v_idx = np.arange(7, dtype=np.float32)[:, None, None, None, None]
    lf = LightField(np.broadcast_to(v_idx**2, (7, 5, 4, 4, 1)).astype(np.float32))
    # Keys' cubic reproduces quadratics inside the grid; bilinear does not
    assert perspective(lf, 2.5, 2.0, interp="cubic")[0, 0, 0] == pytest.approx(6.25, abs=1e-5)
    assert perspective(lf, 2.5, 2.0, interp="linear")[0, 0, 0] == pytest.approx(6.5, abs=1e-5)


def test_positions_outside_the_grid_are_rejected():
    lf = random_lf()
    with pytest.raises(ValueError, match="v must be within"):
        perspective(lf, -0.1, 2.0)
    with pytest.raises(ValueError, match="u must be within"):
        perspective(lf, 1.0, 8.5)
    with pytest.raises(ValueError, match="interp"):
        perspective(lf, 1.0, 1.0, interp="nearest")


def test_parallax_path_is_a_circle_around_the_centre():
    lf = random_lf(9, 9)
    path = parallax_path(lf, 12, 3.0)
    assert len(path) == 12
    pts = np.array(path)
    np.testing.assert_allclose(np.hypot(pts[:, 0] - 4, pts[:, 1] - 4), 3.0, atol=1e-12)
    ang = np.unwrap(np.arctan2(pts[:, 0] - 4, pts[:, 1] - 4))
    np.testing.assert_allclose(np.diff(ang), 2 * np.pi / 12, atol=1e-12)
    assert parallax_path(lf, 4)[0] == pytest.approx((4.0, 7.0))          # default radius 3/4 of 4 views
    with pytest.raises(ValueError, match="radius"):
        parallax_path(lf, 12, 4.5)
    with pytest.raises(ValueError, match="n_frames"):
        parallax_path(lf, 0)


def test_render_parallax_frames_are_the_perspective_views():
    lf = random_lf(9, 9)
    calls = []
    frames = render_parallax(lf, 6, 2.0, progress=lambda d, t: calls.append(d))
    assert frames.shape == (6, 12, 14, 3)
    for frame, (v, u) in zip(frames, parallax_path(lf, 6, 2.0)):
        np.testing.assert_array_equal(frame, perspective(lf, v, u))
    assert calls == list(range(1, 7))
    assert not np.allclose(frames[0], frames[3])                        # the viewpoint moves


def test_weighted_perspective_leaves_out_samples_without_data_and_fills_the_edge_gaps():
    """A decoded light field's weight-0 samples (hex -> rect edge gaps, lenses off the sensor) hold 0: a
    perspective view between views must not blend those zeros in (the parallax animation's edges flickered
    black), and a view's own gaps take their nearest neighbour's value."""
    lf = random_lf()
    weight = np.ones(lf.shape[:4], np.float32)
    weight[2, 5, :, 0] = 0.0                   # view (2, 5): its left column has no samples
    weight[:, :, 0, ::2] = 0.0                 # every view: alternate pixels of the top row
    data = lf.data * (weight[..., None] > 0)
    holed = LightField(data, weight=weight)
    out = perspective(holed, 2.25, 5.6)
    # the left column from the three views that have it, their bilinear taps renormalised
    taps = {(2, 6): 0.75 * 0.6, (3, 5): 0.25 * 0.4, (3, 6): 0.25 * 0.6}
    expect = sum(t * lf.data[v, u, 1:, 0] for (v, u), t in taps.items()) / sum(taps.values())
    np.testing.assert_allclose(out[1:, 0], expect, atol=1e-5)
    # where every view has data, as without weights
    np.testing.assert_allclose(out[1:, 1:], perspective(lf, 2.25, 5.6)[1:, 1:], atol=1e-6)
    # an integer position: the view as it is, its gaps from the nearest pixel with data
    view = perspective(holed, 2, 5)
    np.testing.assert_array_equal(view[1:, 1:], lf.data[2, 5, 1:, 1:])
    assert np.all(view[0, ::2] > 0) and np.all(view[1:, 0] > 0)
    assert any(np.array_equal(view[0, 2], lf.data[2, 5, y, x]) for y, x in ((0, 1), (0, 3), (1, 2)))
