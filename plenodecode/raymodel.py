"""The ray model of a lenslet-based plenoptic camera (Dansereau, Pizarro & Williams, CVPR 2013).

Every sample of a decoded light field ``lf.data[j, i, l, k]`` (``(V, U, Y, X)``: ``j`` angular row,
``i`` angular column, ``l`` spatial row, ``k`` spatial column, all **0-based**) records one ray.
The intrinsic matrix ``H`` (5 x 5, homogeneous) maps the sample index ``n = [i, j, k, l, 1]`` to
the *measured* ray in the relative two-plane parameterisation::

    [s, t, u, v, 1]^T = H n

``(s, t)`` (m) is where the ray crosses the plane ``z = 0`` of the camera frame and ``(u, v)`` its
direction as a slope (``dx/dz``, ``dy/dz``): the ray is ``(s + u z, t + v z, z)``, with ``z`` (m)
along the optical axis, ``x`` to the right (growing ``k``) and ``y`` down (growing ``l``).  ``s``
and ``u`` depend on ``(i, k)`` only, ``t`` and ``v`` on ``(j, l)`` only, so ``H`` has 12 free
entries (:data:`FREE_ENTRIES`).

Lens distortion acts on the direction.  The five parameters ``[k1, k2, k3, b1, b2]`` map a measured
direction ``theta_m = (u, v)`` to the ideal (pinhole) one in closed form::

    theta = (1 + k1 r^2 + k2 r^4 + k3 r^6) (theta_m - b) + b,     r = |theta_m - b|

(:func:`correct_directions`; ``b`` decentres it).  Its inverse (ideal -> measured, needed to find
which sample sees a given ray) has no closed form and is found by fixed-point iteration
(:func:`distort_directions`).  This is the direction in which the Light Field Toolbox applies its
stored ``EstCamDistortionV`` (cheap in the calibration cost, iterated in rectification), so
``CalInfo.json`` files carry over unchanged apart from the 1-based indices
(:func:`from_toolbox_intrinsics`; files: :mod:`plenodecode.io.calinfo`).

A checkerboard pose is ``[tx, ty, tz, rx, ry, rz]``: a board point ``X_b = (x_b, y_b, 0)`` (m) lies
at ``R(r) X_b + t`` in the camera frame, ``R`` the rotation of the Rodrigues vector ``r``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

#: Names of the distortion parameters, in the order stored (the toolbox's order).
DISTORTION_NAMES = ("k1", "k2", "k3", "b1", "b2")
#: (row, col) of the 12 entries of ``H`` the model lets vary; the rest are 0 (or 1 at [4, 4]).
FREE_ENTRIES = ((0, 0), (0, 2), (0, 4), (1, 1), (1, 3), (1, 4),
                (2, 0), (2, 2), (2, 4), (3, 1), (3, 3), (3, 4))
#: Fixed-point iterations of :func:`distort_directions` (enough for the toolbox's largest
#: distortions to 1e-12 of a slope; the loop also stops when the update is below that).
DISTORTION_ITERATIONS = 50


def intrinsics_from_entries(values: Sequence[float]) -> np.ndarray:
    """The 5 x 5 ``H`` (float64) with :data:`FREE_ENTRIES` set to ``values`` (12,) and ``H[4, 4] = 1``."""
    values = np.asarray(values, dtype=np.float64).ravel()
    if values.size != len(FREE_ENTRIES):
        raise ValueError(f"H has {len(FREE_ENTRIES)} free entries, got {values.size} values")
    h = np.zeros((5, 5))
    for (r, c), value in zip(FREE_ENTRIES, values):
        h[r, c] = value
    h[4, 4] = 1.0
    return h


def check_intrinsics(h: Any) -> np.ndarray:
    """``h`` as a float64 (5, 5) array; raises ValueError when it is not of the model's form."""
    h = np.asarray(h, dtype=np.float64)
    if h.shape != (5, 5):
        raise ValueError(f"the intrinsic matrix H must be 5 x 5, got shape {h.shape}")
    mask = np.zeros((5, 5), bool)
    for r, c in FREE_ENTRIES:
        mask[r, c] = True
    mask[4, 4] = True
    if np.any(h[~mask] != 0.0) or h[4, 4] != 1.0:
        raise ValueError("H must couple (i, k) to (s, u) and (j, l) to (t, v) only, with H[4, 4] = 1")
    if not np.all(np.isfinite(h)):
        raise ValueError("H has non-finite entries")
    return h


def check_distortion(distortion: Any) -> np.ndarray:
    """``[k1, k2, k3, b1, b2]`` as float64 (5,); None means no distortion."""
    d = np.zeros(5) if distortion is None else np.asarray(distortion, dtype=np.float64).ravel()
    if d.size != 5 or not np.all(np.isfinite(d)):
        raise ValueError(f"distortion must be 5 finite numbers {DISTORTION_NAMES}, got {distortion!r}")
    return d


def measured_rays(h: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Rays ``H n`` of sample indices: ``samples`` (..., 4) ``(i, j, k, l)`` -> (..., 4) ``(s, t, u, v)`` float64."""
    n = np.asarray(samples, dtype=np.float64)
    return n @ h[:4, :4].T + h[:4, 4]


def correct_directions(directions: np.ndarray, distortion: Any) -> np.ndarray:
    """Measured directions (..., 2) ``(u, v)`` -> ideal ones: ``(1 + k1 r^2 + k2 r^4 + k3 r^6)(theta - b) + b``."""
    k1, k2, k3, b1, b2 = check_distortion(distortion)
    theta = np.asarray(directions, dtype=np.float64)
    centred = theta - np.array([b1, b2])
    r2 = np.sum(centred * centred, axis=-1, keepdims=True)
    return (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) * centred + np.array([b1, b2])


def distort_directions(directions: np.ndarray, distortion: Any, *,
                       iterations: int = DISTORTION_ITERATIONS) -> np.ndarray:
    """Ideal directions (..., 2) -> the measured ones that :func:`correct_directions` maps onto them.

    Fixed point of ``theta_m = b + (theta - b) / (1 + k1 r^2 + k2 r^4 + k3 r^6)``, ``r = |theta_m - b|``,
    started at ``theta_m = theta``.
    """
    k1, k2, k3, b1, b2 = check_distortion(distortion)
    b = np.array([b1, b2])
    target = np.asarray(directions, dtype=np.float64) - b
    centred = target.copy()
    if k1 == k2 == k3 == 0.0:
        return centred + b
    for _ in range(iterations):
        r2 = np.sum(centred * centred, axis=-1, keepdims=True)
        update = target / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        step = np.max(np.abs(update - centred)) if update.size else 0.0
        centred = update
        if step < 1e-12:
            break
    return centred + b


def sample_rays(h: np.ndarray, distortion: Any, samples: np.ndarray) -> np.ndarray:
    """Ideal rays (..., 4) ``(s, t, u, v)`` of sample indices (..., 4) ``(i, j, k, l)``: ``H n``, then
    :func:`correct_directions` on ``(u, v)``."""
    rays = measured_rays(h, samples)
    rays[..., 2:] = correct_directions(rays[..., 2:], distortion)
    return rays


def samples_of_rays(h: np.ndarray, distortion: Any, rays: np.ndarray, *,
                    iterations: int = DISTORTION_ITERATIONS) -> np.ndarray:
    """Inverse of :func:`sample_rays`: ideal rays (..., 4) -> continuous sample indices (..., 4) ``(i, j, k, l)``.

    ``(u, v)`` are distorted back (:func:`distort_directions`, at most ``iterations``), then
    ``n = H^-1 [s, t, u, v, 1]``.
    """
    measured = np.array(rays, dtype=np.float64)
    measured[..., 2:] = distort_directions(measured[..., 2:], distortion, iterations=iterations)
    inverse = np.linalg.inv(h)
    return measured @ inverse[:4, :4].T + inverse[:4, 4]


def point_ray_offset(points: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """The vector ``(P - o) x d / |d|`` (..., 3) of 3-D points (..., 3) and rays (..., 4) ``(s, t, u, v)``.

    The ray passes through ``o = (s, t, 0)`` with direction ``d = (u, v, 1)``; the vector is
    perpendicular to ``d`` and its length is the point-to-ray distance (m), so it serves as a
    smooth 3-component residual whose squared norm is the squared distance.
    """
    p = np.asarray(points, dtype=np.float64)
    r = np.asarray(rays, dtype=np.float64)
    offset = np.stack([p[..., 0] - r[..., 0], p[..., 1] - r[..., 1], p[..., 2]], axis=-1)
    direction = np.stack([r[..., 2], r[..., 3], np.ones_like(r[..., 2])], axis=-1)
    return np.cross(offset, direction) / np.linalg.norm(direction, axis=-1, keepdims=True)


def point_ray_distance(points: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Distance (m) from 3-D points (..., 3) to rays (..., 4) ``(s, t, u, v)``.

    The ray passes through ``o = (s, t, 0)`` with direction ``d = (u, v, 1)``;
    distance = ``|(P - o) x d| / |d|`` (the length of :func:`point_ray_offset`).
    """
    return np.linalg.norm(point_ray_offset(points, rays), axis=-1)


def project_points(h: np.ndarray, distortion: Any, points: np.ndarray, view: tuple[float, float], *,
                   iterations: int = DISTORTION_ITERATIONS) -> np.ndarray:
    """Where 3-D points appear in one sub-aperture view: the spatial indices ``(k, l)`` whose ray from
    angular sample ``view = (i, j)`` passes through each point.

    With ``u = u_m + du`` (``du`` the distortion correction of the measured direction), the x equation
    ``s + u z = x`` is linear in ``k``::

        k = (x - H00 i - H04 - (H20 i + H24 + du) z) / (H02 + H22 z)

    (and ``l`` alike from the y row); ``du`` is updated from the new ``(k, l)`` until it settles.

    Parameters
    ----------
    points : (..., 3) float
        Camera-frame points (m), ``z > 0``.
    view : (i, j)
        Angular sample (column, row), 0-based, may be fractional.

    Returns
    -------
    (..., 2) float64 ``(k, l)``.
    """
    p = np.asarray(points, dtype=np.float64)
    i, j = float(view[0]), float(view[1])
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    correction = np.zeros(p.shape[:-1] + (2,))
    kl = np.zeros(p.shape[:-1] + (2,))
    for _ in range(iterations):
        k = (x - h[0, 0] * i - h[0, 4] - (h[2, 0] * i + h[2, 4] + correction[..., 0]) * z) / (h[0, 2] + h[2, 2] * z)
        l_ = (y - h[1, 1] * j - h[1, 4] - (h[3, 1] * j + h[3, 4] + correction[..., 1]) * z) / (h[1, 3] + h[3, 3] * z)
        new = np.stack([k, l_], axis=-1)
        step = np.max(np.abs(new - kl)) if new.size else 0.0
        kl = new
        n = np.concatenate([np.broadcast_to([i, j], kl.shape), kl], axis=-1)
        direction = measured_rays(h, n)[..., 2:]
        correction = correct_directions(direction, distortion) - direction
        if step < 1e-10:
            break
    return kl


def rotation_matrix(rotvec: Sequence[float]) -> np.ndarray:
    """3 x 3 rotation of a Rodrigues vector (axis * angle, rad)."""
    r = np.asarray(rotvec, dtype=np.float64)
    angle = float(np.linalg.norm(r))
    if angle < 1e-15:
        return np.eye(3)
    a = r / angle
    cross = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross


def board_points(rows: int, cols: int, square_m: float) -> np.ndarray:
    """Inner corners of a checkerboard in its own frame: (rows * cols, 3) float64 ``(x_b, y_b, 0)``,
    row-major (``x_b = c * square``, ``y_b = r * square``), origin at the first corner."""
    r, c = np.mgrid[0:rows, 0:cols]
    return np.stack([c.ravel() * square_m, r.ravel() * square_m, np.zeros(rows * cols)], axis=-1)


@dataclass(frozen=True)
class Board:
    """A planar checkerboard target.

    Attributes
    ----------
    rows, cols : int
        Inner corners per column and per row (OpenCV's ``patternSize`` is ``(cols, rows)``).
    square_m : float
        Side of one square (m).
    margin : int
        Width of the light border around the checkers, in whole squares (>= 1, which OpenCV's
        detectors need).
    """

    rows: int
    cols: int
    square_m: float
    margin: int = 1

    def __post_init__(self) -> None:
        if int(self.rows) != self.rows or int(self.cols) != self.cols or self.rows < 2 or self.cols < 2:
            raise ValueError(f"board needs at least 2 x 2 inner corners, got {self.rows} x {self.cols}")
        if not (math.isfinite(self.square_m) and self.square_m > 0):
            raise ValueError(f"board square size must be a positive length in m, got {self.square_m!r}")
        if int(self.margin) != self.margin or self.margin < 1:
            raise ValueError(f"board margin must be a whole number of squares >= 1, got {self.margin!r}")
        object.__setattr__(self, "rows", int(self.rows))
        object.__setattr__(self, "cols", int(self.cols))
        object.__setattr__(self, "square_m", float(self.square_m))
        object.__setattr__(self, "margin", int(self.margin))

    def corners(self) -> np.ndarray:
        """Inner corners in the board frame, (rows * cols, 3) float64, row-major (:func:`board_points`)."""
        return board_points(self.rows, self.cols, self.square_m)

    def outline(self) -> np.ndarray:
        """The 4 corners (4, 3) float64 of the board including its light margin, in the board frame."""
        s, m = self.square_m, self.margin
        x0, x1 = -(1.0 + m) * s, (self.cols + m) * s
        y0, y1 = -(1.0 + m) * s, (self.rows + m) * s
        return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])

    def describe(self) -> str:
        return f"{self.rows} x {self.cols} corners, {self.square_m * 1e3:g} mm squares"

    @classmethod
    def parse(cls, text: str) -> "Board":
        """``'8x6x0.0036'`` (rows x cols x square in metres) -> Board; ValueError otherwise."""
        match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*[xX]\s*([0-9.eE+-]+)\s*", str(text))
        try:
            if match is None:
                raise ValueError
            square = float(match.group(3))
        except ValueError:
            raise ValueError(f"expected ROWSxCOLSxSQUARE_M (e.g. 8x6x0.0036), got {text!r}") from None
        return cls(int(match.group(1)), int(match.group(2)), square)

    @classmethod
    def of(cls, board: "Board | Sequence[float] | str") -> "Board":
        """A Board from a Board, a ``(rows, cols, square_m)`` tuple or a ``'8x6x0.0036'`` string;
        ValueError naming ``board`` otherwise."""
        if isinstance(board, Board):
            return board
        if isinstance(board, str):
            return cls.parse(board)
        try:
            rows, cols, square = board
        except (TypeError, ValueError):
            raise ValueError(f"board must be (rows, cols, square_m), got {board!r}") from None
        return cls(rows, cols, float(square))

    def to_dict(self) -> dict[str, Any]:
        return {"rows": self.rows, "cols": self.cols, "square_m": self.square_m, "margin": self.margin}


def pose_transform(pose: Sequence[float], points: np.ndarray) -> np.ndarray:
    """Board-frame points (..., 3) -> camera frame by ``pose = [tx, ty, tz, rx, ry, rz]``: ``R(r) X + t``."""
    pose = np.asarray(pose, dtype=np.float64)
    return np.asarray(points, dtype=np.float64) @ rotation_matrix(pose[3:]).T + pose[:3]


_ONE_BASED = np.eye(5)
_ONE_BASED[:4, 4] = 1.0   # n_toolbox = T n_0: [i+1, j+1, k+1, l+1, 1]


def from_toolbox_intrinsics(h_toolbox: Any) -> np.ndarray:
    """The toolbox's H (1-based ``n``) -> this model's H (0-based ``n``): ``H0 = H_tb T``."""
    return check_intrinsics(np.asarray(h_toolbox, dtype=np.float64) @ _ONE_BASED)


def to_toolbox_intrinsics(h: Any) -> np.ndarray:
    """This model's H (0-based ``n``) -> the toolbox's (1-based): ``H_tb = H0 T^-1``."""
    return check_intrinsics(h) @ np.linalg.inv(_ONE_BASED)


@dataclass(frozen=True)
class GeometricCalibration:
    """A calibrated plenoptic camera: the ray model above for light fields of one decoded shape.

    Attributes
    ----------
    intrinsics : (5, 5) float64
        ``H`` for 0-based sample indices.
    distortion : (5,) float64
        ``[k1, k2, k3, b1, b2]``.
    lf_shape : (V, U, Y, X)
        Shape of the decoded light fields the calibration applies to (the lenslet grid and
        decoding are part of it: calibrate and decode with the same white image).
    poses : (N, 6) float64
        ``[tx, ty, tz, rx, ry, rz]`` of the board in each calibration capture (may be empty).
    info : dict
        Free-form provenance and quality (board, capture names, reprojection RMS, camera serial ...).
    """

    intrinsics: np.ndarray
    distortion: np.ndarray = field(default_factory=lambda: np.zeros(5))
    lf_shape: tuple[int, int, int, int] = (0, 0, 0, 0)
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "intrinsics", check_intrinsics(self.intrinsics))
        object.__setattr__(self, "distortion", check_distortion(self.distortion))
        object.__setattr__(self, "lf_shape", tuple(int(v) for v in self.lf_shape))
        poses = np.asarray(self.poses, dtype=np.float64).reshape(-1, 6)
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "info", dict(self.info))

    def rays(self, samples: np.ndarray) -> np.ndarray:
        """Ideal rays (..., 4) of sample indices (..., 4) ``(i, j, k, l)`` (:func:`sample_rays`)."""
        return sample_rays(self.intrinsics, self.distortion, samples)

    def samples(self, rays: np.ndarray) -> np.ndarray:
        """Continuous sample indices of ideal rays (:func:`samples_of_rays`)."""
        return samples_of_rays(self.intrinsics, self.distortion, rays)

    def project(self, points: np.ndarray, view: tuple[float, float]) -> np.ndarray:
        """``(k, l)`` of camera-frame points in view ``(i, j)`` (:func:`project_points`)."""
        return project_points(self.intrinsics, self.distortion, points, view)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready document (this project's own format; see :mod:`plenodecode.io.calinfo` for the toolbox's)."""
        return {"format": "plenodecode-geometric-calibration", "version": 1,
                "intrinsics": self.intrinsics.tolist(), "distortion": self.distortion.tolist(),
                "distortion_names": list(DISTORTION_NAMES), "lf_shape": list(self.lf_shape),
                "poses": self.poses.tolist(), "index_base": 0, "info": dict(self.info)}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> "GeometricCalibration":
        if doc.get("format") != "plenodecode-geometric-calibration":
            raise ValueError("not a plenodecode geometric calibration document")
        return cls(intrinsics=np.asarray(doc["intrinsics"]), distortion=np.asarray(doc["distortion"]),
                   lf_shape=tuple(doc.get("lf_shape", (0, 0, 0, 0))), poses=np.asarray(doc.get("poses", [])),
                   info=doc.get("info", {}))
