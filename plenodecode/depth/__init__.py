"""Depth from light fields: disparity with confidence, metric depth, benchmark metrics.

>>> from plenodecode.io.hci import read_hci                        # doctest: +SKIP
>>> scene = read_hci("../shared/data/hci-antinous")                # doctest: +SKIP
>>> dm = estimate_depth(scene.lightfield)                          # doctest: +SKIP
>>> badpix(dm.disparity, scene.disparity), mse100(dm.disparity, scene.disparity)   # doctest: +SKIP
>>> z = disparity_to_depth(dm, scene.lightfield)                   # metres       # doctest: +SKIP

Methods (:data:`DEPTH_METHODS`):

* ``'costvolume'`` (default, accurate): occlusion-aware multi-view cost volume, semi-global edge-aware
  aggregation, sub-label refinement, weighted-median clean-up (:mod:`plenodecode.depth.costvolume`).
* ``'fast'``: the same building blocks on a subset of views, coarser labels and 4 aggregation paths
  (:mod:`plenodecode.depth.fast`).

Disparity is in spatial samples per view step with the HCI sign of design.md:
``view[v, u](y - d (v - vc), x - d (u - uc)) = centre(y, x)``.
"""

from __future__ import annotations

import importlib
import logging
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from ..types import LightField
from .metric import disparity_to_depth
from .metrics import badpix, mse100

log = logging.getLogger(__name__)

#: method name -> module implementing ``estimate(lf, *, progress=None, **kw) -> (disparity, confidence, params)``
DEPTH_METHODS: dict[str, str] = {
    "costvolume": "plenodecode.depth.costvolume",
    "fast": "plenodecode.depth.fast",
}
#: The method :func:`estimate_depth` uses when none is given.
DEFAULT_METHOD = "costvolume"


@dataclass(frozen=True)
class DepthMap:
    """Disparity of the centre view with its confidence.

    Attributes
    ----------
    disparity : ndarray (Y, X) float32
        px per view step, HCI sign convention (positive = closer than the focus plane).
    confidence : ndarray (Y, X) float32 in [0, 1]
        1 = unambiguous match, 0 = no information.
    method : str
        Key of :data:`DEPTH_METHODS`.
    params : dict
        Parameters used (defaults included), the disparity range and its source, and ``seconds``.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    method: str
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.disparity.ndim != 2 or self.disparity.dtype != np.float32:
            raise ValueError(f"disparity must be a 2-D float32 array, got {self.disparity.dtype} {self.disparity.shape}")
        if self.confidence.shape != self.disparity.shape or self.confidence.dtype != np.float32:
            raise ValueError(f"confidence must be float32 of shape {self.disparity.shape}, got "
                             f"{self.confidence.dtype} {self.confidence.shape}")

    @property
    def shape(self) -> tuple[int, int]:
        """``(Y, X)``."""
        return self.disparity.shape  # type: ignore[return-value]


def estimate_depth(lf: LightField, *, method: str = DEFAULT_METHOD,
                   progress: Callable[[int, int], None] | None = None, **kw: Any) -> DepthMap:
    """Estimate the disparity of the centre view of a light field.

    Parameters
    ----------
    lf : LightField
        (V, U, Y, X, C) float32.  ``lf.weight`` (when present) down-weights views; views whose median
        weight is below ``min_view_weight`` (default 0.1) of the centre view's are not used.
    method : str
        A key of :data:`DEPTH_METHODS`.
    progress : callable(done, total), optional
    **kw
        Method parameters (see each module's ``DEFAULTS``), e.g. ``disparity_range=(lo, hi)``; without it
        the range comes from ``lf.metadata['disparity_range']`` (or an HCI scene's disp_min/disp_max), else
        it is estimated by a coarse search.

    Returns
    -------
    DepthMap

    Raises
    ------
    ValueError
        Unknown method (the message lists the names) or parameter.
    DecodeError
        The light field has a single view or an empty centre view.
    """
    if not isinstance(lf, LightField):
        raise ValueError(f"lf must be a LightField, got {type(lf).__name__}")
    if method not in DEPTH_METHODS:
        raise ValueError(f"unknown depth method {method!r}; valid: {', '.join(DEPTH_METHODS)}")
    module = importlib.import_module(DEPTH_METHODS[method])
    t0 = time.perf_counter()
    disparity, confidence, params = module.estimate(lf, progress=progress, **kw)
    seconds = time.perf_counter() - t0
    log.info("depth '%s': %.2f s", method, seconds)
    return DepthMap(disparity=np.ascontiguousarray(disparity, np.float32),
                    confidence=np.ascontiguousarray(confidence, np.float32),
                    method=method, params={**params, "seconds": seconds})


__all__ = ["estimate_depth", "disparity_to_depth", "DEPTH_METHODS", "DEFAULT_METHOD", "DepthMap", "badpix", "mse100"]
