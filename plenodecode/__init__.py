"""plenodecode: plenoptic camera raws to calibrated 4D light fields.

Importing the package is light: the public functions below are loaded on first use.

>>> import plenodecode as pd
>>> raw = pd.read_raw("sample_raws/illum-mini/scene.lfr")      # doctest: +SKIP
>>> grid = pd.calibrate("sample_raws/illum-mini/MOD_0000.RAW")  # doctest: +SKIP
>>> lf = pd.decode(raw, grid)                                   # doctest: +SKIP

The workflow the command line runs (:mod:`plenodecode.pipeline`, :mod:`plenodecode.batch`) is here too:

>>> src = pd.open_source("sample_raws/illum-mini/scene.lfr")               # doctest: +SKIP
>>> pd.write_product(pd.render_product(src, "centre"), "centre.png")     # doctest: +SKIP
>>> pd.run_batch(["sample_raws"], "out", pd.BatchOptions(outputs=("centre",)))  # doctest: +SKIP
"""

from __future__ import annotations

from . import _numba, errors
from .errors import CalibrationError, DecodeError, FormatError, MetadataError, PlenodecodeError
from .registry import lazy_exports
from .types import CameraMetadata, LensletGrid, LightField, RawCapture

__version__ = "0.1.0"

# compiled kernels are cached in the user's cache directory, never inside the installed package
_numba.use_user_cache()

#: public name -> module that defines it (imported on first access)
_LAZY = {
    "read_raw": "plenodecode.io",
    "simulate": "plenodecode.synthetic",
    "calibrate": "plenodecode.calib",
    "calibrate_geometry": "plenodecode.calib.geometry",
    "decode": "plenodecode.decoding",
    "refocus": "plenodecode.render",
    "focal_stack": "plenodecode.render",
    "all_in_focus": "plenodecode.render",
    "perspective": "plenodecode.render",
    "estimate_depth": "plenodecode.depth",
    "disparity_to_depth": "plenodecode.depth",
    "estimate_focused_depth": "plenodecode.depth.focused",
    "save_lightfield": "plenodecode.io.lightfield",
    "load_lightfield": "plenodecode.io.lightfield",
    # the workflow layer both front ends use: any input -> a named product -> its files; a folder of raws
    "open_source": "plenodecode.pipeline",
    "PRODUCTS": "plenodecode.pipeline",
    "render_product": "plenodecode.pipeline",
    "write_product": "plenodecode.pipeline",
    "write_parallax": "plenodecode.pipeline",
    "write_depth": "plenodecode.pipeline",
    "BatchOptions": "plenodecode.batch",
    "run_batch": "plenodecode.batch",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

__all__ = [
    "__version__", "errors", "PlenodecodeError", "FormatError", "MetadataError", "CalibrationError",
    "DecodeError", "CameraMetadata", "RawCapture", "LensletGrid", "LightField", *_LAZY,
]
