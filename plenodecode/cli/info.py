"""``plenodecode info FILE...``: describe raws and Lytro containers without decoding them (with the calibration
decoding would choose: the lens pitch it reads or measures, its files, the decoded shape), and saved light fields
(shape, colour, camera constants); both with the refocusable range (:mod:`plenodecode.render.alpha`)."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import click

from ..errors import FormatError, PlenodecodeError
from .common import RAYTRIX_XML_META, raytrix_xml_option


def _levels(a) -> str:
    vals = sorted({float(v) for v in a.ravel()})
    return "/".join(f"{v:g}" for v in vals)


def _camera_lines(model, make, serial, extra: str = "") -> list[str]:
    cam = model or "model not recorded"
    if make:
        cam += f" ({make})"
    return [f"  camera   {cam}{extra}", f"  serial   {serial or '-'}"]


def _sensor_by_size(camera, shape, *, whose: str = "the file") -> str | None:
    """'Lytro F01 (by its 3280 x 3280 sensor; the file has no camera metadata)' for a mosaic without a sidecar
    (``camera``: its CameraMetadata) at the size (rows, cols) of a known lenslet sensor, as the reader recognised it
    to choose its CFA and levels, else None."""
    from ..io.generic import BARE_MOSAIC_KEY
    from ..io.mosaic_levels import KNOWN_SENSORS

    sensor = KNOWN_SENSORS.get(tuple(shape)) if BARE_MOSAIC_KEY in (camera.extra or {}) else None
    if sensor is None:
        return None
    return f"{sensor.name} (by its {shape[1]} x {shape[0]} sensor; {whose} has no camera metadata)"


def _describe_container(path: Path) -> list[str]:
    from ..io import lytro

    c = lytro.read_container(path)
    lines = [f"{path}: Lytro container ({len(c.sections)} sections)"]
    make = lytro.lookup(c.metadata, "camera", "make")
    lines += _camera_lines(c.model, make if isinstance(make, str) else None, c.serial,
                           " (inferred from the TOC layout)" if c.model_source == "toc layout" else "")
    if c.kind == "raw":
        kind = "raw, white image" if c.white_image else "raw"
    else:
        kind = {"processed": "processed (Lytro Desktop output, no raw inside)",
                "calibration": "calibration archive (data.C.N)"}[c.kind]
    lines.append(f"  kind     {kind}")
    if c.metadata is not None and _has_image(c.metadata):
        try:
            cam, cfa, black, white, w, h, bits, endian = lytro.metadata_from_lytro(
                c.metadata, c.private_metadata, path, white_image=c.white_image)
        except PlenodecodeError as exc:
            lines.append(f"  metadata unreadable: {exc}")
        else:
            if c.kind == "raw":
                lines.append(f"  raw      {w} x {h}, {bits} bit ({endian}), {cfa}, black {_levels(black)}, "
                             f"white {_levels(white)}")
            else:
                lines.append(f"  sensor   {w} x {h}, {bits} bit, {cfa} (the raw is not in this file)")
            lines += _lens_lines(cam)
            if c.kind == "raw" and not c.white_image:
                from ..pipeline import open_raw

                lines += _calibration_lines(open_raw(path))
    images = [it for it in c.contents() if it.type != "json"]
    if images:
        lines.append("  contents")
        for it in images:
            lines.append(f"    {it.name:22s} {it.describe()}, {it.size} B")
    lines.append("  sections")
    lines.append(f"    {'kind':4s} {'offset':>10s} {'length':>10s}  {'sha1':12s}  toc key")
    for s in c.sections:
        it = c.item(s.sha1)
        role = "table of contents" if s.kind == "LFM" else \
            f"{it.key}  [{it.name}: {it.type}]" if it is not None else "(not referenced by the TOC)"
        lines.append(f"    {s.kind:4s} {s.offset:10d} {s.length:10d}  {s.sha1[5:17]:12s}  {role}")
    return lines


def _has_image(meta) -> bool:
    return isinstance(meta, Mapping) and isinstance(meta.get("image"), Mapping)


def _lens_lines(cam) -> list[str]:
    parts = []
    if cam.zoom_step is not None or cam.focus_step is not None:
        parts.append(f"zoom step {cam.zoom_step:g}" if cam.zoom_step is not None else "zoom step ?")
        parts.append(f"focus step {cam.focus_step:g}" if cam.focus_step is not None else "focus step ?")
    if cam.focal_length_m is not None:
        parts.append(f"f = {cam.focal_length_m * 1e3:.2f} mm")
    if cam.f_number is not None:
        parts.append(f"f/{cam.f_number:.2f}")
    if cam.exposure_s is not None:
        parts.append(f"{cam.exposure_s * 1e3:.2f} ms")
    if cam.iso is not None:
        parts.append(f"ISO {cam.iso:g}")
    pitch = cam.lenslet_pitch_px()
    if pitch:
        parts.append(f"lenslet pitch {pitch:.3f} px (metadata)")
    return [f"  lens     {', '.join(parts)}"] if parts else []


def _raw_refocus_lines(cam) -> list[str]:
    """The refocusable range of a Lytro raw from its metadata alone, when it has no calibration: hex lenslets (row
    spacing = pitch * sqrt(3) / 2, the decoder's spatial step) and one view per sensor pixel; nothing for other
    cameras, whose lattice is known only after calibration."""
    import math

    from ..render.alpha import refocus_range_units
    from ..types import LightFieldGeometry

    pitch = cam.lenslet_pitch_px()
    if not (cam.make or "").lower().startswith("lytro") or not pitch or cam.is_white_image:   # 'Lytro, Inc.' too
        return []
    geometry = LightFieldGeometry.from_camera(cam, {"pitch": pitch}, spatial_step_px=pitch * math.sqrt(3) / 2,
                                              view_step_px=1.0)
    return [f"  refocus  {refocus_range_units(geometry).describe()} (from the metadata, hex lenslets)"]


def _how_measured(cal) -> str:
    """Where the pitch of the calibration ``cal`` (a :class:`~plenodecode.pipeline.Calibration`) comes from."""
    if cal.source == "camera":
        return ("read from " + cal.detail.strip("()").replace("Raytrix RayCalibData ", "") if cal.white is None
                else "measured on the picture's own white image (modulationDataRef)")
    if cal.source == "self-calibration":
        return "measured in the scene by self-calibration"
    if cal.source == "grid file":
        return f"from the grid {Path(cal.detail.split(' (')[0]).name}"
    name = Path(cal.white.path).name if cal.white is not None and cal.white.path else "the white image"
    return f"measured on the white image {name}"


def _calibration_lines(raw) -> list[str]:
    """What decoding ``raw`` (a :class:`~plenodecode.types.RawCapture`, read as decoding reads it) would use and
    give, with the calibration it chooses (:func:`plenodecode.pipeline.choose_calibration`, the database it finds):
    the lens pitch (measured or read, and where; beside the metadata's), the calibration and its files, the
    decoded shape and the refocusable range.  Without a calibration: why, and the metadata's range (Lytro)."""
    import numpy as np

    from ..calib.store import find_database
    from ..decoding.rectify import decoded_geometry, decoded_shape
    from ..errors import CalibrationError
    from ..io.generic import BARE_MOSAIC_KEY, is_bare_mosaic
    from ..io.mosaic_levels import nearly_uniform
    from ..pipeline import choose_calibration
    from ..pipeline.inputs import quieted
    from ..render.alpha import missing_refocus_constants, refocus_range_units

    m = raw.metadata
    lines = []
    if m.microscope is not None and not m.microscope.empty:
        from ..io.microscope import optics_and_file_beside

        found = optics_and_file_beside(raw.path) if raw.path else None
        lines.append(f"  optics   {m.microscope.describe()}" + (f" (read from {found[1].name})" if found else ""))
    full = (m.extra.get(BARE_MOSAIC_KEY) or {}).get("file_full_scale") or float(np.max(raw.white))
    flat = nearly_uniform(raw.mosaic, float(full))
    if flat is not None:       # self-calibration would only fail on it, after seconds
        return lines + [f"  calib    none: no micro-images (98 % of the values within {flat[0]:g}..{flat[1]:g}); a "
                        "dark frame is given to decoding as --dark FRAME"]
    try:
        db = find_database(raw.path)                        # named in full: info may be run from anywhere
        with quieted("plenodecode.pipeline.calibration"):   # the line below says it (and, for a mosaic, why)
            cal = choose_calibration(raw, database=None if db is None else db.resolve())
    except CalibrationError as exc:
        return lines + [f"  calib    none found: {exc}"] + _raw_refocus_lines(m)
    g = cal.grid
    said, where = m.lenslet_pitch_px(), "the metadata"
    if said is None and m.microscope and m.microscope.lens_pitch_m and m.microscope.pixel_pitch_m:
        said, where = m.microscope.lens_pitch_m / m.microscope.pixel_pitch_m, "the optics"
    types = f", {len(set(g.lens_type.ravel().tolist()))} lens types" if g.lens_type is not None else ""
    lines.append(f"  lenses   {g.lattice}, pitch {g.pitch:.3f} px {_how_measured(cal)}"
                 + (f" ({where}: {said:.3f} px)" if said else "")
                 + f"; {g.shape[0]} x {g.shape[1]} lenses{types}")
    why = ""
    if cal.source == "self-calibration":
        from ..io.microscope import flat_field_beside, is_flat_field_name

        frame = flat_field_beside(raw.path) if raw.path else None
        why = (" (no white image" + (" or camera identity for a database" if is_bare_mosaic(raw) else "")
               + ": not devignetted" + ("; stays camera RGB, no colour matrix" if raw.cfa and m.ccm is None else "")
               + (f"; -w {frame}, the flat-field frame beside it, calibrates and devignettes)" if frame
                  else "; -w WHITE_IMAGE devignettes)"))
        if raw.path and is_flat_field_name(raw.path):
            why = (" (by its name the flat-field frame: given as -w to decode the light fields beside it, it "
                   "calibrates and devignettes them)")
    lines.append(f"  calib    {cal.source} {cal.detail}{why}")
    if g.lens_type is not None:
        from ..decoding.focused import shown_virtual_depth_range

        lo, hi = shown_virtual_depth_range(g)
        return lines + [f"  refocus  virtual depth {lo:g}..{hi:g} (focused plenoptic: 'plenodecode refocus RAW "
                        "--virtual-depth V'; its lens types' depth ranges)"]
    V, U, Y, X = decoded_shape(g)
    lines.append(f"  decodes  {V} x {U} views of {X} x {Y} px")
    geometry = decoded_geometry(raw, g)
    span = refocus_range_units(geometry)
    missing = missing_refocus_constants(geometry)
    lacks = (f"; alpha needs {', '.join(missing)}, not in the file"
             if span.alpha is None and missing and m.microscope is None else "")
    return lines + [f"  refocus  {span.describe()} (from the calibration{' and the metadata' if span.alpha else ''}"
                    f"{lacks})"]


def _describe_lightfield(path: Path) -> list[str]:
    """A saved light field or an HCI scene folder: shape, colour, camera constants, refocusable range."""
    from ..pipeline import open_input
    from ..render.alpha import refocus_range_units

    lf = open_input(path)
    g = lf.geometry
    from .common import COLOUR_WORDS

    colour = "monochrome" if lf.shape[-1] == 1 else COLOUR_WORDS.get(lf.colour, lf.colour)   # as decode says it
    lines = [f"{path}: light field {' x '.join(map(str, lf.shape))} (V, U, Y, X, C), {colour}"]
    if g.hci is not None:
        lines.append("  camera   HCI scene (pinhole views, parameters.cfg)")
    elif g.camera is not None:
        source = Path(g.source).name if g.source else None
        shape = (g.calibration or {}).get("sensor_shape") or ()
        model = g.camera.model or _sensor_by_size(g.camera, shape, whose=source or "the raw")
        if model is None and source:
            model = f"model not recorded (decoded from {source})"
        lines += _camera_lines(model, g.camera.make, g.camera.serial)
    if g.spatial_step_px:
        lines.append(f"  sampling {g.spatial_step_px:.3f} px per spatial sample, {g.view_step_px or 1:g} px per view")
    consts = [f"f = {g.focal_length_m * 1e3:.2f} mm" if g.focal_length_m else "",
              f"f/{g.f_number:.2f}" if g.f_number else "",
              f"lens pitch {g.lens_pitch_m * 1e6:.2f} um" if g.lens_pitch_m else "",
              f"focus {g.focus_distance_m:.3g} m" if g.focus_distance_m else ""]
    if any(consts):
        lines.append(f"  lens     {', '.join(c for c in consts if c)}")
    lines.append(f"  refocus  {refocus_range_units(lf).describe()}")
    return lines


def _raw_metadata_lines(title: str, metadata: tuple, kind: str) -> list[str]:
    """Title, camera, serial, kind, raw layout and lens of a headerless Lytro raw, from the tuple
    :func:`plenodecode.io.lytro.metadata_from_lytro` returns."""
    cam, cfa, black, white, w, h, bits, endian = metadata
    lines = [title, *_camera_lines(cam.model, cam.make, cam.serial), f"  kind     {kind}",
             f"  raw      {w} x {h}, {bits} bit ({endian}), {cfa}, black {_levels(black)}, white {_levels(white)}"]
    return lines + _lens_lines(cam) + (_raw_refocus_lines(cam) if kind == "metadata of a raw" else [])


def _describe_raw_pair(path: Path) -> list[str]:
    from ..io import lytro
    from ..pipeline import open_raw

    metadata = lytro.read_raw_pair_metadata(path)
    side = lytro.find_sidecar(path)
    white = metadata[0].is_white_image
    lines = _raw_metadata_lines(f"{path}: headerless Lytro raw with metadata {side.name if side else '?'}",
                                metadata, "raw, white image" if white else "raw")
    return lines if white else lines + _calibration_lines(open_raw(path))


def _describe_sidecar(path: Path) -> list[str]:
    """A Lytro JSON metadata file on its own (``MOD_NNNN.TXT``, ``*__frame.json``): what the raw it
    describes is, and whether that raw is beside it."""
    from ..errors import MetadataError
    from ..io import lytro

    try:
        doc = lytro.read_sidecar(path)
    except FormatError:         # a .txt that is no JSON: not the damaged sidecar of a raw, just another file
        if not any(path.with_suffix(ext).is_file() for ext in (".RAW", ".raw")):
            raise FormatError(f"{path}: not JSON, so not the metadata of a Lytro raw (MOD_NNNN.TXT, *__frame.json); "
                              "info describes raws, containers, their metadata and light fields") from None
        raise
    other = _describe_project_json(path, doc) if isinstance(doc, Mapping) else None
    if other is not None:
        return other
    try:
        if not isinstance(doc, Mapping):
            raise MetadataError(f"expected a JSON object, found {type(doc).__name__}")
        metadata = lytro.metadata_from_lytro(doc, None, path)
    except MetadataError as exc:
        raise FormatError(f"{path}: JSON, but not Lytro frame metadata ({exc}); info describes raws, containers "
                          "and the .TXT/.json metadata of Lytro raws") from None
    raw = next((r for r in (path.with_suffix(".RAW"), path.with_suffix(".raw")) if r.is_file()), None)
    beside = f"{raw.name} is beside it" if raw else f"no {path.stem}.RAW beside it"
    return _raw_metadata_lines(f"{path}: Lytro metadata for a headerless raw ({beside})", metadata,
                               "metadata of a white image" if metadata[0].is_white_image else "metadata of a raw")


def _describe_project_json(path: Path, doc: Mapping) -> list[str] | None:
    """The JSON files a user meets beside raws that are not Lytro metadata: a lenslet grid, a mosaic's sidecar,
    a synthetic raw's ground truth, a calibration database's index, a geometric calibration (this project's or
    the toolbox's CalInfo.json); None for any other JSON."""
    from ..io.calinfo import TOOLBOX_KEYS
    from ..io.discovery import MOSAIC_SUFFIXES

    kind = doc.get("format")
    if kind == "plenodecode.LensletGrid":
        from ..calib.grid import SOURCE_KINDS
        from ..report.calibration import angle_text, rms_text, source_kind
        from ..types import LensletGrid

        g = LensletGrid.from_dict(doc)
        white = Path(str(g.info["source"])).name if g.info.get("source") else None
        kind = source_kind(g)
        source = (f"from {white}" if white else "origin not recorded") if kind == "grid-file" else \
            SOURCE_KINDS[kind] + (f": {white}" if white else "")
        return [f"{path}: lenslet grid ({source})",
                f"  lattice  {g.lattice}, pitch {g.pitch:.4f} px, rotation {angle_text(g.rotation)}, "
                f"{g.shape[0]} x {g.shape[1]} lenses (rows x cols), lattice RMS {rms_text(g)}",
                f"  sensor   {g.sensor_shape[1]} x {g.sensor_shape[0]}; {g.n_views()} x {g.n_views()} views "
                "when decoded"]
    if kind == "plenodecode.mosaic":
        image = next((path.with_suffix(ext) for ext in MOSAIC_SUFFIXES if path.with_suffix(ext).is_file()), None)
        if image is None:
            return [f"{path}: JSON sidecar of a mosaic image, but no {path.stem}.png/.tif/... is beside it"]
        return [f"{path}: JSON sidecar of {image.name}", *_describe_other(image)[1:]]
    if kind == "plenodecode.SyntheticTruth":
        shape = doc.get("preset_params", {}).get("sensor_shape") or ["?", "?"]
        return [f"{path}: ground truth of a raw 'plenodecode synth' generated (grid, lens centres, disparity)",
                f"  preset   {doc.get('preset', '?')}, seed {doc.get('seed', '?')}, sensor {shape[1]} x {shape[0]}"]
    if kind == "plenodecode.calibration-db":
        return _describe_database(path.parent, title=f"{path}: calibration database index")
    if kind == "plenodecode-geometric-calibration" or all(k in doc for k in TOOLBOX_KEYS):
        import numpy as np

        from ..io.calinfo import load_geometric_calibration

        cal = load_geometric_calibration(path)
        V, U, Y, X = cal.lf_shape
        what = "the Light Field Toolbox's CalInfo.json" if kind is None else "'plenodecode calibrate-geometry'"
        k = ", ".join(f"{v:.4g}" for v in cal.distortion)
        return [f"{path}: geometric calibration ({what}): the ray model H and the lens distortion",
                f"  for      light fields of {V} x {U} views of {Y} x {X} (V x U x Y x X)" if V else
                "  for      light fields of an unrecorded shape",
                f"  H        {np.array2string(cal.intrinsics, precision=4, suppress_small=True, max_line_width=200)}"
                .replace("\n", "\n           "),
                f"  distortion [k1 k2 k3 b1 b2] = [{k}]"]
    return None


def _describe_database(folder: Path, *, title: str | None = None) -> list[str]:
    """A calibration database: one line per white image (camera, zoom, focus, size, grid cached, file), read only."""
    from ..calib import store

    entries = store.load_index(folder)
    cams = sorted({str(e.serial) for e in entries})
    lines = [title or f"{folder}: calibration database ('plenodecode calibrate --database')",
             f"  whites   {len(entries)} white image(s) of camera(s) {', '.join(cams) or '-'}; "
             f"{sum(1 for e in entries if e.grid and (folder / e.grid).is_file())} grid(s) cached",
             "    serial        zoom    focus  W x H         grid    file"]
    for e in entries:
        size = f"{e.shape[1]} x {e.shape[0]}" if e.shape else "?"
        step = (lambda v: "-" if v is None else f"{v:g}")
        cached = "cached" if e.grid and (folder / e.grid).is_file() else "to fit"
        lines.append(f"    {str(e.serial):12s} {step(e.zoom_step):>6s} {step(e.focus_step):>8s}  {size:12s}  "
                     f"{cached:6s}  {store.white_path(e, folder)}")
    return lines


def _describe_npz(path: Path) -> list[str]:
    """A NumPy archive (a synthetic raw's ground-truth arrays): its arrays' names, shapes and types."""
    import zipfile

    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = [(k, z[k].shape, z[k].dtype) for k in z.files]
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise FormatError(f"{path}: not a readable NumPy .npz archive ({exc})") from None
    truth = path.with_name(path.name[:-len(".npz")] + ".json")
    what = f"the arrays of {truth.name}" if truth.is_file() else "NumPy arrays"
    return [f"{path}: {what}",
            *(f"  {k:20s} {' x '.join(map(str, s)) or 'scalar'} {d}" for k, s, d in arrays)]


def _describe_raycalib(path: Path) -> list[str]:
    """A Raytrix RayCalibData XML: the micro-lens array it describes and the image it belongs to."""
    from ..io.raytrix import parse_raycalib
    from ..report.calibration import angle_text

    cal = parse_raycalib(path)
    images = [p for p in (path.with_suffix(ext) for ext in (".png", ".tif", ".tiff", ".bmp")) if p.is_file()]
    types = ", ".join(f"{t.id} (virtual depth {t.depth_range[0]:g}-{t.depth_range[1]:g})" if t.depth_range
                      else str(t.id) for t in cal.lens_types)
    return [f"{path}: Raytrix RayCalibData (the micro-lens array of a focused-plenoptic camera)"
            + (f"; its image is {images[0].name}" if images else ""),
            f"  lenses   hex, diameter {cal.diameter:.3f} px, rotation {angle_text(cal.rotation)}, "
            f"{len(cal.lens_types) or 'no'} lens type(s){': ' + types if types else ''}"]


def _describe_mat_centres(path: Path) -> list[str] | None:
    """A MATLAB .mat that holds a table of lenslet centres, (rows, cols, 2) in (row, col) or (x, y) order, and no
    'LF' light field (e.g. the F01 JPEGs' ``image_cords.mat``): the lattice it measures; None for any other .mat."""
    import numpy as np
    import scipy.io

    try:
        names = scipy.io.whosmat(str(path))
    except (NotImplementedError, ValueError, OSError, TypeError):
        return None                  # not MATLAB v5: the light-field reader says what it expected
    if any(n == "LF" for n, _, _ in names):
        return None
    table = next(((n, shape) for n, shape, cls in names if len(shape) == 3 and shape[2] == 2
                  and min(shape[:2]) >= 3 and cls not in ("char", "cell", "struct", "object")), None)
    if table is None:
        return None
    name, (R, C, _) = table
    a = np.asarray(scipy.io.loadmat(str(path), variable_names=[name])[name], np.float64)
    across = np.nanmedian(np.abs(a[:, -1] - a[:, 0]), axis=0)      # along a lens row: the column changes most
    col = int(np.argmax(across))
    row = 1 - col
    order = "(row, col)" if col == 1 else "(x, y)"
    pitch = float(np.nanmedian((a[:, -1, col] - a[:, 0, col]) / (C - 1)))
    spacing = float(np.nanmedian((a[-1, :, row] - a[0, :, row]) / (R - 1)))
    rotation = float(np.nanmedian(np.arctan2(a[:, -1, row] - a[:, 0, row], a[:, -1, col] - a[:, 0, col])))
    shift = float(np.nanmedian(np.abs(np.diff(a[:, 0, col]))) / pitch) % 1.0    # odd rows' offset, in pitches
    lattice = "hex" if abs(shift - 0.5) < 0.15 else "square" if min(shift, 1 - shift) < 0.15 else "unclear"
    from ..report.calibration import angle_text

    return [f"{path}: lenslet centres (a MATLAB table, not a light field)",
            f"  centres  {name}: {R} x {C} lenses (rows x cols), {order} px, rows "
            f"{np.nanmin(a[..., row]):g}..{np.nanmax(a[..., row]):g}, cols {np.nanmin(a[..., col]):g}.."
            f"{np.nanmax(a[..., col]):g} (MATLAB pixels count from 1)",
            f"  lattice  {lattice}, pitch {pitch:.3f} px along the rows, rows {spacing:.3f} px apart "
            f"({spacing / pitch:.3f} x pitch), rotation {angle_text(rotation)}",
            "  use      not read by plenodecode; 'plenodecode calibrate --scene IMAGE -o grid.json' measures the "
            "centres in the lenslet image"]


def _describe_other(path: Path, raytrix_xml: Path | None = None) -> list[str]:
    from ..errors import MetadataError

    unusable = None
    try:
        from ..pipeline import open_raw

        # as decoding reads it: a Raytrix image with its XML (``--raytrix-xml``, else beside it), a microscope's optics
        raw = open_raw(path, raytrix_xml=raytrix_xml)
    except ImportError as exc:
        raise FormatError(f"{path}: not a Lytro file, and the reader for other formats is not available "
                          f"({exc}); install the full plenodecode") from None
    except MetadataError as exc:    # e.g. several RayCalibData XMLs beside it: described as an image, with why
        from ..io import read_raw

        if raytrix_xml is not None:     # --raytrix-xml refused for this file, as decoding refuses it
            raise
        try:
            raw, unusable = read_raw(path), exc
        except PlenodecodeError:
            raise exc from None
    m = raw.metadata
    h, w = raw.shape
    from ..io.generic import BARE_MOSAIC_KEY, find_sidecar

    side = None if BARE_MOSAIC_KEY in m.extra or "raytrix" in m.extra else find_sidecar(path)
    lines = [f"{path}: raw image" + (f" with metadata {side.name}" if side else "")]
    lines += _camera_lines(m.model or _sensor_by_size(m, raw.shape), m.make, m.serial)
    lines.append(f"  kind     {'raw, white image' if m.is_white_image else 'raw'}")
    from ..io.raytrix import is_rgb_export

    if is_rgb_export(raw):      # its RawCapture holds the luminance, scaled to 16 bits: not what the file is
        lines.append(f"  raw      {w} x {h}, RGB export ({m.extra['stored_channels']} channels, already demosaiced): "
                     "rendered in colour; its luminance locates the lenses")
    else:
        lines.append(f"  raw      {w} x {h}, {raw.cfa or 'monochrome'}, black {_levels(raw.black)}, "
                     f"white {_levels(raw.white)}, values {int(raw.mosaic.min())}..{int(raw.mosaic.max())}")
    lines += _lens_lines(m)
    if unusable is not None:
        return lines + [f"  calib    none: {unusable}"]
    return lines if m.is_white_image else lines + _calibration_lines(raw)


def describe(path: Path, raytrix_xml: Path | None = None) -> list[str]:
    """Lines that ``plenodecode info`` prints for one file (a Raytrix image read with ``raytrix_xml`` when given,
    which any other file refuses, as decoding does)."""
    from ..io import LYTRO_MAGIC
    from ..io import lytro
    from ..pipeline import input_kind, is_lightfield_path

    from ..calib.store import INDEX_NAME
    from ..io.lightfield import holds_lightfield

    if raytrix_xml is not None:     # refused for what is no Raytrix image (e.g. a .lfr), as decoding refuses it
        from ..io.raytrix import calibration_xml_for

        calibration_xml_for(path, raytrix_xml)

    if path.is_dir() and (path / INDEX_NAME).is_file():
        return _describe_database(path)
    if path.is_dir() and input_kind(path) == "lightfield" and not holds_lightfield(path):
        raise FormatError(f"{path}: a folder holding no light field; info describes files (e.g. "
                          f"'plenodecode info {path}/*'), light-field folders and calibration databases")
    if path.is_file() and path.suffix.lower() == ".mat":
        centres = _describe_mat_centres(path)
        if centres is not None:
            return centres
    if path.exists() and is_lightfield_path(path):
        return _describe_lightfield(path)
    if not path.is_file():
        raise FormatError(f"{path}: no such file" if not path.exists() else f"{path}: is not a file")
    with open(path, "rb") as fh:
        head = fh.read(8)
    if head == LYTRO_MAGIC:
        return _describe_container(path)
    if path.suffix.lower() == ".raw" and lytro.find_sidecar(path) is not None:
        return _describe_raw_pair(path)
    if path.suffix.lower() in (".txt", ".json"):
        return _describe_sidecar(path)
    if path.suffix.lower() == ".npz":
        return _describe_npz(path)
    if path.suffix.lower() == ".xml":
        from ..io.raytrix import is_raycalib_xml

        if is_raycalib_xml(path):
            return _describe_raycalib(path)
    return _describe_other(path, raytrix_xml)


@click.command("info")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@raytrix_xml_option
@click.pass_context
def info(ctx: click.Context, files: tuple[Path, ...]) -> None:
    """Describe raws and containers: camera, serial, kind, image sizes, sections; for a
    raw, the calibration decoding would use (database, white image, Raytrix XML or
    self-calibration, and its files), the lens pitch it reads or measures, the decoded
    shape, and the refocusable range (alpha, slope, metres when the geometry allows).

    Works on Lytro .lfp/.LFP/.lfr containers (raw or processed), MOD_NNNN.RAW + .TXT
    white images (or their .TXT/.json metadata alone), any raw plenodecode reads, and
    saved light fields and HCI scene folders; also on lenslet grids, mosaic sidecars,
    synthetic ground truth, the calibration database's index.json, geometric
    calibrations (CalInfo.json), Raytrix RayCalibData XML and tables of lens centres
    in a .mat (e.g. image_cords.mat).

    \b
    Example:
      plenodecode info IMG_0001.lfr MOD_0000.RAW demo.LFP
      plenodecode info lf.zarr
      plenodecode info scene.png --raytrix-xml calib_b.xml
    """
    xml = ctx.meta.get(RAYTRIX_XML_META)
    failed = 0
    for i, path in enumerate(files):
        if i:
            click.echo("")
        try:
            lines = describe(path, xml)
        except PlenodecodeError as exc:        # one file's problem: say it, and describe the others
            if len(files) == 1:
                raise
            click.echo(f"error: {exc}", err=True)
            failed += 1
            continue
        for line in lines:
            click.echo(line)
    if failed:
        raise click.exceptions.Exit(1)


command = info
