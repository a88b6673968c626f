"""Writing a simulation in its camera's format plus the ground truth, and reading the truth back."""

from __future__ import annotations

import numpy as np
import pytest

from plenodecode import synthetic as syn


@pytest.mark.parametrize("name,shape", [("illum-mini", (96, 128)), ("f01-mini", (96, 128)), ("square", (110, 138)),
                                        ("raytrix", (140, 175))])
def test_write_simulation_round_trips_through_read_raw(tmp_path, name, shape):
    from plenodecode.io import read_raw

    sim = syn.simulate(name, seed=4, shape=shape)
    paths = syn.write_simulation(sim, tmp_path, name="cap")
    assert set(paths) == set(syn.simulation_files(name, "cap"))
    assert all(q.is_file() for q in paths.values())
    raw, white = read_raw(paths["raw"]), read_raw(paths["white"])
    np.testing.assert_array_equal(raw.mosaic, sim.raw.mosaic)
    np.testing.assert_array_equal(white.mosaic, sim.white.mosaic)
    for got, want in ((raw, sim.raw), (white, sim.white)):
        assert got.cfa == want.cfa
        np.testing.assert_array_equal(got.black, want.black)
        np.testing.assert_array_equal(got.white, want.white)
        assert got.metadata.serial == want.metadata.serial
    assert white.metadata.is_white_image and not raw.metadata.is_white_image
    if sim.raw.cfa is not None:
        assert raw.metadata.wb_gains == pytest.approx(dict(sim.raw.metadata.wb_gains))
        np.testing.assert_allclose(np.asarray(raw.metadata.ccm), np.asarray(sim.raw.metadata.ccm), atol=1e-6)
    truth = syn.load_truth(paths["truth_json"])
    assert truth.grid.to_dict() == sim.grid.to_dict()
    np.testing.assert_array_equal(truth.centres, sim.grid.centres())
    np.testing.assert_array_equal(truth.disparity, sim.disparity)
    assert truth.preset == name and truth.seed == 4
    if name == "raytrix":
        assert truth.lightfield is None
        np.testing.assert_array_equal(truth.arrays["lens_type"], sim.grid.lens_type)
        np.testing.assert_array_equal(truth.arrays["total_focus"], sim.truth["total_focus"])
    else:
        assert truth.scene == sim.scene
        lf = sim.ground_truth_lightfield()
        np.testing.assert_array_equal(truth.lightfield.data, lf.data)
        np.testing.assert_array_equal(truth.lightfield.weight, lf.weight)
    # never overwrite silently; nothing half-written
    before = {k: q.stat().st_mtime_ns for k, q in paths.items()}
    with pytest.raises(FileExistsError):
        syn.write_simulation(sim, tmp_path, name="cap")
    assert {k: q.stat().st_mtime_ns for k, q in paths.items()} == before
    syn.write_simulation(sim, tmp_path, name="cap", overwrite=True, lightfield=False)
    assert not [q for q in tmp_path.iterdir() if q.name.endswith(".tmp")]


def test_load_truth_rejects_foreign_files(tmp_path):
    from plenodecode.errors import FormatError

    bad = tmp_path / "x.truth.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(FormatError, match="format"):
        syn.load_truth(bad)
    with pytest.raises(FormatError):
        syn.load_truth(tmp_path / "missing.truth.json")
