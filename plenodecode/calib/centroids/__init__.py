"""Lenslet centre detection: Bayer collapse, lattice vectors from the autocorrelation, sub-pixel peaks.

The pipeline a white image goes through (:func:`plenodecode.calib.calibrate`), one module per step
(each imports only the ones before it):

1. :mod:`.flatten` -- :func:`flatten_white`: levels, per-CFA-position gain equalisation (so the Bayer
   pattern of a white image disappears), isolated hot/dead pixel replacement and a centred 3x3
   binomial low-pass whose response is zero at the CFA's Nyquist frequencies; optional 2x2 binning.
2. :mod:`.lattice_vectors` -- :func:`estimate_lattice_vectors`: pitch, orientation and hex/square from
   the peaks of the autocorrelation of a central crop (Wiener-Khinchin: inverse FFT of the power
   spectrum), so no metadata hint is needed.
3. :mod:`.contrast` -- :func:`devignette`: divide by the local-linear mean (:func:`local_mean`), so
   brightness gradients (vignetting, scene) do not bias the centres.
4. :mod:`.peaks` -- :func:`detect_peaks`: integer local maxima of a Gaussian-filtered image (a matched
   filter for the lenslet disk, as LFToolbox [1]_ and PlenoptiCam [3]_ do) with a local-contrast test.
5. :mod:`.subpixel` -- :func:`refine_peaks`: sub-pixel centres by one of :data:`CENTROID_METHODS`
   (default 'dog': Newton iterations on an exactly evaluated, zero-sum difference-of-Gaussians response).

Scene raws (self-calibration, :mod:`plenodecode.calib.selfcal`) locate the disks by their rims
instead (:mod:`.rims`): :func:`rim_gradients`, :func:`rim_votes` (fixed-radius Hough transform [4]_)
and :func:`refine_rims` (circle of known radius fitted to the lit part of each rim).

The hot loops (levels and binning, hot pixels, contrast at the peaks, Newton steps, rim fits) are numba
kernels, parallel over rows or disks; ``bench/bench_calib.py`` times them on full-size sensors against the
library calls they replace (window maxima and the contrast image are OpenCV calls, which were faster).

References
----------
.. [1] D. G. Dansereau, O. Pizarro, S. B. Williams, "Decoding, calibration and rectification for
   lenselet-based plenoptic cameras", CVPR 2013.
.. [2] D. Cho, M. Lee, S. Kim, Y.-W. Tai, "Modeling the calibration pipeline of the Lytro camera for
   high quality light-field image reconstruction", ICCV 2013.
.. [3] C. Hahne, A. Aggoun, "PlenoptiCam v1.0: a light-field imaging framework", IEEE TIP 2021.
.. [4] C. Kimme, D. Ballard, J. Sklansky, "Finding circles by an array of accumulators",
   Communications of the ACM 18(2), 1975 (votes along the gradient direction).
"""

from __future__ import annotations

from .contrast import devignette, local_mean
from .flatten import cfa_gains, fix_hot_pixels, flatten_image, flatten_white
from .lattice_vectors import MIN_LATTICE_SCORE, LatticeEstimate, estimate_lattice_vectors
from .peaks import detect_peaks, detect_peaks_and_filtered, smoothing_sigma, window_contrast, window_maxima
from .rims import RIM_BAND, refine_rims, rim_gradients, rim_votes
from .subpixel import CENTROID_METHODS, NEWTON_TOL, refine_dog, refine_parabolic, refine_peaks

__all__ = [
    "CENTROID_METHODS", "LatticeEstimate", "MIN_LATTICE_SCORE", "NEWTON_TOL", "RIM_BAND",
    "cfa_gains", "fix_hot_pixels", "flatten_white", "flatten_image", "local_mean", "devignette",
    "estimate_lattice_vectors", "smoothing_sigma", "window_maxima", "window_contrast", "detect_peaks",
    "detect_peaks_and_filtered", "refine_peaks", "refine_dog", "refine_parabolic",
    "rim_gradients", "rim_votes", "refine_rims",
]
