"""What is known about the camera and the scene: the metadata types of :mod:`plenodecode.types`.

:class:`CameraMetadata` (the camera and exposure of a raw), :class:`HCIParameters` (the camera array of an HCI
benchmark scene) and :class:`LightFieldGeometry` (sampling, camera constants, colour state and provenance of a
light field, ``LightField.geometry``), with the legacy dictionary view :class:`LightFieldMetadata`
(``LightField.metadata``).  Frozen dataclasses like the rest of the data model; import them from
:mod:`plenodecode.types`, which hands every name on.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any, Mapping

from .errors import MetadataError
from .optics import MicroscopeOptics

#: Colour states of a light field: linear camera RGB, linear sRGB, and each of them sRGB-encoded for display
#: (:data:`ENCODED_COLOUR_STATES`).
COLOUR_STATES = ("camera", "linear-srgb", "srgb", "camera-srgb-curve")
#: How each colour state reads to a person (the CLI's summary lines, ``info``, the light-field page).
COLOUR_WORDS = {"camera": "camera RGB", "linear-srgb": "linear sRGB", "srgb": "sRGB",
                "camera-srgb-curve": "camera RGB with the sRGB tone curve"}


@dataclass(frozen=True)
class CameraMetadata:
    """What the decoder needs to know about the camera and the exposure.

    Lengths are in metres, angles in radians.  Every field is optional; ``extra``
    keeps the source's full metadata (e.g. the Lytro JSON) for reference.
    """

    make: str | None = None
    model: str | None = None
    serial: str | None = None
    zoom_step: float | None = None
    focus_step: float | None = None
    exposure_s: float | None = None
    iso: float | None = None
    #: white-balance gains per CFA channel name ('r', 'gr', 'gb', 'b') or ('r', 'g', 'b').
    wb_gains: Mapping[str, float] | None = None
    #: camera RGB -> linear sRGB matrix, row-major 3x3 (rows sum to 1 for Lytro).
    ccm: tuple[tuple[float, float, float], ...] | None = None
    pixel_pitch_m: float | None = None
    lens_pitch_m: float | None = None
    mla_rotation: float | None = None
    #: MLA offset relative to the sensor centre (x, y, z) in metres (z = MLA-sensor gap).
    mla_offset_m: tuple[float, float, float] | None = None
    mla_scale: tuple[float, float] | None = None
    focal_length_m: float | None = None
    f_number: float | None = None
    is_white_image: bool = False
    extra: Mapping[str, Any] = field(default_factory=dict)
    #: the optics of a light-field microscope (:class:`~plenodecode.optics.MicroscopeOptics`), None for a camera.
    microscope: MicroscopeOptics | None = None

    def lenslet_pitch_px(self) -> float | None:
        """Lenslet pitch in sensor pixels, ``lens_pitch_m / pixel_pitch_m``, if both are known."""
        if self.lens_pitch_m and self.pixel_pitch_m:
            return self.lens_pitch_m / self.pixel_pitch_m
        return None

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable dictionary (``extra`` included)."""
        d = asdict(self)
        d["wb_gains"] = dict(self.wb_gains) if self.wb_gains is not None else None
        d["extra"] = dict(self.extra)
        d["microscope"] = None if self.microscope is None else self.microscope.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "CameraMetadata":
        """Inverse of :meth:`to_dict`; unknown keys are ignored."""
        names = {f.name for f in fields(cls)}
        kw = {k: v for k, v in d.items() if k in names}
        for key in ("ccm",):
            if kw.get(key) is not None:
                kw[key] = tuple(tuple(float(x) for x in row) for row in kw[key])
        for key in ("mla_offset_m", "mla_scale"):
            if kw.get(key) is not None:
                kw[key] = tuple(float(x) for x in kw[key])
        kw["microscope"] = MicroscopeOptics.from_dict(kw.get("microscope"))
        return cls(**kw)


#: Version of the document :meth:`LightFieldGeometry.to_dict` writes (saved light fields embed it).
GEOMETRY_SCHEMA_VERSION = 1
#: Colour states of linear values: a display export applies the sRGB transfer function to them.
LINEAR_COLOUR_STATES = ("camera", "linear-srgb")
#: The display-encoded state of each linear one: the sRGB transfer function (IEC 61966-2-1) on its values, its
#: primaries kept.  'srgb' is linear sRGB so encoded; 'camera-srgb-curve' is camera RGB so encoded (no white
#: balance or colour matrix applied: the tone curve of sRGB, not its colours).
ENCODED_COLOUR_STATES = {"linear-srgb": "srgb", "camera": "camera-srgb-curve"}


def encoded_colour_state(colour: str) -> str:
    """The colour state of ``colour``'s values after the sRGB transfer function ('camera' -> 'camera-srgb-curve',
    'linear-srgb' -> 'srgb'); a display-encoded state is returned as it is."""
    return ENCODED_COLOUR_STATES.get(colour, colour)


def linear_colour_state(colour: str) -> str:
    """The colour state of ``colour``'s values with the sRGB transfer function undone ('camera-srgb-curve' ->
    'camera', 'srgb' -> 'linear-srgb'); a linear state is returned as it is."""
    return {enc: lin for lin, enc in ENCODED_COLOUR_STATES.items()}.get(colour, colour)


#: Keys of the legacy free-form ``LightField.metadata`` dict that :class:`LightFieldGeometry` replaces.
LEGACY_GEOMETRY_KEYS = ("source", "calibration", "camera", "spatial_step_px", "view_step_px", "geometry",
                        "disparity_range", "hci_parameters", "focus_distance_m", "colour", "microscope",
                        "ray_model")
#: Where each :class:`HCIParameters` field sits in ``parameters.cfg``: field -> (section, key).
_HCI_CFG = {"baseline_mm": ("extrinsics", "baseline_mm"), "focal_length_mm": ("intrinsics", "focal_length_mm"),
            "sensor_size_mm": ("intrinsics", "sensor_size_mm"), "focus_distance_m": ("extrinsics", "focus_distance_m")}


def _number(value: Any, name: str) -> float | None:
    """``float(value)``, None for None; a MetadataError naming ``name`` when it is not a number."""
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        raise MetadataError(f"light-field metadata '{name}' must be a number, got {value!r}") from None


def _ray_model(value: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """:attr:`LightFieldGeometry.ray_model` as plain JSON-ready data (H checked by :func:`raymodel.check_intrinsics`)."""
    if value is None:
        return None
    from .raymodel import check_distortion, check_intrinsics

    try:
        return {"intrinsics": check_intrinsics(value["intrinsics"]).tolist(),
                "distortion": check_distortion(value.get("distortion")).tolist(),
                "rectified": bool(value.get("rectified", False)),
                "calibration": None if value.get("calibration") is None else str(value["calibration"])}
    except (KeyError, TypeError, ValueError) as exc:
        raise MetadataError(f"light-field metadata 'ray_model' is malformed ({exc})") from None


def _pair(value: Any, name: str) -> tuple[float, float] | None:
    """``(float, float)`` of a two-element sequence, None for None (not checked for order or finiteness)."""
    if value is None:
        return None
    try:
        lo, hi = value
        return float(lo), float(hi)
    except (TypeError, ValueError):
        raise MetadataError(f"light-field metadata '{name}' must be a pair of numbers, got {value!r}") from None


@dataclass(frozen=True)
class HCIParameters:
    """The camera array of an HCI benchmark scene (``parameters.cfg``; Honauer et al., ACCV 2016).

    Attributes
    ----------
    baseline_mm : float or None
        Distance between neighbouring cameras, mm (``[extrinsics] baseline_mm``).
    focal_length_mm, sensor_size_mm : float or None
        ``[intrinsics]`` focal length and sensor width, mm.
    resolution_px : (int, int) or None
        ``(image_resolution_x_px, image_resolution_y_px)``; 0 for a side the file does not give.
    focus_distance_m : float or None
        Distance of the plane of disparity 0, m (``[extrinsics] focus_distance_m``).
    disparity_range : (float, float) or None
        ``[meta] (disp_min, disp_max)``, px per view step.
    sections : dict
        The whole parsed file ``{section: {key: value}}``, for reference; the typed fields are written
        into it on construction.
    """

    baseline_mm: float | None = None
    focal_length_mm: float | None = None
    sensor_size_mm: float | None = None
    resolution_px: tuple[int, int] | None = None
    focus_distance_m: float | None = None
    disparity_range: tuple[float, float] | None = None
    sections: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    @property
    def image_resolution_px(self) -> float | None:
        """The longer side, ``max(x, y)`` px: the size the focal length in pixels refers to."""
        return None if self.resolution_px is None else float(max(self.resolution_px))

    @classmethod
    def from_cfg(cls, sections: Mapping[str, Mapping[str, Any]] | None) -> "HCIParameters | None":
        """Typed parameters of a parsed ``parameters.cfg`` (:func:`plenodecode.io.hci.read_parameters`);
        None for an empty one."""
        if not sections:
            return None
        kw: dict[str, Any] = {name: _number((sections.get(sec) or {}).get(key), key)
                              for name, (sec, key) in _HCI_CFG.items()}
        intr, meta = sections.get("intrinsics") or {}, sections.get("meta") or {}
        if "image_resolution_x_px" in intr or "image_resolution_y_px" in intr:
            kw["resolution_px"] = tuple(int(_number(intr.get(f"image_resolution_{a}_px", 0), f"image_resolution_{a}_px"))
                                        for a in "xy")
        if "disp_min" in meta and "disp_max" in meta:
            kw["disparity_range"] = _pair((meta["disp_min"], meta["disp_max"]), "disp_min/disp_max")
        return cls(sections=sections, **kw)

    def __post_init__(self) -> None:
        object.__setattr__(self, "disparity_range", _pair(self.disparity_range, "disparity_range"))
        sections = {s: dict(v) for s, v in self.sections.items()}     # the typed fields written in
        values = {name: getattr(self, name) for name in _HCI_CFG}
        if self.resolution_px is not None:
            x, y = self.resolution_px
            values.update(image_resolution_x_px=x or None, image_resolution_y_px=y or None)
        if self.disparity_range is not None:
            values.update(disp_min=self.disparity_range[0], disp_max=self.disparity_range[1])
        where = {**_HCI_CFG, "image_resolution_x_px": ("intrinsics", "image_resolution_x_px"),
                 "image_resolution_y_px": ("intrinsics", "image_resolution_y_px"),
                 "disp_min": ("meta", "disp_min"), "disp_max": ("meta", "disp_max")}
        for name, value in values.items():
            if value is not None:
                sec, key = where[name]
                sections.setdefault(sec, {})[key] = value
        object.__setattr__(self, "sections", sections)

    def to_cfg(self) -> dict[str, dict[str, Any]]:
        """The ``{section: {key: value}}`` of :meth:`from_cfg` (a copy of :attr:`sections`)."""
        return {s: dict(v) for s, v in self.sections.items()}


def _camera_geometry(doc: Mapping[str, Any], calibration: Mapping[str, Any] | None,
                     legacy_geometry: Mapping[str, Any]) -> dict[str, float | None]:
    """Camera constants of :class:`LightFieldGeometry` from a camera document (``CameraMetadata.to_dict()``).

    ``lens_pitch_m`` falls back to ``calibration['pitch'] * pixel_pitch_m``; the MLA-sensor gap is the legacy
    ``geometry['mla_sensor_gap_m']``, else the z of ``mla_offset_m``; ``infinity_lambda`` is Lytro's
    ``extra['devices']['lens']['infinityLambda']``, else ``legacy_geometry['infinity_lambda']``.
    """
    calib = calibration or {}
    out = {name: _number(doc.get(name), name) for name in ("focal_length_m", "f_number", "lens_pitch_m",
                                                          "pixel_pitch_m")}
    if out["lens_pitch_m"] is None and calib.get("pitch") and out["pixel_pitch_m"]:
        out["lens_pitch_m"] = float(calib["pitch"]) * out["pixel_pitch_m"]
    gap = legacy_geometry.get("mla_sensor_gap_m")
    offset = doc.get("mla_offset_m")
    if gap is None and offset is not None and len(offset) > 2:
        gap = offset[2]
    out["mla_sensor_gap_m"] = _number(gap, "mla_sensor_gap_m")
    lens = (((doc.get("extra") or {}).get("devices") or {}).get("lens") or {})
    lam = lens.get("infinityLambda", legacy_geometry.get("infinity_lambda"))
    out["infinity_lambda"] = _number(lam, "infinity_lambda")
    return out


@dataclass(frozen=True)
class LightFieldGeometry:
    """Sampling, camera geometry, colour state and provenance of a light field: ``LightField.geometry``.

    Every field is optional (None = unknown).  Lengths in metres unless the name says px or mm.

    Attributes
    ----------
    spatial_step_px : float or None
        Sensor pixels between neighbouring spatial samples (the decoded sampling step, ``row_spacing``).
    view_step_px : float or None
        Sensor pixels between neighbouring views under a lenslet (1 for a decoded light field).
    focal_length_m, f_number : float or None
        Main lens.
    lens_pitch_m, pixel_pitch_m : float or None
        Lenslet and sensor pixel pitch.
    mla_sensor_gap_m : float or None
        Distance between the micro-lens array and the sensor.
    infinity_lambda : float or None
        Lytro ``infinityLambda``: refocus steps (of one MLA-sensor gap) to infinity focus.
    focus_distance_m : float or None
        Distance of the plane in focus (disparity 0).
    disparity_range : (float, float) or None
        Disparities the scene spans, px per view step (HCI sign, design.md).
    colour : str or None
        Colour state, one of :data:`COLOUR_STATES`; a :class:`~plenodecode.types.LightField` keeps it equal to ``lf.colour``.
    source : str or None
        The raw file (or scene folder) the light field came from.
    calibration : dict or None
        ``LensletGrid.to_dict()`` of the grid it was decoded with.
    camera : CameraMetadata or None
        The camera and exposure metadata of the raw.
    hci : HCIParameters or None
        The camera array, for an HCI benchmark scene.
    microscope : MicroscopeOptics or None
        The optics of a light-field microscope (metric depth in micrometres); defaults to ``camera.microscope``.
    ray_model : dict or None
        The calibrated ray model of the samples as they are (:mod:`plenodecode.raymodel`), plain data:
        ``{'intrinsics': 5 x 5 nested list (H, 0-based samples), 'distortion': [k1, k2, k3, b1, b2],
        'rectified': bool, 'calibration': the calibration file or None}``; set by
        :func:`plenodecode.decoding.rectify.rectify` (then rectified, distortion 0), read by metric depth.
    """

    spatial_step_px: float | None = None
    view_step_px: float | None = None
    focal_length_m: float | None = None
    f_number: float | None = None
    lens_pitch_m: float | None = None
    pixel_pitch_m: float | None = None
    mla_sensor_gap_m: float | None = None
    infinity_lambda: float | None = None
    focus_distance_m: float | None = None
    disparity_range: tuple[float, float] | None = None
    colour: str | None = None
    source: str | None = None
    calibration: Mapping[str, Any] | None = None
    camera: CameraMetadata | None = None
    hci: HCIParameters | None = None
    microscope: MicroscopeOptics | None = None
    ray_model: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "microscope", MicroscopeOptics.from_dict(self.microscope))
        object.__setattr__(self, "ray_model", _ray_model(self.ray_model))
        if self.microscope is None and self.camera is not None:
            object.__setattr__(self, "microscope", self.camera.microscope)
        if self.colour is not None and self.colour not in COLOUR_STATES:
            raise ValueError(f"colour must be one of {COLOUR_STATES}, got {self.colour!r}")
        object.__setattr__(self, "disparity_range", _pair(self.disparity_range, "disparity_range"))

    @property
    def display_encoded(self) -> bool:
        """True when the values are sRGB-encoded for display (colour 'srgb' or 'camera-srgb-curve'); a display
        export of a light field that is not applies the sRGB transfer function (colour 'camera' or 'linear-srgb')."""
        return self.colour in ENCODED_COLOUR_STATES.values()

    @classmethod
    def from_camera(cls, camera: CameraMetadata, calibration: Mapping[str, Any] | None = None,
                    **fields_: Any) -> "LightFieldGeometry":
        """Geometry of a light field decoded from a raw with metadata ``camera`` on grid ``calibration``
        (``LensletGrid.to_dict()``); the camera constants as :func:`_camera_geometry` finds them; ``fields_``
        sets the others (``spatial_step_px``, ``view_step_px``, ``source``, ...)."""
        consts = _camera_geometry(camera.to_dict(), calibration, {})
        return cls(camera=camera, calibration=calibration, **{**consts, **fields_})

    # -- the legacy free-form dict ------------------------------------------------------------
    @classmethod
    def from_legacy(cls, meta: Mapping[str, Any]) -> "LightFieldGeometry":
        """Read the keys :data:`LEGACY_GEOMETRY_KEYS` of the free-form metadata dict of earlier versions.

        The camera constants come from ``meta['camera']`` (else ``meta['geometry']``); ``spatial_step_px``
        falls back to ``calibration['row_spacing']``; an HCI scene's ``meta['hci_parameters']`` becomes
        :attr:`hci`.
        """
        calib = meta.get("calibration")
        legacy_geometry = meta.get("geometry") or {}
        cam_doc = meta.get("camera")
        camera = CameraMetadata.from_dict(cam_doc) if isinstance(cam_doc, Mapping) else None
        consts = _camera_geometry(cam_doc if camera is not None else legacy_geometry, calib, legacy_geometry)
        step = meta.get("spatial_step_px")
        if step is None and calib and calib.get("row_spacing"):
            step = calib["row_spacing"]
        return cls(spatial_step_px=_number(step, "spatial_step_px"),
                   view_step_px=_number(meta.get("view_step_px"), "view_step_px"),
                   focus_distance_m=_number(meta.get("focus_distance_m"), "focus_distance_m"),
                   disparity_range=meta.get("disparity_range"), colour=meta.get("colour"),
                   source=None if meta.get("source") is None else str(meta["source"]),
                   calibration=None if calib is None else dict(calib), camera=camera,
                   hci=HCIParameters.from_cfg(meta.get("hci_parameters")),
                   microscope=MicroscopeOptics.from_dict(meta.get("microscope")), ray_model=meta.get("ray_model"),
                   **consts)

    def to_legacy(self) -> dict[str, Any]:
        """The legacy free-form keys (inverse of :meth:`from_legacy`); unknown values are left out."""
        consts = {name: getattr(self, name) for name in ("focal_length_m", "f_number", "lens_pitch_m",
                                                         "pixel_pitch_m")}
        out: dict[str, Any] = {"source": self.source, "colour": self.colour,
                               "calibration": None if self.calibration is None else dict(self.calibration),
                               "spatial_step_px": self.spatial_step_px, "view_step_px": self.view_step_px,
                               "focus_distance_m": self.focus_distance_m,
                               "disparity_range": None if self.disparity_range is None else list(self.disparity_range),
                               "hci_parameters": None if self.hci is None else self.hci.to_cfg(),
                               "microscope": None if self.microscope is None else self.microscope.to_dict(),
                               "ray_model": self.ray_model}
        if self.camera is not None:
            cam = self.camera.to_dict()
            out["camera"] = {**cam, **{k: v for k, v in consts.items() if cam.get(k) is None}}
        pitch_px = (self.calibration or {}).get("pitch")
        step_m = None if self.spatial_step_px is None or self.pixel_pitch_m is None else \
            self.spatial_step_px * self.pixel_pitch_m
        geometry = {**consts, "lens_pitch_px": pitch_px, "mla_sensor_gap_m": self.mla_sensor_gap_m,
                    "infinity_lambda": self.infinity_lambda, "spatial_step_m": step_m}
        if any(v is not None for v in geometry.values()):
            out["geometry"] = geometry
        return {k: v for k, v in out.items() if v is not None}

    @classmethod
    def coerce(cls, value: "LightFieldGeometry | Mapping[str, Any] | None") -> "LightFieldGeometry":
        """``value`` itself, the geometry of a legacy metadata dict (:meth:`from_legacy`), or an empty one."""
        if isinstance(value, cls):
            return value
        geometry = getattr(value, "geometry", None)      # a LightField's metadata view carries its geometry
        if isinstance(geometry, cls):
            return geometry
        return cls.from_legacy(value or {})

    # -- versioned document -------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Versioned JSON-ready document (``camera`` as ``CameraMetadata.to_dict()``, ``hci`` as its cfg)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d.update(disparity_range=None if self.disparity_range is None else list(self.disparity_range),
                 calibration=None if self.calibration is None else dict(self.calibration),
                 camera=None if self.camera is None else self.camera.to_dict(),
                 hci=None if self.hci is None else self.hci.to_cfg(),
                 microscope=None if self.microscope is None else self.microscope.to_dict())
        return {"format": "plenodecode.LightFieldGeometry", "version": GEOMETRY_SCHEMA_VERSION, **d}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "LightFieldGeometry":
        """Inverse of :meth:`to_dict`; MetadataError on a newer schema; unknown keys are ignored."""
        if int(d.get("version", 0) or 0) > GEOMETRY_SCHEMA_VERSION:
            raise MetadataError(f"light-field geometry schema version {d.get('version')} is newer than this "
                                f"plenodecode reads ({GEOMETRY_SCHEMA_VERSION}); upgrade plenodecode")
        names = {f.name for f in fields(cls)} - {"camera", "hci"}
        kw = {k: v for k, v in d.items() if k in names}
        if d.get("camera") is not None:
            kw["camera"] = CameraMetadata.from_dict(d["camera"])
        kw["hci"] = HCIParameters.from_cfg(d.get("hci"))
        return cls(**kw)


class LightFieldMetadata(Mapping[str, Any]):
    """``LightField.metadata``: read-only view of the free-form provenance plus the legacy geometry keys.

    Old code reads ``lf.metadata['spatial_step_px']``, ``lf.metadata['camera']``, ...; they come from
    :meth:`LightFieldGeometry.to_legacy`.  New code reads :attr:`~plenodecode.types.LightField.geometry` and
    :attr:`provenance`.
    """

    def __init__(self, provenance: Mapping[str, Any], geometry: LightFieldGeometry) -> None:
        self.provenance = dict(provenance)
        self.geometry = geometry
        self._items = {**geometry.to_legacy(), **self.provenance}

    def __getitem__(self, key: str) -> Any:
        return self._items[key]

    def __iter__(self):
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return f"LightFieldMetadata({self._items!r})"


__all__ = ["COLOUR_STATES", "COLOUR_WORDS", "CameraMetadata", "HCIParameters", "LightFieldGeometry",
           "LightFieldMetadata", "GEOMETRY_SCHEMA_VERSION", "LINEAR_COLOUR_STATES", "ENCODED_COLOUR_STATES",
           "LEGACY_GEOMETRY_KEYS",
           "encoded_colour_state", "linear_colour_state"]
