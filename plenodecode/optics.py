"""The optics of a light-field microscope: :class:`MicroscopeOptics`.

A light-field microscope (Levoy et al., "Light Field Microscopy", SIGGRAPH 2006) puts a micro-lens array
(MLA) in the intermediate image plane of an objective + tube lens and the sensor in the focal plane of the
micro-lenses.  Every lenslet is one spatial sample; the pixels behind it sample the objective's back focal
plane, i.e. the direction of the rays in the specimen.  :mod:`plenodecode.depth.metric` turns disparity into
an axial position from these constants (the derivation is in its docstring).

The values come from the command line (``--lens-pitch-um``, ``--pixel-um``, ``--magnification``, ``--na``,
``--tube-lens-mm``, ``--medium-index``, ``--microlens-focal-um``), an ``--optics FILE`` or a napari-LF /
LFAnalyze ``metadata.txt`` beside the raw (:mod:`plenodecode.io.microscope`).  This module is in the base
layer (``types.py`` carries it in :class:`~plenodecode.types.CameraMetadata` and
:class:`~plenodecode.types.LightFieldGeometry`) and touches no file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any, Mapping

#: Field of :class:`MicroscopeOptics` -> (command-line option, unit of the option, scale option -> field).
#: The library's errors name the Python field; the command line rewrites them in its options
#: (:func:`plenodecode.cli.common.in_option_names`).
OPTICS_OPTIONS: dict[str, tuple[str, str, float]] = {
    "lens_pitch_m": ("--lens-pitch-um", "um", 1e-6),
    "pixel_pitch_m": ("--pixel-um", "um", 1e-6),
    "magnification": ("--magnification", "", 1.0),
    "numerical_aperture": ("--na", "", 1.0),
    "tube_lens_focal_length_m": ("--tube-lens-mm", "mm", 1e-3),
    "medium_index": ("--medium-index", "", 1.0),
    "microlens_focal_length_m": ("--microlens-focal-um", "um", 1e-6),
    "wavelength_m": ("--wavelength-nm", "nm", 1e-9),
}


#: How a Python caller gives a microscope's optics, as the library's errors say it (the command line replaces the
#: phrase by its ``--optics FILE``).
OPTICS_SUPPLY = ("optics=MicroscopeOptics(...) of open_source / open_input, a keyword of disparity_to_depth, or a "
                 "napari-LF metadata.txt beside the raw")


def option_name(field_name: str) -> str:
    """The command-line option that sets ``field_name`` of :class:`MicroscopeOptics` (e.g. ``'--na'``)."""
    return OPTICS_OPTIONS[field_name][0]


@dataclass(frozen=True)
class MicroscopeOptics:
    """Optical constants of a light-field microscope; every field optional (None = unknown).

    Lengths in metres (the command line takes um / mm, see :data:`OPTICS_OPTIONS`).

    Attributes
    ----------
    lens_pitch_m : float or None
        Micro-lens pitch (e.g. 125e-6).
    pixel_pitch_m : float or None
        Sensor pixel size referred to the micro-lens focal plane, i.e. including any relay lens between
        the MLA and the camera (LFAnalyze's ``--pixel-size``; 4.55e-6 for 6.5 um pixels behind a 50:35 relay).
    magnification : float or None
        Objective magnification with its design tube lens (specimen -> MLA plane), e.g. 20.
    numerical_aperture : float or None
        Objective NA, ``n sin(theta_max)`` in the specimen's medium.
    tube_lens_focal_length_m : float or None
        Tube lens focal length; the objective's focal length is ``tube / magnification`` (kept for reference;
        the disparity -> depth relation needs only the magnification).
    medium_index : float or None
        Refractive index of the immersion / specimen medium (1.33 water, 1.515 oil, 1.0 air).
    microlens_focal_length_m : float or None
        Distance from the micro-lenses to the sensor plane they focus on (LFAnalyze ``ulens_focal_distance``,
        else ``ulens_focal_length``).  Without it the micro-images are assumed to fill the lens pitch exactly
        (the MLA's f-number matched to the objective's image side: ``M / f_mu = 2 NA / pitch``).
    wavelength_m : float or None
        Centre emission wavelength (reference only).
    """

    lens_pitch_m: float | None = None
    pixel_pitch_m: float | None = None
    magnification: float | None = None
    numerical_aperture: float | None = None
    tube_lens_focal_length_m: float | None = None
    medium_index: float | None = None
    microlens_focal_length_m: float | None = None
    wavelength_m: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{f.name} must be a number, got {value!r}") from None
            if not (v > 0 and math.isfinite(v)):
                raise ValueError(f"{f.name} must be a positive number, got {value!r}")
            object.__setattr__(self, f.name, v)
        if self.medium_index is not None and self.medium_index < 1.0:
            raise ValueError(f"medium_index must be at least 1 (vacuum), got {self.medium_index:g}")
        if self.numerical_aperture is not None and self.medium_index is not None \
                and self.numerical_aperture >= self.medium_index:
            raise ValueError(f"numerical_aperture {self.numerical_aperture:g} must be below medium_index "
                             f"{self.medium_index:g} "
                             "(NA = n sin(theta))")

    @property
    def empty(self) -> bool:
        """True when no value is known."""
        return all(getattr(self, f.name) is None for f in fields(self))

    def merged(self, override: "MicroscopeOptics | None") -> "MicroscopeOptics":
        """These optics with every value that ``override`` knows replaced by it."""
        if override is None:
            return self
        return replace(self, **{f.name: getattr(override, f.name) for f in fields(self)
                                if getattr(override, f.name) is not None})

    def to_dict(self) -> dict[str, float | None]:
        """``{field: value}`` (metres), JSON-ready."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | "MicroscopeOptics" | None) -> "MicroscopeOptics | None":
        """Inverse of :meth:`to_dict` (unknown keys ignored); None for None; an instance passes through."""
        if d is None or isinstance(d, cls):
            return d
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})

    @classmethod
    def from_options(cls, **values: float | None) -> "MicroscopeOptics":
        """From command-line values in the options' units, keyed by field name: ``lens_pitch_m=125`` means
        125 um (``--lens-pitch-um 125``); see :data:`OPTICS_OPTIONS`.  None values are left unknown."""
        bad = set(values) - set(OPTICS_OPTIONS)
        if bad:
            raise ValueError(f"unknown microscope optics {sorted(bad)}; valid: {', '.join(OPTICS_OPTIONS)}")
        return cls(**{k: None if v is None else float(v) * OPTICS_OPTIONS[k][2] for k, v in values.items()})

    def describe(self) -> str:
        """One line in the command-line units, e.g. ``'20x / NA 0.5, n 1.33, lens pitch 125 um, ...'``."""
        parts = []
        for name, (opt, unit, scale) in OPTICS_OPTIONS.items():
            value = getattr(self, name)
            if value is not None:
                parts.append(f"{opt.lstrip('-')} {value / scale:g}{(' ' + unit) if unit else ''}")
        return ", ".join(parts) if parts else "no values"


__all__ = ["MicroscopeOptics", "OPTICS_OPTIONS", "OPTICS_SUPPLY", "option_name"]
