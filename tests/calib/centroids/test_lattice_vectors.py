"""Lattice vectors from the autocorrelation (:mod:`plenodecode.calib.centroids.lattice_vectors`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plenodecode.calib import centroids as C
from plenodecode.errors import CalibrationError
from plenodecode.synthetic import simulate_white


@pytest.mark.parametrize("preset,transpose", [("f01-mini", False), ("illum-mini", False), ("square", False),
                                              ("f01-mini", True)])
def test_lattice_vectors_from_the_autocorrelation(preset, transpose):
    white, truth = simulate_white(preset, seed=0, rotation=0.006, shape=(420, 460))
    img = C.flatten_white(white)
    if transpose:
        img = np.ascontiguousarray(img.T)
    est = C.estimate_lattice_vectors(img)
    assert est.lattice == truth.lattice
    assert abs(est.pitch - truth.pitch) < 0.05
    expected = (math.pi / 2 - 0.006) if transpose else 0.006
    assert abs(est.rotation - expected) < 2e-3
    with pytest.raises(ValueError, match="lattice"):
        C.estimate_lattice_vectors(img, lattice="tri")


def test_lattice_vectors_fail_on_structureless_images():
    with pytest.raises(CalibrationError):
        C.estimate_lattice_vectors(np.full((200, 200), 0.5, np.float32))
