"""The white-image database: build from MOD pairs, select by serial/zoom/focus, fit once, cache."""

from __future__ import annotations

from pathlib import Path

import json
from dataclasses import replace

import numpy as np
import pytest

from plenodecode.calib import store
from plenodecode.errors import CalibrationError
from plenodecode.io.lytro import write_raw_pair
from plenodecode.synthetic import simulate_white
from plenodecode.types import CameraMetadata, RawCapture

SHAPE = (240, 300)


def _white(serial: str, zoom: float, focus: float, seed: int = 0, offset=(0.3, 0.4)) -> tuple[RawCapture, object]:
    raw, truth = simulate_white("f01-mini", seed=seed, shape=SHAPE, offset=offset)
    md = replace(raw.metadata, serial=serial, zoom_step=zoom, focus_step=focus)
    return replace(raw, metadata=md), truth


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under a folder (relative name -> bytes), to show that a lookup wrote nothing."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def whites(tmp_path):
    """Three white images of camera A (zooms 100/500, focus 10/300) and one of camera B, as MOD pairs."""
    src = tmp_path / "caldata"
    (src / "A").mkdir(parents=True)
    (src / "B").mkdir()
    truths = {}
    for k, (serial, zoom, focus, off) in enumerate([("A000000001", 100, 10, (0.3, 0.4)),
                                                    ("A000000001", 500, 10, (1.3, -0.4)),
                                                    ("A000000001", 500, 300, (-0.7, 0.9)),
                                                    ("A000000002", 100, 10, (0.0, 0.0))]):
        raw, truth = _white(serial, zoom, focus, seed=k, offset=off)
        path = src / serial[-1:].replace("1", "A").replace("2", "B") / f"MOD_{k:04d}.RAW"
        write_raw_pair(path, raw)
        truths[path.name] = truth
    return src, truths


@pytest.fixture
def calls(monkeypatch):
    """The argument tuples of every plenodecode.calib.calibrate call the test makes (it still calibrates)."""
    import plenodecode.calib as calib_pkg

    made = []
    real = calib_pkg.calibrate

    def counting(*a, **k):
        made.append(a)
        return real(*a, **k)
    monkeypatch.setattr(calib_pkg, "calibrate", counting)
    return made


def test_build_select_and_cache(whites, tmp_path, calls):
    src, truths = whites
    db = tmp_path / "calib"
    entries = store.build_database(src, db, fit=False)
    assert len(entries) == 4
    doc = json.loads((db / "index.json").read_text())
    assert doc["format"] == "plenodecode.calibration-db" and len(doc["entries"]) == 4
    assert all(not e["file"].startswith("/") for e in doc["entries"])      # relative paths

    def md(serial, zoom, focus):
        return CameraMetadata(serial=serial, zoom_step=zoom, focus_step=focus)
    assert store.select_white(db, md("A000000001", 480, 250)).file.endswith("MOD_0002.RAW")   # zoom, then focus
    assert store.select_white(db, md("A000000001", 480, 0)).file.endswith("MOD_0001.RAW")
    assert store.select_white(db, md("A000000001", 90, 999)).file.endswith("MOD_0000.RAW")    # zoom wins
    assert store.select_white(db, md("A000000002", 500, 300)).file.endswith("MOD_0003.RAW")   # serial first
    with pytest.raises(CalibrationError, match="A000000001, A000000002"):
        store.select_white(db, md("B999", 100, 10))
    with pytest.raises(CalibrationError, match="several cameras"):
        store.select_white(db, md(None, 100, 10))

    # a lookup never writes: without a cached grid it fits in memory; cache_grids is the step that stores it,
    # after which lookups read the cache
    raw = RawCapture(np.zeros(SHAPE, np.uint16), "BGGR", 168.0, 4095.0,
                     md("A000000001", 500, 290))
    before = _snapshot(db)
    g1 = store.grid_for(raw, db)
    assert len(calls) == 1 and _snapshot(db) == before
    store.cache_grids(db, files=[e.file for e in store.load_index(db) if e.file.endswith("MOD_0002.RAW")])
    assert len(calls) == 2
    g2 = store.grid_for(raw, db)
    assert len(calls) == 2
    truth = truths["MOD_0002.RAW"]
    np.testing.assert_allclose(g1.centres(), g2.centres())
    from scipy.spatial import cKDTree
    t = truth.centres()
    R = truth.radius
    full = (t[:, 0] - R >= 0) & (t[:, 0] + R <= SHAPE[0] - 1) & (t[:, 1] - R >= 0) & (t[:, 1] + R <= SHAPE[1] - 1)
    d, _ = cKDTree(g1.centres()).query(t[full])
    assert np.sqrt(np.mean(d ** 2)) < 0.05
    entry = [e for e in store.load_index(db) if e.file.endswith("MOD_0002.RAW")][0]
    assert entry.grid is not None and (db / entry.grid).is_file()
    wrong = replace(raw, mosaic=np.zeros((100, 100), np.uint16))
    with pytest.raises(CalibrationError, match="another sensor"):
        store.grid_for(wrong, db)


def test_build_with_fit_and_errors(whites, tmp_path):
    src, _ = whites
    db = tmp_path / "db2"
    entries = store.build_database(src / "B", db)                 # fits now
    assert len(entries) == 1 and entries[0].grid is not None
    assert (db / entries[0].grid).is_file()
    with pytest.raises(CalibrationError, match="no white images found"):
        store.build_database(db, tmp_path / "db3")               # a folder without white images
    with pytest.raises(CalibrationError, match="not a folder"):
        store.build_database(tmp_path / "nope", tmp_path / "db3")
    with pytest.raises(CalibrationError, match="no calibration database"):
        store.load_index(tmp_path / "empty")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "index.json").write_text('{"format": "other"}')
    with pytest.raises(CalibrationError, match="not a plenodecode calibration index"):
        store.load_index(tmp_path / "bad")


def test_calibration_for_returns_the_grid_and_its_white(whites, tmp_path, calls):
    src, truths = whites
    db = tmp_path / "calib"
    store.build_database(src, db, fit=False)
    raw = RawCapture(np.zeros(SHAPE, np.uint16), "BGGR", 168.0, 4095.0,
                     CameraMetadata(serial="A000000001", zoom_step=480, focus_step=0))
    before = _snapshot(db)
    grid, white = store.calibration_for(raw, db)
    assert len(calls) == 1 and _snapshot(db) == before           # fitted in memory, nothing written ...
    assert grid.info["source"].endswith("MOD_0001.RAW")
    # ... the white is the very file the grid was fitted on (zoom 500, focus 10), read back bit-exactly
    from plenodecode.io import read_raw
    expected = read_raw(src / "A" / "MOD_0001.RAW")
    assert isinstance(white, RawCapture) and white.path.endswith("MOD_0001.RAW")
    np.testing.assert_array_equal(white.mosaic, expected.mosaic)
    assert white.metadata.zoom_step == 500 and white.metadata.focus_step == 10
    # once cached (the explicit step), grid_for and calibration_for read it (no further fit): the same grid
    store.cache_grids(db, files=[e.file for e in store.load_index(db) if e.file.endswith("MOD_0001.RAW")])
    assert len(calls) == 2
    g2 = store.grid_for(raw, db)
    g3, _ = store.calibration_for(raw, db)
    assert len(calls) == 2
    np.testing.assert_allclose(g2.centres(), grid.centres())
    np.testing.assert_allclose(g3.centres(), grid.centres())
    from scipy.spatial import cKDTree
    truth = truths["MOD_0001.RAW"]
    t = truth.centres()
    R = truth.radius
    full = (t[:, 0] - R >= 0) & (t[:, 0] + R <= SHAPE[0] - 1) & (t[:, 1] - R >= 0) & (t[:, 1] + R <= SHAPE[1] - 1)
    d, _ = cKDTree(grid.centres()).query(t[full])
    assert np.sqrt(np.mean(d ** 2)) < 0.05
    # a white image that disappeared from disk: a one-line CalibrationError naming it
    (src / "A" / "MOD_0001.RAW").unlink()
    with pytest.raises(CalibrationError, match="MOD_0001.RAW.*missing"):
        store.calibration_for(raw, db)
    with pytest.raises(CalibrationError, match="no white image of camera"):
        store.calibration_for(replace(raw, metadata=CameraMetadata(serial="Z9")), db)


def test_database_indexes_white_mosaics_marked_in_their_sidecar(tmp_path):
    """A microscope-style white (16-bit mosaic + sidecar with is_white_image) is indexed and selected;
    a mosaic not marked as white is not."""
    from dataclasses import replace

    from plenodecode.calib.store import build_database, calibration_for
    from plenodecode.io.generic import write_mosaic
    from plenodecode.synthetic import simulate_white

    white, truth = simulate_white("square", seed=5, shape=(300, 320))
    assert white.metadata.is_white_image
    src = tmp_path / "whites"
    write_mosaic(src / "flat.png", white)
    write_mosaic(src / "scene.png", replace(white, metadata=replace(white.metadata, is_white_image=False)))
    entries = build_database(src, tmp_path / "db")
    assert [Path(e.file).name for e in entries] == ["flat.png"]
    grid, w = calibration_for(white, tmp_path / "db")
    assert w.shape == white.shape and abs(grid.pitch - truth.pitch) < 1e-3


_WORKER = """
import sys, time
from pathlib import Path
from plenodecode.calib import store
src, db, go = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
deadline = time.monotonic() + 60
while not go.exists() and time.monotonic() < deadline:   # start together, to make the writers overlap
    time.sleep(0.005)
for folder in sorted(src.iterdir()):
    store.build_database(folder, db, fit=False)
"""


def test_concurrent_writers_keep_every_entry(tmp_path):
    """Several processes indexing into one database at once: index.json stays valid and loses no entry
    (every read-merge-write holds the lock; each write is atomic)."""
    import os
    import shutil
    import subprocess
    import sys

    raw, _ = simulate_white("f01-mini", seed=0, shape=(60, 80))
    pair = tmp_path / "pair" / "MOD_0000.RAW"
    write_raw_pair(pair, raw)
    n_workers, n_folders = 4, 8
    for w in range(n_workers):
        for f in range(n_folders):
            folder = tmp_path / f"w{w}" / f"f{f:02d}"
            folder.mkdir(parents=True)
            for p in pair.parent.iterdir():
                shutil.copy(p, folder / p.name)
    db, go = tmp_path / "db", tmp_path / "go"
    root = str(Path(__file__).resolve().parents[2])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    procs = [subprocess.Popen([sys.executable, "-c", _WORKER, str(tmp_path / f"w{w}"), str(db), str(go)], env=env,
                              stderr=subprocess.PIPE, text=True) for w in range(n_workers)]
    go.touch()
    errors = [p.communicate(timeout=300)[1] for p in procs]
    assert [p.returncode for p in procs] == [0] * n_workers, errors
    entries = store.load_index(db)                               # valid JSON of the right format
    expected = {os.path.relpath(tmp_path / f"w{w}" / f"f{f:02d}" / "MOD_0000.RAW", db)
                for w in range(n_workers) for f in range(n_folders)}
    assert {e.file for e in entries} == expected                 # complete: no writer lost another's entries
    assert sorted(p.name for p in db.iterdir()) == [".index.json.lock", "index.json"]   # no temporaries left


def test_cache_grids_is_the_step_that_writes(whites, tmp_path, calls):
    """cache_grids fits only what the index lacks (overwrite refits); the CLI's --database DIR runs it."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    src, _ = whites
    db = tmp_path / "calib"
    store.build_database(src / "B", db, fit=False)
    assert [e.grid for e in store.load_index(db)] == [None]
    entries = store.cache_grids(db)
    assert len(calls) == 1 and entries[0].grid is not None and (db / entries[0].grid).is_file()
    assert store.cache_grids(db) == entries and len(calls) == 1             # nothing left to fit
    store.cache_grids(db, overwrite=True)
    assert len(calls) == 2
    store.build_database(src / "A", db, fit=False)                          # three more, not fitted yet
    r = CliRunner().invoke(cli, ["calibrate", "--database", str(db)], obj={})
    assert r.exit_code == 0, r.output
    assert len(calls) == 5 and all(e.grid for e in store.load_index(db))
    r = CliRunner().invoke(cli, ["calibrate", "--database", str(tmp_path / "none")], obj={})
    assert r.exit_code == 2 and "needs the folder" in r.output
