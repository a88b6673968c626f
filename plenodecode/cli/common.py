"""Options and helpers shared by every command, so they behave the same everywhere.

Every ``click.Choice`` lists the keys of a registry.  Registries in heavy modules (numba, OpenCV) are read
through :class:`RegistryChoice`, which imports them only when a command's help or its arguments need them, so
``plenodecode --help`` imports no command at all.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import math
import sys
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import click
from click.core import ParameterSource

from ..io.atomic import refuse_folder, refuse_unwritable
from ..metadata import COLOUR_WORDS     # how a colour state reads in a summary line (info, decode's)
from ..pipeline import BIT_DEPTHS


class RegistryChoice(click.Choice):
    """A :class:`click.Choice` of the names of a registry (dict keys, or a tuple of names), imported on first use.

    Parameters
    ----------
    module : str
        Absolute module name, e.g. ``'plenodecode.render'``.
    attribute : str
        The registry in that module, e.g. ``'REFOCUS_METHODS'``.
    """

    def __init__(self, module: str, attribute: str, *, sort: bool = False) -> None:
        self._registry = (module, attribute)
        self._sort = sort
        self.case_sensitive = True

    @property
    def choices(self) -> tuple[str, ...]:  # type: ignore[override]
        names = tuple(getattr(importlib.import_module(self._registry[0]), self._registry[1]))
        return tuple(sorted(names)) if self._sort else names


class DatabaseOption(click.Option):
    """``--database DIR``; its old spelling ``--white-dir`` is accepted but not shown in the help, and the help
    shows the default folder :data:`plenodecode.calib.store.DEFAULT_DB` (read only when help is shown)."""

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        from ..calib.store import DEFAULT_DB

        shown, self.opts = self.opts, self.opts[:1]
        try:
            record = super().get_help_record(ctx)
        finally:
            self.opts = shown
        return None if record is None else (record[0], f"{record[1]}  [default: ./{DEFAULT_DB}, else {DEFAULT_DB}/ "
                                                        "beside the raw or in a folder above it]")

    def get_error_hint(self, ctx: click.Context) -> str:
        """Errors name the option ``'--database'``, not its hidden old spelling."""
        return f"'{self.opts[0]}'"


database_option = click.option("--database", "--white-dir", "database", cls=DatabaseOption, default=None,
                               type=click.Path(exists=True, file_okay=False, path_type=Path),
                               help="Calibration database of raws (white images and fitted grids).")


class OneInputCommand(click.Command):
    """A command that reads one input.  Several files typed (``plenodecode IMG_1.jpg IMG_2.jpg -o x.png``, a
    shell glob) got click's 'Got unexpected extra argument (IMG_2.jpg)'; they now get one line that says the
    command reads one input and gives the ``plenodecode batch`` command that takes them all, with the batch
    output of the same product (:attr:`batch_output`, ``None``: no batch output for it)."""

    #: The ``plenodecode batch --outputs`` name of what this command writes, per command name.
    batch_output = {"render": "photo", "decode": "lightfield", "refocus": "refocus", "views": "views",
                    "depth": "depth"}

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        allow = ctx.allow_extra_args
        ctx.allow_extra_args = True
        rest = super().parse_args(ctx, args)
        ctx.allow_extra_args = allow
        extra = list(ctx.args)
        if extra and not allow and not ctx.resilient_parsing:
            if not all(Path(a).exists() for a in extra):
                ctx.fail(f"Got unexpected extra argument{'s' if len(extra) > 1 else ''} ({' '.join(extra)})")
            typed = [ctx.params.get(p.name or "") for p in self.params if isinstance(p, click.Argument)]
            files = [str(f) for f in typed if f is not None] + extra
            output = self.batch_output.get(self.name or "")
            hint = (f"; for several, 'plenodecode batch {' '.join(files)} -o OUT/ --outputs {output}' writes one "
                    "folder per raw" if output else "; run it once per file")
            ctx.fail(f"'plenodecode {self.name}' reads one input, got {len(files)} ({' '.join(files)}){hint}")
        return rest


#: ``ctx.meta`` key of the checked :class:`~plenodecode.io.mosaic_levels.MosaicOptions` of a command.
MOSAIC_META = "plenodecode.mosaic_options"


def mosaic_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """How to read an image mosaic (JPEG/PNG/TIFF) without a sidecar: ``--cfa``, ``--black-level``,
    ``--white-level``, ``--input-encoding`` (see :mod:`plenodecode.io.mosaic_levels`).

    The values are checked together before the command runs (a bad one is a usage error naming its option)
    and handed to the command as one :class:`~plenodecode.io.mosaic_levels.MosaicOptions` through
    ``ctx.meta`` (:func:`current_mosaic_options`), so the commands' own signatures do not change.
    """
    @functools.wraps(fn)
    def checked(*args: Any, cfa: str | None, black_level: float | None, white_level: float | None,
                input_encoding: str, **kwargs: Any) -> Any:
        if black_level is not None and white_level is not None and white_level <= black_level:
            raise click.BadParameter(f"must exceed --black-level {black_level:g}, got {white_level:g}",
                                     param_hint="--white-level")
        from ..io.mosaic_levels import MosaicOptions

        click.get_current_context().meta[MOSAIC_META] = MosaicOptions(cfa, black_level, white_level, input_encoding)
        return fn(*args, **kwargs)

    checked = click.option("--input-encoding", type=RegistryChoice("plenodecode.io.mosaic_levels", "INPUT_ENCODINGS"), default="linear", show_default=True,
                           help="Image mosaics: 'srgb' if the values are display-encoded (inverse sRGB first).")(checked)
    checked = click.option("--white-level", type=POSITIVE, default=None,
                           help="Image mosaics: white (clipping) level in the file's units [default: the sidecar's, "
                                "the known camera's, else the full scale].")(checked)
    checked = click.option("--black-level", type=NON_NEGATIVE, default=None,
                           help="Image mosaics: black level in the file's units [default: the sidecar's, the known "
                                "camera's, else estimated from the gaps between micro-images].")(checked)
    return click.option("--cfa", type=RegistryChoice("plenodecode.io.mosaic_levels", "CFA_CHOICES"), default=None,
                        help="Image mosaics: colour filter pattern, or 'mono' [default: the sidecar's, else by the "
                             "size of a known sensor (3280 x 3280 Lytro F01: BGGR; 7728 x 5368 Illum: GRBG), "
                             "else monochrome].")(checked)


def current_mosaic_options() -> Any:
    """The :class:`~plenodecode.io.mosaic_levels.MosaicOptions` of the running command (None outside one)."""
    ctx = click.get_current_context(silent=True)
    return None if ctx is None else ctx.meta.get(MOSAIC_META)


#: ``ctx.meta`` key of the ``--raytrix-xml`` file of a command.
RAYTRIX_XML_META = "plenodecode.raytrix_xml"


def _check_raytrix_xml(ctx: click.Context, param: click.Parameter, value: Path | None) -> Path | None:
    """``--raytrix-xml``: a RayCalibData document (else a usage error naming the option), kept in ``ctx.meta``."""
    if value is not None:
        from ..io.raytrix import is_raycalib_xml

        if not is_raycalib_xml(value):
            raise click.BadParameter(f"{value} is not a RayCalibData XML (no <RayCalibData> element); pass the "
                                     "calibration RxLive exported with the image", ctx=ctx, param=param)
    ctx.meta[RAYTRIX_XML_META] = value
    return value


raytrix_xml_option = click.option(
    "--raytrix-xml", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None, expose_value=False,
    callback=_check_raytrix_xml, metavar="FILE",
    help="Raytrix images: the RayCalibData XML [default: X.xml beside X.png, else the only XML in its folder].")


#: ``ctx.meta`` key of the geometric calibration (``--geometry``) of a command.
GEOMETRY_META = "plenodecode.geometry"


def _load_geometry(ctx: click.Context, param: click.Parameter, value: Path | None) -> Any:
    """``--geometry FILE``: the :class:`~plenodecode.raymodel.GeometricCalibration` it holds (this project's JSON
    or the toolbox's ``CalInfo.json``), else a usage error naming the option; kept in ``ctx.meta``."""
    cal = None
    if value is not None:
        from ..errors import FormatError
        from ..io.calinfo import load_geometric_calibration

        try:
            cal = load_geometric_calibration(value)
        except FormatError as exc:
            raise click.BadParameter(str(exc), ctx=ctx, param=param) from None
    ctx.meta[GEOMETRY_META] = cal
    return cal


geometry_option = click.option(
    "--geometry", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None, expose_value=False,
    callback=_load_geometry, is_eager=False, metavar="CAL.json",
    help="Rectify with this geometric calibration ('plenodecode calibrate-geometry' JSON or the Light Field "
         "Toolbox's CalInfo.json): undistorted pinhole views, metric depth from the calibration.")


def current_geometry() -> Any:
    """The ``--geometry`` calibration of the running command (None when not given or outside a command)."""
    ctx = click.get_current_context(silent=True)
    return None if ctx is None else ctx.meta.get(GEOMETRY_META)


#: ``ctx.meta`` key of the dark frame and the microscope optics of a command (:func:`microscope_options`).
MICROSCOPE_META = "plenodecode.microscope_inputs"
#: ``--option`` -> (MicroscopeOptics field, help) of the microscope optics options.
_OPTICS_HELP = {
    "lens_pitch_m": "micro-lens pitch (um)",
    "pixel_pitch_m": "pixel size at the micro-lens focal plane, relay included (um)",
    "magnification": "objective magnification",
    "numerical_aperture": "objective numerical aperture",
    "tube_lens_focal_length_m": "tube lens focal length (mm)",
    "medium_index": "refractive index of the immersion medium",
    "microlens_focal_length_m": "micro-lens focal length (um) [default: micro-images fill the pitch]",
    "wavelength_m": "emission wavelength (nm, for the record)",
}


def in_option_names(text: str) -> str:
    """A library message about microscope optics in the command's words: the :class:`~plenodecode.optics.
    MicroscopeOptics` fields it names become their options (``numerical_aperture`` -> ``--na``), the Python way of
    giving optics (:data:`~plenodecode.optics.OPTICS_SUPPLY`) becomes ``--optics FILE.json``."""
    import re

    from ..optics import OPTICS_OPTIONS, OPTICS_SUPPLY, option_name

    text = text.replace(OPTICS_SUPPLY, "or --optics FILE.json, or a napari-LF metadata.txt beside the raw")
    # a bare field name only: not the tail of an option already named ('--magnification' stays as it is)
    return re.sub(r"(?<![-\w])(" + "|".join(OPTICS_OPTIONS) + r")\b", lambda m: option_name(m.group(1)), text)


@contextlib.contextmanager
def optics_in_option_names() -> Iterator[None]:
    """Errors raised inside (ValueError, the library's errors, usage errors) with their message in the command's
    option names (:func:`in_option_names`); the same exception object, so its type and attributes are kept."""
    from ..errors import MissingConstantsError, PlenodecodeError

    try:
        yield
    except click.ClickException as exc:
        exc.message = in_option_names(exc.message)
        raise
    except (ValueError, PlenodecodeError) as exc:
        # a camera's missing constants (lens_pitch_m of a Lytro) are no microscope option: left as they are
        camera_constants = isinstance(exc, MissingConstantsError) and bool(exc.missing)
        if len(exc.args) == 1 and isinstance(exc.args[0], str) and not camera_constants:
            exc.args = (in_option_names(exc.args[0]),)
        raise


def microscope_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Light-field microscope inputs: ``--dark FRAME`` and the optics (``--lens-pitch-um``, ``--pixel-um``,
    ``--magnification``, ``--na``, ``--tube-lens-mm``, ``--medium-index``, ``--microlens-focal-um``,
    ``--wavelength-nm``, ``--optics FILE``; a napari-LF ``metadata.txt`` beside the raw is read anyway).

    Checked before the command runs (a bad value is a usage error naming its option) and handed over through
    ``ctx.meta`` (:func:`current_microscope_inputs`) as ``{'dark': Path | None, 'optics': MicroscopeOptics |
    None}``: the option values win over ``--optics FILE``, which wins over ``metadata.txt``.
    """
    from ..optics import OPTICS_OPTIONS

    names = {field: OPTICS_OPTIONS[field][0].lstrip("-").replace("-", "_") for field in _OPTICS_HELP}

    @functools.wraps(fn)
    def checked(*args: Any, dark: Path | None, optics_file: Path | None, **kwargs: Any) -> Any:
        from ..errors import PlenodecodeError
        from ..io.microscope import read_optics
        from ..optics import MicroscopeOptics

        values = {field: kwargs.pop(name) for field, name in names.items()}
        try:
            optics = read_optics(optics_file) if optics_file is not None else None
        except PlenodecodeError as exc:
            raise click.BadParameter(in_option_names(str(exc)), param_hint="--optics") from None
        try:
            given = MicroscopeOptics.from_options(**values)
            optics = optics.merged(given) if optics is not None else given
        except ValueError as exc:
            raise click.UsageError(in_option_names(str(exc))) from None
        click.get_current_context().meta[MICROSCOPE_META] = {
            "dark": dark, "optics": None if optics.empty else optics}
        with optics_in_option_names():       # e.g. metric depth missing an optical constant
            return fn(*args, **kwargs)

    for field, help_text in reversed(_OPTICS_HELP.items()):
        checked = click.option(OPTICS_OPTIONS[field][0], names[field], type=POSITIVE,
                               default=None, help=f"Microscopes: {help_text}.")(checked)
    checked = click.option("--optics", "optics_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                           default=None, help="Microscopes: optics file (plenodecode JSON, napari-LF metadata.txt "
                                              "or LFAnalyze 'name value unit' lines) [default: metadata.txt "
                                              "beside the raw].")(checked)
    return click.option("--dark", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
                        help="Dark frame, subtracted pixel by pixel from raw and white (microscopes).")(checked)


def current_microscope_inputs() -> dict[str, Any]:
    """``{'dark': Path | None, 'optics': MicroscopeOptics | None}`` of the running command (:func:`microscope_options`)."""
    ctx = click.get_current_context(silent=True)
    found = None if ctx is None else ctx.meta.get(MICROSCOPE_META)
    return dict(found) if found else {"dark": None, "optics": None}


def input_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The input options of every command that reads a raw: the calibration (``--calibration/-g``,
    ``--white/-w``, ``--database``, ``--self-calibrate``; see :func:`plenodecode.pipeline.choose_calibration`),
    the RayCalibData XML of a Raytrix image (``--raytrix-xml``), how to read an image mosaic
    (:func:`mosaic_options`), a microscope's dark frame and optics (:func:`microscope_options`), and the
    geometric calibration that rectifies (``--geometry``, :func:`current_geometry`)."""
    fn = geometry_option(fn)
    fn = microscope_options(fn)
    fn = mosaic_options(fn)
    fn = raytrix_xml_option(fn)
    fn = self_calibrate_option(fn)
    fn = database_option(fn)
    fn = click.option("--white", "-w", "white", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                      default=None, help="White image of the same zoom/focus: devignetting (and the grid, if no "
                                         "--calibration).")(fn)
    return calibration_option(fn)


def check_grid_file(ctx: click.Context, param: click.Parameter, value: Path | None) -> Path | None:
    """--calibration read while the command line is parsed (a small JSON file): a file that is not a lenslet grid
    is a usage error naming the option, before any raw is read (in a batch: not one failure per raw)."""
    if value is not None:
        from ..errors import PlenodecodeError
        from ..pipeline.calibration import grid_from_file

        try:
            grid_from_file(value)
        except PlenodecodeError as exc:
            raise click.BadParameter(str(exc), ctx, param) from None
    return value


#: ``--calibration/-g GRID.json``: the ``grid`` of :func:`plenodecode.pipeline.choose_calibration`.
calibration_option = click.option("--calibration", "-g", "calibration",
                                  type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
                                  callback=check_grid_file,
                                  help="Lenslet grid JSON written by 'plenodecode calibrate'.")
#: ``--self-calibrate``: the ``self_calibrate`` of :func:`plenodecode.pipeline.choose_calibration`.
self_calibrate_option = click.option("--self-calibrate", "self_calibrate", is_flag=True,
                                     help="Raws without any other calibration: find the lenslet grid in the scene "
                                          "itself (automatic for image mosaics without a sidecar).")


def _check_n_views(ctx: click.Context, param: click.Parameter, value: int | None) -> int | None:
    if value is not None and (value < 1 or value % 2 == 0):
        raise click.BadParameter("must be a positive odd number")
    return value


def decoding_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """How a raw is decoded (``decode`` and ``batch``): ``--demosaic``, ``--resample``, ``--views``, ``--colour``,
    ``--no-hot-pixels``; the keywords of :func:`plenodecode.decode` (``demosaic``, ``resample``, ``n_views``,
    ``colour``, ``hot_pixels=not no_hot_pixels``) and of :class:`plenodecode.batch.BatchOptions`."""
    fn = click.option("--no-hot-pixels", is_flag=True, help="Do not repair hot pixels.")(fn)
    fn = click.option("--colour", type=RegistryChoice("plenodecode.decoding.colour", "DECODE_COLOURS"),
                      default="linear-srgb", show_default=True,
                      help="Colour of the light field: white balance + colour matrix, or camera RGB.")(fn)
    fn = click.option("--views", "n_views", type=int, default=None, callback=_check_n_views,
                      help="Views per angular axis (odd; a view step is one sensor pixel), at most "
                           "2*ceil(pitch/2)+1 [default: 2*floor(pitch/2)+1, pitch in px].")(fn)
    fn = click.option("--resample", type=RegistryChoice("plenodecode.imaging", "RESAMPLE_METHODS"), default="cubic",
                      show_default=True,
                      help="Hex -> rect resampling: 'cubic' along each lens row; 'hex' a 2-D kernel over 5 lens rows, "
                           "half the row-alternating zipper at vertical edges and up to 2 dB sharper, 50 % slower, "
                           "softer on fine oblique detail.")(fn)
    fn = click.option("--demosaic", type=RegistryChoice("plenodecode.decoding.demosaic", "DEMOSAIC_METHODS",
                                                        sort=True),
                      default="malvar", show_default=True, help="Demosaicing method (within each micro-image).")(fn)
    return fn


def views_anyway_option(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``--views-anyway``: the products of a focused-plenoptic raw's decoded views all the same
    (:func:`refuse_focused_views`)."""
    return click.option("--views-anyway", is_flag=True,
                        help="Focused-plenoptic (Raytrix) raws: cut views from the micro-images even so (the camera "
                             "gives pictures per lens, not views: one pixel per lens; 'plenodecode RAW -o photo.png' "
                             "renders its total focus).")(fn)


def aperture_option(help_text: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """``--aperture`` in (0, 1], default 1 (all views): the ``aperture`` of refocus, the one-liner and batch."""
    return click.option("--aperture", type=FiniteFloat(0, 1, min_open=True), default=1.0, show_default=True,
                        help=help_text)


def refuse_focused_views(focused: bool, raw_path: Path, views_anyway: bool, *, instead: str) -> None:
    """The usage error (exit 2, one line, before any decoding) of a command that would render a focused-plenoptic
    (Raytrix) raw's decoded views (decode, views, parallax, a refocus by slope), unless ``--views-anyway``: such
    views have one pixel per lens (the real R42 crop: 35 x 35 views of 22 x 31 px).  ``instead``: what to type."""
    if focused and not views_anyway:
        raise click.UsageError(f"{raw_path.name} is a focused-plenoptic (Raytrix) raw: its micro-images are small "
                               f"pictures, not a light field of views (one pixel per lens); {instead} (or pass "
                               "--views-anyway)")


#: What to type instead of the decoded views of a focused-plenoptic raw (:func:`refuse_focused_views`).
FOCUSED_PHOTO = "render it with 'plenodecode render {raw} --total-focus -o photo.png'"
FOCUSED_REFOCUS = ("refocus it at a virtual depth with 'plenodecode refocus {raw} --virtual-depth V -o photo.png', "
                   "or render its total focus with 'plenodecode render {raw} --total-focus -o photo.png'")


def refuse_database_with_grid(calibration: Path | None, white: Path | None, database: Path | None) -> None:
    """Usage error when ``--database`` is given with ``--calibration`` or ``--white`` (``decode``,
    ``calibrate-geometry``): :func:`~plenodecode.pipeline.choose_calibration` would take the grid and white
    and leave the database unread without a word."""
    if database is not None and (calibration is not None or white is not None):
        raise click.UsageError("--database cannot be combined with --calibration or --white")


def calibration_kwargs(calibration: Path | None, white: Path | None, database: Path | None,
                       self_calibrate: bool) -> dict[str, Any]:
    """The command's input options as keywords of :func:`plenodecode.pipeline.open_source`: the calibration
    (the keywords of :func:`~plenodecode.pipeline.choose_calibration`), ``mosaic`` (:func:`current_mosaic_options`),
    ``raytrix_xml`` (``--raytrix-xml``), ``dark`` and ``optics`` (:func:`current_microscope_inputs`) and
    ``geometry`` (``--geometry``, :func:`current_geometry`)."""
    ctx = click.get_current_context(silent=True)
    return {"grid": calibration, "white": white, "database": database, "self_calibrate": self_calibrate,
            "mosaic": current_mosaic_options(), "raytrix_xml": None if ctx is None else ctx.meta.get(RAYTRIX_XML_META),
            "geometry": current_geometry(), **current_microscope_inputs()}


@contextlib.contextmanager
def usage_errors(param_hint: str | None = None) -> Iterator[None]:
    """Turn a refused overwrite (FileExistsError) and a bad value (ValueError) into usage errors (exit 2);
    with ``param_hint`` a ValueError names that option."""
    try:
        yield
    except (IsADirectoryError, NotADirectoryError) as exc:     # a file never replaces a folder, nor a folder a file
        raise click.UsageError(str(exc)) from exc
    except FileExistsError as exc:
        text = str(exc).replace("overwrite=True", "--overwrite")       # the library's keyword, as the CLI spells it
        raise click.UsageError(f"{text}; pass --overwrite" if "--overwrite" not in text else text) from exc
    except ValueError as exc:
        if param_hint is not None:
            raise click.BadParameter(str(exc), param_hint=param_hint) from exc
        raise click.UsageError(str(exc)) from exc


def quiet(ctx: click.Context) -> bool:
    """True with ``plenodecode -q``."""
    return bool((ctx.obj or {}).get("quiet"))


def empty_views_note(lf: Any, name: str) -> str:
    """``'; 24 corner views ... hold no data ...'`` for a light field written as images (views, eslf) whose views
    past the round micro-images have no sample with data (black in the files, or the rims' stripes), else ''."""
    if name not in ("views", "eslf") or lf.weight is None:
        return ""
    from ..imaging import MIN_DATA_WEIGHT, view_data_share

    empty = int((view_data_share(lf.weight) == 0).sum())
    if not empty:
        return ""
    where = "weight.npy" if name == "views" else "the image's last channel"
    return (f"; {empty} corner views past the round micro-images hold no data (weight under {MIN_DATA_WEIGHT:g}: "
            f"black, or the rims' stripes; {where} holds every sample's weight)")


def encoded_note(name: str) -> str:
    """``'; 8-bit views are sRGB-encoded for viewing ...'``: the note of a light field saved sRGB-encoded
    (:func:`~plenodecode.pipeline.output.stores_display_encoded`)."""
    what = "an 8-bit ESLF mosaic is" if name == "eslf" else f"8-bit {name} are"
    return f"; {what} sRGB-encoded for viewing (--bit-depth 16 keeps linear light)"


def lightfield_summary(shape: tuple[int, ...], colour: str) -> str:
    """``'9x9 views of 381x381, camera RGB'`` for a (V, U, Y, X, C) light field; one channel reads 'monochrome'."""
    V, U, Y, X, C = shape
    words = "monochrome" if C == 1 else COLOUR_WORDS.get(colour, colour)
    return f"{V}x{U} views of {Y}x{X}, {words}"


output_option = click.option("-o", "--output", "output", type=click.Path(path_type=Path), required=True,
                             help="Output file or folder.")
overwrite_option = click.option("--overwrite", is_flag=True, help="Replace existing outputs.")
bit_depth_option = click.option("--bit-depth", type=click.Choice([str(b) for b in BIT_DEPTHS]), default="16", show_default=True,
                                help="Bits per sample of image outputs (32 = float).")
jobs_option = click.option("--jobs", "-j", type=click.IntRange(min=1), default=None,
                           help="Worker processes (default: all cores).")


def image_bit_depth(ctx: click.Context, bit_depth: str, suffix: str, *, param_hint: str = "-o / --output") -> int:
    """The bit depth of image files of type ``suffix`` ('.jpg'), checked before any work: ``--bit-depth`` as
    typed, else its default (16) or, for a type that cannot hold it, the deepest the type holds (8 for JPEG, 32 for
    PFM).  Usage errors (exit 2): a type that is no image file (naming ``param_hint``, the option that gave it) and
    a typed ``--bit-depth`` the type cannot hold."""
    from ..io.images import IMAGE_FORMATS

    ext = suffix.lower() if suffix.startswith(".") else f".{suffix.lower()}"
    if ext not in IMAGE_FORMATS:
        raise click.BadParameter(f"an image file ends in {', '.join(sorted(IMAGE_FORMATS))}; got "
                                 f"{suffix or 'no extension'!r}", param_hint=param_hint)
    holds = IMAGE_FORMATS[ext]
    if ctx.get_parameter_source("bit_depth") is not ParameterSource.COMMANDLINE and int(bit_depth) not in holds:
        return max(holds)
    if int(bit_depth) not in holds:
        raise click.BadParameter(f"{ext} files hold {' or '.join(map(str, holds))} bits per sample, not {bit_depth}",
                                 param_hint="--bit-depth")
    return int(bit_depth)


def lightfield_bit_depth(ctx: click.Context, name: str, output: Path, bit_depth: str,
                         image_type: str | None = None) -> int:
    """The bit depth a light field in format ``name`` is written with at ``output``, checked before any work
    (usage errors naming the option): zarr and npy store float32, so a typed ``--bit-depth`` other than 32 is
    refused; mat stores 16 bits; an ESLF mosaic is a .png/.tif (:data:`~plenodecode.io.lightfield.ESLF_EXTENSIONS`)
    at a depth it holds; views at a depth their ``--image-type`` holds (:func:`image_bit_depth`)."""
    from ..io.lightfield import ESLF_EXTENSIONS, ESLF_NAMES

    typed = ctx.get_parameter_source("bit_depth") is ParameterSource.COMMANDLINE
    if image_type is not None and name != "views":
        raise click.BadParameter(f"is the image type of a views folder; {name} has none (leave it out, or write "
                                 "--format views)", param_hint="--image-type")
    if name in ("zarr", "npy"):
        if typed and bit_depth != "32":
            raise click.BadParameter(f"{name} stores float32 samples (lossless), not {bit_depth}-bit ones; leave it "
                                     "out, or write --format views, eslf or mat", param_hint="--bit-depth")
        return int(bit_depth)
    if name == "mat":
        if bit_depth != "16" and typed:
            raise click.BadParameter(f"the LFToolbox .mat format stores 16-bit samples, not {bit_depth}",
                                     param_hint="--bit-depth")
        return 16
    if name == "eslf":
        if output.suffix.lower() not in ESLF_EXTENSIONS:
            given = output.suffix or "a name without extension"
            raise click.BadParameter(f"an ESLF mosaic is written as {ESLF_NAMES} (its 4th channel is the weight, and "
                                     f"it loads back by that extension), not {given}", param_hint="-o / --output")
        return image_bit_depth(ctx, bit_depth, output.suffix)
    if name == "views" and image_type is not None:
        return image_bit_depth(ctx, bit_depth, f".{image_type}", param_hint="--image-type")
    return int(bit_depth)


def refuse_writing_over_inputs(written: list[Path], inputs: list[Any], *,
                               param_hint: str = "-o / --output") -> None:
    """A usage error naming the output option, before any work, when a file to be written would replace an input
    or its sidecar (``X.json``, ``X.TXT``): '-o scene.png' for the mosaic scene.png, '-o MOD_0000.TXT'."""
    read = {}
    for p in (Path(i) for i in inputs if isinstance(i, (str, Path))):
        for q in (p, *(p.with_suffix(ext) for ext in (".json", ".JSON", ".TXT", ".txt"))):
            if q.exists():
                read.setdefault(q.resolve(), p)
    for out in written:
        hit = read.get(Path(out).resolve())
        if hit is not None:
            what = hit.name if Path(out).resolve() == hit.resolve() else f"{Path(out).name}, the sidecar of {hit.name}"
            raise click.BadParameter(f"writing {Path(out).name} would replace the input {what}; choose another name",
                                     param_hint=param_hint)


def refuse_writing_over_command_inputs(written: list[Path], input_path: Path, calibration: Path | None = None,
                                       white: Path | None = None, *, param_hint: str = "-o / --output") -> None:
    """:func:`refuse_writing_over_inputs` for a command with :func:`input_options`: the files ``written`` must not
    replace RAW_OR_LF, ``--calibration``, ``--white``, ``--dark``, ``--raytrix-xml`` or their sidecars
    (``plenodecode scene.png -o scene.png --overwrite``)."""
    ctx = click.get_current_context(silent=True)
    xml = None if ctx is None else ctx.meta.get(RAYTRIX_XML_META)
    refuse_writing_over_inputs(written, [input_path, calibration, white, current_microscope_inputs()["dark"], xml],
                               param_hint=param_hint)


def check_writable(path: Path, param_hint: str = "-o / --output") -> None:
    """Refuse, before any work, an output that cannot be created: under a file, or in a folder that cannot be
    written (usage error naming ``param_hint``, exit 2)."""
    try:
        refuse_unwritable(path)
    except OSError as exc:
        raise click.BadParameter(str(exc), param_hint=param_hint) from None


def check_output(path: Path, overwrite: bool, param_hint: str = "-o / --output") -> None:
    """Refuse an output file that is an existing folder, even with ``--overwrite``, one that cannot be created
    (:func:`check_writable`), and to replace an existing output unless ``--overwrite`` was given (usage errors,
    exit 2)."""
    check_writable(path, param_hint)
    with usage_errors():
        refuse_folder(path)
    if path.exists() and not overwrite:
        raise click.UsageError(f"{path} exists; pass --overwrite to replace it")


def check_folder_output(folder: Path, names: list[str], overwrite: bool, *, what: str = "the output") -> None:
    """Refuse a folder output that is a file, that is named like an image file (``-o stack.png`` would make a
    folder called stack.png), or where one of ``names`` exists without ``--overwrite`` (usage error, exit 2).
    Creates nothing: the folder appears only when its files are written."""
    from ..io.images import ANIMATION_FORMATS, IMAGE_FORMATS
    from ..pipeline import refuse_folder_clash

    if not folder.is_dir() and folder.suffix.lower() in (*IMAGE_FORMATS, *ANIMATION_FORMATS):
        raise click.BadParameter(f"{what} goes into a folder, and {folder.name} names an image file; give a "
                                 f"folder, e.g. {folder.with_suffix('')}/", param_hint="-o / --output")
    check_writable(folder / "-" if folder.is_dir() else folder)
    with usage_errors():
        refuse_folder_clash(folder, names, overwrite)


def lightfield_output_format(output: Path, fmt: str | None, overwrite: bool) -> str:
    """The light-field format to write ``output`` in: ``fmt``, else detected from its name (usage errors for an
    existing output without ``--overwrite``, for a name that says no format, for a file format over a folder and
    for a folder of other files)."""
    from ..io.lightfield import FOLDER_FORMATS, detect_format, format_of_extension, refuse_foreign_folder

    try:
        name = fmt or detect_format(output, option="--format")
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    said = format_of_extension(output)
    if fmt is not None and said is not None and said != fmt and not output.is_dir():   # a file no loader reads back
        right = output.with_suffix(".png" if fmt == "eslf" else "" if fmt == "views" else f".{fmt}")
        raise click.BadParameter(f"-o {output.name} says {said} by its extension, and --format {fmt} would write "
                                 f"{fmt} under that name; name it {right.name}, or leave --format out",
                                 param_hint="--format")
    check_writable(output)
    if name not in FOLDER_FORMATS:
        with usage_errors():
            refuse_folder(output)       # '-o lf.npy' naming a folder: a file never replaces a folder
    try:
        refuse_foreign_folder(output)       # before 'pass --overwrite', which would delete the folder's files
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="-o / --output") from None
    if output.exists() and not overwrite:
        raise click.UsageError(f"{output} exists; pass --overwrite to replace it")
    return name


def progress_bar(label: str, ctx: click.Context | None = None) -> Callable[[int, int], None]:
    """A ``callback(done, total)`` that draws a click progress bar on stderr (silent with -q)."""
    ctx = ctx or click.get_current_context(silent=True)
    quiet = bool(ctx and ctx.obj and ctx.obj.get("quiet"))
    state: dict = {}

    def callback(done: int, total: int) -> None:
        if quiet:
            return
        bar = state.get("bar")
        if bar is None:
            bar = click.progressbar(length=total, label=label, show_pos=True, show_eta=True, file=sys.stderr)
            bar.__enter__()
            state["bar"] = bar
            state["done"] = 0
        bar.update(done - state["done"])
        state["done"] = done
        if done >= total:
            bar.__exit__(None, None, None)
            state.pop("bar")

    return callback


# ----------------------------------------------------------------------------------------- numeric options
class FiniteFloat(click.FloatRange):
    """A :class:`click.FloatRange` that also refuses nan and inf (``FloatRange`` lets nan through every bound).

    A bad value is a usage error naming the option, raised while the command line is parsed, before any work.
    """

    name = "finite float"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        number = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return super().convert(number, param, ctx)

    def _describe_range(self) -> str:
        # click's help shows "[x<=None]" for a range without bounds: an unbounded one says nothing
        return "" if self.min is None and self.max is None else super()._describe_range()


#: Any finite number (slopes, rotations, offsets).
FINITE = FiniteFloat()
#: A finite number > 0 (lengths, distances, alphas, rates).
POSITIVE = FiniteFloat(min=0, min_open=True)
#: A finite number >= 0.
NON_NEGATIVE = FiniteFloat(min=0)
#: A finite number in [0, 1] (confidences, fractions).
UNIT_INTERVAL = FiniteFloat(min=0, max=1)


class Exposure(click.ParamType):
    """``--exposure``: stops (EV) within +-MAX_EXPOSURE_EV, or 'auto'; a bad value is a usage error naming the
    option."""

    name = "EV|auto"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        from ..pipeline.output import check_exposure

        try:
            return check_exposure(value)
        except ValueError as exc:
            self.fail(str(exc).replace("exposure must be", "must be"), param, ctx)


exposure_option = click.option(
    "--exposure", type=Exposure(), default=0.0, show_default=True,
    help="Brighten (+) or darken (-) image outputs by this many stops, or 'auto': the brightest 0.5 % of the "
         "picture (a views folder's centre view, a stack's middle slice) at full scale.")


def note_if_dark(ctx: click.Context, rendered: Any, exposure: float | str, what: str = "the picture") -> None:
    """After writing a photograph (views, parallax frames: ``what`` names the one measured) at the default exposure:
    say on stderr when it is dark (its brightest 0.5 % below :data:`~plenodecode.pipeline.DARK_LEVEL` of full
    scale, e.g. a dim microscope sample over a bright white frame) and name ``--exposure``
    (:func:`~plenodecode.pipeline.dark_note`; a batch: :meth:`~plenodecode.batch.TaskResult.dark_note`)."""
    from ..pipeline import dark_note, image_level

    if quiet(ctx) or exposure != 0.0:
        return
    note = dark_note(image_level(rendered), what)
    if note is not None:
        click.echo(f"note: {note}", err=True)


class BoardSpec(click.ParamType):
    """A checkerboard ``ROWSxCOLSxSQUARE``: inner corners per column and per row, square side in m
    (``8x6x0.0036``) -> :class:`plenodecode.raymodel.Board`; a malformed value is a usage error naming the option."""

    name = "ROWSxCOLSxSQUARE"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        from ..raymodel import Board

        try:
            return Board.of(value)
        except ValueError as exc:
            self.fail(f"{value!r}: {exc} (a board needs at least 2 x 2 inner corners and a positive square size "
                      "in m, e.g. 8x6x0.0036).", param, ctx)


#: ``--board`` / ``--checkerboard`` values.
BOARD = BoardSpec()


def parse_focus_at(text: str | None) -> tuple[float, float, bool] | None:
    """``--focus-at X,Y`` -> ``(x, y, fractional)``; None for None.

    The rule: fractions of the width and height (0-1) when both numbers are at most 1 and both are written with
    a decimal point (``0.5,0.25``); otherwise pixels of the centre view (``40,12``, ``12.5,3``).

    Raises
    ------
    click.BadParameter
        Naming ``--focus-at``: not two finite numbers >= 0.
    """
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 2:
            raise ValueError
        x, y = float(parts[0]), float(parts[1])
    except ValueError:
        raise click.BadParameter(f"expected X,Y (pixels of the centre view, or fractions 0.0-1.0), got {text!r}",
                                 param_hint="--focus-at") from None
    if not (math.isfinite(x) and math.isfinite(y) and x >= 0 and y >= 0):
        raise click.BadParameter(f"X and Y must be finite and >= 0, got {text!r}", param_hint="--focus-at")
    return x, y, all("." in p for p in parts) and x <= 1 and y <= 1


def focus_point(at: tuple[float, float, bool] | None, shape: tuple[int, ...]) -> tuple[float, float] | None:
    """A parsed ``--focus-at`` as the ``focus_at = (x, y)`` samples of the workflow
    (:func:`plenodecode.pipeline.products.render_refocus`) for a light field of ``shape`` (V, U, Y, X, C):
    fractions ``f`` map to ``f (size - 1)``; a point outside the picture is a usage error naming ``--focus-at``."""
    from ..render.refocus_methods import check_point

    if at is None:
        return None
    x, y, fractional = at
    point = (y * (shape[2] - 1), x * (shape[3] - 1)) if fractional else (y, x)
    try:
        row, column = check_point(point, shape[2:4])
        return column, row
    except ValueError:      # the library's message names its keyword 'at' and (row, column): say it as typed
        raise click.BadParameter(f"X,Y = {x:g},{y:g} lies outside the centre view: X (column) 0 to {shape[3] - 1}, "
                                 f"Y (row) 0 to {shape[2] - 1}, or fractions 0.0-1.0",
                                 param_hint="--focus-at") from None


def focus_hint(*, alpha: Any = None, focus_distance: Any = None, focus_at: Any = None, stack: Any = None) -> str:
    """The option a photograph's focus came from, as a usage error about it names it (``--slope`` when none of
    the others, which covers the default, slope 0)."""
    given = [(alpha, "--refocus / --alpha"), (focus_distance, "--focus-distance"), (focus_at, "--focus-at"),
             (stack, "--focal-stack")]
    return next((hint for value, hint in given if value is not None), "--slope")


def focus_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``--focus-at X,Y``, ``--no-depth`` and ``--focus-distance METRES``: the ways besides slope and alpha of
    saying where a photograph is focused (:func:`plenodecode.render.refocus_methods.focus_slope`)."""
    fn = click.option("--focus-distance", "focus_distance", type=POSITIVE, default=None, metavar="METRES",
                      help="Focus at this distance (needs the focus distance in the metadata: Lytro, HCI "
                           "parameters.cfg, generated scenes).")(fn)
    fn = click.option("--no-depth", "no_depth", is_flag=True,
                      help="With --focus-at: pick the sharpest slice of a small focal stack instead of the depth map.")(fn)
    fn = click.option("--focus-at", "focus_at", metavar="X,Y", default=None,
                      callback=lambda ctx, param, value: parse_focus_at(value),
                      help="Focus on what is at column X, row Y of the centre view (pixels; fractions of the size "
                           "when both are written 0.x).")(fn)
    return fn


def check_focus_options(given: Mapping[str, Any], no_depth: bool, *, optional: bool = False) -> None:
    """Exactly one (with ``optional``, at most one) of the focus options in ``given`` (option name, maybe with its
    metavar, ``'--focus-at X,Y'`` -> value or None) was typed, and ``--no-depth`` only with ``--focus-at``; a usage
    error (exit 2) naming them otherwise."""
    typed = [name for name, value in given.items() if value is not None and value is not False]
    if len(typed) != 1 and not (optional and not typed):
        raise click.UsageError(f"pass {'at most' if optional else 'exactly'} one of {', '.join(given)}"
                               + (f" (got {' and '.join(typed)})" if typed else ""))
    if no_depth and not any(name.split()[0] == "--focus-at" for name in typed):
        raise click.UsageError("--no-depth applies to --focus-at only")


def focus_choices(rendered_data: Mapping[str, Any], options: tuple[str, ...]) -> str:
    """``'--slope, --focus-at or --focus-distance'``: of ``options`` (in the command's order, among ``--slope``,
    ``--alpha`` / ``--refocus``, ``--focus-at``, ``--focus-distance``), the ways of choosing a photograph's focus
    that its input serves: alpha and a distance only where the refocusable range of the 'refocus' product's
    ``Rendered.data`` could be given in them (the camera constants, the focus distance)."""
    span = rendered_data["range"]
    served = [o for o in options if not (o in ("--alpha", "--refocus") and span.alpha is None
                                         or o == "--focus-distance" and span.distance_m is None)]
    return ", ".join(served[:-1]) + f" or {served[-1]}"


def picture_size(image: Any, bits: int | None = None) -> str:
    """``'382 x 383 px, 16-bit'``: width x height of an (H, W[, C]) image and the bits per sample it is written with
    (32: float), for the 'wrote ...' line of a picture."""
    h, w = image.shape[:2]
    depth = "" if bits is None else f", {'32-bit float' if int(bits) == 32 else f'{int(bits)}-bit'}"
    return f"{w} x {h} px{depth}"


def describe_focus(rendered_data: Mapping[str, Any]) -> str:
    """``'alpha 1.015 = slope +0.90 px/view; refocusable alpha 0.9814-1.0194 = ...'`` for the report line of a
    refocused photograph (``Rendered.data`` of the 'refocus' product)."""
    what = f"slope {rendered_data['slope']:+.3f} px/view"
    if rendered_data.get("alpha") is not None:
        what = f"alpha {rendered_data['alpha']:g} = {what}"
    elif rendered_data.get("focus_distance") is not None:
        what = f"focus distance {rendered_data['focus_distance']:g} m = {what}"
    return f"{what}; refocusable {rendered_data['range'].describe()}"
