"""Refinement of a disparity map: edge-aware weighted median and sub-label refinement.

* :func:`weighted_median`: the clean-up after the winner-take-all, guided by the grey centre view
  (Ma et al., ICCV 2013).
* :func:`refine_disparity`: a narrow second cost volume of offsets around the estimate, every view warped
  per pixel, whose parabolic minimum is added to the estimate: sub-label accuracy without the
  fronto-parallel bias of the label-wise cost volume.
"""

from __future__ import annotations

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


def refine_radius_for(shape: tuple[int, int], radius: int | str) -> int:
    """The box radius of the refinement cost: ``radius`` itself, or for ``'auto'``
    ``clip(round(min(Y, X) / 85), 3, 6)``: the window grows with the image, 13 x 13 on 512 px views,
    7 x 7 below 300 px."""
    if radius == "auto":
        return int(np.clip(round(min(shape) / 85.0), 3, 6))
    return int(radius)


def refine_disparity(views: Views, disparity: np.ndarray, *, half_range: float, samples: int, radius: int,
                     progress: Progress = None) -> np.ndarray:
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

    Returns
    -------
    ndarray (Y, X) float32, a new array.
    """
    deltas = np.linspace(-half_range, half_range, samples)
    fine = half_plane_cost_volume(views, deltas, radius=radius, interpolation=cv2.INTER_CUBIC,
                                  base=disparity, progress=progress)
    offset, _ = winner(fine, deltas)
    return disparity + offset


__all__ = ["weighted_median", "refine_radius_for", "refine_disparity"]
