"""Data model of plenodecode: raw captures, lenslet grids and light fields.

All three are frozen dataclasses.  Arrays inside them are never modified in place by
the library; functions return new objects (use :func:`dataclasses.replace`).  What is known
about the camera and the scene (:class:`CameraMetadata`, :class:`HCIParameters`,
:class:`LightFieldGeometry`) is defined in :mod:`plenodecode.metadata` and handed on here, so
``from plenodecode.types import X`` serves every name of the data model.

Coordinates are ``(row, col)`` with pixel centres at integers and the origin top-left.

Lattice frame of a :class:`LensletGrid`
---------------------------------------
A lattice point with lattice coordinates ``(a, b)`` (pixels; ``a`` across lens rows,
``b`` along a lens row) lies on the sensor at::

    p = origin + a * e_row + b * e_col
    e_col = ( sin(theta), cos(theta))     # direction along a lens row, (row, col)
    e_row = ( cos(theta), -sin(theta))    # direction from one lens row to the next

so ``theta = rotation`` is the angle of the lens rows from the sensor's +col axis,
positive towards +row.  Lens ``(i, j)`` (lens row ``i``, lens column ``j``) sits at::

    a = i * row_spacing
    b = j * pitch + odd_row_shift * pitch * (i % 2)

A hexagonal grid has ``row_spacing ~= pitch * sqrt(3) / 2`` and ``odd_row_shift = +-0.5``;
a square grid has ``row_spacing ~= pitch`` and ``odd_row_shift = 0``.  A hexagonal grid
whose lenses are packed in columns rather than rows is the same model with
``rotation ~= +-pi/2``.

Decoded sampling (the contract between the synthetic generator and the decoder)
-------------------------------------------------------------------------------
A decoded light field ``LF[v, u, y, x, c]`` samples, for view ``(v, u)`` and spatial
sample ``(y, x)``, the ray through the lattice-frame position::

    a = y * step + a0,  b = x * step + b0          (spatial: the virtual lens centre)
    offset from that centre = ((v - vc) * view_step, (u - uc) * view_step)   (lattice frame, px)

with ``step = row_spacing`` (square output pixels for hex and square grids alike),
``view_step = 1`` sensor pixel, and ``(a0, b0)`` the first lattice position covered by
every lens row (see :meth:`LensletGrid.decoded_sampling`).  The number of views per axis
is ``2 * floor(pitch / 2) + 1`` unless the caller asks for another odd number.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal, Mapping

import numpy as np

from .errors import CalibrationError
from .metadata import (COLOUR_STATES, COLOUR_WORDS, ENCODED_COLOUR_STATES, GEOMETRY_SCHEMA_VERSION,
                       LEGACY_GEOMETRY_KEYS, LINEAR_COLOUR_STATES, CameraMetadata, HCIParameters, LightFieldGeometry,
                       LightFieldMetadata, encoded_colour_state, linear_colour_state)
from .optics import MicroscopeOptics

#: Bayer pattern names, upper-left 2x2 tile read row-major.
CFA_PATTERNS = ("RGGB", "GRBG", "GBRG", "BGGR")
#: Version written into every serialised LensletGrid.
GRID_JSON_VERSION = 1

Lattice = Literal["hex", "square"]


def cfa_channel_map(cfa: str | None) -> np.ndarray:
    """Channel index (0=R, 1=G, 2=B) of each position of the 2x2 CFA tile.

    Parameters
    ----------
    cfa : str or None
        One of :data:`CFA_PATTERNS`, or None for a monochrome sensor.

    Returns
    -------
    ndarray, shape (2, 2), int8
        Channel of ``mosaic[r % 2, c % 2]``; all zeros for monochrome.
    """
    if cfa is None:
        return np.zeros((2, 2), np.int8)
    if cfa not in CFA_PATTERNS:
        raise ValueError(f"cfa must be one of {CFA_PATTERNS} or None, got {cfa!r}")
    lut = {"R": 0, "G": 1, "B": 2}
    return np.array([[lut[cfa[0]], lut[cfa[1]]], [lut[cfa[2]], lut[cfa[3]]]], np.int8)


#: ``metadata.extra`` key of a raw read from an image mosaic without a sidecar (no white image, no camera identity,
#: no colour matrix can come with it): how the reader chose its CFA and levels.
BARE_MOSAIC_KEY = "bare_mosaic"


@dataclass(frozen=True)
class RawCapture:
    """A raw sensor image as read from a file.

    Attributes
    ----------
    mosaic : ndarray, shape (H, W), uint16
        Sensor values as stored (black level not subtracted).
    cfa : str or None
        Bayer pattern of the upper-left 2x2 tile ('RGGB', 'GRBG', 'GBRG', 'BGGR'), None if monochrome.
    black, white : ndarray, shape (2, 2), float64
        Black and white (saturation) level of each position of the 2x2 CFA tile.
    metadata : CameraMetadata
    path : str or None
        Source file.
    """

    mosaic: np.ndarray
    cfa: str | None
    black: np.ndarray
    white: np.ndarray
    metadata: CameraMetadata = field(default_factory=CameraMetadata)
    path: str | None = None

    def __post_init__(self) -> None:
        if self.mosaic.ndim != 2 or self.mosaic.dtype != np.uint16:
            raise ValueError(f"mosaic must be a 2-D uint16 array, got {self.mosaic.dtype} {self.mosaic.shape}")
        if self.cfa is not None and self.cfa not in CFA_PATTERNS:
            raise ValueError(f"cfa must be one of {CFA_PATTERNS} or None, got {self.cfa!r}")
        for name in ("black", "white"):
            v = np.broadcast_to(np.asarray(getattr(self, name), np.float64), (2, 2)).copy()
            v.setflags(write=False)
            object.__setattr__(self, name, v)

    @property
    def shape(self) -> tuple[int, int]:
        """Sensor size ``(H, W)``."""
        return self.mosaic.shape  # type: ignore[return-value]

    def normalised(self) -> np.ndarray:
        """Mosaic scaled to ``(x - black) / (white - black)`` per CFA position.

        Returns
        -------
        ndarray, shape (H, W), float32 (not clipped)
        """
        h, w = self.mosaic.shape
        reps = ((h + 1) // 2, (w + 1) // 2)
        black = np.tile(self.black, reps)[:h, :w].astype(np.float32)
        scale = np.tile(1.0 / (self.white - self.black), reps)[:h, :w].astype(np.float32)
        return (self.mosaic.astype(np.float32) - black) * scale


@dataclass(frozen=True)
class LensletGrid:
    """The lenslet lattice of one camera (see the module docstring for the model).

    Attributes
    ----------
    lattice : 'hex' or 'square'
    pitch : float
        Lens spacing along a lens row, px.
    row_spacing : float
        Spacing between lens rows, px.
    rotation : float
        Angle of the lens rows from the sensor +col axis, rad, positive towards +row.
    origin : tuple of float
        Sensor ``(row, col)`` of lens (0, 0).
    shape : tuple of int
        ``(rows, cols)`` of lenses.
    odd_row_shift : float
        Shift of odd lens rows along the row, in units of pitch (+-0.5 hex, 0 square).
    sensor_shape : tuple of int
        ``(H, W)`` of the sensor the grid was fitted on.
    radius : float
        Radius of the useful disk under each lens, px.
    refined : ndarray (rows, cols, 2) float64 or None
        Measured centres where they deviate from the lattice; NaN where not measured.
    lens_type : ndarray (rows, cols) int8 or None
        Lens type per lens (Raytrix multi-focus MLAs), None otherwise.
    residual_rms : float or None
        RMS distance between measured centres and the lattice fit, px.
    info : dict
        Free-form provenance (source white image, camera serial, zoom/focus, fit statistics).
    """

    lattice: Lattice
    pitch: float
    row_spacing: float
    rotation: float
    origin: tuple[float, float]
    shape: tuple[int, int]
    odd_row_shift: float
    sensor_shape: tuple[int, int]
    radius: float
    refined: np.ndarray | None = None
    lens_type: np.ndarray | None = None
    residual_rms: float | None = None
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.lattice not in ("hex", "square"):
            raise ValueError(f"lattice must be 'hex' or 'square', got {self.lattice!r}")
        if not (self.pitch > 0 and self.row_spacing > 0):
            raise ValueError(f"pitch and row_spacing must be positive, got {self.pitch}, {self.row_spacing}")
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        object.__setattr__(self, "shape", (int(self.shape[0]), int(self.shape[1])))
        object.__setattr__(self, "sensor_shape", (int(self.sensor_shape[0]), int(self.sensor_shape[1])))
        if self.refined is not None and self.refined.shape != (*self.shape, 2):
            raise ValueError(f"refined must have shape {(*self.shape, 2)}, got {self.refined.shape}")
        if self.lens_type is not None and self.lens_type.shape != self.shape:
            raise ValueError(f"lens_type must have shape {self.shape}, got {self.lens_type.shape}")

    # -- geometry -------------------------------------------------------------------
    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors ``(e_row, e_col)`` of the lattice frame in sensor (row, col)."""
        s, c = math.sin(self.rotation), math.cos(self.rotation)
        return np.array([c, -s]), np.array([s, c])

    def lattice_to_sensor(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Sensor ``(row, col)`` of lattice-frame points.

        Parameters
        ----------
        a, b : array_like, float64, same shape S
            Lattice coordinates in px (across rows, along rows).

        Returns
        -------
        ndarray, shape S + (2,), float64
            ``origin + a * e_row + b * e_col``.
        """
        e_row, e_col = self.axes()
        a = np.asarray(a, np.float64)[..., None]
        b = np.asarray(b, np.float64)[..., None]
        return np.asarray(self.origin) + a * e_row + b * e_col

    def sensor_to_lattice(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inverse of :meth:`lattice_to_sensor`: ``p`` (..., 2) -> ``(a, b)``."""
        e_row, e_col = self.axes()
        d = np.asarray(p, np.float64) - np.asarray(self.origin)
        return d @ e_row, d @ e_col

    def lattice_centres(self) -> np.ndarray:
        """Ideal lattice position of every lens, shape (rows, cols, 2), float64 (row, col)."""
        i, j = np.meshgrid(np.arange(self.shape[0]), np.arange(self.shape[1]), indexing="ij")
        a = i * self.row_spacing
        b = j * self.pitch + self.odd_row_shift * self.pitch * (i % 2)
        return self.lattice_to_sensor(a, b)

    def centres_2d(self) -> np.ndarray:
        """Every lens centre, shape (rows, cols, 2), float64: refined where measured, else lattice."""
        ideal = self.lattice_centres()
        if self.refined is None:
            return ideal
        return np.where(np.isfinite(self.refined), self.refined, ideal)

    def centres(self) -> np.ndarray:
        """Every lens centre as (N, 2) float64 ``(row, col)``, row-major over (lens row, lens col)."""
        return self.centres_2d().reshape(-1, 2)

    def n_views(self) -> int:
        """Default number of views per angular axis: ``2 * floor(pitch / 2) + 1``."""
        return 2 * int(math.floor(self.pitch / 2)) + 1

    def max_views(self) -> int:
        """Most views per angular axis that still see a micro-image: ``2 * ceil(pitch / 2) + 1`` (a view step is one
        sensor pixel; views farther out sample the neighbouring lenses' disks, or nothing)."""
        return 2 * int(math.ceil(self.pitch / 2)) + 1

    def decoded_sampling(self) -> dict[str, float | int]:
        """Spatial sampling of the decoded light field (see the module docstring).

        Returns
        -------
        dict with keys
            ``step`` (px between output samples, = row_spacing), ``a0``, ``b0`` (lattice
            position of sample (0, 0)), ``Y``, ``X`` (number of spatial samples).

        The covered span along rows is the intersection of all rows' lens ranges, so for
        a hex grid ``X = floor(((cols - 1 - |shift|) * pitch) / step) + 1`` and ``Y = rows``.
        """
        rows, cols = self.shape
        step = self.row_spacing
        shift = self.odd_row_shift * self.pitch if rows > 1 else 0.0
        b0 = max(0.0, shift)
        b1 = min((cols - 1) * self.pitch, (cols - 1) * self.pitch + shift)
        nx = int(math.floor((b1 - b0) / step + 1e-9)) + 1
        return {"step": step, "a0": 0.0, "b0": b0, "Y": rows, "X": nx}

    # -- serialisation --------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Versioned JSON-serialisable dictionary."""
        return {
            "format": "plenodecode.LensletGrid",
            "version": GRID_JSON_VERSION,
            "lattice": self.lattice,
            "pitch": self.pitch,
            "row_spacing": self.row_spacing,
            "rotation": self.rotation,
            "origin": list(self.origin),
            "shape": list(self.shape),
            "odd_row_shift": self.odd_row_shift,
            "sensor_shape": list(self.sensor_shape),
            "radius": self.radius,
            "refined": None if self.refined is None else np.where(
                np.isfinite(self.refined), self.refined, None).tolist(),
            "lens_type": None if self.lens_type is None else self.lens_type.tolist(),
            "residual_rms": self.residual_rms,
            "info": dict(self.info),
        }

    def to_json(self) -> str:
        """The grid as a JSON string (see :meth:`to_dict`)."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "LensletGrid":
        """Inverse of :meth:`to_dict`; raises CalibrationError on a foreign or newer document."""
        if d.get("format") != "plenodecode.LensletGrid":
            raise CalibrationError(f"not a plenodecode lenslet grid (format={d.get('format')!r}); "
                                   "pass a file written by 'plenodecode calibrate'")
        if int(d.get("version", 0)) > GRID_JSON_VERSION:
            raise CalibrationError(f"grid file version {d.get('version')} is newer than this plenodecode "
                                   f"understands ({GRID_JSON_VERSION}); upgrade plenodecode")
        try:
            refined = d.get("refined")
            if refined is not None:
                refined = np.array(refined, dtype=np.float64)  # None -> nan
            lens_type = d.get("lens_type")
            if lens_type is not None:
                lens_type = np.array(lens_type, dtype=np.int8)
            return cls(
                lattice=d["lattice"], pitch=float(d["pitch"]), row_spacing=float(d["row_spacing"]),
                rotation=float(d["rotation"]), origin=tuple(d["origin"]), shape=tuple(d["shape"]),
                odd_row_shift=float(d["odd_row_shift"]), sensor_shape=tuple(d["sensor_shape"]),
                radius=float(d["radius"]), refined=refined, lens_type=lens_type,
                residual_rms=None if d.get("residual_rms") is None else float(d["residual_rms"]),
                info=dict(d.get("info") or {}),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"lenslet grid document is incomplete or malformed: {exc}") from exc

    @classmethod
    def from_json(cls, text: str) -> "LensletGrid":
        """Parse :meth:`to_json` output."""
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise CalibrationError(f"lenslet grid is not valid JSON: {exc}") from exc
        return cls.from_dict(d)

    def replace(self, **changes: Any) -> "LensletGrid":
        """A copy with some fields changed."""
        return replace(self, **changes)


@dataclass(frozen=True)
class LightField:
    """A decoded 4D light field.

    Attributes
    ----------
    data : ndarray, shape (V, U, Y, X, C), float32
        Angular row, angular column, spatial row, spatial column, channel (C = 1 or 3).
    weight : ndarray, shape (V, U, Y, X), float32, or None
        Confidence of each sample in [0, 1] (low where a view leaves the lenslet disk).
    colour : str
        'camera', 'linear-srgb', or either sRGB-encoded: 'srgb' (linear sRGB encoded) or 'camera-srgb-curve'
        (camera RGB encoded: the sRGB tone curve without sRGB colours).
    metadata : Mapping
        Given: free-form provenance (decoder settings, ...), optionally with the legacy keys
        :data:`LEGACY_GEOMETRY_KEYS` ('source', 'calibration', 'camera', 'spatial_step_px', ...), which are
        read into ``geometry`` (they win over a ``geometry`` passed alongside).  Stored: a read-only
        :class:`LightFieldMetadata`, the provenance plus the legacy keys written from ``geometry``.
    geometry : LightFieldGeometry
        Sampling, camera geometry, colour state and source: what refocusing by alpha, depth and export
        read.  Its ``colour`` always equals :attr:`colour`.
    """

    data: np.ndarray
    weight: np.ndarray | None = None
    colour: str = "camera"
    metadata: Mapping[str, Any] = field(default_factory=dict)
    geometry: LightFieldGeometry | None = None

    def __post_init__(self) -> None:
        if self.data.ndim != 5:
            raise ValueError(f"data must be 5-D (V, U, Y, X, C), got shape {self.data.shape}")
        if self.data.shape[-1] not in (1, 3):
            raise ValueError(f"data must have C = 1 or 3 channels, got {self.data.shape[-1]}")
        if self.data.dtype != np.float32:
            raise ValueError(f"data must be float32, got {self.data.dtype}")
        if self.weight is not None and self.weight.shape != self.data.shape[:4]:
            raise ValueError(f"weight must have shape {self.data.shape[:4]}, got {self.weight.shape}")
        if self.colour not in COLOUR_STATES:
            raise ValueError(f"colour must be one of {COLOUR_STATES}, got {self.colour!r}")
        given = self.metadata if self.metadata is not None else {}
        geometry = self.geometry
        if isinstance(given, LightFieldMetadata):            # another light field's: its provenance only
            provenance: Mapping[str, Any] = given.provenance
        else:
            provenance = {k: v for k, v in given.items() if k not in LEGACY_GEOMETRY_KEYS}
            if len(provenance) < len(given):
                geometry = LightFieldGeometry.from_legacy(given)
        geometry = geometry if geometry is not None else LightFieldGeometry()
        if geometry.colour != self.colour:
            geometry = replace(geometry, colour=self.colour)
        object.__setattr__(self, "geometry", geometry)
        object.__setattr__(self, "metadata", LightFieldMetadata(provenance, geometry))

    @property
    def provenance(self) -> dict[str, Any]:
        """The free-form part of :attr:`metadata` (decoder settings and the like), without the geometry."""
        return dict(self.metadata.provenance)  # type: ignore[attr-defined]

    @property
    def shape(self) -> tuple[int, int, int, int, int]:
        """``(V, U, Y, X, C)``."""
        return self.data.shape  # type: ignore[return-value]

    @property
    def centre_index(self) -> tuple[int, int]:
        """``(V // 2, U // 2)``."""
        return self.data.shape[0] // 2, self.data.shape[1] // 2

    def centre_view(self) -> np.ndarray:
        """The centre view, shape (Y, X, C), float32."""
        vc, uc = self.centre_index
        return self.data[vc, uc]

    def replace(self, **changes: Any) -> "LightField":
        """A copy with some fields changed.

        ``metadata=`` without ``geometry=`` replaces the whole metadata: the geometry is read from the legacy
        keys of the new dict, so ``lf.replace(metadata={})`` drops it and ``lf.replace(metadata={**lf.metadata,
        'disparity_range': r})`` changes one value.  Keep the geometry with ``geometry=lf.geometry``.
        """
        if "metadata" in changes:
            changes.setdefault("geometry", None)
        return replace(self, **changes)


__all__ = [
    "CFA_PATTERNS", "COLOUR_STATES", "GRID_JSON_VERSION", "cfa_channel_map",
    "CameraMetadata", "RawCapture", "LensletGrid", "LightField", "LightFieldGeometry", "HCIParameters",
    "LightFieldMetadata", "GEOMETRY_SCHEMA_VERSION", "LINEAR_COLOUR_STATES", "LEGACY_GEOMETRY_KEYS", "MicroscopeOptics",
    "ENCODED_COLOUR_STATES", "COLOUR_WORDS", "encoded_colour_state", "linear_colour_state",
]
