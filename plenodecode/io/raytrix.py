"""Raytrix (focused, multi-focus plenoptic) raws: an image exported by RxLive plus its
``RayCalibData`` XML (formats.md section 5; Perwass & Wietzke 2012).

XML conventions
---------------
* ``offset`` (px): the centre lens relative to the image centre, ``+x`` right, ``+y`` **up**.
  In plenodecode's (row, col) frame the centre lens sits at ``(H/2 - y, W/2 + x)``
  (:data:`CENTRE_CONVENTION`; checked on the real R42 crop, see ``tests/test_io_raytrix.py``).
* ``diameter`` (px): the lens pitch.  ``lens_base_x``, ``lens_base_y`` (lens units, +y up):
  the lattice vectors, so lens ``(m, n)`` sits at ``offset + diameter * (m * base_x + n * base_y)``.
  With ``base_y = (0.5, -0.866)`` the next lens row (n + 1) is half a pitch to the right and
  0.866 pitch **down** in the image.
* ``rotation`` (rad): applied to both base vectors, counter-clockwise in the +y-up frame, so
  the LensletGrid rotation is ``-rotation`` when ``base_x = (1, 0)``.  A rotation near pi/2
  (TLCT reads rotation > pi/4 as a grid turned 90 degrees) therefore gives lens rows along the
  sensor columns.  No real file with a non-zero rotation was available to check the sign.
* Lens types: lattice point ``(m, n)`` gets the colour ``c = (m + k n) mod 3`` with
  ``k = -sign(base_x . base_y)`` (so that the six neighbours ``(+-1, 0)``, ``(0, +-1)``,
  ``+-(1, k)`` all have another colour: a 3-colouring of the hexagonal lattice).  The type
  whose ``offset`` (lens units, relative to the centre lens) has the same colour is the lens's
  type.  ``sub_grid_base`` (the repeat cell of the type pattern, e.g. 3 x 1.732 lens units) is
  checked to be a vector of the same-type sub-lattice; a mismatch is logged.
"""

from __future__ import annotations

import json
import logging
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import FormatError, MetadataError
from ..types import CameraMetadata, LensletGrid, RawCapture
from .generic import _FAST_PNG, find_sidecar, is_known_sensor_image, json_safe, read_sidecar, sidecar_document
from .atomic import atomic_outputs, refuse_existing
from .images import read_image, write_image

log = logging.getLogger(__name__)

#: Image files a Raytrix calibration XML may accompany.
RAYTRIX_IMAGE_EXTENSIONS = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg", ".exr", ".pgm", ".ppm")
#: How the XML offset maps to (row, col): centre lens = (H * 0.5 - y, W * 0.5 + x).
CENTRE_CONVENTION = "pixel-edge"   # image centre at (H/2, W/2), i.e. pixel-corner coordinates
#: Rec. 709 luma weights used to turn an RGB export into one channel.
LUMA_WEIGHTS = (0.2126, 0.7152, 0.0722)


@dataclass(frozen=True)
class RaytrixLensType:
    """One lens type of a multi-focus MLA."""

    id: int
    offset: tuple[float, float] = (0.0, 0.0)          # lens units, (x, y +up), relative to the centre lens
    depth_range: tuple[float, float] | None = None    # virtual depth (min, max)


@dataclass(frozen=True)
class RaytrixDistortion:
    """The ``<distortion>`` element (radial model; 'constant' = none)."""

    type: str = "radial"
    function: str = "constant"
    parameters: tuple[float, ...] = ()
    offset: tuple[float, float] = (0.0, 0.0)          # px


@dataclass(frozen=True)
class RaytrixCalibration:
    """Every field of a ``RayCalibData`` document (formats.md section 5).

    Attributes
    ----------
    offset : (x, y)
        Centre lens relative to the image centre, px, +y up.
    diameter : float
        Lens pitch, px.
    rotation : float
        Rad (see the module docstring).
    lens_border : float
        Margin ignored at each micro-image rim, px.
    tcp : float or None
        Total covering plane, virtual depth.
    lens_base_x, lens_base_y : (x, y)
        Lattice vectors, lens units, +y up.
    sub_grid_base : (x, y) or None
        Repeat cell of the lens-type pattern, lens units.
    distortion : RaytrixDistortion or None
    lens_types : tuple of RaytrixLensType
    version : str
    """

    offset: tuple[float, float]
    diameter: float
    rotation: float = 0.0
    lens_border: float = 0.0
    tcp: float | None = None
    lens_base_x: tuple[float, float] = (1.0, 0.0)
    lens_base_y: tuple[float, float] = (0.5, -math.sqrt(3) / 2)
    sub_grid_base: tuple[float, float] | None = None
    distortion: RaytrixDistortion | None = None
    lens_types: tuple[RaytrixLensType, ...] = ()
    version: str = "1.0"

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable dictionary (lists for pairs)."""
        return json_safe(asdict(self))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "RaytrixCalibration":
        """Inverse of :meth:`to_dict`."""
        def pair(v):
            return None if v is None else (float(v[0]), float(v[1]))

        dist = d.get("distortion")
        return cls(
            offset=pair(d["offset"]), diameter=float(d["diameter"]), rotation=float(d.get("rotation", 0.0)),
            lens_border=float(d.get("lens_border", 0.0)),
            tcp=None if d.get("tcp") is None else float(d["tcp"]),
            lens_base_x=pair(d.get("lens_base_x", (1.0, 0.0))),
            lens_base_y=pair(d.get("lens_base_y", (0.5, -math.sqrt(3) / 2))),
            sub_grid_base=pair(d.get("sub_grid_base")),
            distortion=None if dist is None else RaytrixDistortion(
                type=dist.get("type", "radial"), function=dist.get("function", "constant"),
                parameters=tuple(float(x) for x in dist.get("parameters", ())), offset=pair(dist.get("offset", (0, 0)))),
            lens_types=tuple(RaytrixLensType(int(t["id"]), pair(t.get("offset", (0, 0))), pair(t.get("depth_range")))
                             for t in d.get("lens_types", ())),
            version=str(d.get("version", "1.0")),
        )

    def to_xml(self) -> str:
        """The calibration as a ``RayCalibData`` XML document."""
        def num(v: float) -> str:  # RxLive writes 12 decimals; keep full precision when needed
            text = f"{float(v):.12f}"
            return text if float(text) == float(v) else repr(float(v))

        def pair_el(parent, tag, value, units):
            el = ET.SubElement(parent, tag, units=units)
            ET.SubElement(el, "x").text = num(value[0])
            ET.SubElement(el, "y").text = num(value[1])
            return el

        root = ET.Element("RayCalibData", version=self.version)
        pair_el(root, "offset", self.offset, "pix")
        ET.SubElement(root, "diameter", units="pix").text = num(self.diameter)
        ET.SubElement(root, "rotation", units="rad").text = num(self.rotation)
        ET.SubElement(root, "lens_border", units="pix").text = num(self.lens_border)
        if self.tcp is not None:
            ET.SubElement(root, "tcp", units="virtual_depth").text = num(self.tcp)
        pair_el(root, "lens_base_x", self.lens_base_x, "lens")
        pair_el(root, "lens_base_y", self.lens_base_y, "lens")
        if self.sub_grid_base is not None:
            pair_el(root, "sub_grid_base", self.sub_grid_base, "lens")
        if self.distortion is not None:
            d = ET.SubElement(root, "distortion", type=self.distortion.type)
            ET.SubElement(d, "function").text = self.distortion.function
            ET.SubElement(d, "parameter", count=str(len(self.distortion.parameters))).text = (
                " ".join(num(x) for x in self.distortion.parameters) or "0")
            pair_el(d, "offset", self.distortion.offset, "pix")
        for t in self.lens_types:
            el = ET.SubElement(root, "lens_type", id=str(t.id))
            pair_el(el, "offset", t.offset, "lens")
            if t.depth_range is not None:
                dr = ET.SubElement(el, "depth_range", units="virtual_depth")
                ET.SubElement(dr, "min").text = num(t.depth_range[0])
                ET.SubElement(dr, "max").text = num(t.depth_range[1])
        ET.indent(root, "  ")
        return ET.tostring(root, encoding="unicode") + "\n"


# ----------------------------------------------------------------------------- finding and parsing
def is_raycalib_xml(path: str | os.PathLike) -> bool:
    """True when ``path`` is a readable file whose first 64 KiB contain ``<RayCalibData``."""
    try:
        with open(path, "rb") as fh:
            return b"<RayCalibData" in fh.read(65536)
    except OSError:
        return False


def _calibrations_in_folder(folder: Path) -> list[Path]:
    """Every RayCalibData XML (``*.xml`` of any case) in ``folder``, sorted by name."""
    try:
        entries = sorted(folder.iterdir())
    except OSError:
        return []
    return [f for f in entries if f.suffix.lower() == ".xml" and f.is_file() and is_raycalib_xml(f)]


def find_calibration_xml(path: str | os.PathLike) -> Path | None:
    """The RayCalibData XML of a Raytrix image, or None.

    The rule: ``X.xml`` (or ``X.XML``) beside ``X.png`` (or another image extension in
    :data:`RAYTRIX_IMAGE_EXTENSIONS`); else the only RayCalibData XML in the image's folder, unless the image
    has a Lytro sensor's size (:func:`~.generic.is_known_sensor_image`: an F01 JPEG beside a Raytrix image and
    its XML is no Raytrix image; a Raytrix image of that size takes its XML by stem).  A candidate counts only if
    it contains ``<RayCalibData``.  Never raises: several XMLs and no same-stem one give None here
    (:func:`calibration_xml_for` says so as an error).
    """
    p = Path(path)
    if p.suffix.lower() not in RAYTRIX_IMAGE_EXTENSIONS:
        return None
    for cand in (p.with_suffix(".xml"), p.with_suffix(".XML")):
        if cand.is_file() and is_raycalib_xml(cand):
            return cand
    found = _calibrations_in_folder(p.parent)
    return found[0] if len(found) == 1 and not is_known_sensor_image(p) else None


def calibration_xml_for(path: str | os.PathLike, xml: str | os.PathLike | None = None) -> Path | None:
    """The RayCalibData XML to read the image ``path`` with: ``xml`` when given, else
    :func:`find_calibration_xml`'s; None when ``path`` is no Raytrix image.

    Raises
    ------
    MetadataError
        ``xml`` is not a RayCalibData document, or ``path`` is no image; or no XML of the image's stem and
        several RayCalibData XMLs in its folder (ambiguous: the message lists them and names ``--raytrix-xml``),
        unless the image has a Lytro sensor's size.
    """
    p = Path(path)
    if xml is not None:
        if p.suffix.lower() not in RAYTRIX_IMAGE_EXTENSIONS:
            raise MetadataError(f"{p.name}: --raytrix-xml applies to Raytrix images "
                                f"({', '.join(RAYTRIX_IMAGE_EXTENSIONS)}); this is not one")
        if not is_raycalib_xml(xml):
            raise MetadataError(f"{xml}: not a RayCalibData XML (no <RayCalibData> element); pass the calibration "
                                "RxLive exported with the image as --raytrix-xml")
        return Path(xml)
    found = find_calibration_xml(p)
    if found is not None or p.suffix.lower() not in RAYTRIX_IMAGE_EXTENSIONS:
        return found
    several = _calibrations_in_folder(p.parent)
    if len(several) > 1 and not is_known_sensor_image(p):
        names = ", ".join(f.name for f in several)
        raise MetadataError(f"{p.name}: {len(several)} RayCalibData XMLs beside it ({names}) and none named "
                            f"{p.stem}.xml; say which one with --raytrix-xml FILE")
    return None


def _float(el: ET.Element | None, what: str, src: str) -> float:
    if el is None or el.text is None:
        raise MetadataError(f"{src}: RayCalibData has no <{what}>; expected a complete Raytrix calibration file")
    try:
        return float(el.text.strip())
    except ValueError as exc:
        raise MetadataError(f"{src}: <{what}> is {el.text!r}, expected a number") from exc


def _pair(el: ET.Element | None, what: str, src: str, default=None) -> tuple[float, float] | None:
    if el is None:
        if default is None:
            return None
        return default
    return _float(el.find("x"), f"{what}/x", src), _float(el.find("y"), f"{what}/y", src)


def parse_raycalib(path_or_text: str | os.PathLike) -> RaytrixCalibration:
    """Parse a ``RayCalibData`` XML file or string.

    Parameters
    ----------
    path_or_text : path-like or str
        A path, or the XML text itself (a string starting with ``<``).

    Returns
    -------
    RaytrixCalibration
        ``offset`` and ``diameter`` are required; missing optional fields take the defaults
        of :class:`RaytrixCalibration`.

    Raises
    ------
    MetadataError
        Unreadable file, malformed XML, another root element, a missing or non-numeric field.
    """
    if isinstance(path_or_text, str) and path_or_text.lstrip().startswith("<"):
        text, src = path_or_text, "RayCalibData text"
    else:
        src = str(path_or_text)
        try:
            text = Path(path_or_text).read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise MetadataError(f"{src}: cannot read the calibration XML ({exc})") from exc
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise MetadataError(f"{src}: calibration XML is malformed ({exc}); expected a RayCalibData document") from exc
    if root.tag != "RayCalibData":
        raise MetadataError(f"{src}: root element is <{root.tag}>, expected <RayCalibData>")
    dist = None
    d_el = root.find("distortion")
    if d_el is not None:
        params: list[float] = []
        for par in d_el.findall("parameter"):
            count = int(par.get("count", "1") or 0)
            vals = (par.text or "").replace(",", " ").split()
            try:
                params += [float(v) for v in vals[:count]]
            except ValueError as exc:
                raise MetadataError(f"{src}: distortion parameter {par.text!r} is not numeric") from exc
        fn = d_el.find("function")
        dist = RaytrixDistortion(type=d_el.get("type", "radial"),
                                 function=(fn.text or "").strip() if fn is not None else "constant",
                                 parameters=tuple(params),
                                 offset=_pair(d_el.find("offset"), "distortion/offset", src, (0.0, 0.0)))
    types = []
    for t in root.findall("lens_type"):
        try:
            tid = int(t.get("id", len(types)))
        except ValueError as exc:
            raise MetadataError(f"{src}: lens_type id {t.get('id')!r} is not an integer") from exc
        dr = t.find("depth_range")
        rng = None if dr is None else (_float(dr.find("min"), "depth_range/min", src),
                                       _float(dr.find("max"), "depth_range/max", src))
        types.append(RaytrixLensType(tid, _pair(t.find("offset"), "lens_type/offset", src, (0.0, 0.0)), rng))
    cal = RaytrixCalibration(
        offset=_pair(root.find("offset"), "offset", src) or _missing(src, "offset"),
        diameter=_float(root.find("diameter"), "diameter", src),
        rotation=_float(root.find("rotation"), "rotation", src) if root.find("rotation") is not None else 0.0,
        lens_border=_float(root.find("lens_border"), "lens_border", src) if root.find("lens_border") is not None else 0.0,
        tcp=_float(root.find("tcp"), "tcp", src) if root.find("tcp") is not None else None,
        lens_base_x=_pair(root.find("lens_base_x"), "lens_base_x", src, (1.0, 0.0)),
        lens_base_y=_pair(root.find("lens_base_y"), "lens_base_y", src, (0.5, -math.sqrt(3) / 2)),
        sub_grid_base=_pair(root.find("sub_grid_base"), "sub_grid_base", src),
        distortion=dist,
        lens_types=tuple(types),
        version=root.get("version", "1.0"),
    )
    if not cal.diameter > 0:
        raise MetadataError(f"{src}: diameter is {cal.diameter}, expected a positive lens pitch in pixels")
    return cal


def _missing(src: str, what: str):
    raise MetadataError(f"{src}: RayCalibData has no <{what}>; expected a complete Raytrix calibration file")


# ----------------------------------------------------------------------------- geometry
def _xml_to_rc(v: tuple[float, float], rotation: float, scale: float) -> np.ndarray:
    """A vector of the XML frame (x right, y up; rotated by ``rotation``) in sensor (row, col) px."""
    c, s = math.cos(rotation), math.sin(rotation)
    x, y = v
    xr, yr = x * c - y * s, x * s + y * c
    return np.array([-yr, xr]) * scale


def centre_lens_position(cal: RaytrixCalibration, sensor_shape: tuple[int, int]) -> np.ndarray:
    """Sensor (row, col) of the centre lens: ``(H/2 - offset.y, W/2 + offset.x)``."""
    h, w = sensor_shape
    return np.array([h / 2.0 - cal.offset[1], w / 2.0 + cal.offset[0]])


def _lens_colours(bx: tuple[float, float], by: tuple[float, float]) -> int:
    """``k`` of the 3-colouring ``c = (m + k n) mod 3`` of the lattice spanned by bx, by."""
    return -1 if (bx[0] * by[0] + bx[1] * by[1]) > 0 else 1


def _lattice_coords(v: tuple[float, float], bx, by, what: str) -> tuple[int, int]:
    """Integer (m, n) with ``v = m bx + n by`` (lens units); MetadataError if not integral."""
    sol = np.linalg.solve(np.array([[bx[0], by[0]], [bx[1], by[1]]], np.float64), np.asarray(v, np.float64))
    r = np.rint(sol)
    if np.max(np.abs(sol - r)) > 0.05:
        raise MetadataError(f"{what} {tuple(v)} is not a lattice vector of lens_base_x/lens_base_y "
                            f"(coordinates {sol.round(3).tolist()}); the calibration is inconsistent")
    return int(r[0]), int(r[1])


def grid_from_raycalib(cal: RaytrixCalibration, sensor_shape: tuple[int, int]) -> LensletGrid:
    """The hexagonal lenslet grid described by a RayCalibData calibration, used as given.

    Parameters
    ----------
    cal : RaytrixCalibration
    sensor_shape : (H, W)
        Size of the image the calibration belongs to.

    Returns
    -------
    LensletGrid
        ``pitch = |diameter * base_x|``; ``rotation`` = angle of ``base_x`` in (row, col);
        ``row_spacing`` = component of ``diameter * base_y`` across the rows (the row index
        grows downwards); ``shape`` is the smallest block of lens rows x columns holding every
        lens whose centre lies on the sensor (``-0.5 <= row <= H - 0.5``, same for columns).
        Lens rows of the centre lens's parity are the unshifted ones, the others are shifted
        by the along-row component of ``base_y`` (mod 1; 0.5 for hex), so ``odd_row_shift``
        is +0.5, or -0.5 when the block's first row is a shifted one (the convention of
        :func:`plenodecode.synthetic.make_grid`).  ``radius = diameter / 2 - lens_border``;
        ``lens_type`` (int8) from the rule in the module docstring (None without lens types);
        ``info['raytrix']`` = ``cal.to_dict()``, ``info['centre_lens']`` = its (i, j).

    Raises
    ------
    MetadataError
        Degenerate base vectors, a row shift other than 0 or half a pitch, or lens-type offsets
        that do not form a 3-colouring of the hexagonal lattice.
    """
    h, w = int(sensor_shape[0]), int(sensor_shape[1])
    if h <= 0 or w <= 0:
        raise ValueError(f"sensor_shape must be positive (H, W), got {sensor_shape}")
    d = float(cal.diameter)
    vx = _xml_to_rc(cal.lens_base_x, cal.rotation, d)
    vy = _xml_to_rc(cal.lens_base_y, cal.rotation, d)
    pitch = float(np.hypot(*vx))
    if pitch < 1e-6:
        raise MetadataError("lens_base_x has zero length; the calibration is unusable")
    theta = math.atan2(vx[0], vx[1])
    e_row = np.array([math.cos(theta), -math.sin(theta)])
    e_col = np.array([math.sin(theta), math.cos(theta)])
    rs = float(vy @ e_row)
    n_sign = 1
    if rs < 0:                        # make the row index grow along +e_row
        vy, rs, n_sign = -vy, -rs, -1
    if rs < 1e-3 * pitch:
        raise MetadataError(f"lens_base_x {cal.lens_base_x} and lens_base_y {cal.lens_base_y} are parallel; "
                            "the calibration is unusable")
    along = float(vy @ e_col) / pitch
    two_along = int(round(2 * along))
    if abs(2 * along - two_along) > 1e-3:
        raise MetadataError(f"lens_base_y shifts each lens row by {along:.4f} pitch; only 0 or 1/2 "
                            "(square or hexagonal grids) are supported")
    shift = 0.5 * (two_along % 2)

    p0 = centre_lens_position(cal, (h, w))
    corners = np.array([[-0.5, -0.5], [-0.5, w - 0.5], [h - 0.5, -0.5], [h - 0.5, w - 0.5]]) - p0
    a_c, b_c = corners @ e_row, corners @ e_col
    n_lo, n_hi = math.floor(a_c.min() / rs) - 1, math.ceil(a_c.max() / rs) + 1
    off_lo = min(n_lo * two_along, n_hi * two_along) / 2.0
    off_hi = max(n_lo * two_along, n_hi * two_along) / 2.0
    m_lo = math.floor(b_c.min() / pitch - off_hi) - 1
    m_hi = math.ceil(b_c.max() / pitch - off_lo) + 1
    nn, mm = np.meshgrid(np.arange(n_lo, n_hi + 1), np.arange(m_lo, m_hi + 1), indexing="ij")
    a = nn * rs
    b = (mm + nn * two_along / 2.0) * pitch
    pos = p0 + a[..., None] * e_row + b[..., None] * e_col
    on = ((pos[..., 0] >= -0.5) & (pos[..., 0] <= h - 0.5) & (pos[..., 1] >= -0.5) & (pos[..., 1] <= w - 0.5))
    if not on.any():
        raise MetadataError(f"no lens centre of the calibration falls on a {h}x{w} sensor; wrong image or XML")
    # Rows of the centre lens's parity sit at whole pitches from it, the others at +shift:
    # b = (jj + shift * (n' mod 2)) * pitch with jj = m + floor(n' * along).
    jj = mm + (nn * two_along) // 2
    n0 = int(nn[on].min())
    j0 = int(jj[on].min())
    rows = int(nn[on].max()) - n0 + 1
    cols = int(jj[on].max()) - j0 + 1
    first_odd = n0 % 2 == 1
    odd_row_shift = -shift if first_odd else shift
    origin = p0 + (n0 * rs) * e_row + ((j0 + (shift if first_odd else 0.0)) * pitch) * e_col
    lattice = "hex" if shift else "square"

    lens_type = None
    ii, jg = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    n_row = ii + n0                              # n' of lens (i, j)
    m_idx = jg + j0 - (n_row * two_along) // 2   # XML m of lens (i, j)
    n_idx = n_sign * n_row                       # XML n of lens (i, j)
    if len(cal.lens_types) == 1:
        lens_type = np.full((rows, cols), cal.lens_types[0].id, np.int8)
    elif len(cal.lens_types) == 3 and lattice == "hex":
        k = _lens_colours(cal.lens_base_x, cal.lens_base_y)
        lut = np.full(3, -1, np.int64)
        for t in cal.lens_types:
            mt, nt = _lattice_coords(t.offset, cal.lens_base_x, cal.lens_base_y, f"lens_type {t.id} offset")
            c = (mt + k * nt) % 3
            if lut[c] != -1:
                raise MetadataError(f"lens types {lut[c]} and {t.id} have offsets of the same colour; expected "
                                    "three interleaved lens types on a hexagonal grid")
            lut[c] = t.id
        lens_type = lut[(m_idx + k * n_idx) % 3].astype(np.int8)
        if cal.sub_grid_base is not None:
            try:
                sm, sn = _lattice_coords(cal.sub_grid_base, cal.lens_base_x, cal.lens_base_y, "sub_grid_base")
                if (sm + k * sn) % 3:
                    log.warning("sub_grid_base %s joins lenses of different types under the 3-colouring rule",
                                cal.sub_grid_base)
            except MetadataError as exc:
                log.warning("%s", exc)
    elif len(cal.lens_types) > 1:
        raise MetadataError(f"{len(cal.lens_types)} lens types on a {lattice} grid: only 1 type, or 3 interleaved "
                            "types on a hexagonal grid, are supported")

    i_c, j_c = -n0, -j0
    return LensletGrid(
        lattice=lattice, pitch=pitch, row_spacing=rs, rotation=theta, origin=(float(origin[0]), float(origin[1])),
        shape=(rows, cols), odd_row_shift=odd_row_shift, sensor_shape=(h, w), radius=d / 2.0 - float(cal.lens_border),
        lens_type=lens_type,
        info={"source": "RayCalibData", "raytrix": cal.to_dict(), "centre_lens": [int(i_c), int(j_c)]},
    )


def raycalib_from_grid(grid: LensletGrid, *, template: RaytrixCalibration | None = None) -> RaytrixCalibration:
    """The RayCalibData description of a lenslet grid (inverse of :func:`grid_from_raycalib`).

    The centre lens is the lens nearest to the sensor centre ``(H/2, W/2)`` on an unshifted
    row (even rows for ``odd_row_shift > 0``, odd rows otherwise), so the row parity, and with
    it the grid's (i, j) indexing, survives the round trip;
    ``base_x = (1, 0)``, ``base_y = (shift', -row_spacing / pitch)`` with ``shift'`` the
    row-to-row shift in ``[0, 1)`` pitches, ``rotation = -grid.rotation``.  Lens types must be
    a 3-colouring of the hex lattice (or a single type).  ``tcp``, ``lens_border``, depth
    ranges and distortion come from ``template`` (default: ``grid.info['raytrix']`` when
    present; else ``lens_border = pitch / 2 - radius`` and no tcp / depth ranges).

    Raises
    ------
    ValueError
        ``grid.lens_type`` cannot be described by RayCalibData lens types.
    """
    if template is None and grid.info.get("raytrix"):
        template = RaytrixCalibration.from_dict(grid.info["raytrix"])
    h, w = grid.sensor_shape
    centres = grid.lattice_centres()
    dist = np.hypot(centres[..., 0] - h / 2.0, centres[..., 1] - w / 2.0)
    if grid.odd_row_shift != 0 and grid.shape[0] > 1:
        unshifted = 0 if grid.odd_row_shift > 0 else 1
        dist[(np.arange(grid.shape[0]) % 2) != unshifted] = np.inf
    ic, jc = np.unravel_index(int(np.argmin(dist)), dist.shape)
    c = centres[ic, jc]
    shift = grid.odd_row_shift * (1 if ic % 2 == 0 else -1)
    shift = shift - math.floor(shift)
    bx = (1.0, 0.0)
    by = (float(shift), -grid.row_spacing / grid.pitch)

    types: tuple[RaytrixLensType, ...] = ()
    tmpl_types = {t.id: t for t in (template.lens_types if template else ())}
    if grid.lens_type is not None:
        ids = np.unique(grid.lens_type)
        if ids.size == 1:
            tid = int(ids[0])
            types = (RaytrixLensType(tid, (0.0, 0.0), getattr(tmpl_types.get(tid), "depth_range", None)),)
        else:
            if grid.lattice != "hex" or ids.size > 3:
                raise ValueError(f"grid.lens_type has {ids.size} types on a {grid.lattice} grid; RayCalibData "
                                 "describes 1 type or 3 interleaved types on a hexagonal grid")
            k = _lens_colours(bx, by)
            ii, jj = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
            # XML (m, n) of every lens relative to the centre lens: n = i - ic, b-offset in pitches
            b_rel = (jj - jc) + grid.odd_row_shift * ((ii % 2) - (ic % 2))
            n = ii - ic  # base_y has y < 0 (down in the image), so n grows with the lens row
            m = np.rint(b_rel - n * shift).astype(np.int64)
            colour = (m + k * n) % 3
            found = []
            for cidx, off in zip(range(3), ((0.0, 0.0), (1.0, 0.0), (-1.0, 0.0))):
                vals = np.unique(grid.lens_type[colour == cidx])
                if vals.size != 1:
                    raise ValueError("grid.lens_type is not a 3-colouring of the hexagonal lattice; RayCalibData "
                                     "lens types cannot describe it")
                tid = int(vals[0])
                found.append(RaytrixLensType(tid, off, getattr(tmpl_types.get(tid), "depth_range", None)))
            if len({t.id for t in found}) != 3:
                raise ValueError("grid.lens_type repeats a type among neighbouring lenses; expected three "
                                 "interleaved types")
            types = tuple(sorted(found, key=lambda t: t.id))
    return RaytrixCalibration(
        offset=(float(c[1] - w / 2.0), float(h / 2.0 - c[0])),
        diameter=float(grid.pitch),
        rotation=float(-grid.rotation),
        lens_border=template.lens_border if template else float(grid.pitch / 2.0 - grid.radius),
        tcp=template.tcp if template else None,
        lens_base_x=bx, lens_base_y=by,
        sub_grid_base=(3.0, 2 * by[1]) if len(types) == 3 else None,
        distortion=template.distortion if template else None,
        lens_types=types,
    )


# ----------------------------------------------------------------------------- images
def _luminance_u16(img: np.ndarray) -> np.ndarray:
    """Rec. 709 luma of the stored RGB values, scaled to the uint16 range."""
    wts = np.asarray(LUMA_WEIGHTS, np.float64)
    y = img[..., :3].astype(np.float64) @ wts
    if img.dtype == np.uint8:
        y *= 65535.0 / 255.0
    elif img.dtype.kind == "f":
        y *= 65535.0
    return np.rint(np.clip(y, 0, 65535)).astype(np.uint16)


def read_raytrix_rgb(path: str | os.PathLike) -> np.ndarray:
    """The stored RGB image of a Raytrix export (already demosaiced by RxLive).

    Returns
    -------
    ndarray, shape (H, W, 3), stored dtype (uint8 / uint16)

    Raises
    ------
    FormatError
        The image is single-channel (a sensor mosaic: use :func:`read_raytrix`).
    """
    img = read_image(path)
    if img.ndim != 3 or img.shape[2] < 3:
        raise FormatError(f"{path}: a 3-channel RGB export is expected, found a single-channel image; "
                          "read it as a mosaic with read_raytrix")
    return np.ascontiguousarray(img[..., :3])


def is_rgb_export(raw: RawCapture) -> bool:
    """True for a Raytrix RGB export read by :func:`read_raytrix` (its mosaic is the luminance; the colour is
    in the file: :func:`read_raytrix_linear_rgb`)."""
    extra = raw.metadata.extra
    return "raytrix" in extra and int(extra.get("stored_channels", 1)) >= 3 and raw.path is not None


def read_raytrix_linear_rgb(path: str | os.PathLike) -> np.ndarray:
    """The RGB export of :func:`read_raytrix_rgb` as linear sRGB values in [0, 1].

    An RxLive export is an image for display (8-bit sRGB, demosaiced: on the R42 crop the three channels
    differ, means 106 / 78 / 71 of 255, and no 2 x 2 Bayer pattern is left); the values are taken as
    sRGB-encoded and decoded with the inverse sRGB transfer function ``L = V / 12.92`` for ``V <= 0.04045``, else ``((V + 0.055) / 1.055) ** 2.4``
    (:func:`plenodecode.io.images.srgb_decode`) with ``V = stored / full scale``.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
    """
    from .images import srgb_decode

    rgb = read_raytrix_rgb(path)
    scale = float(np.iinfo(rgb.dtype).max) if rgb.dtype.kind in "ui" else 1.0
    return srgb_decode(rgb / scale).astype(np.float32)


def rgb_export_channels(raw: RawCapture) -> list[RawCapture]:
    """The three colour channels of a Raytrix RGB export (:func:`is_rgb_export`) as monochrome captures:
    mosaic ``rint(65535 * L_c)`` uint16 of the linear values ``L_c`` (:func:`read_raytrix_linear_rgb`),
    black 0, white 65535, the raw's metadata and path; each decodes like the luminance capture."""
    from dataclasses import replace

    rgb = read_raytrix_linear_rgb(raw.path)
    return [replace(raw, mosaic=np.rint(rgb[..., c] * 65535.0).astype(np.uint16), cfa=None,
                    black=np.zeros((2, 2)), white=np.full((2, 2), 65535.0)) for c in range(3)]


def read_raytrix(path: str | os.PathLike, *, xml: str | os.PathLike | None = None) -> RawCapture:
    """Read a Raytrix image + RayCalibData XML into a RawCapture.

    The XML is ``xml`` when given, else the one beside the image (:func:`calibration_xml_for`: same stem,
    or the only RayCalibData XML in the folder).

    A single-channel image is the sensor mosaic as stored (uint8 values kept, white 255);
    its CFA and levels come from a JSON sidecar (:func:`plenodecode.io.generic.read_sidecar`)
    when there is one, else monochrome, black 0, white ``2**bits - 1``.  An RGB export (the
    real R42 crop is 8-bit RGB, demosaiced by RxLive) becomes one luminance channel
    (Rec. 709 luma of the stored values, scaled to 0..65535, white 65535, cfa None); the RGB
    image stays available through :func:`read_raytrix_rgb`.

    ``metadata.extra['raytrix']`` holds :meth:`RaytrixCalibration.to_dict`,
    ``extra['raytrix_xml']`` the XML path and ``extra['stored_channels']`` the channel count.

    Raises
    ------
    MetadataError
        No RayCalibData XML beside the image, or a malformed one.
    FormatError
        Unreadable image.
    """
    p = Path(path)
    xml = calibration_xml_for(p, xml)
    if xml is None:
        raise MetadataError(f"{p}: no RayCalibData XML beside it ({p.with_suffix('.xml').name}, or the only XML in "
                            "the folder); export the calibration from RxLive next to the image or pass --raytrix-xml")
    cal = parse_raycalib(xml)
    img = read_image(p)
    extra: dict[str, Any] = {"raytrix": cal.to_dict(), "raytrix_xml": str(xml),
                             "stored_channels": 1 if img.ndim == 2 else int(img.shape[2])}
    side = find_sidecar(p)
    sc = read_sidecar(side) if side is not None else None
    if img.ndim == 3:
        if img.shape[2] < 3:
            raise FormatError(f"{p}: {img.shape[2]}-channel image; expected a mosaic or an RGB export")
        log.info("%s: RGB Raytrix export (already demosaiced); using its Rec. 709 luminance as the mosaic", p)
        mosaic = _luminance_u16(img)
        cfa, black, white = None, np.zeros((2, 2)), np.full((2, 2), 65535.0)
        extra["rgb_to_grey"] = "rec709 luma of stored values, scaled to 16 bit"
    else:
        if img.dtype not in (np.uint8, np.uint16):
            raise FormatError(f"{p}: samples of type {img.dtype}; expected an 8- or 16-bit mosaic")
        mosaic = img.astype(np.uint16)
        top = float(np.iinfo(img.dtype).max)
        cfa = sc["cfa"] if sc else None
        black = sc["black"] if sc and sc["black"] is not None else np.zeros((2, 2))
        white = sc["white"] if sc and sc["white"] is not None else np.full((2, 2), top)
    base = sc["metadata"] if sc else CameraMetadata(make="Raytrix")
    meta = CameraMetadata.from_dict({**base.to_dict(), "extra": {**dict(base.extra), **extra}})
    return RawCapture(mosaic, cfa, black, white, meta, str(p))


def write_raytrix(path: str | os.PathLike, raw: RawCapture, grid: LensletGrid, *, overwrite: bool = False) -> Path:
    """Write a Raytrix-style pair: 16-bit PNG/TIFF mosaic, ``X.xml`` (RayCalibData) and ``X.json``.

    The XML comes from :func:`raycalib_from_grid`, so :func:`parse_raycalib` +
    :func:`grid_from_raycalib` give back the grid's lattice; the JSON sidecar carries cfa, levels
    and camera metadata so :func:`read_raytrix` returns an equal RawCapture.  All files are
    written to temporary names first and renamed.

    Returns
    -------
    Path
        The image file.
    """
    p = Path(path)
    if p.suffix.lower() not in (".png", ".tif", ".tiff"):
        raise ValueError(f"path must end in .png, .tif or .tiff, got {p.name!r}")
    if tuple(grid.sensor_shape) != tuple(raw.shape):
        raise ValueError(f"grid.sensor_shape {grid.sensor_shape} differs from the raw's shape {raw.shape}")
    xml, side, stale = p.with_suffix(".xml"), p.with_suffix(".json"), p.with_name(p.name + ".json")
    refuse_existing([stale], overwrite)
    cal = raycalib_from_grid(grid)
    with atomic_outputs([p, xml, side], overwrite=overwrite, keep_suffix=True) as (tmp, tmp_xml, tmp_side):
        tmp_xml.write_text(cal.to_xml(), encoding="utf-8")
        tmp_side.write_text(json.dumps(sidecar_document(raw), indent=1), encoding="utf-8")
        write_image(tmp, raw.mosaic, bit_depth=16, overwrite=True, attributes=_FAST_PNG)
    if stale.exists():
        stale.unlink()
    return p


__all__ = ["RaytrixCalibration", "RaytrixLensType", "RaytrixDistortion", "find_calibration_xml",
           "calibration_xml_for", "is_raycalib_xml", "is_rgb_export", "read_raytrix_linear_rgb", "rgb_export_channels",
           "parse_raycalib", "grid_from_raycalib", "raycalib_from_grid", "centre_lens_position",
           "read_raytrix", "read_raytrix_rgb", "write_raytrix"]
