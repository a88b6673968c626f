"""The parameters of ``H`` the checkerboard data fix, and the conventions that fix the others.

Of the 12 free entries of ``H`` (:data:`plenodecode.raymodel.FREE_ENTRIES`) the calibration
solves for 7 (:data:`SOLVED_ENTRIES`); the other 5 are set by two conventions, because changing
them moves the camera frame without changing any ray relative to the board:

* **Re-centring** (as the Light Field Toolbox does): the offsets ``H[:4, 4]`` are chosen so that the
  central sample ``n_c`` of the light field maps to the ray ``(0, 0, 0, 0)``, the ``z`` axis:
  ``H[:4, 4] = -H[:4, :4] n_c``.  A shift of ``(s, t)`` is a translation of the frame (absorbed by the
  poses); a shift of ``(u, v)`` is nearly a rotation of it.
* **Reference plane** ``H02 = 0``: moving the plane ``z = 0`` by ``d`` along ``z`` adds ``d`` times
  rows 2, 3 of ``H`` to rows 0, 1 and subtracts ``d`` from every pose's ``tz`` (:func:`move_reference_plane`)
  and no ray changes, so one ``d`` must be chosen: the plane through the central view's centre of
  projection in ``x`` (the entrance pupil), where ``s`` no longer depends on ``k``.

:func:`to_solver_gauge` brings any ``H`` (e.g. a generator's ground truth) into this form so that
entries can be compared one by one.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ...raymodel import check_intrinsics

#: (row, col) of the entries of ``H`` the solver estimates; H02 = 0, the offsets follow by re-centring.
SOLVED_ENTRIES = ((0, 0), (2, 0), (2, 2), (1, 1), (1, 3), (3, 1), (3, 3))


def lf_centre(lf_shape: Sequence[int]) -> np.ndarray:
    """The central sample ``n_c = (i_c, j_c, k_c, l_c)`` of light fields of shape (V, U, Y, X): (4,) float64,
    ``((U - 1) / 2, (V - 1) / 2, (X - 1) / 2, (Y - 1) / 2)``."""
    V, U, Y, X = (int(v) for v in lf_shape[:4])
    return np.array([(U - 1) / 2, (V - 1) / 2, (X - 1) / 2, (Y - 1) / 2])


def recentred_intrinsics(values: Sequence[float], lf_shape: Sequence[int]) -> np.ndarray:
    """The 5 x 5 ``H`` (float64) with :data:`SOLVED_ENTRIES` = ``values`` (7,), ``H02 = 0`` and
    ``H[:4, 4] = -H[:4, :4] n_c``."""
    h = np.zeros((5, 5))
    for (r, c), value in zip(SOLVED_ENTRIES, np.asarray(values, dtype=np.float64).ravel()):
        h[r, c] = value
    h[:4, 4] = -h[:4, :4] @ lf_centre(lf_shape)
    h[4, 4] = 1.0
    return h


def solved_values(h: np.ndarray) -> np.ndarray:
    """The (7,) :data:`SOLVED_ENTRIES` of ``H``."""
    return np.array([h[r, c] for r, c in SOLVED_ENTRIES])


def move_reference_plane(h: np.ndarray, poses: np.ndarray, depth_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The same rays with the reference plane moved to ``z = depth_m`` of the old frame.

    ``s' = s + u d`` (rows 0, 1 of ``H`` gain ``d`` x rows 2, 3), ``z' = z - d`` (pose ``tz`` loses ``d``).

    Returns
    -------
    (H' (5, 5), poses' (N, 6)) float64
    """
    moved = check_intrinsics(h).copy()
    moved[0] += depth_m * moved[2]
    moved[1] += depth_m * moved[3]
    poses = np.array(poses, dtype=np.float64).reshape(-1, 6)
    poses[:, 2] -= depth_m
    return moved, poses


def to_solver_gauge(h: np.ndarray, poses: np.ndarray, lf_shape: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """``H`` and poses in the solver's form: reference plane at ``H02 = 0``, position offsets re-centred.

    The central sample's ray ``(s0, t0, u0, v0)`` must already be a direction of ~0: a translation of
    the frame by ``(s0, t0)`` is exact, a direction offset is not a rigid motion.

    Raises
    ------
    ValueError
        The central direction ``(u0, v0)`` exceeds 1e-9 (not re-centrable without changing rays).
    """
    h = check_intrinsics(h)
    if h[2, 2] == 0:
        raise ValueError("H[2, 2] is zero: not a camera")
    moved, poses = move_reference_plane(h, poses, -h[0, 2] / h[2, 2])
    central = moved[:4, :4] @ lf_centre(lf_shape) + moved[:4, 4]
    if np.any(np.abs(central[2:]) > 1e-9):
        raise ValueError(f"the central sample's direction {central[2:]} is not 0: H is not re-centred")
    moved[:2, 4] -= central[:2]
    poses[:, :2] -= central[:2]
    return moved, poses
