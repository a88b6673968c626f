"""Reading the optics of a light-field microscope: napari-LF / LFAnalyze ``metadata.txt`` and ``--optics`` files.

Three dialects, told apart by their content (:func:`read_optics`):

napari-LF ``metadata.txt`` (JSON)
    ``{"calibrate": {"ulens_pitch": 125.0, "pixel_size": 4.55, "ulens_focal_length": 2433.0,
    "ulens_focal_distance": 2433.0, "objective_magnification": 20, "objective_na": 0.5,
    "tubelens_focal_length": 180.0, "center_wavelength": 510.0, "medium_index": 1.33, ...}, "main": ...,
    "rectify": ..., "deconvolve": ..., "hw": ...}``.  The keys are those of LFAnalyze's ``lfcalibrate``
    options, whose documented units are: pitch, pixel size, micro-lens focal length and focal distance in
    um, tube lens focal length in mm, wavelength in nm.  The pixel size includes any relay magnification.
LFAnalyze parameter list (text)
    One ``name value [unit]`` per line with the ``lfcalibrate`` option names (``pitch 125 um``,
    ``pixel-size 4.55 um``, ``focal-length 2433 um``, ``magnification 20 x``, ``na 0.5``,
    ``tubelens-focal-length 180.0``, ``wavelength 510``, ``medium-index 1.33``), as in the README of the
    LFAnalyze sample data; other lines are ignored.  Same units.
plenodecode optics JSON (``--optics FILE.json``)
    The command-line option names without dashes: ``{"lens_pitch_um": 125, "pixel_um": 4.55,
    "magnification": 20, "na": 0.5, "tube_lens_mm": 180, "medium_index": 1.33, "microlens_focal_um": 2433}``
    (:func:`format_optics_json` writes it).

:func:`optics_beside` finds ``metadata.txt`` in the raw's folder (else an LFAnalyze sample's README);
:func:`format_metadata_txt` writes a napari-LF file (the tests generate theirs with it).  Readers never write.
"""

from __future__ import annotations

import json
import logging
import os
import re
from pathlib import Path
from typing import Any, Mapping

from ..errors import MetadataError
from ..optics import OPTICS_OPTIONS, MicroscopeOptics

log = logging.getLogger(__name__)

#: The file napari-LF keeps beside a light-field image.
METADATA_NAME = "metadata.txt"
#: READMEs beside a raw read for optics when there is no ``metadata.txt`` (LFAnalyze's sample data keep them
#: there as ``pitch 125 um`` lines), and the values one must give to count (a README that merely mentions an NA
#: does not make a camera a microscope); larger files are no such README.
README_NAMES = ("README", "README.txt")
README_REQUIRED = ("lens_pitch_m", "pixel_pitch_m", "magnification", "numerical_aperture")
README_MAX_BYTES = 64 * 1024
#: napari-LF ``calibrate`` key -> (MicroscopeOptics field, metres per file unit).
NAPARI_KEYS: dict[str, tuple[str, float]] = {
    "ulens_pitch": ("lens_pitch_m", 1e-6),
    "pixel_size": ("pixel_pitch_m", 1e-6),
    "objective_magnification": ("magnification", 1.0),
    "objective_na": ("numerical_aperture", 1.0),
    "tubelens_focal_length": ("tube_lens_focal_length_m", 1e-3),
    "medium_index": ("medium_index", 1.0),
    "ulens_focal_length": ("microlens_focal_length_m", 1e-6),
    "ulens_focal_distance": ("microlens_focal_length_m", 1e-6),     # wins: the MLA-sensor distance
    "center_wavelength": ("wavelength_m", 1e-9),
}
#: LFAnalyze option names (text dialect) -> the napari-LF key of the same value.
LFANALYZE_NAMES = {"pitch": "ulens_pitch", "pixel-size": "pixel_size", "focal-length": "ulens_focal_length",
                   "ulens-focal-distance": "ulens_focal_distance", "magnification": "objective_magnification",
                   "na": "objective_na", "tubelens-focal-length": "tubelens_focal_length",
                   "wavelength": "center_wavelength", "medium-index": "medium_index"}


def _optics_json_key(field_name: str) -> str:
    """``'--lens-pitch-um'`` -> ``'lens_pitch_um'``: the key of a field in a plenodecode optics JSON."""
    return OPTICS_OPTIONS[field_name][0].lstrip("-").replace("-", "_")


def _number(value: Any, key: str, path: Path) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise MetadataError(f"{path}: '{key}' must be a number, got {value!r}") from None


def _from_napari(section: Mapping[str, Any], path: Path) -> MicroscopeOptics:
    values: dict[str, float] = {}
    for key, (name, scale) in NAPARI_KEYS.items():       # dict order: focal distance after focal length
        if section.get(key) not in (None, ""):
            values[name] = _number(section[key], key, path) * scale
    return _checked(values, path)


def _checked(values: Mapping[str, float], path: Path) -> MicroscopeOptics:
    try:
        return MicroscopeOptics(**values)
    except ValueError as exc:
        raise MetadataError(f"{path}: {exc}") from None


def parse_optics(text: str, path: str | os.PathLike = "<optics>") -> MicroscopeOptics:
    """Microscope optics of the text of an optics file in any of the three dialects (module docstring).

    Raises
    ------
    MetadataError
        No optical value found, or a value that is not a positive number (naming the file and key).
    """
    path = Path(path)
    try:
        doc = json.loads(text)
    except ValueError:
        doc = None
    if isinstance(doc, dict):
        by_key = {_optics_json_key(name): name for name in OPTICS_OPTIONS}
        if isinstance(doc.get("calibrate"), dict):
            optics = _from_napari(doc["calibrate"], path)
        elif set(doc) <= set(by_key):
            optics = _checked({by_key[k]: _number(v, k, path) * OPTICS_OPTIONS[by_key[k]][2]
                               for k, v in doc.items() if v is not None}, path)
        elif any(k in doc for k in NAPARI_KEYS):
            optics = _from_napari(doc, path)
        else:
            raise MetadataError(f"{path}: unknown optics key(s) {sorted(set(doc) - set(by_key))}; valid: "
                                f"{', '.join(by_key)} (or a napari-LF metadata.txt)")
    else:
        section = {}
        for line in text.splitlines():
            m = re.match(r"\s*([A-Za-z][\w-]*)\s+([-+0-9.eE]+)\b", line)
            if m and m.group(1).lower() in LFANALYZE_NAMES:
                section[LFANALYZE_NAMES[m.group(1).lower()]] = m.group(2)
        optics = _from_napari(section, path)
    if optics.empty:
        raise MetadataError(f"{path}: no microscope optics found (expected a napari-LF metadata.txt with a "
                            "'calibrate' section, LFAnalyze 'pitch 125 um' lines, or a JSON with keys "
                            f"{', '.join(_optics_json_key(n) for n in OPTICS_OPTIONS)})")
    return optics


def read_optics(path: str | os.PathLike) -> MicroscopeOptics:
    """Read an optics file (``--optics``, or a ``metadata.txt``); see :func:`parse_optics`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MetadataError(f"{p}: cannot read the microscope optics ({exc})") from exc
    return parse_optics(text, p)


def _readme_optics(folder: Path) -> tuple[MicroscopeOptics, Path] | None:
    """The optics an LFAnalyze sample's README in ``folder`` lists (:data:`README_NAMES`, text dialect), when it
    gives every one of :data:`README_REQUIRED`, and that README; else None (any other README says nothing of
    optics)."""
    for name in README_NAMES:
        readme = folder / name
        try:
            if not readme.is_file() or readme.stat().st_size > README_MAX_BYTES:
                continue
            optics = parse_optics(readme.read_text(encoding="utf-8", errors="replace"), readme)
        except (OSError, MetadataError):
            continue
        if all(getattr(optics, f) is not None for f in README_REQUIRED):
            log.info("microscope optics from %s: %s", readme, optics.describe())
            return optics, readme
    return None


def optics_and_file_beside(raw_path: str | os.PathLike) -> tuple[MicroscopeOptics, Path] | None:
    """The optics of the napari-LF ``metadata.txt`` in the raw's folder, else those an LFAnalyze sample's README
    beside it lists (``pitch 125 um`` lines giving at least pitch, pixel size, magnification and NA), with the file
    they come from; None when there are none.

    A ``metadata.txt`` that holds no optical value (another program's file) is ignored with a warning.
    """
    meta = Path(raw_path).parent / METADATA_NAME
    if not meta.is_file():
        return _readme_optics(Path(raw_path).parent)
    try:
        optics = read_optics(meta)
    except MetadataError as exc:
        log.warning("ignoring %s: %s", meta, exc)
        return None
    log.info("microscope optics from %s: %s", meta, optics.describe())
    return optics, meta


def optics_beside(raw_path: str | os.PathLike) -> MicroscopeOptics | None:
    """The optics :func:`optics_and_file_beside` finds beside the raw, None when there are none."""
    found = optics_and_file_beside(raw_path)
    return None if found is None else found[0]


#: Words in the name of a flat-field (white, radiometry) frame kept beside light-field images (LFAnalyze's
#: ``radiometry_frame.png``).
FLAT_FIELD_WORDS = ("radiometry", "flat", "white")


def is_flat_field_name(path: str | os.PathLike) -> bool:
    """True when the file name of ``path`` says a flat field: an image whose stem holds one of
    :data:`FLAT_FIELD_WORDS` (case-insensitive)."""
    from .discovery import MOSAIC_SUFFIXES

    p = Path(path)
    return p.suffix.lower() in MOSAIC_SUFFIXES and any(w in p.stem.lower() for w in FLAT_FIELD_WORDS)


def flat_field_beside(raw_path: str | os.PathLike) -> Path | None:
    """The first file (by name) in the folder of ``raw_path``, the raw itself excepted, that
    :func:`is_flat_field_name` takes for its flat-field frame (``radiometry_frame.png``), as ``raw_path``'s folder
    joined with its name; None when there is none."""
    p = Path(raw_path)
    if not p.parent.is_dir():
        return None
    names = sorted(f.name for f in p.parent.iterdir() if f.name != p.name and f.is_file() and is_flat_field_name(f))
    return p.parent / names[0] if names else None


def format_metadata_txt(optics: MicroscopeOptics, *, comments: str = "") -> str:
    """A napari-LF ``metadata.txt`` (``main`` + ``calibrate`` sections) holding ``optics``."""
    calibrate: dict[str, Any] = {}
    for key, (name, scale) in NAPARI_KEYS.items():
        value = getattr(optics, name)
        if value is not None:
            calibrate[key] = round(value / scale, 9)
    return json.dumps({"main": {"comments": comments}, "calibrate": calibrate}, indent=4) + "\n"


def format_optics_json(optics: MicroscopeOptics) -> str:
    """The plenodecode optics JSON (``--optics FILE.json``) of ``optics``, in the options' units."""
    doc = {_optics_json_key(name): round(getattr(optics, name) / scale, 9)
           for name, (_, _, scale) in OPTICS_OPTIONS.items() if getattr(optics, name) is not None}
    return json.dumps(doc, indent=1) + "\n"


__all__ = ["FLAT_FIELD_WORDS", "is_flat_field_name", "flat_field_beside", "METADATA_NAME", "NAPARI_KEYS",
           "LFANALYZE_NAMES", "parse_optics", "read_optics", "optics_beside", "optics_and_file_beside",
           "format_metadata_txt", "format_optics_json"]
