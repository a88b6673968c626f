"""The synthetic generator: plenoptic raws with exact ground truth (a physical forward model).

The model is the unfocused plenoptic camera of Ng et al. (2005) and Ng (2006, thesis,
ch. 3): a micro-lens array (MLA) one focal length in front of the sensor, so the pixels
under one lenslet sample the directions of the rays through that lenslet.  The lattice is
:class:`~plenodecode.types.LensletGrid`; the mapping from sensor pixels to light-field
coordinates is the *decoded sampling contract* of :mod:`plenodecode.types`:

* a sensor pixel ``q`` belongs to the lens ``k`` whose centre is nearest (the hexagonal
  or square Voronoi cell), and ``o = (o_a, o_b)`` is its lattice-frame offset from that
  centre in px (= view units, the view step is one sensor pixel);
* lens ``k`` at lattice position ``(A_k, B_k)`` has decoded spatial coordinate
  ``y = (A_k - a0) / step``, ``x = (B_k - b0) / step`` (:meth:`LensletGrid.decoded_sampling`);
* the radiance of that ray is ``L(o, y, x) = T((y + d * o_a, x + d * o_b))`` for the
  front-most scene plane (texture ``T``, disparity ``d`` in decoded px per view step, HCI
  convention) whose support contains the hit point.

A pixel records the mean of ``L`` over its 1 x 1 px box in ``o`` (2 x 2 Gauss-Legendre rule),
times the lenslet's disk response (also box-averaged), the sensor vignetting
(``cos^4`` law) and an exposure scale.  The white image is the same with ``T = 1`` in every
camera channel, so ``(raw - black) / (white - black)`` is the camera-RGB radiance exactly
(noise-free).  Camera RGB is ``diag(1 / wb) @ inv(ccm) @ srgb``, so a decoder applying
``ccm @ diag(wb)`` recovers linear sRGB.  Then Bayer sampling, Poisson-Gaussian noise
(full well, read noise), hot pixels, quantisation and clipping.

The 'raytrix' preset is a focused plenoptic camera (Lumsdaine & Georgiev 2009; Perwass &
Wietzke 2012): each micro-image is a small inverted image of the main lens's virtual
image; see :func:`simulate`.

Modules, each importing only those listed before it: :mod:`.presets` (the simulated cameras),
:mod:`.lattice` (the true lenslet grid, pixel -> lens assignment), :mod:`.kernels` (the compiled
kernels), :mod:`.scene` (planes, textures, radiance), :mod:`.sensor` (disk response,
vignetting, noise, rendering the mosaic), :mod:`.truth` (:class:`Simulation`, ground-truth
files), :mod:`.thin` (thin-structure scenes), :mod:`.archives` (white images in the cameras' calibration
archives), :mod:`.focused` (the focused camera), :mod:`.forward` (:func:`simulate`, :func:`simulate_ideal`,
:func:`simulate_white`), :mod:`.checkerboard` (checkerboard captures with geometric ground truth through
the ray model of :mod:`plenodecode.raymodel`).  Importing the package loads only :mod:`.presets`; the
other names load on first access.
"""

from ..registry import lazy_exports
from .presets import PRESETS, Preset, get_preset

#: public name -> module that defines it (imported on first access: the forward model compiles numba kernels
#: and uses OpenCV, while the presets stay light for the CLI's help)
_LAZY = {
    "SUBSAMPLES": "plenodecode.synthetic.kernels",
    **dict.fromkeys(["assign_pixels", "make_grid", "raytrix_lens_types"], "plenodecode.synthetic.lattice"),
    **dict.fromkeys(["Plane", "Scene", "default_scene", "dot_chart"], "plenodecode.synthetic.scene"),
    **dict.fromkeys(["BAND_ROWS", "disk_profile", "disk_response", "vignetting"], "plenodecode.synthetic.sensor"),
    **dict.fromkeys(["simulate", "simulate_ideal", "simulate_white"], "plenodecode.synthetic.forward"),
    **dict.fromkeys(["Simulation", "Truth", "load_truth", "simulation_files", "truth_document", "write_simulation"],
                    "plenodecode.synthetic.truth"),
    **dict.fromkeys(["THIN_SCENES", "thin_scene"], "plenodecode.synthetic.thin"),
    **dict.fromkeys(["ARCHIVE_KINDS", "WrittenArchive", "write_calibration_archive"], "plenodecode.synthetic.archives"),
    "Board": "plenodecode.raymodel",
    **dict.fromkeys(["board_lightfield", "board_corners", "default_intrinsics", "CheckerboardSet",
                     "simulate_checkerboard_set", "write_checkerboard_set"],
                    "plenodecode.synthetic.checkerboard"),
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = ["Preset", "PRESETS", "get_preset", "make_grid", "raytrix_lens_types", "assign_pixels", "disk_profile",
           "disk_response", "vignetting", "simulate_white", "simulate_ideal", "Simulation", "simulate",
           "write_simulation", "simulation_files", "truth_document", "Truth", "load_truth", "SUBSAMPLES", "BAND_ROWS",
           "Plane", "Scene", "default_scene", "dot_chart", "THIN_SCENES", "thin_scene", "ARCHIVE_KINDS",
           "WrittenArchive", "write_calibration_archive", "Board", "board_lightfield", "board_corners",
           "default_intrinsics", "CheckerboardSet", "simulate_checkerboard_set", "write_checkerboard_set"]
