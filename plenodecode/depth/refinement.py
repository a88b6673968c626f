"""Refinement of a disparity map: edge-aware weighted median and sub-label refinement.

* :func:`weighted_median`: the clean-up after the winner-take-all, guided by the grey centre view
  (Ma et al., ICCV 2013).
* :func:`cost_gate`: a clean-up may not move a pixel to a disparity its matching cost rejects (a median
  across a thin structure would).
* :func:`refine_disparity`: a narrow second cost volume of offsets around the estimate, every view warped
  per pixel, whose parabolic minimum is added to the estimate: sub-label accuracy without the
  fronto-parallel bias of the label-wise cost volume.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from .aggregation import winner
from .cost import Progress, half_plane_cost_volume
from .views import Views


def weighted_median(guide: np.ndarray, disparity: np.ndarray, radius: int, sigma: float = 0.1) -> np.ndarray:
    """Edge-aware weighted median of the disparity (Ma et al., ICCV 2013 via ``cv2.ximgproc``), guided by the
    grey centre view in [0, 1]; ``sigma`` in the guide's units."""
    if radius <= 0:
        return disparity
    g8 = np.clip(np.round(guide * 255.0), 0, 255).astype(np.uint8)
    return cv2.ximgproc.weightedMedianFilter(g8, np.ascontiguousarray(disparity, np.float32), int(radius),
                                              float(sigma * 255.0))


def cost_at(cost: np.ndarray, labels: np.ndarray, disparity: np.ndarray) -> np.ndarray:
    """The cost volume read at a disparity map, linear between labels: (Y, X) float32.

    Parameters
    ----------
    cost : ndarray (Y, X, L) float32
        Labels last.
    labels : ndarray (L,) uniformly spaced
    disparity : ndarray (Y, X)
        Clipped to the labels' range.
    """
    L = len(labels)
    step = (labels[-1] - labels[0]) / (L - 1)
    t = np.clip((np.asarray(disparity, np.float64) - labels[0]) / step, 0.0, L - 1.0)
    k0 = np.minimum(np.floor(t).astype(np.intp), L - 2)
    f = (t - k0).astype(np.float32)
    c0 = np.take_along_axis(cost, k0[..., None], axis=-1)[..., 0]
    c1 = np.take_along_axis(cost, (k0 + 1)[..., None], axis=-1)[..., 0]
    return (c0 * (1.0 - f) + c1 * f).astype(np.float32)


def cost_gate(cost: np.ndarray, labels: np.ndarray, before: np.ndarray, after: np.ndarray, *, ratio: float,
              floor: float | np.ndarray, base: float = 0.0) -> np.ndarray:
    """Undo the changes of a clean-up step that the matching cost contradicts.

    A pixel keeps ``before`` where ``C(after) - base > ratio * max(C(before) - base, 0) + floor``, with ``C``
    the (unaggregated) cost volume read at the map (:func:`cost_at`) and ``base`` the cost noise alone
    leaves (0 on clean views): the views say the new value is clearly worse than the old one.  A median over
    a window that a thin structure (a 1-3 px slat or gap) crosses replaces it by the surface around it, which
    its own pixels match badly; where the views cannot tell the values apart (no texture, noise) ``C`` is
    about equal for both and the clean-up stands.  Regularisation then never
    smooths over an edge the views support, whatever the guide image shows.

    Parameters
    ----------
    cost : ndarray (Y, X, L) float32
        The matching cost, normalised (median per-pixel span 1 in the pipeline).
    labels : ndarray (L,)
    before, after : ndarray (Y, X) float32
        The map before and after the step.
    ratio : float
        How much worse the new value's cost must be (factor).
    floor : float or ndarray (Y, X) float32
        ... plus this absolute margin in cost units (per pixel: the pipeline scales it by each pixel's span).
    base : float
        The cost of views that differ by noise only (cost units), subtracted before the ratio: on noisy views
        it is shared by every label, so a ratio of costs stays near 1 even where the views prefer one value.

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    b = np.float32(base)
    c_before = cost_at(cost, labels, before)
    if b > 0:
        c_before = np.maximum(c_before - b, np.float32(0.0))
    worse = cost_at(cost, labels, after) - b > np.float32(ratio) * c_before + np.asarray(floor, np.float32)
    return np.where(worse, before, after).astype(np.float32)


def refine_radius_for(shape: tuple[int, int], radius: int | str) -> int:
    """The box radius of the refinement cost: ``radius`` itself, or for ``'auto'``
    ``clip(round(min(Y, X) / 85), 3, 6)``: the window grows with the image, 13 x 13 on 512 px views,
    7 x 7 below 300 px."""
    if radius == "auto":
        return int(np.clip(round(min(shape) / 85.0), 3, 6))
    return int(radius)


def refine_disparity(views: Views, disparity: np.ndarray, *, half_range: float, samples: int, radius: int,
                     progress: Progress = None, **strips: Any) -> np.ndarray:
    """Sub-label refinement of a disparity map by a per-pixel cost volume around it.

    The offsets ``delta_k`` are ``samples`` values uniformly spaced over ``[-half_range, half_range]``; the
    cost of an offset is :func:`plenodecode.depth.cost.half_plane_cost_volume` with every view warped per
    pixel by ``d(y, x) + delta_k`` (bicubic, box radius ``radius``), so a slanted surface matches at one
    offset everywhere (the label penalties of SGM favour fronto-parallel steps).  The result is
    ``d + delta*`` with ``delta*`` the parabolic minimum of that cost (:func:`plenodecode.depth.aggregation.winner`).

    Parameters
    ----------
    views : Views
        The matching views.
    disparity : ndarray (Y, X) float32
    half_range : float
        Largest offset searched, px per view step.
    samples : int
        Number of offsets (>= 3).
    radius : int
        Box aggregation radius of the refinement cost.
    progress : callable(done, total), optional
        Called per offset.
    **strips
        ``strips``, ``strip_width``, ``strip_radius``, ``strip_penalty`` of
        :func:`~plenodecode.depth.cost.half_plane_cost_volume`: the oriented strips of views that keep a thin
        structure's offset from being pulled by the occluded background a square box around it holds.

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    deltas = np.linspace(-half_range, half_range, samples)
    fine = half_plane_cost_volume(views, deltas, radius=radius, interpolation=cv2.INTER_CUBIC,
                                  base=disparity, progress=progress, **strips)
    offset, _ = winner(fine, deltas)
    return disparity + offset


__all__ = ["weighted_median", "cost_at", "cost_gate", "refine_radius_for", "refine_disparity"]
