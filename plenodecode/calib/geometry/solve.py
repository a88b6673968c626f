"""Joint refinement of ``H``, distortion and the board poses by ray reprojection (Dansereau et al. 2013, sec. 4).

The cost is the one of the paper and the Light Field Toolbox: for every corner ``X_p`` of the board
seen at sample ``n = (i, j, k, l)`` of capture ``c``, the 3-D distance (m) between the corner in the
camera frame, ``P = R(r_c) X_p + t_c``, and the ray of the sample, ``sample_rays(H, distortion, n)``::

    minimise  sum over observations of | (P - o) x d | ^ 2 / | d | ^ 2

with ``o = (s, t, 0)``, ``d = (u, v, 1)``.  Each observation contributes the 3 components of
:func:`plenodecode.raymodel.point_ray_offset` (smooth, unlike the distance itself).  The Jacobian is
sparse: an observation's residuals depend on the 7 solved entries of ``H`` (:mod:`.gauge`), the 5
distortion parameters and the 6 pose parameters of its own capture only, so finite differences cost
``2 (7 + 5 + 6)`` evaluations whatever the number of captures, and only its non-zero blocks are kept
(3M x 18).  :func:`levenberg_marquardt` takes exact steps on the (P, P) normal equations built from
them: 15-20 iterations per stage, where scipy's sparse trust-region solver (inexact LSMR steps) ran out
of its 200 evaluations per stage on 8 generated captures and took ~40x the time (issue 22).

Stages (as the toolbox): without distortion (``[k1 k2 k3 b1 b2] = 0``), then with it; then the last stage
again with each capture's residuals weighted by the inverse of their mean square (:func:`capture_weights`);
then every board's other tilt (the planar pose ambiguity, :func:`flipped_pose`) is tried, and the whole
solved again if one fits better (:func:`flip_check`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ...raymodel import (Board, point_ray_distance, point_ray_offset, pose_transform, project_points, rotation_matrix,
                         sample_rays)
from .corners import ViewCorners
from .gauge import SOLVED_ENTRIES, recentred_intrinsics, solved_values
from .initial import stacked_observations

log = logging.getLogger(__name__)

N_H = len(SOLVED_ENTRIES)
N_DISTORTION = 5
N_POSE = 6
#: A board's flipped pose replaces its pose in :func:`solve` when it fits with an RMS below this fraction of it.
FLIP_GAIN = 0.8
#: Passes of per-capture inverse-variance reweighting in :func:`solve`.
REWEIGHT_PASSES = 2


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
    within a block (focal length against distance, say) no longer make the normal equations of
    :func:`levenberg_marquardt` ill-conditioned or its damping ``mu diag(J^T J)`` uneven, and the block
    sparsity is unchanged.
    """

    def __init__(self, obs: Observations, with_distortion: bool, start: np.ndarray,
                 capture_weights: np.ndarray | None = None) -> None:
        self.obs = obs
        weights = np.ones(obs.n_captures) if capture_weights is None else np.asarray(capture_weights, np.float64)
        self.row_scale = np.repeat(np.sqrt(weights)[obs.capture], 3)      # sqrt(w_c) on each residual row
        self.with_distortion = with_distortion
        self.n_intrinsic = N_H + (N_DISTORTION if with_distortion else 0)
        self.x0 = start
        self.blocks = [np.arange(self.n_intrinsic)] + [self.n_intrinsic + N_POSE * c + np.arange(N_POSE)
                                                       for c in range(obs.n_captures)]
        self.transform = [np.eye(len(b)) for b in self.blocks]
        self.transform = self._whitening()

    @classmethod
    def at(cls, obs: Observations, h: np.ndarray, distortion: np.ndarray, poses: np.ndarray,
           with_distortion: bool, capture_weights: np.ndarray | None = None) -> "_Problem":
        parts = [solved_values(h)] + ([distortion] if with_distortion else []) + [np.ravel(poses)]
        return cls(obs, with_distortion, np.concatenate(parts).astype(np.float64), capture_weights)

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
        return point_ray_offset(camera_points(poses, self.obs), rays).ravel() * self.row_scale

    def jacobian_blocks(self, y: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
        """The non-zero blocks of the Jacobian of :meth:`residuals` at ``y`` by central differences.

        A residual depends on the intrinsic parameters and on its own capture's 6 pose parameters only, so
        pose parameter ``k`` of **all** captures is perturbed at once: ``2 (n_intrinsic + 6)`` evaluations
        whatever the number of captures (Curtis, Powell and Reid's column grouping).

        Returns
        -------
        intrinsic : (3M, n_intrinsic) float64
            d residuals / d intrinsic parameters.
        pose : (3M, 6) float64
            Row ``m``: d residual ``m`` / d the pose parameters of its capture.
        """
        rows = 3 * len(self.obs.samples)
        intrinsic = np.empty((rows, self.n_intrinsic))
        pose = np.empty((rows, N_POSE))
        delta = np.zeros_like(y)
        columns = [[k] for k in range(self.n_intrinsic)] + [
            self.n_intrinsic + N_POSE * np.arange(self.obs.n_captures) + k for k in range(N_POSE)]
        for n, cols in enumerate(columns):
            delta[cols] = step
            derivative = (self.residuals(y + delta) - self.residuals(y - delta)) / (2 * step)
            delta[cols] = 0.0
            if n < self.n_intrinsic:
                intrinsic[:, n] = derivative
            else:
                pose[:, n - self.n_intrinsic] = derivative
        return intrinsic, pose

    def normal_equations(self, intrinsic: np.ndarray, pose: np.ndarray,
                         residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(J^T J, J^T r)`` of the block-sparse ``J`` of :meth:`jacobian_blocks`: (P, P) and (P,) float64."""
        capture = np.repeat(self.obs.capture, 3)
        n_int = self.n_intrinsic
        gram = np.zeros((len(self.x0), len(self.x0)))
        gradient = np.empty(len(self.x0))
        gram[:n_int, :n_int] = intrinsic.T @ intrinsic
        gradient[:n_int] = intrinsic.T @ residual
        for c in range(self.obs.n_captures):
            rows = capture == c
            block = slice(n_int + N_POSE * c, n_int + N_POSE * (c + 1))
            gram[:n_int, block] = intrinsic[rows].T @ pose[rows]
            gram[block, :n_int] = gram[:n_int, block].T
            gram[block, block] = pose[rows].T @ pose[rows]
            gradient[block] = pose[rows].T @ residual[rows]
        return gram, gradient

    def _whitening(self) -> list[np.ndarray]:
        """``T_b`` of every block from the Jacobian at ``x0`` (:meth:`jacobian_blocks`)."""
        h_size = np.abs(self.x0[:N_H]).max()
        steps = 1e-6 * np.maximum(np.abs(self.x0[:self.n_intrinsic]), np.r_[np.full(N_H, 1e-3 * h_size),
                                                                             np.full(self.n_intrinsic - N_H, 1e-3)])
        # unit steps in every parameter's own scale: columns scaled back below
        self.transform = [np.diag(np.r_[steps / 1e-7])] + self.transform[1:]
        intrinsic, pose = self.jacobian_blocks(np.zeros_like(self.x0), 1e-7)
        # J_b^T J_b: the diagonal blocks of the normal matrix
        normal, _ = self.normal_equations(intrinsic, pose, np.zeros(len(intrinsic)))
        out = []
        for block, t in zip(self.blocks, self.transform):
            gram = normal[np.ix_(block, block)]
            gram = gram + np.eye(len(gram)) * 1e-12 * max(np.trace(gram), 1e-300)
            out.append(t @ np.linalg.inv(np.linalg.cholesky(gram)).T)
        return out


def levenberg_marquardt(problem: _Problem, *, max_iterations: int = 100, ftol: float = 1e-10,
                        xtol: float = 1e-10) -> tuple[np.ndarray, dict[str, Any]]:
    """Minimise ``|problem.residuals(y)|^2`` from ``y = 0`` by Levenberg-Marquardt on the normal equations.

    Each iteration solves ``(J^T J + mu diag(J^T J)) delta = -J^T r`` (Marquardt 1963) with ``J`` from
    :meth:`_Problem.jacobian_blocks` (block-sparse: the (P, P) normal equations are formed without storing a
    (3M, P) matrix); a step is taken when the gain ratio ``rho = (F(y) - F(y + delta)) / (L(0) - L(delta))``
    is positive, and ``mu`` is updated by ``mu *= max(1/3, 1 - (2 rho - 1)^3)`` or, on a rejected step,
    ``mu *= nu, nu *= 2`` (Madsen, Nielsen and Tingleff, *Methods for non-linear least squares problems*,
    2004, algorithm 3.16).  scipy's ``least_squares`` takes exact steps only with a dense ``J`` (3M x P:
    gigabytes for real boards) and otherwise inexact LSMR ones, which needed > 200 evaluations per stage here.

    Stops when an accepted step lowers the cost by less than ``ftol`` of it, or moves ``y`` by less than
    ``xtol (|y| + xtol)`` in whitened units, or after ``max_iterations`` Jacobians.

    Returns
    -------
    y : (P,) float64
    info : dict
        ``iterations`` (Jacobians), ``evaluations`` (residual calls outside the Jacobians), ``cost``
        (``|r|^2 / 2``), ``message``.
    """
    y = np.zeros_like(problem.x0)
    residual = problem.residuals(y)
    cost = 0.5 * float(residual @ residual)
    step = 1e-6 * max(np.sqrt(2 * cost), 1e-12)        # whitened units are residual units
    mu, nu, evaluations, message = 1e-3, 2.0, 1, "maximum number of iterations reached"
    iteration = 0
    for iteration in range(1, max_iterations + 1):
        gram, gradient = problem.normal_equations(*problem.jacobian_blocks(y, step), residual)
        diagonal = np.maximum(np.diag(gram), 1e-12 * max(np.diag(gram).max(), 1e-300))
        while True:
            delta = -cho_solve(cho_factor(gram + mu * np.diag(diagonal)), gradient)
            trial = problem.residuals(y + delta)
            evaluations += 1
            trial_cost = 0.5 * float(trial @ trial)
            predicted = 0.5 * float(delta @ (mu * diagonal * delta - gradient))
            rho = (cost - trial_cost) / predicted if predicted > 0 else -1.0
            if rho > 0:
                break
            mu, nu = mu * nu, nu * 2
            if mu > 1e16:
                return y, {"iterations": iteration, "evaluations": evaluations, "cost": cost,
                           "message": "no step lowers the cost"}
        small_step = np.linalg.norm(delta) <= xtol * (np.linalg.norm(y) + xtol)
        small_gain = cost - trial_cost <= ftol * cost
        y, residual, cost = y + delta, trial, trial_cost
        mu, nu = mu * max(1 / 3, 1 - (2 * rho - 1) ** 3), 2.0
        if small_gain or small_step:
            message = "cost change below ftol" if small_gain else "step below xtol"
            break
    return y, {"iterations": iteration, "evaluations": evaluations, "cost": cost, "message": message}


def refine(obs: Observations, h: np.ndarray, distortion: np.ndarray, poses: np.ndarray, *,
           with_distortion: bool, max_iterations: int = 100,
           capture_weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One stage of the joint refinement (module docstring), by :func:`levenberg_marquardt`.

    Parameters
    ----------
    obs : Observations
    h : (5, 5) float64
        Starting ``H`` (re-centred, ``H02 = 0``).
    distortion : (5,) float64
        Starting ``[k1, k2, k3, b1, b2]``; kept at 0 when ``with_distortion`` is False.
    poses : (N, 6) float64
    with_distortion : bool
    max_iterations : int
        Bound on the Jacobians evaluated.
    capture_weights : (N,) float, optional
        ``w_c`` of each capture: its squared residuals count ``w_c`` times (default all 1).

    Returns
    -------
    (H (5, 5), distortion (5,), poses (N, 6)) float64
    """
    problem = _Problem.at(obs, h, np.asarray(distortion, dtype=np.float64), poses, with_distortion,
                          capture_weights)
    y, info = levenberg_marquardt(problem, max_iterations=max_iterations)
    log.debug("refinement (%s distortion): %s after %d iterations", "with" if with_distortion else "without",
              info["message"], info["iterations"])
    return problem.unpack(y)


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


def capture_weights(obs: Observations, h: np.ndarray, distortion: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Inverse-variance weight of each capture's residuals, (N,) float64, mean 1 in the geometric sense.

    ``w_c = 1 / sigma_c^2`` with ``sigma_c^2`` the mean squared point-to-ray distance of capture ``c`` at
    ``(H, distortion, poses)`` (its 6 pose parameters are negligible against its ~10^3 observations):
    the maximum-likelihood weighting when each capture's corners are noisy alike but captures differ
    (blur out of focus, distance: a pixel error moves a ray by ``z H22`` per pixel).
    """
    distance = reprojection(obs, h, distortion, poses).ray_m
    variance = np.array([np.mean(distance[obs.capture == c] ** 2) for c in range(obs.n_captures)])
    weights = 1.0 / np.maximum(variance, 1e-30)
    return weights / np.exp(np.mean(np.log(weights)))


def flipped_pose(pose: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The other pose of a tilted board that a narrow camera sees almost alike (the planar pose ambiguity).

    Seen along ``w`` (the unit vector from the camera to the board's centre ``m = R c + t``, ``c`` in the
    board's frame), mirroring the board's axes through the plane normal to ``w``, ``M = I - 2 w w^T``, keeps
    their projection across the line of sight and reverses their depths: ``R' = M R diag(1, 1, -1)`` (a
    rotation) and ``t' = m - R' c``.  (6,) float64.
    """
    from scipy.spatial.transform import Rotation

    pose = np.asarray(pose, dtype=np.float64)
    rot = rotation_matrix(pose[3:])
    middle = rot @ centre + pose[:3]
    w = middle / np.linalg.norm(middle)
    flipped = (np.eye(3) - 2.0 * np.outer(w, w)) @ rot @ np.diag([1.0, 1.0, -1.0])
    return np.concatenate([middle - flipped @ centre, Rotation.from_matrix(flipped).as_rotvec()])


def fit_pose(obs: Observations, h: np.ndarray, distortion: np.ndarray, capture: int,
             start: np.ndarray) -> tuple[np.ndarray, float]:
    """Capture ``capture``'s pose (6,) fitted to its observations with ``H`` and the distortion fixed, from
    ``start`` (scipy's Levenberg-Marquardt), and its RMS point-to-ray offset (m)."""
    from scipy.optimize import least_squares

    rows = obs.capture == capture
    rays = sample_rays(h, distortion, obs.samples[rows])
    points = obs.board_points[rows]

    def residuals(x: np.ndarray) -> np.ndarray:
        return point_ray_offset(pose_transform(x, points), rays).ravel()

    fit = least_squares(residuals, np.asarray(start, dtype=np.float64), method="lm")
    return fit.x, float(np.sqrt(np.mean(fit.fun ** 2)))


def flip_check(obs: Observations, h: np.ndarray, distortion: np.ndarray,
               poses: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """Poses (N, 6) with every board whose :func:`flipped_pose` fits its observations better (RMS below
    :data:`FLIP_GAIN` of its own, :func:`fit_pose` from each at the given ``H`` and distortion) flipped, and
    the captures flipped."""
    out = np.array(poses, dtype=np.float64, copy=True)
    flipped = []
    for c in range(obs.n_captures):
        centre = obs.board_points[obs.capture == c].mean(axis=0)
        _, own = fit_pose(obs, h, distortion, c, out[c])
        other, cost = fit_pose(obs, h, distortion, c, flipped_pose(out[c], centre))
        if cost < FLIP_GAIN * own:
            out[c] = other
            flipped.append(c)
    return out, flipped


def solve(obs: Observations, h: np.ndarray, poses: np.ndarray, *, distortion: bool = True,
          reweight: int = REWEIGHT_PASSES, flips: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both stages from an initial ``(H, poses)``: without distortion, then (if ``distortion``) with it.

    Then the captures are weighted by :func:`capture_weights` at the solution and the last stage is solved
    again, ``reweight`` times (iteratively reweighted least squares).  Unweighted, a capture whose corners are
    2-3x noisier than the others' (a blurred one far from the focus) moved ``H`` of 10 generated F01 captures
    by up to 2.4 % (bench/bench_geometry.py).

    With ``flips``, every board whose other tilt (:func:`flipped_pose`) fits better at the solution is flipped
    and all is solved again once (:func:`flip_check`): 10 generated F01 captures with boards at the field's
    corners and k1 = 4 had 3 boards 26-50 degrees off, H 1.66 % off and RMS 1.9x the floor; after the flips
    H 0.58 %, RMS at the floor.

    Returns
    -------
    (H (5, 5), distortion (5,), poses (N, 6)) float64
    """
    h, dist, poses = refine(obs, h, np.zeros(N_DISTORTION), poses, with_distortion=False)
    if distortion:
        h, dist, poses = refine(obs, h, dist, poses, with_distortion=True)
    for _ in range(int(reweight)):
        h, dist, poses = refine(obs, h, dist, poses, with_distortion=distortion,
                                capture_weights=capture_weights(obs, h, dist, poses))
    if flips:
        # the planar calibration that starts the poses may tilt a board the wrong way (flipped_pose), which no
        # refinement undoes: each board's other tilt is tried at the solution, and the problem solved again
        flipped_poses, flipped = flip_check(obs, h, dist, poses)
        if flipped:
            log.info("captures %s: the board's other tilt fits better; solving again", [c + 1 for c in flipped])
            return solve(obs, h, flipped_poses, distortion=distortion, reweight=reweight, flips=False)
    return h, dist, poses
