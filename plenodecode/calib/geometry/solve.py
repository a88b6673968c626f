"""Joint refinement of ``H``, distortion and the board poses by ray reprojection (Dansereau et al. 2013, sec. 4).

The cost is the one of the paper and the Light Field Toolbox: for every corner ``X_p`` of the board
seen at sample ``n = (i, j, k, l)`` of capture ``c``, the 3-D distance (m) between the corner in the
camera frame, ``P = R(r_c) X_p + t_c``, and the ray of the sample, ``sample_rays(H, distortion, n)``::

    minimise  sum over observations of | (P - o) x d | ^ 2 / | d | ^ 2

with ``o = (s, t, 0)``, ``d = (u, v, 1)``.  Each observation contributes the 3 components of
:func:`plenodecode.raymodel.point_ray_offset` (smooth, unlike the distance itself) to
``scipy.optimize.least_squares`` (trust-region reflective), whose Jacobian is sparse: an
observation's residuals depend on the 7 solved entries of ``H`` (:mod:`.gauge`), the 5 distortion
parameters and the 6 pose parameters of its own capture only, which ``jac_sparsity`` states so that
finite differences cost ``7 + 5 + 6`` evaluations whatever the number of captures.

Stages (as the toolbox): without distortion (``[k1 k2 k3 b1 b2] = 0``), then with it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from ...raymodel import Board, point_ray_distance, point_ray_offset, project_points, rotation_matrix, sample_rays
from .corners import ViewCorners
from .gauge import SOLVED_ENTRIES, recentred_intrinsics, solved_values
from .initial import stacked_observations

log = logging.getLogger(__name__)

N_H = len(SOLVED_ENTRIES)
N_DISTORTION = 5
N_POSE = 6


@dataclass(frozen=True)
class Observations:
    """All corner observations of N captures, flat and grouped by capture.

    Attributes
    ----------
    samples : (M, 4) float64
        ``(i, j, k, l)``.
    board_points : (M, 3) float64
        The observed corner in its board's frame.
    capture : (M,) int64
        Capture index, non-decreasing.
    n_captures : int
    lf_shape : (V, U, Y, X)
    """

    samples: np.ndarray
    board_points: np.ndarray
    capture: np.ndarray
    n_captures: int
    lf_shape: tuple[int, int, int, int]

    @classmethod
    def of(cls, captures: Sequence[ViewCorners], board: Board) -> "Observations":
        samples, point, capture = stacked_observations(captures, board.rows * board.cols)
        return cls(samples, board.corners()[point], capture, len(captures), tuple(captures[0].lf_shape))


def camera_points(poses: np.ndarray, obs: Observations) -> np.ndarray:
    """The observed corners in the camera frame, (M, 3) float64: ``R(r_c) X + t_c`` for each capture ``c``."""
    rotations = np.array([rotation_matrix(p[3:]) for p in poses]).reshape(-1, 3, 3)
    return (np.einsum("mij,mj->mi", rotations[obs.capture], obs.board_points)
            + np.asarray(poses).reshape(-1, 6)[obs.capture, :3])


class _Problem:
    """Parameter vector <-> model for one stage.

    The optimiser sees ``y`` with ``x = x0 + T y``, ``T`` block-diagonal (one block for the intrinsics,
    one 6 x 6 block per capture's pose) and chosen so that each block of the Jacobian at ``x0`` has
    orthonormal columns (``T_b = L_b^-T`` with ``J_b^T J_b = L_b L_b^T``): the units and the correlations
    within a block (focal length against distance, say) no longer slow the sparse (LSMR) trust-region
    steps, and the sparsity pattern is unchanged.
    """

    def __init__(self, obs: Observations, with_distortion: bool, start: np.ndarray) -> None:
        self.obs = obs
        self.with_distortion = with_distortion
        self.n_intrinsic = N_H + (N_DISTORTION if with_distortion else 0)
        self.x0 = start
        self.blocks = [np.arange(self.n_intrinsic)] + [self.n_intrinsic + N_POSE * c + np.arange(N_POSE)
                                                       for c in range(obs.n_captures)]
        self.transform = [np.eye(len(b)) for b in self.blocks]
        self.transform = self._whitening()

    @classmethod
    def at(cls, obs: Observations, h: np.ndarray, distortion: np.ndarray, poses: np.ndarray,
           with_distortion: bool) -> "_Problem":
        parts = [solved_values(h)] + ([distortion] if with_distortion else []) + [np.ravel(poses)]
        return cls(obs, with_distortion, np.concatenate(parts).astype(np.float64))

    def params(self, y: np.ndarray) -> np.ndarray:
        x = self.x0.copy()
        for block, t in zip(self.blocks, self.transform):
            x[block] += t @ y[block]
        return x

    def unpack(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = self.params(y)
        h = recentred_intrinsics(x[:N_H], self.obs.lf_shape)
        distortion = x[N_H:self.n_intrinsic] if self.with_distortion else np.zeros(N_DISTORTION)
        return h, distortion, x[self.n_intrinsic:].reshape(-1, N_POSE)

    def residuals(self, y: np.ndarray) -> np.ndarray:
        h, distortion, poses = self.unpack(y)
        rays = sample_rays(h, distortion, self.obs.samples)
        return point_ray_offset(camera_points(poses, self.obs), rays).ravel()

    def _whitening(self) -> list[np.ndarray]:
        """``T_b`` of every block from a central-difference Jacobian at ``x0`` (the pose columns of all
        captures perturbed together: a residual sees only its own capture's)."""
        h_size = np.abs(self.x0[:N_H]).max()
        steps = 1e-6 * np.maximum(np.abs(self.x0[:self.n_intrinsic]), np.r_[np.full(N_H, 1e-3 * h_size),
                                                                             np.full(self.n_intrinsic - N_H, 1e-3)])
        capture = np.repeat(self.obs.capture, 3)
        intrinsic = np.empty((len(capture), self.n_intrinsic))
        pose = np.empty((len(capture), N_POSE))
        y = np.zeros_like(self.x0)
        for k, step in enumerate(steps):
            y[k] = step
            intrinsic[:, k] = (self.residuals(y) - self.residuals(-y)) / (2 * step)
            y[k] = 0.0
        for k in range(N_POSE):
            columns = self.n_intrinsic + N_POSE * np.arange(self.obs.n_captures) + k
            y[columns] = 1e-7
            pose[:, k] = (self.residuals(y) - self.residuals(-y)) / 2e-7
            y[columns] = 0.0
        grams = [intrinsic.T @ intrinsic] + [pose[capture == c].T @ pose[capture == c]
                                             for c in range(self.obs.n_captures)]
        out = []
        for gram in grams:
            gram = gram + np.eye(len(gram)) * 1e-12 * max(np.trace(gram), 1e-300)
            out.append(np.linalg.inv(np.linalg.cholesky(gram)).T)
        return out

    def sparsity(self) -> csr_matrix:
        """(3M, n_params) 0/1: each residual depends on the intrinsics and its own capture's pose."""
        m3 = 3 * len(self.obs.samples)
        rows = np.repeat(np.arange(m3), self.n_intrinsic + N_POSE)
        first_pose = self.n_intrinsic + N_POSE * np.repeat(self.obs.capture, 3)
        cols = np.concatenate([np.broadcast_to(np.arange(self.n_intrinsic), (m3, self.n_intrinsic)),
                               first_pose[:, None] + np.arange(N_POSE)], axis=1).ravel()
        shape = (m3, self.n_intrinsic + N_POSE * self.obs.n_captures)
        return csr_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=shape)


def refine(obs: Observations, h: np.ndarray, distortion: np.ndarray, poses: np.ndarray, *,
           with_distortion: bool, max_evaluations: int = 200) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One stage of the joint refinement (module docstring).

    Parameters
    ----------
    obs : Observations
    h : (5, 5) float64
        Starting ``H`` (re-centred, ``H02 = 0``).
    distortion : (5,) float64
        Starting ``[k1, k2, k3, b1, b2]``; kept at 0 when ``with_distortion`` is False.
    poses : (N, 6) float64
    with_distortion : bool
    max_evaluations : int
        Bound on the residual evaluations of ``least_squares``.

    Returns
    -------
    (H (5, 5), distortion (5,), poses (N, 6)) float64
    """
    problem = _Problem.at(obs, h, np.asarray(distortion, dtype=np.float64), poses, with_distortion)
    result = least_squares(problem.residuals, np.zeros_like(problem.x0), jac_sparsity=problem.sparsity(),
                           method="trf", xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=max_evaluations)
    log.debug("refinement (%s distortion): %s after %d evaluations", "with" if with_distortion else "without",
              result.message, result.nfev)
    return problem.unpack(result.x)


@dataclass(frozen=True)
class Reprojection:
    """Residuals of a calibration on its observations.

    Attributes
    ----------
    ray_m : (M,) float64
        Point-to-ray distance (m) of every observation.
    pixel : (M, 2) float64
        Projected minus observed ``(k, l)`` (px) of every observation.
    capture : (M,) int64
    """

    ray_m: np.ndarray
    pixel: np.ndarray
    capture: np.ndarray

    def rms_m(self, capture: int | None = None) -> float:
        """RMS point-to-ray distance (m), of one capture or of all."""
        d = self.ray_m if capture is None else self.ray_m[self.capture == capture]
        return float(np.sqrt(np.mean(d ** 2)))

    def rms_px(self, capture: int | None = None) -> float:
        """RMS length (px) of the 2-D reprojection error, of one capture or of all."""
        e = self.pixel if capture is None else self.pixel[self.capture == capture]
        return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


def reprojection(obs: Observations, h: np.ndarray, distortion: np.ndarray, poses: np.ndarray) -> Reprojection:
    """Ray distances and pixel errors of ``(H, distortion, poses)`` on ``obs``: the corners are projected
    into their view with :func:`plenodecode.raymodel.project_points`."""
    points = camera_points(poses, obs)
    ray_m = point_ray_distance(points, sample_rays(h, distortion, obs.samples))
    pixel = np.empty((len(points), 2))
    views, which = np.unique(obs.samples[:, :2], axis=0, return_inverse=True)
    for n, view in enumerate(views):
        rows = which.ravel() == n
        pixel[rows] = project_points(h, distortion, points[rows], (view[0], view[1])) - obs.samples[rows, 2:]
    return Reprojection(ray_m=ray_m, pixel=pixel, capture=obs.capture)


def solve(obs: Observations, h: np.ndarray, poses: np.ndarray, *,
          distortion: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both stages from an initial ``(H, poses)``: without distortion, then (if ``distortion``) with it.

    Returns
    -------
    (H (5, 5), distortion (5,), poses (N, 6)) float64
    """
    h, dist, poses = refine(obs, h, np.zeros(N_DISTORTION), poses, with_distortion=False)
    if distortion:
        h, dist, poses = refine(obs, h, dist, poses, with_distortion=True)
    return h, dist, poses

