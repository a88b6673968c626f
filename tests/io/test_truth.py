"""The ground-truth files of the synthetic generator: plain documents and arrays in, the same out."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from plenodecode.errors import FormatError
from plenodecode.io.truth import TRUTH_FORMAT, TRUTH_VERSION, find_truth_json, read_truth, write_truth


def document(**extra):
    return {"format": TRUTH_FORMAT, "version": TRUTH_VERSION, "preset": "square", "seed": 3, **extra}


def arrays():
    rng = np.random.default_rng(0)
    return {"disparity": rng.random((4, 5), dtype=np.float32), "centres": rng.random((6, 2)),
            "lens_type": np.arange(6, dtype=np.int8).reshape(2, 3)}


def test_write_and_read_round_trip(tmp_path):
    js, npz = write_truth(tmp_path / "sub" / "cap.truth.json", document(), arrays())
    assert (js.name, npz.name) == ("cap.truth.json", "cap.truth.npz")
    assert not [p for p in js.parent.iterdir() if p.name.startswith(".")]           # no temporaries left
    doc, got, path = read_truth(js)
    assert path == js
    assert doc == {**document(), "npz_arrays": ["centres", "disparity", "lens_type"]}
    assert list(json.loads(js.read_text())) == [*document(), "npz_arrays"]          # key order kept
    assert set(got) == set(arrays())
    for key, value in arrays().items():
        assert got[key].dtype == value.dtype
        np.testing.assert_array_equal(got[key], value)
    # the npz, or the folder holding one truth, lead to the same JSON
    assert find_truth_json(npz) == js and find_truth_json(js.parent) == js
    with pytest.raises(FileExistsError):
        write_truth(js, document(seed=4), arrays())
    assert read_truth(js)[0]["seed"] == 3
    write_truth(js, document(seed=4), arrays(), overwrite=True)
    assert read_truth(js)[0]["seed"] == 4


def test_bad_names_and_foreign_or_incomplete_files(tmp_path):
    with pytest.raises(ValueError, match="truth.json"):
        write_truth(tmp_path / "cap.json", document(), arrays())
    js, npz = write_truth(tmp_path / "a.truth.json", document(), arrays())
    write_truth(tmp_path / "b.truth.json", document(), arrays())
    with pytest.raises(FormatError, match="exactly one"):
        find_truth_json(tmp_path)
    newer = tmp_path / "n.truth.json"
    newer.write_text(json.dumps(document(version=TRUTH_VERSION + 1)))
    with pytest.raises(FormatError, match="newer"):
        read_truth(newer)
    foreign = tmp_path / "f.truth.json"
    foreign.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(FormatError, match="format"):
        read_truth(foreign)
    broken = tmp_path / "j.truth.json"
    broken.write_text("{not json")
    with pytest.raises(FormatError, match="JSON"):
        read_truth(broken)
    npz.unlink()
    with pytest.raises(FormatError, match="stay together"):
        read_truth(js)
    with pytest.raises(FormatError, match="no such"):
        read_truth(tmp_path / "missing.truth.json")


def test_io_truth_does_not_import_the_generator():
    code = "import sys, plenodecode.io.truth; print(any(m.startswith('plenodecode.synthetic') for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
