"""The true lenslet grid of the synthetic generator and the pixel -> lens assignment."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode import synthetic as syn

SMALL = (240, 320)


@pytest.mark.parametrize("name", sorted(syn.PRESETS))
def test_grid_covers_every_lens_on_the_sensor(name):
    grid = syn.make_grid(name, shape=SMALL, rotation=0.01 if name != "raytrix" else None, offset=(0.3, -0.6))
    h, w = SMALL
    # every lens of an extended block that lies on the sensor must be in the grid
    big = grid.replace(origin=tuple(grid.lattice_to_sensor(-4 * grid.row_spacing, -4 * grid.pitch)),
                       shape=(grid.shape[0] + 8, grid.shape[1] + 8), lens_type=None)
    c = big.centres()
    on = (c[:, 0] >= -0.5) & (c[:, 0] <= h - 0.5) & (c[:, 1] >= -0.5) & (c[:, 1] <= w - 0.5)
    ib, jb = np.divmod(np.arange(c.shape[0]), big.shape[1])
    assert ib[on].min() == 4 and jb[on].min() == 4
    assert ib[on].max() == grid.shape[0] + 3 and jb[on].max() == grid.shape[1] + 3
    assert grid.sensor_shape == SMALL
    assert 0.44 * grid.pitch < grid.radius < 0.49 * grid.pitch
    if syn.PRESETS[name].lattice == "hex":
        assert grid.row_spacing == pytest.approx(grid.pitch * np.sqrt(3) / 2)
        assert abs(grid.odd_row_shift) == 0.5
    else:
        assert grid.row_spacing == grid.pitch and grid.odd_row_shift == 0.0
    assert (grid.lens_type is not None) == (name == "raytrix")


def test_offset_moves_the_lattice_by_sub_pixels():
    g0 = syn.make_grid("f01-mini", offset=(0.0, 0.0), shape=SMALL)
    g1 = syn.make_grid("f01-mini", offset=(0.25, -0.4), shape=SMALL)
    moved = g1.centres() - [0.25, -0.4]
    lens = syn.assign_pixels(g0, moved[:, 0], moved[:, 1])   # every moved lens is a lens of g0's lattice
    np.testing.assert_allclose(np.hypot(lens.oa, lens.ob), 0.0, atol=1e-9)
    anchor = syn.assign_pixels(g1, np.array([(SMALL[0] - 1) / 2 + 0.25]), np.array([(SMALL[1] - 1) / 2 - 0.4]))
    np.testing.assert_allclose([anchor.oa[0], anchor.ob[0]], 0.0, atol=1e-9)


def test_raytrix_lens_types_are_a_three_colouring():
    grid = syn.make_grid("raytrix")
    t = grid.lens_type
    assert set(np.unique(t)) == {0, 1, 2}
    c = grid.centres_2d()
    # each lens's 6 nearest neighbours have other types; lenses sqrt(3) pitch apart share a type
    flat_c, flat_t = c.reshape(-1, 2), t.ravel()
    d = np.hypot(*(flat_c[:, None, :] - flat_c[None, :, :]).transpose(2, 0, 1)) / grid.pitch
    near = (d > 0.5) & (d < 1.2)
    same = flat_t[:, None] == flat_t[None, :]
    assert near.sum() > 0 and not (near & same).any()
    second = (d > 1.6) & (d < 1.9)
    assert (second & same).sum() == second.sum()


def test_assign_pixels_picks_the_nearest_lens():
    grid = syn.make_grid("illum-mini", shape=SMALL, rotation=0.008)
    rng = np.random.default_rng(1)
    pts = rng.uniform([0, 0], SMALL, size=(5000, 2))
    lens = syn.assign_pixels(grid, pts[:, 0], pts[:, 1])
    big = grid.replace(origin=tuple(grid.lattice_to_sensor(-2 * grid.row_spacing, -2 * grid.pitch)),
                       shape=(grid.shape[0] + 4, grid.shape[1] + 4))
    if big.odd_row_shift != grid.odd_row_shift:  # pragma: no cover - two rows keeps parity
        raise AssertionError
    c = big.centres()
    d = np.hypot(pts[:, None, 0] - c[None, :, 0], pts[:, None, 1] - c[None, :, 1])
    near = np.argmin(d, axis=1)
    np.testing.assert_array_equal(lens.i + 2, near // big.shape[1])
    np.testing.assert_array_equal(lens.j + 2, near % big.shape[1])
    np.testing.assert_allclose(np.hypot(lens.oa, lens.ob), d.min(axis=1), atol=1e-9)
