"""Depth from light fields: disparity with confidence, metric depth, benchmark scores.

>>> from plenodecode.io.hci import read_hci                        # doctest: +SKIP
>>> scene = read_hci("../shared/data/hci-antinous")                # doctest: +SKIP
>>> dm = estimate_depth(scene.lightfield)                          # doctest: +SKIP
>>> badpix(dm.disparity, scene.disparity), mse100(dm.disparity, scene.disparity)   # doctest: +SKIP
>>> z = disparity_to_depth(dm, scene.lightfield)                   # metres       # doctest: +SKIP

Methods (:data:`DEPTH_METHODS`, :mod:`plenodecode.depth.methods`):

* ``'costvolume'`` (default, accurate) and ``'fast'``: presets of one pipeline
  (:mod:`plenodecode.depth.pipeline`): occlusion-aware multi-view cost volume, semi-global edge-aware
  aggregation, weighted-median clean-up, sub-label refinement, occlusion-edge pass; ``'fast'`` on the star
  of views through the centre with coarser labels and 4 aggregation paths.
* ``'focus'``: depth from focus over a focal stack (:mod:`plenodecode.depth.focus`).

Modules, one per stage, each importing only the ones before it: ``views`` (matching-ready views) <- ``cost``
(labels, half-plane cost volume) <- ``aggregation`` (SGM, winner-take-all) <- ``refinement`` (weighted
median, sub-label refinement) <- ``occlusion`` (depth-edge pass) <- ``pipeline`` (parameters, disparity
range, :func:`~plenodecode.depth.pipeline.run_pipeline`) <- ``methods`` (presets, registry) and ``focus``.
``metric`` converts disparity to metric depth; ``scores`` holds the benchmark's BadPix and MSE.

Disparity is in spatial samples per view step with the HCI sign of design.md:
``view[v, u](y - d (v - vc), x - d (u - uc)) = centre(y, x)``.
"""

from __future__ import annotations

from .methods import DEFAULT_METHOD, DEPTH_METHODS, DepthMap, estimate_depth
from .metric import disparity_to_depth
from .scores import badpix, mse100

__all__ = ["estimate_depth", "disparity_to_depth", "DEPTH_METHODS", "DEFAULT_METHOD", "DepthMap", "badpix", "mse100"]
