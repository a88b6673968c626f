"""A simulation's result and its exact ground truth, in memory and on disk.

:class:`Simulation` holds the scene raw, the white image, the true grid, the disparity map and
the scene, and renders the ideal decoded light field (:meth:`Simulation.ground_truth_lightfield`).
:func:`write_simulation` writes a simulation in its camera's real file format plus
``<name>.truth.json`` / ``<name>.truth.npz``; :func:`load_truth` reads the ground truth back as a
:class:`Truth`.  This module builds the documents and arrays; the files are written and read by
:mod:`plenodecode.io` (the camera formats, and :mod:`plenodecode.io.truth` for the ground truth).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..io.atomic import refuse_existing
from ..io.truth import TRUTH_FORMAT, TRUTH_JSON_SUFFIX, TRUTH_NPZ_SUFFIX, TRUTH_VERSION, read_truth, write_truth
from ..types import LensletGrid, LightField, RawCapture
from .presets import Preset, get_preset
from .scene import Scene, box_radiance
from .sensor import Progress, disk_response

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Simulation:
    """A synthetic capture and its exact ground truth.

    Attributes
    ----------
    raw : RawCapture
        The scene raw.
    white : RawCapture
        The white image of the same camera (same exposure scale and noise model).
    grid : LensletGrid
        The true lenslet grid.
    disparity : ndarray (Y, X) float32
        Disparity of the centre view at the decoded sampling (px per view step, HCI convention).
    scene : Scene
        The scene description (planes).
    preset : Preset
    seed : int
    truth : dict
        Extra ground truth (focused presets: virtual depth, total-focus image, lens types).
    """

    raw: RawCapture
    white: RawCapture
    grid: LensletGrid
    disparity: np.ndarray
    scene: Any
    preset: Preset
    seed: int = 0
    noise: bool = True
    truth: Mapping[str, Any] = field(default_factory=dict)
    textures: Any = field(default=None, repr=False, compare=False)

    @property
    def disparity_range(self) -> tuple[float, float]:
        """``(min, max)`` disparity over the centre view."""
        d = self.disparity[np.isfinite(self.disparity)]
        return (float(d.min()), float(d.max())) if d.size else (0.0, 0.0)

    def ground_truth_lightfield(self, n_views: int | None = None, *, progress: Progress = None) -> LightField:
        """The ideal decoded light field of the scene, from the continuous model (no lenses).

        ``LF[v, u, y, x, c]`` is the mean over the 1 x 1 px box in ``o`` centred at
        ``o = (v - vc, u - uc)`` (view steps = sensor px) of the linear-sRGB radiance
        ``L(o, y, x)`` (2 x 2 Gauss-Legendre rule, as the raw), for every decoded sample
        ``(y, x)`` of :meth:`LensletGrid.decoded_sampling`.  ``weight`` is the lenslet
        disk response at that ``o`` (what a real decoder sees there).

        Parameters
        ----------
        n_views : int, optional
            Odd number of views per axis; default ``grid.n_views()``.

        Returns
        -------
        LightField
            data (V, U, Y, X, C) float32, C = 3 (1 for monochrome presets), colour 'linear-srgb'.
            15 x 15 views of a full-size Illum is 1.8 GB: use the small presets.
        """
        if self.preset.focused:
            raise ValueError("ground_truth_lightfield is defined for unfocused presets; a focused (Raytrix) "
                             "simulation has truth['total_focus'] and truth['virtual_depth'] instead")
        n = self.grid.n_views() if n_views is None else int(n_views)
        if n < 1 or n % 2 == 0:
            raise ValueError(f"n_views must be a positive odd number, got {n_views!r}")
        smp = self.grid.decoded_sampling()
        ny, nx = int(smp["Y"]), int(smp["X"])
        c = self.textures.srgb.shape[1]
        half = n // 2
        o = np.arange(n, dtype=np.float64) - half
        yy, xx = np.meshgrid(np.arange(ny, dtype=np.float64), np.arange(nx, dtype=np.float64), indexing="ij")
        data = np.empty((n, n, ny, nx, c), np.float32)
        for v in range(n):
            for ch in range(c):
                data[v, :, :, :, ch] = box_radiance(self.textures, yy[None], xx[None], o[v],
                                                    o[:, None, None], ch, space="srgb")
            if progress is not None:
                progress(v + 1, n)
        weight = disk_response(o[:, None], o[None, :], self.grid.radius, edge_px=self.preset.edge_px,
                               falloff=self.preset.disk_falloff).astype(np.float32)
        weight = np.ascontiguousarray(np.broadcast_to(weight[:, :, None, None], (n, n, ny, nx)))
        meta = {
            "source": "plenodecode.io.synthetic", "preset": self.preset.name, "seed": self.seed,
            "spatial_step_px": float(smp["step"]), "view_step_px": 1.0, "calibration": self.grid.to_dict(),
            "camera": self.raw.metadata.to_dict(), "disparity_range": list(self.disparity_range),
        }
        return LightField(data=data, weight=weight, colour="linear-srgb", metadata=meta)

    def ground_truth_photograph(self, scale: int = 1, *, progress: Progress = None) -> np.ndarray:
        """The centre view of the ideal light field sampled ``scale`` times finer: the exact photograph of a
        fronto-parallel scene refocused at its disparity, at any resolution.

        ``out[j, i, c]`` is the mean over the 1 x 1 px box in ``o`` centred at ``o = 0`` of the linear-sRGB
        radiance ``L(o, y, x)`` at decoded ``(y, x) = (j / scale, i / scale)``, the rule of
        :meth:`ground_truth_lightfield` (``scale = 1`` gives its centre view).  When every plane has the same
        disparity ``d`` this is the photograph refocused at slope ``d``: view ``(v, u)`` at
        ``P - d (v - vc, u - uc)`` averages ``T(P + d o')`` over the same box for every view.  Elsewhere it is
        the centre view (all-in-focus, pinhole at the centre of the aperture).

        Parameters
        ----------
        scale : int
            Samples per decoded pixel (>= 1).
        progress : callable(done, total), optional
            Called after each channel.

        Returns
        -------
        ndarray, shape (scale Y, scale X, C), float32
        """
        if self.preset.focused:
            raise ValueError("ground_truth_photograph is defined for unfocused presets; a focused (Raytrix) "
                             "simulation has truth['total_focus'] instead")
        k = int(scale)
        if k < 1 or k != scale:
            raise ValueError(f"scale must be a positive integer, got {scale!r}")
        smp = self.grid.decoded_sampling()
        ny, nx = int(smp["Y"]), int(smp["X"])
        c = self.textures.srgb.shape[1]
        yy = (np.arange(k * ny, dtype=np.float64) / k)[:, None]
        xx = (np.arange(k * nx, dtype=np.float64) / k)[None, :]
        out = np.empty((k * ny, k * nx, c), np.float32)
        for ch in range(c):
            out[..., ch] = box_radiance(self.textures, yy, xx, 0.0, 0.0, ch, space="srgb")
            if progress is not None:
                progress(ch + 1, c)
        return out


# ---------------------------------------------------------------------------------------
# writing and reading back
# ---------------------------------------------------------------------------------------
#: Presets whose truth npz holds the ground-truth light field by default (small sensors).
_SMALL_SENSOR_PX = 2_000_000


def simulation_files(preset: str | Preset, name: str = "scene") -> dict[str, str]:
    """File names :func:`write_simulation` writes for a preset: key -> name (sidecars included)."""
    p = get_preset(preset)
    if not name or any(c in name for c in "/\\") or name in (".", ".."):
        raise ValueError(f"name must be a plain file stem, got {name!r}")
    names = _raw_names(p, name)
    names.update({"truth_json": name + TRUTH_JSON_SUFFIX, "truth_npz": name + TRUTH_NPZ_SUFFIX})
    return names


def _raw_names(p: Preset, name: str) -> dict[str, str]:
    if p.model == "ILLUM":
        return {"raw": f"{name}.lfr", "white": "MOD_0000.RAW", "white_txt": "MOD_0000.TXT"}
    if p.model == "F01":
        return {"raw": f"{name}.lfp", "white": "MOD_0000.RAW", "white_txt": "MOD_0000.TXT"}
    if p.focused:
        return {"raw": f"{name}.png", "raw_xml": f"{name}.xml", "raw_json": f"{name}.json",
                "white": f"{name}_white.png", "white_xml": f"{name}_white.xml", "white_json": f"{name}_white.json"}
    return {"raw": f"{name}.png", "raw_json": f"{name}.json", "white": f"{name}_white.png",
            "white_json": f"{name}_white.json"}


def write_camera_file(p: Preset, path: str | os.PathLike, capture: RawCapture, grid: LensletGrid, *,
                      overwrite: bool = False) -> None:
    """Write one capture in the preset camera's own format (the names of :func:`simulation_files`).

    Lytro presets: a scene as Illum ``.lfr`` / F01 ``.lfp``, a white image (``capture.metadata.is_white_image``)
    as ``MOD_NNNN.RAW`` + ``.TXT``; focused presets: PNG + RayCalibData XML of ``grid``; others: 16-bit PNG +
    JSON sidecar.  Each file is written by :mod:`plenodecode.io` to a temporary name and renamed.
    """
    if p.model == "ILLUM" or p.model == "F01":
        from ..io import lytro

        if capture.metadata.is_white_image:
            lytro.write_raw_pair(path, capture, overwrite=overwrite)
        else:
            (lytro.write_lfr if p.model == "ILLUM" else lytro.write_lfp)(path, capture, overwrite=overwrite)
    elif p.focused:
        from ..io.raytrix import write_raytrix

        write_raytrix(path, capture, grid, overwrite=overwrite)
    else:
        from ..io.generic import write_mosaic

        write_mosaic(path, capture, overwrite=overwrite)


def truth_document(sim: Simulation, files: Mapping[str, str] | None = None) -> dict[str, Any]:
    """The JSON ground-truth document of a simulation (see :func:`write_simulation`)."""
    smp = sim.grid.decoded_sampling()
    doc = {
        "format": TRUTH_FORMAT, "version": TRUTH_VERSION, "generator": "plenodecode.io.synthetic",
        "preset": sim.preset.name, "preset_params": json.loads(json.dumps(asdict(sim.preset))),
        "seed": sim.seed, "noise": sim.noise, "grid": sim.grid.to_dict(),
        "decoded_sampling": {k: (float(v) if k in ("step", "a0", "b0") else int(v)) for k, v in smp.items()},
        "scene": sim.scene.to_dict() if hasattr(sim.scene, "to_dict") else None,
        "disparity_range": list(sim.disparity_range),
        "disparity_convention": ("virtual-depth micro-image disparity D / v (px)" if sim.preset.focused else
                                 "HCI: view[v,u](y - d*(v-vc), x - d*(u-uc)) = centre(y, x); px per view step"),
        "camera": sim.raw.metadata.to_dict(), "files": dict(files or {}),
    }
    return doc


def write_simulation(sim: Simulation, out_dir: str | os.PathLike, *, name: str = "scene", overwrite: bool = False,
                     lightfield: bool | None = None) -> dict[str, Path]:
    """Write a simulation in its camera's real file format plus the ground truth.

    * illum / illum-mini: ``<name>.lfr`` (Illum LFR) and the white image ``MOD_0000.RAW`` + ``.TXT``;
    * f01 / f01-mini: ``<name>.lfp`` (F01 raw LFP) and ``MOD_0000.RAW`` + ``.TXT``;
    * square: ``<name>.png`` + ``<name>.json`` (16-bit mosaic + sidecar) and ``<name>_white.png`` + json;
    * raytrix: ``<name>.png`` + RayCalibData ``<name>.xml`` + ``<name>.json``, likewise the white;
    * ``<name>.truth.json``: grid, preset, seed, scene, disparity range, camera metadata;
    * ``<name>.truth.npz``: ``centres`` (N, 2) float64, ``disparity`` (Y, X) float32, for
      focused presets ``lens_type``, ``virtual_depth``, ``total_focus``..., and when
      ``lightfield`` (default: sensors up to 2 Mpx) ``lf_data`` / ``lf_weight``.

    The files are written by :mod:`plenodecode.io` (the ground truth by
    :func:`plenodecode.io.truth.write_truth`), each to a temporary name and renamed.  Nothing is
    replaced unless ``overwrite``: existing targets raise FileExistsError before anything is written.

    Returns
    -------
    dict
        Key (``raw``, ``white``, ``white_txt``, ``truth_json``, ``truth_npz``, ...) -> Path.
    """
    out = Path(out_dir)
    p = sim.preset
    paths = {k: out / v for k, v in simulation_files(p, name).items()}
    refuse_existing(paths.values(), overwrite)
    write_camera_file(p, paths["raw"], sim.raw, sim.grid, overwrite=overwrite)
    write_camera_file(p, paths["white"], sim.white, sim.grid, overwrite=overwrite)
    arrays: dict[str, np.ndarray] = {"centres": sim.grid.centres(), "disparity": sim.disparity}
    for key, val in sim.truth.items():
        if isinstance(val, np.ndarray):
            arrays[key] = val
    if lightfield is None:
        lightfield = not p.focused and sim.raw.shape[0] * sim.raw.shape[1] <= _SMALL_SENSOR_PX
    if lightfield:
        lf = sim.ground_truth_lightfield()
        arrays["lf_data"] = lf.data
        arrays["lf_weight"] = lf.weight
    write_truth(paths["truth_json"], truth_document(sim, {k: v.name for k, v in paths.items()}), arrays,
                overwrite=overwrite)
    log.info("wrote synthetic %s capture to %s", p.name, out)
    return paths


@dataclass(frozen=True)
class Truth:
    """Ground truth read back by :func:`load_truth`.

    Attributes
    ----------
    grid : LensletGrid
    preset : str
    seed : int
    scene : Scene or None
    centres : ndarray (N, 2) float64
    disparity : ndarray (Y, X) float32
    disparity_range : (float, float)
    lightfield : LightField or None
        When the npz holds it.
    arrays : dict
        Every array of the npz (focused presets: ``lens_type``, ``virtual_depth``, ``total_focus``...).
    document : dict
        The whole truth JSON.
    """

    grid: LensletGrid
    preset: str
    seed: int
    scene: Any
    centres: np.ndarray
    disparity: np.ndarray
    disparity_range: tuple[float, float]
    lightfield: LightField | None
    arrays: Mapping[str, np.ndarray]
    document: Mapping[str, Any]


def load_truth(path: str | os.PathLike) -> Truth:
    """Read ``<name>.truth.json`` and its ``.truth.npz`` (either path, or a folder holding one) with
    :func:`plenodecode.io.truth.read_truth`, and rebuild the grid, the scene and the light field.

    Raises
    ------
    FormatError
        Missing files, or not a plenodecode synthetic-truth document.
    """
    doc, arrays, p = read_truth(path)
    grid = LensletGrid.from_dict(doc["grid"])
    lf = None
    if "lf_data" in arrays:
        smp = doc.get("decoded_sampling", {})
        lf = LightField(data=arrays["lf_data"], weight=arrays.get("lf_weight"), colour="linear-srgb",
                        metadata={"source": str(p), "preset": doc.get("preset"), "seed": doc.get("seed"),
                                  "spatial_step_px": smp.get("step"), "view_step_px": 1.0,
                                  "calibration": doc["grid"], "disparity_range": doc.get("disparity_range"),
                                  "camera": doc.get("camera")})
    scene = Scene.from_dict(doc["scene"]) if doc.get("scene") else None
    dr = doc.get("disparity_range") or (0.0, 0.0)
    return Truth(grid=grid, preset=str(doc.get("preset")), seed=int(doc.get("seed", 0)), scene=scene,
                 centres=arrays["centres"], disparity=arrays["disparity"],
                 disparity_range=(float(dr[0]), float(dr[1])), lightfield=lf, arrays=arrays, document=doc)


__all__ = ["Simulation", "TRUTH_FORMAT", "TRUTH_VERSION", "simulation_files", "truth_document", "write_simulation",
           "write_camera_file",
           "Truth", "load_truth"]
