"""Geometric calibrations on disk: this project's JSON and the Light Field Toolbox's ``CalInfo.json``.

:func:`load_geometric_calibration` reads either (told apart by their keys);
:func:`save_geometric_calibration` writes this project's document, or the toolbox's when asked
(``toolbox=True``) so that a calibration made here can rectify in the toolbox and back.

The toolbox's file (``LFCalRefine``, v0.5) holds ``EstCamIntrinsicsH`` (5 x 5, for **1-based**
sample indices), ``EstCamDistortionV`` ``[k1, k2, k3, b1, b2]``, ``EstCamPosesV`` (one
``[tx, ty, tz, rx, ry, rz]`` per capture), the lenslet grid (``LensletGridModel``), the camera
(``CamInfo``) and ``CalOptions`` (``LFSize`` = ``[V, U, Y, X, C]`` of the decoded light fields,
``ExpectedCheckerSize`` corners and ``ExpectedCheckerSpacing_m``).  Indices are converted to the
0-based convention of :mod:`plenodecode.raymodel` on reading and back on writing.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..errors import FormatError
from .atomic import write_text_atomic

#: Keys that mark a Light Field Toolbox calibration file.
TOOLBOX_KEYS = ("EstCamIntrinsicsH", "EstCamDistortionV")


def _from_toolbox(doc: dict[str, Any], source: str):
    from ..raymodel import GeometricCalibration, from_toolbox_intrinsics

    options = doc.get("CalOptions", {}) or {}
    lf_size = options.get("LFSize") or [0, 0, 0, 0]
    info = {"source": source, "format": "LFToolbox CalInfo.json",
            "generated_by": doc.get("GeneratedByInfo", {}), "camera": doc.get("CamInfo", {}),
            "lenslet_grid_model": doc.get("LensletGridModel", {})}
    if "ExpectedCheckerSize" in options:
        info["board"] = {"corners": list(options["ExpectedCheckerSize"]),
                         "spacing_m": list(options.get("ExpectedCheckerSpacing_m", []))}
    if "FileList" in options:
        info["captures"] = list(options["FileList"])
    return GeometricCalibration(intrinsics=from_toolbox_intrinsics(doc["EstCamIntrinsicsH"]),
                                distortion=doc.get("EstCamDistortionV") or [0.0] * 5,
                                lf_shape=tuple(int(v) for v in list(lf_size)[:4]),
                                poses=doc.get("EstCamPosesV") or [], info=info)


def _to_toolbox(cal) -> dict[str, Any]:
    from ..raymodel import to_toolbox_intrinsics

    info = dict(cal.info)
    options: dict[str, Any] = {"LFSize": [*cal.lf_shape, 3]}
    board = info.get("board") or {}
    if "corners" in board:
        options["ExpectedCheckerSize"] = list(board["corners"])
    if "spacing_m" in board:
        options["ExpectedCheckerSpacing_m"] = list(board["spacing_m"])
    if "captures" in info:
        options["FileList"] = list(info["captures"])
    doc: dict[str, Any] = {"GeneratedByInfo": {"mfilename": "plenodecode"},
                           "EstCamIntrinsicsH": to_toolbox_intrinsics(cal.intrinsics).tolist(),
                           "EstCamDistortionV": cal.distortion.tolist(),
                           "EstCamPosesV": cal.poses.tolist(), "CalOptions": options}
    if info.get("camera"):
        doc["CamInfo"] = info["camera"]
    if info.get("lenslet_grid_model"):
        doc["LensletGridModel"] = info["lenslet_grid_model"]
    return doc


def load_geometric_calibration(path: str | os.PathLike):
    """Read a :class:`~plenodecode.raymodel.GeometricCalibration` from this project's JSON
    or a toolbox ``CalInfo.json``; FormatError naming the file otherwise."""
    from ..raymodel import GeometricCalibration

    p = Path(path)
    try:
        doc = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FormatError(f"{p}: not a readable JSON geometric calibration ({exc})") from exc
    try:
        if isinstance(doc, dict) and all(k in doc for k in TOOLBOX_KEYS):
            return _from_toolbox(doc, str(p))
        return GeometricCalibration.from_dict(doc)
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(f"{p}: not a geometric calibration ({exc})") from exc


def save_geometric_calibration(cal, path: str | os.PathLike, *, toolbox: bool = False,
                               overwrite: bool = False) -> Path:
    """Write ``cal`` as JSON (atomically): this project's document, or the toolbox's ``CalInfo.json``
    layout with ``toolbox=True``."""
    doc = _to_toolbox(cal) if toolbox else cal.to_dict()
    write_text_atomic(path, json.dumps(doc, indent=1) + "\n", overwrite=overwrite)
    return Path(path)
