"""Decoding: raw lenslet mosaic + LensletGrid -> LightField ``(V, U, Y, X, C)``.

Pipeline (one band of lens rows at a time, bands spread over threads; every step float32):

1. levels per CFA position, or the dark frame pixel by pixel (:mod:`.devignette`);
2. hot-pixel repair (outliers above all same-colour neighbours -> median of the lit ones);
3. devignetting by the white image, with a floor; the weight of every sample comes from the white;
4. demosaicing within each micro-image (:mod:`.demosaic`, ``DEMOSAIC_METHODS``);
5. slicing: every view offset sampled bilinearly under every lens from that lens's own pixels,
   colour matrix applied on the way (:mod:`.slice`, :mod:`.colour`);
6. hex -> rect resampling along the lens rows onto square output pixels (:mod:`.resample`).

Output size (the decoded sampling contract of :mod:`plenodecode.types`)
----------------------------------------------------------------------
With ``p`` the lens pitch in sensor px (``lens_pitch_m / pixel_pitch_m``) and ``H x W`` the sensor:

* views per axis ``N = 2 * floor(p / 2) + 1`` (one view step = one sensor pixel, so the views span
  the lenslet diameter): Illum 20 um / 1.4 um = 14.29 px -> 15 x 15; F01 9.93 px -> 9 x 9
  (``n_views=11`` gives LFToolbox's untrimmed 11 x 11, whose outer ring has low weight);
* ``Y`` = one output row per lens row = the lens rows whose centre lies on the sensor, about
  ``H / row_spacing`` with ``row_spacing = p * sqrt(3) / 2`` on a hex grid: Illum 5368 / 12.37 ->
  434 (435 with some offsets), F01 3280 / 8.60 -> 381-382;
* ``X``: along the rows the output step is also the row spacing (square pixels), over the span that
  even and odd rows both cover, ``(cols - 1.5) * p``: ``X = floor((cols - 1.5) * p / row_spacing) + 1
  = floor((cols - 1.5) * 2 / sqrt(3)) + 1`` with ``cols ~ W / p`` lenses per row: Illum 541 -> 624-625,
  F01 330 -> 380-381;
* square grids (microscopes): ``Y = rows ~ H / p``, ``X = cols ~ W / p`` (2160 x 2592 at 27.5 px -> 79 x 94).

Importing this package is light (no numba, no OpenCV): :func:`decode` (:mod:`.decoder`) and the
compiled steps load on first access; :data:`DEMOSAIC_METHODS` (:mod:`.demosaic`) and ``DECODE_COLOURS``
(:mod:`.colour`) can be read for the CLI's help without them.
"""

from __future__ import annotations

from ..registry import lazy_exports
from .demosaic import DEMOSAIC_METHODS

#: public name -> module that defines it (imported on first access)
_LAZY = {
    "decode": "plenodecode.decoding.decoder",
    "decode_timed": "plenodecode.decoding.decoder",
    "decode_samples": "plenodecode.decoding.decoder",
    "DEFAULT_DEMOSAIC": "plenodecode.decoding.decoder",
    "RESAMPLE_METHODS": "plenodecode.decoding.resample",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = ["decode", "decode_timed", "decode_samples", "DEMOSAIC_METHODS", "RESAMPLE_METHODS", "DEFAULT_DEMOSAIC"]
