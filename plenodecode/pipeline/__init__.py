"""The workflow both front ends use: open any input, choose the calibration, decode, render a product, write it.

The command line (:mod:`plenodecode.cli`), :mod:`plenodecode.batch` and Python callers go through the same
five steps, each implemented once here::

    open_input(path)          raw file (Lytro container, raw + sidecar, Raytrix image + XML, camera raw, mosaic
                              + sidecar) -> RawCapture; saved light field or HCI scene folder -> LightField
    check_product(item, name) what the products asked of it need from its metadata (alpha, a focus distance,
                              metric depth: the camera constants),
                              refused before the calibration and any decoding (:mod:`.needs`)
    choose_calibration(raw)   explicit grid JSON / white image > the camera's own calibration (Raytrix XML)
                              > the calibration database > self-calibration from the scene (when allowed);
                              the choice is logged in one info line
    Source                    an opened input; a raw is decoded on first use of ``Source.lightfield``
    render_product(src, name) a product of :data:`PRODUCTS` (centre, views, refocus, focal-stack, all-in-focus,
                              parallax, depth, total-focus, focused-refocus) -> :class:`Rendered`
    write_product(r, output)  display encoding, bit depth, file names, atomic rename, overwrite checks

Display encoding (one rule, :func:`display_encoding`): images of a linear light field (colour state
'camera' or 'linear-srgb') get the sRGB transfer function, except 32-bit float outputs, which stay linear;
sRGB-encoded images ('srgb', or camera RGB with the curve, 'camera-srgb-curve') are written as they are.  A
light field saved by ``decode`` / ``export`` stays linear, except as 8-bit views or ESLF
(:func:`stores_display_encoded`).

Importing this module is light (no numba, OpenCV or OpenImageIO): the CLI reads its registries for
``click.Choice`` lists.

The steps live in one module each (:mod:`.inputs`, :mod:`.needs`, :mod:`.calibration`, :mod:`.source`,
:mod:`.products`, :mod:`.output`); this package hands on their public names.
"""

from __future__ import annotations

from .inputs import (LIGHTFIELD_EXTENSIONS, IMAGE_EXTENSIONS, BIT_DEPTHS, INPUT_READERS, input_kind, is_hci_folder,
                     is_lightfield_path, open_input, open_raw, with_optics, read_dark_frame)
from .needs import REQUESTS, check_product
from .calibration import Calibration, choose_calibration
from .source import Source, check_geometry, decode_raw, load_lightfield_input, open_source
from .products import (MAX_STACK_SLICES, PRODUCTS, STACK_UNITS, Rendered, virtual_depth_stem, render_product,
                       check_total_focus_patch, view_names, refocus_stem, focal_stack_names, parallax_frame_names)
from .output import (AUTO_EXPOSURE, DARK_LEVEL, check_exposure, dark_note, display_encoding, default_extension, expose,
                     exposure_gain, image_level, stores_display_encoded,
                     write_image_file, refuse_folder_clash, staged_folder,
                     write_product, write_parallax, write_depth, write_lightfield)

__all__ = [
    "LIGHTFIELD_EXTENSIONS", "IMAGE_EXTENSIONS", "BIT_DEPTHS", "MAX_STACK_SLICES", "INPUT_READERS", "PRODUCTS",
    "STACK_UNITS", "REQUESTS", "Calibration", "Source", "Rendered", "input_kind", "is_hci_folder", "is_lightfield_path",
    "open_input", "check_product", "choose_calibration", "check_geometry", "decode_raw", "open_raw", "open_source", "with_optics",
    "read_dark_frame", "virtual_depth_stem", "load_lightfield_input", "render_product",
    "check_total_focus_patch", "display_encoding", "stores_display_encoded", "default_extension", "write_image_file",
    "AUTO_EXPOSURE",
    "DARK_LEVEL", "dark_note", "check_exposure", "expose", "exposure_gain", "image_level",
    "refuse_folder_clash", "staged_folder", "write_product", "write_parallax", "write_depth",
    "write_lightfield", "view_names", "refocus_stem", "focal_stack_names", "parallax_frame_names",
]
