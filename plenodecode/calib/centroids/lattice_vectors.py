"""Pitch, orientation and hex/square type of a lenslet lattice from the autocorrelation of a central crop.

The autocorrelation of a periodic image (Wiener-Khinchin: inverse FFT of the power spectrum) peaks
at every lattice vector, so no metadata hint is needed (:func:`estimate_lattice_vectors`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ...errors import CalibrationError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LatticeEstimate:
    """Coarse lattice found in the autocorrelation.

    Attributes
    ----------
    lattice : 'hex' or 'square'
    pitch : float
        Nearest-neighbour distance, px.
    rotation : float
        Angle of the lens rows from +col, rad, in [-pi/4, 3pi/4).
    v1, v2 : ndarray (2,) float64
        Lattice basis (row, col): ``v1`` along a lens row, ``v2`` to the next row (for hex the
        neighbour shifted by +pitch/2 along the row).
    score : float
        Normalised autocorrelation at the nearest-neighbour peaks (1 = perfect periodicity).
    """

    lattice: str
    pitch: float
    rotation: float
    v1: np.ndarray
    v2: np.ndarray
    score: float


#: Smallest normalised autocorrelation at the neighbour peaks accepted as a lattice (white and scene
#: raws of every simulated camera and the real F01, microscope and Raytrix images give 0.83-0.995).
MIN_LATTICE_SCORE = 0.2


def _autocorrelation(img: np.ndarray) -> np.ndarray:
    """Normalised, fftshifted autocorrelation of a Hann-windowed zero-mean image (float64)."""
    a = img.astype(np.float64)
    a = a - a.mean()
    wy = np.hanning(a.shape[0])[:, None]
    wx = np.hanning(a.shape[1])[None, :]
    a = a * wy * wx
    f = np.fft.rfft2(a, s=(2 * a.shape[0], 2 * a.shape[1]))  # zero-padded: linear, not circular
    ac = np.fft.irfft2(np.abs(f) ** 2, s=(2 * a.shape[0], 2 * a.shape[1]))
    # normalise by the overlap of the window with itself so that far lags are not damped; the
    # window is separable, so its autocorrelation is the outer product of two 1-D ones
    def acf_1d(v: np.ndarray) -> np.ndarray:
        f1 = np.fft.rfft(v, 2 * len(v))
        return np.fft.fftshift(np.fft.irfft(np.abs(f1) ** 2, 2 * len(v)))
    ac = np.fft.fftshift(ac)
    norm = acf_1d(wy[:, 0])[:, None] * acf_1d(wx[0])[None, :]
    cy, cx = a.shape[0], a.shape[1]
    ac = ac / np.maximum(norm, norm[cy, cx] * 0.05)
    return ac / ac[cy, cx]


def _subpixel_peak(ac: np.ndarray, r: int, c: int) -> tuple[float, float]:
    """Parabolic sub-pixel refinement of a local maximum of a 2-D array (separable 3-point fits)."""
    def vertex(m1: float, m0: float, p1: float) -> float:
        den = m1 - 2 * m0 + p1
        return 0.0 if den >= 0 else max(-0.5, min(0.5, float(0.5 * (m1 - p1) / den)))
    return (r + vertex(ac[r - 1, c], ac[r, c], ac[r + 1, c]),
            c + vertex(ac[r, c - 1], ac[r, c], ac[r, c + 1]))


def _wrap_angle(theta: float) -> float:
    """Angle of an undirected line, wrapped into [-pi/4, 3pi/4)."""
    return (theta + math.pi / 4) % math.pi - math.pi / 4


def estimate_lattice_vectors(img: np.ndarray, *, pitch_hint: float | None = None, lattice: str = "auto",
                             crop: int = 512) -> LatticeEstimate:
    """Pitch, orientation and type of a lenslet lattice from the autocorrelation of a central crop.

    The autocorrelation of a periodic image peaks at every lattice vector (Wiener-Khinchin).
    The nearest of its strong off-centre peaks (at least half the strongest; weak maxima sit in the
    gaps between disks) is a nearest neighbour, and the strong peaks at the same distance give the
    6 (hex) or 4 (square) neighbour directions.  All peaks within 6 lattice steps are then indexed
    and a least-squares fit gives the basis to ~0.01 px.

    Parameters
    ----------
    img : ndarray, shape (H, W), float32
        Flattened image (:func:`flatten_white`).
    pitch_hint : float, optional
        Expected pitch in px of ``img``; only used to break ties (peaks near it are preferred).
    lattice : 'auto', 'hex' or 'square'
    crop : int
        Side of the central crop analysed.

    Returns
    -------
    LatticeEstimate

    Raises
    ------
    CalibrationError
        No periodic structure (uniform, dark or random image).
    """
    if lattice not in ("auto", "hex", "square"):
        raise ValueError(f"lattice must be 'auto', 'hex' or 'square', got {lattice!r}")
    h, w = img.shape
    s_r, s_c = min(h, crop), min(w, crop)
    r0, c0 = (h - s_r) // 2, (w - s_c) // 2
    sub = img[r0:r0 + s_r, c0:c0 + s_c]
    if float(sub.std()) <= 1e-6 * max(1e-12, float(np.abs(sub).mean())) or float(sub.std()) == 0.0:
        raise CalibrationError("the image is uniform (no lenslet pattern): expected a white image showing "
                               "the lenslet disks; check the file and its exposure")
    ac = _autocorrelation(sub)
    cy, cx = s_r, s_c
    rmax = min(s_r, s_c) // 3
    win = ac[cy - rmax:cy + rmax + 1, cx - rmax:cx + rmax + 1].astype(np.float32)
    dil = cv2.dilate(win, np.ones((3, 3), np.uint8))
    yy, xx = np.nonzero((win >= dil) & (win > 0.05))
    dy, dx = yy - rmax, xx - rmax
    dist = np.hypot(dy, dx)
    keep = (dist >= 2.5) & (yy > 0) & (xx > 0) & (yy < win.shape[0] - 1) & (xx < win.shape[1] - 1)
    yy, xx, dist = yy[keep], xx[keep], dist[keep]
    if len(dist) < 4:
        raise CalibrationError("no periodic lenslet pattern found in the image centre (autocorrelation "
                               "has no peaks): expected a white image of a plenoptic camera")
    vals = win[yy, xx]
    # nearest neighbours: the closest of the strong peaks (weak local maxima sit in the gaps
    # between disks, e.g. at pitch / sqrt(3) in a hex lattice)
    strong = vals >= 0.5 * vals.max()
    if pitch_hint:
        near_hint = strong & (np.abs(dist - pitch_hint) < 0.2 * pitch_hint)
        d1 = float(dist[near_hint].min()) if near_hint.any() else float(dist[strong].min())
    else:
        d1 = float(dist[strong].min())
    nn = strong & (np.abs(dist - d1) < 0.15 * d1)
    if nn.sum() < 4:
        raise CalibrationError(f"the autocorrelation shows no 2-D lattice (only {int(nn.sum())} neighbour "
                               "peaks): expected a hexagonal or square lenslet pattern")
    vecs = np.array([_subpixel_peak(win, y, x) for y, x in zip(yy[nn], xx[nn])]) - rmax
    angles = np.array([_wrap_angle(math.atan2(v[0], v[1])) for v in vecs])
    # group the neighbour directions modulo pi
    dirs: list[float] = []
    for a in np.sort(angles):
        if not dirs or min(abs(((a - d + math.pi / 2) % math.pi) - math.pi / 2) for d in dirs) > 0.2:
            dirs.append(float(a))
    if lattice == "auto":
        kind = "hex" if len(dirs) >= 3 else "square"
    else:
        kind = lattice
    # the row direction: the neighbour direction closest to an axis (0 or pi/2), preferring 0
    def axis_dist(a: float) -> float:
        return min(abs(a), abs(a - math.pi / 2)) + (0.0 if abs(a) <= math.pi / 4 else 1e-3)
    theta = min(dirs, key=axis_dist)
    if kind == "square" and abs(theta) > math.pi / 4:
        theta = _wrap_angle(theta - math.pi / 2)
    pitch = float(np.median(np.hypot(vecs[:, 0], vecs[:, 1])))
    e_col = np.array([math.sin(theta), math.cos(theta)])
    e_row = np.array([math.cos(theta), -math.sin(theta)])
    v1 = pitch * e_col
    v2 = (pitch * math.sqrt(3) / 2) * e_row + 0.5 * pitch * e_col if kind == "hex" else pitch * e_row
    # refine (v1, v2) on all autocorrelation peaks within a few pitches
    B = np.stack([v1, v2], axis=1)
    allv = np.array([dy, dx], np.float64).T[keep]
    mn = np.linalg.solve(B, allv.T).T
    mn_r = np.round(mn)
    ok = (np.abs(mn - mn_r).max(axis=1) < 0.15) & (np.abs(mn_r).max(axis=1) <= 6) & (win[yy, xx] > 0.2)
    if ok.sum() >= 4:
        pts = np.array([_subpixel_peak(win, y, x) for y, x in zip(yy[ok], xx[ok])]) - rmax
        sol, *_ = np.linalg.lstsq(mn_r[ok], pts, rcond=None)
        v1, v2 = sol[0], sol[1]
        pitch = float(np.hypot(*v1))
        theta = _wrap_angle(math.atan2(v1[0], v1[1]))
    score = float(np.median(vals[nn]))
    if score < MIN_LATTICE_SCORE:
        raise CalibrationError(f"no regular lenslet pattern: the autocorrelation's neighbour peaks reach only "
                               f"{score:.2f} (a lenslet image gives > 0.8, noise ~0.05); expected a white image or "
                               "a raw of a plenoptic camera")
    log.debug("autocorrelation lattice: %s pitch %.4f px rotation %.5f rad score %.2f", kind, pitch, theta, score)
    return LatticeEstimate(kind, pitch, theta, np.asarray(v1, float), np.asarray(v2, float), score)
