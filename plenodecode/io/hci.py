"""Reader for scenes of the HCI 4D light-field benchmark (Honauer et al., ACCV 2016).

A scene folder holds ``input_Cam000.png`` ... ``input_Cam080.png`` (9x9 views, index
``row * 9 + col``), ``parameters.cfg`` and, for training scenes, ``gt_disp_lowres.pfm``.
The disparity convention of the benchmark is the one of plenodecode (design.md).
"""

from __future__ import annotations

import configparser
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..errors import FormatError
from ..types import HCIParameters, LightField, LightFieldGeometry
from .pfm import read_pfm


@dataclass(frozen=True)
class HCIScene:
    """One benchmark scene: the light field, its parameters, and ground truth when present."""

    lightfield: LightField
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    disparity: np.ndarray | None = None   # (Y, X) float32, centre view


def _parse_value(text: str) -> Any:
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def read_parameters(path: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """Parse ``parameters.cfg`` into ``{section: {key: int | float | str}}``."""
    cp = configparser.ConfigParser()
    if not cp.read(path):
        raise FormatError(f"{path}: cannot read HCI parameters.cfg")
    return {s: {k: _parse_value(v) for k, v in cp[s].items()} for s in cp.sections()}


def scene_parameters(folder: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """The parsed ``parameters.cfg`` of a scene folder, ``{}`` when the folder has none."""
    cfg = Path(folder) / "parameters.cfg"
    return read_parameters(cfg) if cfg.is_file() else {}


def scene_geometry(folder: str | os.PathLike, params: dict[str, dict[str, Any]]) -> LightFieldGeometry:
    """Geometry of an HCI scene: one pixel per spatial sample and per view step (a camera array), the camera
    parameters of its ``parameters.cfg`` (``params``), the folder as source.  Read by :func:`read_hci` and by
    :func:`plenodecode.io.lightfield.load_lightfield` on a scene folder."""
    return LightFieldGeometry(spatial_step_px=1.0, view_step_px=1.0, source=str(folder),
                              hci=HCIParameters.from_cfg(params))


def read_hci(folder: str | os.PathLike) -> HCIScene:
    """Read an HCI benchmark scene folder.

    Returns
    -------
    HCIScene
        ``lightfield.data`` is (9, 9, 512, 512, 3) float32 in [0, 1] (sRGB-encoded as stored,
        colour state 'srgb'; ``lightfield.geometry`` from :func:`scene_geometry`); ``disparity`` (512, 512)
        float32 when ``gt_disp_lowres.pfm`` exists.
    """
    root = Path(folder)
    files = sorted(root.glob("input_Cam*.png"))
    if not files:
        raise FormatError(f"{root}: no input_Cam*.png views; expected an HCI benchmark scene folder")
    params = scene_parameters(root)
    ext = params.get("extrinsics", {})
    nv, nu = int(ext.get("num_cams_y", 0)), int(ext.get("num_cams_x", 0))
    if nv * nu != len(files):
        side = math.isqrt(len(files))
        if side * side != len(files):
            raise FormatError(f"{root}: {len(files)} views is not a square grid and parameters.cfg does not say")
        nv = nu = side
    first = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED)
    if first is None:
        raise FormatError(f"{files[0]}: unreadable PNG")
    scale = 1.0 / np.iinfo(first.dtype).max
    data = np.empty((nv, nu, *first.shape[:2], 3), np.float32)
    for idx, f in enumerate(files):
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None or img.shape[:2] != first.shape[:2]:
            raise FormatError(f"{f}: unreadable or of a different size than {files[0].name}")
        data[idx // nu, idx % nu] = img[..., ::-1] * np.float32(scale)
    disp = None
    if (root / "gt_disp_lowres.pfm").exists():
        disp = read_pfm(root / "gt_disp_lowres.pfm")
    return HCIScene(LightField(data, None, "srgb", geometry=scene_geometry(root, params)), params, disp)
