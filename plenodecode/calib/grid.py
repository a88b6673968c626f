"""Robust lattice fit: lens indices for detected centres, least-squares grid parameters, grid extent.

The lattice model is the one of :class:`plenodecode.types.LensletGrid` (see :mod:`plenodecode.types`).
Detected centres ``P_k`` are indexed in the basis ``(v1, v2)`` found by
:func:`plenodecode.calib.centroids.estimate_lattice_vectors` -- ``v1`` along a lens row, ``v2`` to
the next row -- so lens ``(n, m)`` of the infinite lattice lies at::

    P(n, m) = o + n * rs * e_row(theta) + (m + s * n) * p * e_col(theta)

with ``s = 1/2`` for a hexagonal and ``0`` for a square lattice.  The five parameters
``(o_row, o_col, theta, p, rs)`` are found by Gauss-Newton least squares with iterative outlier
rejection (residuals beyond 4 robust sigmas, from the median absolute residual), as in the
lattice fit of Dansereau et al. (CVPR 2013) but over every detected lens rather than along a few
row and column walks.  Indexing grows a region from the centre lens outwards, refitting a free
affine lattice at each step so that a slightly wrong initial pitch never mis-indexes far lenses.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import ndimage

from ..errors import CalibrationError
from ..types import LensletGrid

if TYPE_CHECKING:
    from .centroids import LatticeEstimate

log = logging.getLogger(__name__)

#: ``grid.info["source_kind"]``: how a grid was obtained, set by each calibration path -> what it is, in words.
SOURCE_KINDS: dict[str, str] = {
    "white-image": "fitted to white image(s)",
    "self-calibration": "self-calibration from a scene (no white image)",
    "camera-file": "the camera's own calibration file (Raytrix RayCalibData XML), used as given",
    "grid-file": "a grid given as is, e.g. a grid JSON (no record of how it was made)",
}
#: Side, in lenses, of the blocks over which :func:`residual_statistics` averages residuals.
MISFIT_BLOCK = 5


def residual_statistics(residuals: np.ndarray, lens_ij: np.ndarray, *, block: int = MISFIT_BLOCK) -> dict[str, Any]:
    """Statistics of the residuals of measured centres against a lattice (the inlier lenses).

    * ``rms_px``: RMS distance between the measured centres and the lattice,
      ``sqrt(mean |r_k|^2)``;
    * ``sigma_px``: robust per-axis sigma from the median distance (``median |r| = 1.1774 sigma``
      for a 2-D Gaussian), so ``rms / (sqrt(2) sigma)`` is ~1 for noise-like residuals;
    * ``local_misfit_px``: the part of the residuals common to blocks of ``block x block``
      lenses, i.e. how far the lattice sits from the centres locally, detection noise removed:
      ``sqrt( sum_b n_b (|mean_b|^2 - s_w^2 / n_b) / sum_b n_b )`` over blocks of >= 5 lenses,
      with ``s_w^2`` the pooled within-block variance (both axes).  Measured on generated
      scenes, it reads a shifted or scaled lattice's true error 1:1 and bounds a fitted one's
      from above (scene bias common to nearby lenses also enters it).

    Parameters
    ----------
    residuals : ndarray (N, 2) float64
        Measured minus lattice centre, px.
    lens_ij : ndarray (N, 2) int
        Lens index of each residual (any integer lattice indices).
    block : int

    Returns
    -------
    dict
        ``rms_px``, ``sigma_px``, ``local_misfit_px`` (float, NaN without data) and ``n`` (int).
    """
    r = np.asarray(residuals, np.float64).reshape(-1, 2)
    out: dict[str, Any] = {"n": int(len(r)), "rms_px": float("nan"), "sigma_px": float("nan"),
                           "local_misfit_px": float("nan")}
    if not len(r):
        return out
    d = np.hypot(r[:, 0], r[:, 1])
    out["rms_px"] = float(np.sqrt(np.mean(d ** 2)))
    out["sigma_px"] = float(np.median(d) / 1.1774)
    _, inv, cnt = np.unique(np.asarray(lens_ij) // block, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    mean = np.stack([np.bincount(inv, r[:, a]) for a in (0, 1)], axis=1) / cnt[:, None]
    within = float(np.sum((r - mean[inv]) ** 2)) / max(1, int(np.sum(cnt - 1)))
    use = cnt >= 5
    if use.any():
        common = np.sum(cnt[use] * (np.sum(mean[use] ** 2, axis=1) - within / cnt[use])) / np.sum(cnt[use])
        out["local_misfit_px"] = float(np.sqrt(max(0.0, common)))
    return out


#: Degree of the polynomial field (in the lens indices) that :func:`smooth_distortion` fits to a grid's residuals.
SMOOTH_FIELD_DEGREE = 3


def smooth_field(ij: np.ndarray, d: np.ndarray, degree: int = SMOOTH_FIELD_DEGREE, *,
                 k_sigma: float | None = None, rounds: int = 3) -> tuple[np.ndarray, np.ndarray] | None:
    """Least-squares polynomial field of lens-centre departures over the lens indices.

    ``d_k = sum_{i + j <= degree} a_ij r'^i k'^j + e_k`` per axis, ``r', k'`` the lens indices centred and scaled
    to [-1, 1].  With ``k_sigma`` the fit is repeated ``rounds`` times without the lenses whose ``|e|`` exceeds
    ``k_sigma`` robust sigmas (``median |e| / 1.1774``): scene texture moves single lenses, not the field.

    Parameters
    ----------
    ij : ndarray (N, 2) int, lens (row, col) indices
    d : ndarray (N, 2) float64, departures (px)
    degree : int
    k_sigma : float, optional
    rounds : int

    Returns
    -------
    (field, used) : ndarray (N, 2) float64 and ndarray (N,) bool, or None with fewer than 5 lenses per coefficient
    """
    r, k = (np.asarray(ij)[:, a].astype(np.float64) for a in (0, 1))
    terms = [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]
    if len(r) < 5 * len(terms):
        return None
    r = (r - 0.5 * (r.min() + r.max())) / max(0.5 * (r.max() - r.min()), 1.0)
    k = (k - 0.5 * (k.min() + k.max())) / max(0.5 * (k.max() - k.min()), 1.0)
    design = np.stack([r ** i * k ** j for i, j in terms], axis=1)
    used = np.ones(len(r), bool)
    for _ in range(rounds if k_sigma is not None else 1):
        coef, *_ = np.linalg.lstsq(design[used], d[used], rcond=None)
        if k_sigma is None:
            break
        e = np.hypot(*(d - design @ coef).T)
        keep = e <= k_sigma * max(float(np.median(e[used])) / 1.1774, 1e-6)
        if keep.sum() < 5 * len(terms) or np.array_equal(keep, used):
            break
        used = keep
    return design @ coef, used


def smooth_distortion(grid: LensletGrid, degree: int = SMOOTH_FIELD_DEGREE) -> dict[str, float] | None:
    """How far the measured lens centres of ``grid`` depart from its regular lattice smoothly, and the rest.

    Optics between the lens array and the sensor (a microscope's relay lens) bend the array's image: the
    measured centres ``c_rk`` (``grid.refined``) then depart from the lattice ``l_rk`` by a smooth field that
    the decoder follows (it uses each lens's measured centre), on top of the centres' own scatter.  Fitted per
    axis by least squares (:func:`smooth_field`).

    Returns
    -------
    dict or None
        ``max_px``: the largest ``|field|`` over the measured lenses; ``rest_rms_px``: ``sqrt(mean |e|^2)``;
        None with fewer than 5 measured lenses per coefficient.
    """
    if grid.refined is None:
        return None
    d = grid.refined - grid.lattice_centres().reshape(grid.refined.shape)
    ok = np.all(np.isfinite(d), axis=-1)
    fitted = smooth_field(np.argwhere(ok), d[ok], degree)
    if fitted is None:
        return None
    field = fitted[0]
    rest = d[ok] - field
    return {"max_px": float(np.hypot(*field.T).max()), "rest_rms_px": float(np.sqrt(np.mean(np.sum(rest ** 2, 1))))}


def inner_lens_count(grid: LensletGrid, margin: float = 1.0) -> int:
    """Lenses of ``grid`` whose centre lies more than ``margin`` pitches inside the sensor."""
    c = grid.centres()
    H, W = grid.sensor_shape
    m = margin * grid.pitch
    return int(np.sum((c[:, 0] > m) & (c[:, 1] > m) & (c[:, 0] < H - 1 - m) & (c[:, 1] < W - 1 - m)))


@dataclass(frozen=True)
class LatticeFit:
    """Result of :func:`fit_lattice`.

    Attributes
    ----------
    lattice : 'hex' or 'square'
    pitch, row_spacing, rotation : float
        Fitted model parameters (px, px, rad).
    origin : ndarray (2,) float64
        Sensor ``(row, col)`` of lattice index ``(n, m) = (0, 0)``.
    shift : float
        ``s`` of the model: 0.5 (hex) or 0 (square).
    indices : ndarray (N, 2) int64
        ``(n, m)`` of every input point (meaningless where ``inlier`` is False).
    inlier : ndarray (N,) bool
        Points used in the final fit.
    residuals : ndarray (N, 2) float64
        ``P_k - P(n_k, m_k)``, px.
    rms : float
        RMS residual distance over the inliers, px.
    sigma : float
        Robust per-axis residual sigma, px.
    """

    lattice: str
    pitch: float
    row_spacing: float
    rotation: float
    origin: np.ndarray
    shift: float
    indices: np.ndarray
    inlier: np.ndarray
    residuals: np.ndarray
    rms: float
    sigma: float
    stats: dict[str, Any] = field(default_factory=dict)

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """``(e_row, e_col)`` unit vectors, (row, col)."""
        s, c = math.sin(self.rotation), math.cos(self.rotation)
        return np.array([c, -s]), np.array([s, c])

    def position(self, n: np.ndarray, m: np.ndarray) -> np.ndarray:
        """Sensor position of lattice indices ``(n, m)``, shape ``n.shape + (2,)``."""
        return _model(np.array([*self.origin, self.rotation, self.pitch, self.row_spacing]), self.shift,
                      np.asarray(n, np.float64), np.asarray(m, np.float64))


def _model(x: np.ndarray, s: float, n: np.ndarray, m: np.ndarray) -> np.ndarray:
    o_r, o_c, th, p, rs = x
    a = n * rs
    b = (m + s * n) * p
    sn, cs = math.sin(th), math.cos(th)
    return np.stack([o_r + a * cs + b * sn, o_c - a * sn + b * cs], axis=-1)


def _normal_equations(x: np.ndarray, s: float, pts: np.ndarray, n: np.ndarray,
                      m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A = Jr^T Jr + Jc^T Jc`` (5, 5) and ``g = Jr^T rr + Jc^T rc`` (5,) of the 5-parameter model, float64.

    ``rr, rc`` (N,) are the row and column residuals ``pts - P``; ``Jr, Jc`` (N, 5) their Jacobians
    (see :func:`_gauss_newton_step`).
    """
    o_r, o_c, th, p, rs = x
    sn, cs = math.sin(th), math.cos(th)
    a = n * rs
    k = m + s * n
    b = k * p
    res_r = pts[:, 0] - (o_r + a * cs + b * sn)
    res_c = pts[:, 1] - (o_c - a * sn + b * cs)
    one, zero = np.ones_like(a), np.zeros_like(a)
    jr = np.stack([one, zero, -a * sn + b * cs, k * sn, n * cs], axis=1)
    jc = np.stack([zero, one, -a * cs - b * sn, k * cs, -n * sn], axis=1)
    return jr.T @ jr + jc.T @ jc, jr.T @ res_r + jc.T @ res_c


def _gauss_newton_step(x: np.ndarray, s: float, pts: np.ndarray, n: np.ndarray,
                       m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One Gauss-Newton step of the 5-parameter model (normal equations, column-scaled).

    Jacobian of ``P = (o_r + a cos t + b sin t, o_c - a sin t + b cos t)`` with ``a = n rs``,
    ``b = (m + s n) p`` with respect to ``(o_r, o_c, t, p, rs)``.
    """
    A, g = _normal_equations(x, float(s), np.ascontiguousarray(pts, np.float64),
                             np.ascontiguousarray(n, np.float64), np.ascontiguousarray(m, np.float64))
    sc = np.sqrt(np.diag(A)) + 1e-300
    dx = np.linalg.solve(A / np.outer(sc, sc), g / sc) / sc
    return x + dx, dx


def _robust_fit(x0: np.ndarray, s: float, pts: np.ndarray, n: np.ndarray, m: np.ndarray, use: np.ndarray, *,
                n_reject: int = 3, k_sigma: float = 4.0) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                 np.ndarray, float]:
    """Gauss-Newton fit of ``(o_r, o_c, theta, p, rs)`` with rounds of outlier rejection.

    A point is kept when its residual distance is below ``k_sigma`` robust sigmas (per-axis
    sigma from the median residual distance: ``median = sigma * sqrt(2 ln 2)`` for a 2-D
    Gaussian).

    Returns
    -------
    x : ndarray (5,)
    inlier : ndarray (N,) bool
    residuals : ndarray (N, 2)
    distance : ndarray (N,)
    sigma : float
    """
    x = np.asarray(x0, np.float64).copy()
    w = use.copy()
    sigma = float("nan")
    for rnd in range(n_reject + 1):
        if w.sum() < 3:
            raise CalibrationError(f"only {int(w.sum())} lenslet centres agree with the lattice; the fit failed")
        for _ in range(8):
            x, dx = _gauss_newton_step(x, s, pts[w], n[w], m[w])
            if np.all(np.abs(dx[[0, 1, 3, 4]]) < 1e-10) and abs(dx[2]) < 1e-13:
                break
        res = pts - _model(x, s, n, m)
        d = np.hypot(res[:, 0], res[:, 1])
        sigma = float(np.median(d[w]) / 1.1774)
        if rnd == n_reject:
            break
        w_new = use & (d < max(k_sigma * sigma, 1e-3))
        if np.array_equal(w_new, w):
            break
        w = w_new
    return x, w, res, d, sigma


def index_points(points: np.ndarray, v1: np.ndarray, v2: np.ndarray, *, seed: np.ndarray | None = None,
                 tolerance: float = 0.3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integer lattice indices ``(n, m)`` of points, growing outwards from a seed.

    Starting from the point nearest ``seed`` (default: the points' median), points within a
    radius are indexed by rounding their coordinates in the current basis, a free affine lattice
    ``P = o + m * v1 + n * v2`` is refitted to them, and the radius doubles until it covers all.

    Parameters
    ----------
    points : ndarray (N, 2) float64
    v1, v2 : ndarray (2,) float64
        Initial basis (along a row; to the next row).
    seed : ndarray (2,), optional
    tolerance : float
        Largest fractional-index error (in lattice units) accepted.

    Returns
    -------
    nm : ndarray (N, 2) int64
        ``(n, m)`` per point.
    ok : ndarray (N,) bool
        Points whose coordinates were within ``tolerance`` of an integer pair.
    basis : ndarray (3, 2) float64
        Fitted ``(o, v1, v2)``.
    """
    pts = np.asarray(points, np.float64)
    if len(pts) < 6:
        raise CalibrationError(f"only {len(pts)} lenslet centres detected; expected hundreds: "
                               "is this a white image of a plenoptic camera?")
    seed = np.median(pts, axis=0) if seed is None else np.asarray(seed, np.float64)
    k0 = int(np.argmin(np.sum((pts - seed) ** 2, axis=1)))
    o, b1, b2 = pts[k0].copy(), np.asarray(v1, np.float64), np.asarray(v2, np.float64)
    pitch = float(np.hypot(*b1))
    dist = np.hypot(pts[:, 0] - pts[k0, 0], pts[:, 1] - pts[k0, 1])
    span = float(dist.max())
    radius = 6.0 * pitch
    while True:
        basis = np.stack([b2, b1], axis=1)                 # columns: v2 (n), v1 (m)
        if not abs(np.linalg.det(basis)) > 0.1 * pitch ** 2:   # the vectors collapsed: these are not its points
            raise np.linalg.LinAlgError("the lattice vectors became parallel while indexing the centres")
        inv = np.linalg.inv(basis)
        ata, atp, n_good = _affine_normal_equations(pts, dist, radius, o, inv, tolerance)
        if n_good >= 6:
            sol = np.linalg.lstsq(ata, atp, rcond=None)[0]  # least squares P = o + n v2 + m v1 (good points)
            o, b2, b1 = sol[0], sol[1], sol[2]
        if radius >= span:
            break
        radius *= 2.0
    f = _lattice_coords(pts, o, b1, b2)
    r = np.round(f)
    ok = np.maximum(np.abs(f[:, 0] - r[:, 0]), np.abs(f[:, 1] - r[:, 1])) < tolerance
    return r.astype(np.int64), ok, np.stack([o, b1, b2])


def _affine_normal_equations(pts: np.ndarray, dist: np.ndarray, radius: float, o: np.ndarray, inv: np.ndarray,
                             tol: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Normal equations of the affine lattice fit over the points within ``radius`` whose
    fractional lattice coordinates ``inv @ (p - o)`` are within ``tol`` of integers ``(n, m)``:
    ``A^T A`` (3, 3) and ``A^T P`` (3, 2) with rows ``A = [1, n, m]``, and the number of points."""
    near = pts[dist <= radius]
    f = (near - o) @ inv.T                      # fractional (n, m)
    nm = np.round(f)
    good = np.all(np.abs(f - nm) < tol, axis=1)
    a = np.concatenate([np.ones((int(good.sum()), 1)), nm[good]], axis=1)
    return a.T @ a, a.T @ near[good], int(good.sum())


def _lattice_coords(pts: np.ndarray, o: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Fractional ``(n, m)`` of points in the affine lattice ``o + m b1 + n b2``, shape (N, 2)."""
    inv = np.linalg.inv(np.stack([b2, b1], axis=1))  # columns: v2 (n), v1 (m)
    dr, dc = pts[:, 0] - o[0], pts[:, 1] - o[1]
    out = np.empty((len(pts), 2))
    out[:, 0] = inv[0, 0] * dr + inv[0, 1] * dc
    out[:, 1] = inv[1, 0] * dr + inv[1, 1] * dc
    return out


def _dedupe(nm: np.ndarray, ok: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Keep, for each lattice index, only the point nearest its lattice position."""
    idx = np.nonzero(ok)[0]
    if len(idx) == 0:
        return ok
    n, m = nm[idx, 0], nm[idx, 1]
    key = (n - n.min()) * (int(m.max() - m.min()) + 1) + (m - m.min())     # the cell, one integer per (n, m)
    out = np.zeros_like(ok)
    order = np.lexsort((dist[idx], key))        # by cell, then distance; stable: the first point on ties
    first = np.ones(len(order), bool)
    first[1:] = key[order][1:] != key[order][:-1]
    out[idx[order[first]]] = True
    return out


def fit_lattice(points: np.ndarray, v1: np.ndarray, v2: np.ndarray, lattice: str, *,
                fit_mask: np.ndarray | None = None, n_reject: int = 3, k_sigma: float = 4.0) -> LatticeFit:
    """Robust least-squares fit of the lenslet lattice model to detected centres.

    Parameters
    ----------
    points : ndarray (N, 2) float64
        Detected centres ``(row, col)``.
    v1, v2 : ndarray (2,)
        Approximate basis (:class:`~plenodecode.calib.centroids.LatticeEstimate`).
    lattice : 'hex' or 'square'
    fit_mask : ndarray (N,) bool, optional
        Points allowed in the least squares (e.g. not at the sensor border, where a lens's
        missing neighbours bias its centre); all points are still indexed.
    n_reject : int
        Rounds of outlier rejection.
    k_sigma : float
        Rejection threshold in robust sigmas of the residual distance.

    Returns
    -------
    LatticeFit

    Raises
    ------
    CalibrationError
        Too few consistent lattice points.
    """
    if lattice not in ("hex", "square"):
        raise ValueError(f"lattice must be 'hex' or 'square', got {lattice!r}")
    pts = np.asarray(points, np.float64)
    try:
        nm, ok, basis = index_points(pts, v1, v2)
    except np.linalg.LinAlgError:
        raise CalibrationError(f"the detected centres do not form a {lattice} lattice; check the lattice type "
                               "(--lattice; auto detects it)") from None
    o, b1, b2 = basis
    pred = o + nm[:, 1:2] * b1 + nm[:, 0:1] * b2
    dist = np.hypot(*(pts - pred).T)
    pitch0 = float(np.hypot(*b1))
    ok &= dist < 0.25 * pitch0
    ok = _dedupe(nm, ok, dist)
    use = ok & (fit_mask if fit_mask is not None else True)
    if use.sum() < 6:
        raise CalibrationError(f"only {int(use.sum())} detected centres fit a {lattice} lattice; expected "
                               "hundreds: check the lattice type (--lattice) and that this is a white image")
    s = 0.5 if lattice == "hex" else 0.0
    theta0 = math.atan2(b1[0], b1[1])
    e_row0 = np.array([math.cos(theta0), -math.sin(theta0)])
    rs0 = float(abs(b2 @ e_row0))
    # (n, m) = (0, 0) is the affine fit's origin; b2 = rs e_row + s p e_col
    x0 = np.array([o[0], o[1], theta0, pitch0, rs0])
    n = nm[:, 0].astype(np.float64)
    m = nm[:, 1].astype(np.float64)
    x, w, res, d, sigma = _robust_fit(x0, s, pts, n, m, use, n_reject=n_reject, k_sigma=k_sigma)
    inl = w
    rms = float(np.sqrt(np.mean(d[inl] ** 2))) if inl.any() else float("nan")
    theta = float(x[2])
    fit = LatticeFit(lattice=lattice, pitch=float(x[3]), row_spacing=float(x[4]), rotation=theta,
                     origin=np.array(x[:2]), shift=s, indices=nm, inlier=inl, residuals=res, rms=rms,
                     sigma=sigma, stats={"n_points": int(len(pts)), "n_indexed": int(ok.sum()),
                                         "n_fit": int(inl.sum())})
    log.debug("lattice fit: %s pitch %.5f rs %.5f rot %.6f rms %.4f (%d of %d points)", lattice, fit.pitch,
              fit.row_spacing, theta, rms, inl.sum(), len(pts))
    return fit


def lens_block(fit: LatticeFit, sensor_shape: tuple[int, int]) -> tuple[int, int, int, int, float, np.ndarray]:
    """The smallest block of lens rows x columns holding every lens whose centre is on the sensor.

    "On the sensor" means ``-0.5 <= row <= H - 0.5`` and likewise for col (pixel edges).

    Returns
    -------
    n0, rows, m0_even, cols : int
        First lattice row ``n0`` and the block size; ``m0_even`` is the ``m`` index of lens
        ``(0, 0)`` of the block (on lattice row ``n0``).
    odd_row_shift : float
        Shift of the block's odd rows in units of pitch (+-0.5, or 0 for square).
    origin : ndarray (2,)
        Sensor position of block lens (0, 0).
    """
    h, w = sensor_shape
    corners = np.array([[-0.5, -0.5], [-0.5, w - 0.5], [h - 0.5, -0.5], [h - 0.5, w - 0.5]])
    e_row, e_col = fit.axes()
    d = corners - fit.origin
    a_c, b_c = d @ e_row, d @ e_col
    n_lo = int(math.floor(a_c.min() / fit.row_spacing)) - 1
    n_hi = int(math.ceil(a_c.max() / fit.row_spacing)) + 1
    b_lo = int(math.floor(b_c.min() / fit.pitch)) - 2
    b_hi = int(math.ceil(b_c.max() / fit.pitch)) + 2
    nn = np.arange(n_lo, n_hi + 1)
    # along-row coordinate in pitch units is k = m + s * n; enumerate k on each row's own offset
    kk = np.arange(b_lo, b_hi + 1)
    N, K = np.meshgrid(nn, kk, indexing="ij")
    frac = (fit.shift * N) % 1.0
    kpos = K + frac  # along-row positions (pitch units) of lenses of row n
    pos = fit.position(N, kpos - fit.shift * N)
    on = (pos[..., 0] >= -0.5) & (pos[..., 0] <= h - 0.5) & (pos[..., 1] >= -0.5) & (pos[..., 1] <= w - 0.5)
    if not on.any():
        raise CalibrationError("the fitted lattice has no lens on the sensor; the fit failed")
    rows_on = np.nonzero(on.any(axis=1))[0]
    n0 = int(nn[rows_on[0]])
    n1 = int(nn[rows_on[-1]])
    par = (N - n0) % 2
    kmin_even = float(kpos[on & (par == 0)].min())
    kmax_even = float(kpos[on & (par == 0)].max())
    if (on & (par == 1)).any():
        kmin_odd = float(kpos[on & (par == 1)].min())
        kmax_odd = float(kpos[on & (par == 1)].max())
    else:
        kmin_odd, kmax_odd = kmin_even + fit.shift, kmax_even + fit.shift
    best = None
    shifts = (0.5, -0.5) if fit.lattice == "hex" else (0.0,)
    for sh in shifts:
        # start of even rows k0 (same class as kmin_even), odd rows start at k0 + sh
        need = min(kmin_even, kmin_odd - sh)
        k0 = kmin_even - math.ceil(kmin_even - need - 1e-9)
        cols = int(round(max(kmax_even - k0, kmax_odd - (k0 + sh)))) + 1
        if best is None or cols < best[0]:
            best = (cols, sh, k0)
    cols, sh, k0 = best  # type: ignore[misc]
    m0 = int(round(k0 - fit.shift * n0))
    origin = fit.position(np.array(n0), np.array(m0))
    return n0, n1 - n0 + 1, m0, cols, sh, origin


def block_index(fit: LatticeFit, nm: np.ndarray, n0: int, m0: int, odd_row_shift: float) -> np.ndarray:
    """Grid ``(i, j)`` of lattice indices ``(n, m)`` in the block of :func:`lens_block`."""
    n, m = nm[:, 0], nm[:, 1]
    i = n - n0
    k = (m + fit.shift * n) - (m0 + fit.shift * n0)  # along-row offset from lens (0, 0), pitch units
    j = np.round(k - odd_row_shift * (i % 2)).astype(np.int64)
    return np.stack([i, j], axis=1)


def smooth_deviations(grid_shape: tuple[int, int], ij: np.ndarray, residuals: np.ndarray, sigma: float, *,
                      window: int = 5, min_px: float = 0.1, k_sigma: float = 5.0) -> np.ndarray:
    """Per-lens centre deviations from the lattice that are significant (lens distortion).

    Residuals of the measured centres are averaged over a ``window x window`` block of lenses
    (NaN-aware) so that noise averages out while a smooth distortion stays; a lens keeps the
    averaged deviation only where its magnitude exceeds ``max(min_px, k_sigma * s / sqrt(count))``
    with ``s`` the smaller of ``sigma`` and the robust scatter of the residuals about their
    local mean (the measurement noise).

    Parameters
    ----------
    grid_shape : (rows, cols)
    ij : ndarray (N, 2) int
        Grid indices of the measured lenses.
    residuals : ndarray (N, 2) float64
        Measured minus lattice position, px.
    sigma : float
        Per-axis measurement noise, px.

    Returns
    -------
    ndarray (rows, cols, 2) float64
        Deviation to add to the lattice position; NaN where not significant.
    """
    rows, cols = grid_shape
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < rows) & (ij[:, 1] >= 0) & (ij[:, 1] < cols)
    ij, residuals = ij[inside], residuals[inside]
    acc = np.zeros((rows, cols, 2))
    cnt = np.zeros((rows, cols))
    acc[ij[:, 0], ij[:, 1]] = residuals
    cnt[ij[:, 0], ij[:, 1]] = 1.0
    size = (window, window)
    n = ndimage.uniform_filter(cnt, size, mode="constant") * window * window
    mean = np.stack([ndimage.uniform_filter(acc[..., c], size, mode="constant") for c in range(2)], -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = mean * (window * window) / n[..., None]
    # the scatter of the residuals about their local mean is the measurement noise; the fit's own
    # sigma also holds the distortion we are looking for, so it is only an upper bound
    local = mean[ij[:, 0], ij[:, 1]]
    ok = np.isfinite(local[:, 0])
    if ok.sum() >= 9:
        noise = float(np.median(np.hypot(*(residuals[ok] - local[ok]).T)) / 1.1774)
        sigma = min(sigma, noise) if np.isfinite(sigma) else noise
    thr = np.maximum(min_px, k_sigma * sigma / np.sqrt(np.maximum(n, 1)))
    sig = (n >= max(3, window)) & (np.hypot(mean[..., 0], mean[..., 1]) > thr)
    out = np.full((rows, cols, 2), np.nan)
    out[sig] = mean[sig]
    return out


def refit_grid(grid: LensletGrid, points: np.ndarray, *, max_shift: float = 0.3, n_reject: int = 3,
               k_sigma: float = 4.0) -> LensletGrid:
    """Re-fit origin, rotation, pitch and row spacing of an existing grid to measured centres.

    Each point is assigned to the nearest lens ``(i, j)`` of ``grid`` (kept when within
    ``max_shift * pitch``), so shape, lens indices and ``lens_type`` stay as they are; the model
    ``P(i, j) = origin + i rs e_row + (j + shift (i mod 2)) p e_col`` is fitted by robust
    Gauss-Newton (written as ``n = i``, ``m = j - 2 shift floor(i / 2)``).

    Parameters
    ----------
    grid : LensletGrid
    points : ndarray (N, 2)
        Measured centres, sensor ``(row, col)``.

    Returns
    -------
    LensletGrid
        ``refined`` is dropped; ``info['refit']`` holds the points used and parameter changes.

    Raises
    ------
    CalibrationError
        Fewer than 10 points near the grid's lenses.
    """
    pts = np.asarray(points, np.float64)
    a, b = grid.sensor_to_lattice(pts)
    i = np.round(a / grid.row_spacing)
    j = np.round(b / grid.pitch - grid.odd_row_shift * np.mod(i, 2))
    s = float(grid.odd_row_shift)
    n = i
    m = j - 2 * s * np.floor(i / 2)
    x0 = np.array([grid.origin[0], grid.origin[1], grid.rotation, grid.pitch, grid.row_spacing])
    d0 = np.hypot(*(pts - _model(x0, s, n, m)).T) if len(pts) else np.zeros(0)
    use = d0 < max_shift * grid.pitch
    if use.sum() < 10:
        raise CalibrationError(f"only {int(use.sum())} lenslet disks found near the given grid; expected "
                               "hundreds: the grid does not match the image")
    x, inl, res, d, sigma = _robust_fit(x0, s, pts, n, m, use, n_reject=n_reject, k_sigma=k_sigma)
    rms = float(np.sqrt(np.mean(d[inl] ** 2)))
    change = {"origin_px": [float(x[0] - x0[0]), float(x[1] - x0[1])], "rotation_rad": float(x[2] - x0[2]),
              "pitch_px": float(x[3] - x0[3]), "row_spacing_px": float(x[4] - x0[4])}
    info = {**dict(grid.info), "refit": {"n_points": int(inl.sum()), "rms_px": rms, "sigma_px": sigma,
                                         "change": change}}
    log.debug("grid refit on %d disks: %s", inl.sum(), change)
    return grid.replace(origin=(float(x[0]), float(x[1])), rotation=float(x[2]), pitch=float(x[3]),
                        row_spacing=float(x[4]), refined=None, residual_rms=rms, info=info)


def _explained_deviations(fit: "LatticeFit", ij: np.ndarray, inliers: np.ndarray, grid_shape: tuple[int, int],
                          window: int, measured: np.ndarray, k_sigma: float = 4.0, rounds: int = 10) -> np.ndarray:
    """:func:`smooth_deviations` of the inliers, then also of the lenses the rigid lattice's cut rejected but the
    smooth deviations explain (within ``k_sigma`` of the fit's sigma), until no more join (at most ``rounds``).

    A smooth distortion of the lens array's image (a microscope's relay lens) grows toward the corners past the
    lattice fit's cut (the ant-leg radiometry frame: 60 of a corner's 108 lenses, 1.5-2.5 px off the lattice), so
    those lenses would keep their lattice position; a corner's lenses are explained once their neighbours are in.

    Returns
    -------
    ndarray (rows, cols, 2) float64, NaN where not significant.
    """
    rows, cols = grid_shape
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < rows) & (ij[:, 1] >= 0) & (ij[:, 1] < cols)
    spare = np.flatnonzero(measured & inside & ~fit.inlier & (np.hypot(*fit.residuals.T) < 0.25 * fit.pitch))
    use = inliers.copy()
    for _ in range(rounds):
        dev = smooth_deviations(grid_shape, ij[use], fit.residuals[use], fit.sigma, window=window)
        at = dev[ij[spare, 0], ij[spare, 1]]
        near = np.isfinite(at[:, 0]) & (np.hypot(*(fit.residuals[spare] - at).T) < k_sigma * fit.sigma)
        if not near.any():
            break
        use[spare[near]] = True
        spare = spare[~near]
    return dev


def grid_from_fit(fit: LatticeFit, points: np.ndarray, sensor_shape: tuple[int, int], *,
                  measured_mask: np.ndarray | None = None, radius: float | None = None,
                  refine: bool = True, refine_window: int = 5, info: dict[str, Any] | None = None) -> LensletGrid:
    """Build the :class:`LensletGrid` covering the sensor from a lattice fit.

    Parameters
    ----------
    fit : LatticeFit
    points : ndarray (N, 2)
        The points given to :func:`fit_lattice`.
    sensor_shape : (H, W)
    measured_mask : ndarray (N,) bool, optional
        Points trusted for per-lens refinement (default: the fit's inliers).
    radius : float, optional
        Useful disk radius (default ``0.46 * pitch``).
    refine : bool
        Keep significant smoothed deviations as ``refined`` centres.
    refine_window : int
        Side, in lenses, of the block the deviations are averaged over (:func:`smooth_deviations`).
    info : dict, optional
        Provenance merged into ``grid.info``.

    Returns
    -------
    LensletGrid
    """
    n0, rows, m0, cols, sh, origin = lens_block(fit, sensor_shape)
    ij = block_index(fit, fit.indices, n0, m0, sh)
    mask = fit.inlier if measured_mask is None else (measured_mask & fit.inlier)
    refined = None
    n_ref = 0
    if refine and mask.sum() >= 9:
        dev = _explained_deviations(fit, ij, mask, (rows, cols), refine_window,
                                    fit.indices[:, 0] == fit.indices[:, 0] if measured_mask is None else measured_mask)
        n_ref = int(np.isfinite(dev[..., 0]).sum())
        if n_ref:
            grid0 = LensletGrid(lattice=fit.lattice, pitch=fit.pitch, row_spacing=fit.row_spacing,
                                rotation=fit.rotation, origin=(origin[0], origin[1]), shape=(rows, cols),
                                odd_row_shift=sh, sensor_shape=sensor_shape, radius=1.0)
            refined = grid0.lattice_centres() + dev
    inside = mask & (ij[:, 0] >= 0) & (ij[:, 0] < rows) & (ij[:, 1] >= 0) & (ij[:, 1] < cols)
    detected = np.zeros((rows, cols), bool)
    detected[ij[inside, 0], ij[inside, 1]] = True
    stats = residual_statistics(fit.residuals[mask], fit.indices[mask])
    meta = dict(info or {})
    meta.update({
        "fit_local_misfit_px": stats["local_misfit_px"],
        "n_lenses": int(rows * cols),
        "n_detected": int(fit.stats.get("n_points", len(points))),
        "n_fit": int(fit.inlier.sum()),
        "n_refined": n_ref,
        "fit_rms_px": fit.rms,
        "fit_sigma_px": fit.sigma,
    })
    return LensletGrid(
        lattice=fit.lattice, pitch=fit.pitch, row_spacing=fit.row_spacing, rotation=fit.rotation,
        origin=(float(origin[0]), float(origin[1])), shape=(rows, cols), odd_row_shift=sh,
        sensor_shape=(int(sensor_shape[0]), int(sensor_shape[1])),
        radius=float(radius if radius is not None else 0.46 * fit.pitch),
        refined=refined, residual_rms=fit.rms, info=meta,
    )


def grid_from_points(points: np.ndarray, est: "LatticeEstimate", sensor_shape: tuple[int, int], *,
                     scale: float = 1.0, shift: float = 0.0, refine: bool = True, refine_window: int = 5,
                     info: dict[str, Any] | None = None) -> LensletGrid:
    """Robust lattice fit of measured disk centres and the grid covering the sensor.

    Parameters
    ----------
    points : ndarray (N, 2) float64
        Measured centres in image pixels; sensor position = ``scale * p + shift``.
    est : LatticeEstimate
        Lattice vectors in image pixels (:func:`~plenodecode.calib.centroids.estimate_lattice_vectors`).
    sensor_shape : (H, W)
    scale, shift : float
        2 and 0.5 for a 2x2-binned image, else 1 and 0.
    refine, refine_window : see :func:`plenodecode.calib.white.calibrate_image`.
    info : dict, optional
        Provenance stored in ``grid.info``.

    Returns
    -------
    LensletGrid

    Raises
    ------
    CalibrationError
        Fewer than ~5 % of the lenses on the fitted lattice, or an RMS residual above a quarter pitch.
    """
    pts = np.asarray(points, np.float64) * scale + shift
    H, W = sensor_shape
    pitch_s = est.pitch * scale
    # a lens within ~one pitch of the border misses neighbours inside the estimator's window
    edge = 1.0 * pitch_s
    away = (pts[:, 0] > edge) & (pts[:, 1] > edge) & (pts[:, 0] < H - 1 - edge) & (pts[:, 1] < W - 1 - edge)
    fit = fit_lattice(pts, est.v1 * scale, est.v2 * scale, est.lattice, fit_mask=away)
    meta = dict(info or {})
    meta.update({"autocorrelation_score": est.score})
    grid = grid_from_fit(fit, pts, (H, W), measured_mask=away, refine=refine, refine_window=refine_window,
                         info=meta)
    n_on = grid.info["n_lenses"]
    frac = fit.inlier.sum() / max(1, n_on)
    if fit.inlier.sum() < max(6, 0.05 * n_on):
        raise CalibrationError(f"only {int(fit.inlier.sum())} of ~{n_on} lenses were found on the fitted lattice; "
                               "expected a white image with visible lenslet disks")
    if fit.rms > 0.25 * fit.pitch:
        raise CalibrationError(f"the lattice fit is poor (RMS residual {fit.rms:.2f} px at pitch {fit.pitch:.2f} px); "
                               "expected a regular lenslet pattern")
    n_inner = inner_lens_count(grid)
    found = int((fit.inlier & away).sum())
    return grid.replace(info={**grid.info, "fraction_fit": float(frac), "n_lenses_inner": n_inner,
                              "fraction_found": float(min(1.0, found / max(1, n_inner)))})


__all__ = ["SOURCE_KINDS", "MISFIT_BLOCK", "residual_statistics", "inner_lens_count", "LatticeFit", "index_points", "fit_lattice", "refit_grid", "lens_block", "block_index", "smooth_deviations",
           "grid_from_fit", "grid_from_points"]
