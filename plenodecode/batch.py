"""Batch decoding of many raws: a local process pool by default, a Dask cluster when asked.

Each raw becomes one task that runs entirely on a worker (read -> pick the calibration from
the database -> decode -> render the requested outputs -> write), so a light field never
travels between processes; only small :class:`TaskResult` records stream back.  At most
``max_in_flight`` tasks are submitted at a time and a task holds one light field, so the light
fields in memory never exceed the number of tasks running at once (local processes, or the
threads of the Dask workers).

Layout of ``out_dir``::

    out_dir/<name>/           one folder per raw, <name> = the raw's file stem (made unique)
        refocus_s+0.00.png (or total_focus.png: 'photo'), centre.png, disparity.pfm (virtual_depth.pfm: a focused
                              raw's 'depth'; depth.pfm: metric, + .ply; + .exr, .png, _confidence.exr/.png as
                              'plenodecode depth' writes them), lightfield.zarr, views/, focal_stack/,
                              parallax.gif + parallax_frames/ ...
        thumbs/<product>.png  8-bit thumbnails (longest side <= THUMB_SIZE) for the index
        .done.json            the task key, the products and thumbnails (written last)
    out_dir/summary.json      every result of the last run
    out_dir/index.html        thumbnails of every output and the error of every failure

All-or-nothing per raw: a task writes into a hidden staging folder ``out_dir/.<name>.<random>.tmp``
(:func:`plenodecode.io.atomic.atomic_output`) and renames it to ``out_dir/<name>`` only when every product and
the ``.done.json`` marker are written, so a killed run leaves no output under its final name (the next run
removes the staging folders of runs that no longer live, and leaves those of a live one alone).  Two batches
must not write into the same ``out_dir`` at the same time.

Resuming: ``.done.json`` holds the task key, the SHA-256 of the input's bytes and of the options
(:func:`task_key`); a later run with the same key skips the raw.  A folder ``out_dir/<name>`` of a
changed input or option, or without a marker (not written by a batch), is replaced only with
``overwrite=True``: without it the whole run is refused before any work (:func:`check_outputs_to_replace`).

Where the tasks run (forked local workers, a Dask cluster) and how those are kept busy:
:mod:`plenodecode.batch_workers`.  On a Dask cluster (``scheduler=``) the workers must see the inputs,
the calibration database and ``out_dir`` under the same paths as the client (a shared file system).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import hashlib
import json
import logging
import math
import os
import socket
import threading
import time
import traceback
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

from .deprecation import renamed_fields
from .errors import DecodeError, MissingConstantsError, PlenodecodeError, one_line
from .io.atomic import (OLD_MARK, TEMP_MARK, atomic_output, discard, is_temporary, os_error_text,
                        remove_stale_temporaries, refuse_unwritable, write_text_atomic)
from .registry import lookup
from .threads import limit_threads

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None] | None

#: Outputs a batch can produce per raw (the CLI's --outputs choices): the decoded light field, and products of
#: :data:`plenodecode.pipeline.PRODUCTS` under the same names (their options: :class:`BatchOptions`).
BATCH_OUTPUTS = ("photo", "lightfield", "views", "centre", "refocus", "depth", "all-in-focus", "total-focus",
                 "focal-stack", "parallax")
#: Slices of a 'focal-stack' output without ``focal_stack``: over the raw's refocusable range.
DEFAULT_STACK_SLICES = 9
#: Files and folders of the 'focal-stack' and 'parallax' outputs in a raw's folder.
FOCAL_STACK_DIR = "focal_stack"
PARALLAX_NAME = "parallax.gif"
PARALLAX_FRAMES_DIR = "parallax_frames"
#: Light-field file formats of the 'lightfield' output -> name of the written file or folder.
LIGHTFIELD_NAMES = {"zarr": "lightfield.zarr", "views": "lightfield_views", "mat": "lightfield.mat",
                    "npy": "lightfield.npy", "eslf": "lightfield.eslf.png"}
DONE_MARKER = ".done.json"
#: Suffix of the staging folders of earlier versions (still removed as leftovers).
STAGING_SUFFIX = ".partial"
THUMB_DIR = "thumbs"
SUMMARY_JSON = "summary.json"
INDEX_HTML = "index.html"
SUMMARY_FILES = (SUMMARY_JSON, INDEX_HTML)
SUMMARY_FORMAT = "plenodecode.BatchSummary"
#: Longest side of a thumbnail, px.
THUMB_SIZE = 256
#: Width (inches at 100 dpi) and text size (points) of the map in a disparity thumbnail.
THUMB_FIGURE = {"width_in": 1.9, "dpi": 100, "fontsize": 6}


# ---------------------------------------------------------------------------------- data
#: Fields of :class:`BatchOptions` renamed to their ``plenodecode batch`` option -> their old name: the old
#: keyword and attribute still work for one release (DeprecationWarning), and the task key keeps the old names so
#: the outputs of earlier runs stay done (:meth:`BatchOptions.as_key_dict`).
RENAMED_FIELDS = {"database": "db_dir", "format": "lightfield_format", "focus_distance": "distance_m"}


@renamed_fields({old: new for new, old in RENAMED_FIELDS.items()})
@dataclass(frozen=True)
class BatchOptions:
    """What to produce for every raw (all of it is hashed into each task's key).

    Attributes
    ----------
    outputs : tuple of str
        Non-empty subset of :data:`BATCH_OUTPUTS`; default 'photo', the camera's photograph
        (:func:`plenodecode.pipeline.products.render_photo`, as the one-liner writes it).
    database : str or None
        Calibration database folder (``--database``); None (default): each raw's, as the single commands find it
        (:func:`plenodecode.calib.store.find_database`: ./calib, else calib/ beside the raw or above it).
    format : str
        Format of the 'lightfield' output (``--format``), a key of :data:`LIGHTFIELD_NAMES`.
    bit_depth : {8, 16, 32}
        Image outputs: 8/16-bit sRGB-encoded PNG, or 32 = linear float EXR.
    exposure : float or 'auto'
        Stops the image outputs (the 'views' folder too, from its centre view, as ``plenodecode views``; not the
        'lightfield' data) and their thumbnails are brightened by, or 'auto' (``--exposure``;
        :func:`plenodecode.pipeline.exposure_gain`).
    slope : float
        Refocus slope of the 'refocus' and 'photo' outputs (px per view step, design.md), unless ``alpha`` or
        ``focus_distance``.
    alpha : float or None
        Ng's relative film depth of the 'refocus' and 'photo' outputs instead of ``slope`` (the same name as
        :func:`plenodecode.render.refocus` and ``--alpha``).
    focus_distance : float or None
        Focus distance (m) of the 'refocus' and 'photo' outputs instead of ``slope`` (``--focus-distance``; needs
        the focus distance in the metadata).
    depth_method : str or None
        Method of the 'depth' output (None: the library's default).
    aperture : float in (0, 1]
        Synthetic aperture radius of the 'refocus' and 'photo' outputs, a fraction of the view grid (``--aperture``,
        the ``aperture`` of :func:`plenodecode.refocus`); not of a Raytrix raw's total-focus photograph.
    disparity_range : (lo, hi) or None
        Disparities (px per view step) the 'depth' output searches (``--disparity-range LO:HI``; None: the
        method's default); refused for a focused-plenoptic raw, whose depth is its virtual depth.
    min_confidence : float in [0, 1] or None
        Pixels of the 'depth' thumbnail with a lower confidence are grey (None:
        :data:`plenodecode.io.depthio.DEFAULT_MIN_CONFIDENCE`; 0 = none), as ``plenodecode depth --min-confidence``.
    cfa, black_level, white_level, input_encoding :
        How to read image mosaics without a sidecar (the CLI options of the same names;
        :class:`plenodecode.io.mosaic_levels.MosaicOptions`): 'mono' or a Bayer pattern, levels in the file's
        units, 'linear' or 'srgb'.  None / 'linear': found out per file.
    white, dark : str or None
        White (radiometry) image and dark frame used for every raw (``--white``, ``--dark``; light-field
        microscopes): the white calibrates the grid and devignettes, the dark frame is subtracted pixel by pixel.
    optics : dict or None
        Light-field microscope optics given for every raw (``MicroscopeOptics.to_dict()``, metres); they win
        over a napari-LF ``metadata.txt`` beside a raw.
    views_anyway : bool
        Write the outputs cut from the decoded views (:data:`VIEW_OUTPUTS`) of a focused-plenoptic (Raytrix) raw
        too (``--views-anyway``); without it such a raw asking for them fails in one line, before decoding.
    grid : str or None
        Lenslet grid JSON used for every raw (``--calibration``; the ``grid`` of
        :func:`plenodecode.pipeline.choose_calibration`), instead of the database.
    self_calibrate : bool
        Raws without any other calibration find their grid in the scene (``--self-calibrate``).
    demosaic, resample, n_views, colour, hot_pixels :
        How every raw is decoded: the keywords of :func:`plenodecode.decode` (``--demosaic``, ``--resample``,
        ``--views``, ``--colour``, ``--no-hot-pixels``, as ``plenodecode decode`` takes them).

    The old names of :data:`RENAMED_FIELDS` (``db_dir``, ``lightfield_format``, ``distance_m``) still work, with a
    DeprecationWarning.
    geometry : dict or None
        Geometric calibration that rectifies every light field (``--geometry``;
        ``GeometricCalibration.to_dict()``, so its values, not its path, are hashed); a raw whose decoded
        shape differs fails before decoding.
    focal_stack : (start, stop, n) or None
        Slices of the 'focal-stack' output (``--focal-stack START:STOP:N``, in ``stack_units``); None:
        :data:`DEFAULT_STACK_SLICES` slopes over each raw's refocusable range
        (:func:`plenodecode.render.alpha.refocus_range`).
    stack_units : {'slope', 'alpha'}
        Units of ``focal_stack`` (``--stack-units``; 'alpha' needs ``focal_stack``).
    frames, radius, interp :
        The 'parallax' output's viewpoints, circle radius (view steps; None: 3/4 of the view grid's half-size) and
        interpolation (``--frames``, ``--radius``, ``--interp``, as ``plenodecode parallax``).
    fps : float > 0
        Frames per second of the 'parallax' animation (``--fps``).
    parallax_frames : bool
        Write the parallax frames (``parallax_frames/frame_000.png`` ...) beside the animation (``--no-frames``:
        False); PNGs, so ``bit_depth=32`` needs False.
    metric : bool
        The 'depth' output is metric depth, ``depth.pfm`` (m; um for a light-field microscope), instead of
        ``disparity.pfm`` (``--metric``), from each raw's own metadata (its focus distance: a raw without one fails
        in one line; ``plenodecode depth --focus-distance`` supplies it for one raw).
    ply : bool
        The 'depth' output also writes a coloured point cloud ``<stem>.ply`` (``--ply``; needs the constants
        ``metric`` needs).
    depth_focus_distance : float > 0 or None
        Distance (m) of the plane in focus for ``metric`` and ``ply`` of every raw, instead of its metadata's
        (``--depth-focus-distance``: ``plenodecode depth --focus-distance``; a batch's ``--focus-distance`` is the
        refocus distance, ``focus_distance``).
    """

    outputs: tuple[str, ...] = ("photo",)
    database: str | None = None
    format: str = "zarr"
    bit_depth: int = 16
    exposure: float | str = 0.0
    slope: float = 0.0
    depth_method: str | None = None
    cfa: str | None = None
    black_level: float | None = None
    white_level: float | None = None
    input_encoding: str = "linear"
    alpha: float | None = None
    focus_distance: float | None = None
    white: str | None = None
    dark: str | None = None
    optics: Mapping[str, float | None] | None = None
    geometry: Mapping[str, Any] | None = None
    min_confidence: float | None = None
    views_anyway: bool = False
    grid: str | None = None
    self_calibrate: bool = False
    demosaic: str = "malvar"
    resample: str = "cubic"
    n_views: int | None = None
    colour: str = "linear-srgb"
    hot_pixels: bool = True
    aperture: float = 1.0
    disparity_range: tuple[float, float] | None = None
    focal_stack: tuple[float, float, int] | None = None
    stack_units: str = "slope"
    frames: int = 24
    radius: float | None = None
    fps: float = 12.0
    interp: str = "linear"
    parallax_frames: bool = True
    metric: bool = False
    ply: bool = False
    depth_focus_distance: float | None = None

    def __post_init__(self) -> None:
        outs = tuple(self.outputs) if not isinstance(self.outputs, str) else (self.outputs,)
        bad = [o for o in outs if o not in BATCH_OUTPUTS]
        if bad or not outs:
            raise ValueError(f"outputs must be a non-empty subset of {BATCH_OUTPUTS}, got {self.outputs!r}")
        object.__setattr__(self, "outputs", tuple(dict.fromkeys(outs)))
        lookup(LIGHTFIELD_NAMES, self.format, param="format")
        if self.bit_depth not in (8, 16, 32):
            raise ValueError(f"bit_depth must be 8, 16 or 32, got {self.bit_depth!r}")
        from .pipeline.output import check_exposure

        object.__setattr__(self, "exposure", check_exposure(self.exposure))
        if self.depth_method is not None:
            from .depth import DEPTH_METHODS

            lookup(DEPTH_METHODS, self.depth_method, param="depth_method")
        if self.min_confidence is not None:
            from .io.depthio import check_min_confidence

            object.__setattr__(self, "min_confidence", check_min_confidence(self.min_confidence))
        object.__setattr__(self, "slope", float(self.slope))
        mosaic = self.mosaic_options()          # checks the four mosaic options (ValueError naming the option)
        object.__setattr__(self, "black_level", mosaic.black_level)
        object.__setattr__(self, "white_level", mosaic.white_level)
        if not math.isfinite(self.slope):
            raise ValueError(f"slope must be a finite number, got {self.slope}")
        if self.depth_focus_distance is not None:
            value = float(self.depth_focus_distance)
            if not (value > 0 and math.isfinite(value)):
                raise ValueError("depth_focus_distance must be a finite number > 0 (m), got "
                                 f"{self.depth_focus_distance}")
            object.__setattr__(self, "depth_focus_distance", value)
        if self.alpha is not None and self.focus_distance is not None:
            raise ValueError("pass at most one of alpha and focus_distance (they replace slope)")
        for name in ("alpha", "focus_distance"):
            value = getattr(self, name)
            if value is not None and not (float(value) > 0 and math.isfinite(float(value))):
                raise ValueError(f"{name} must be a finite number > 0, got {value}")
        if self.database is not None:
            object.__setattr__(self, "database", str(self.database))
        self._check_decoding()
        if not (0 < float(self.aperture) <= 1):
            raise ValueError(f"aperture must be in (0, 1] (a fraction of the view grid), got {self.aperture!r}")
        object.__setattr__(self, "aperture", float(self.aperture))
        if self.disparity_range is not None:
            lo, hi = (float(v) for v in self.disparity_range)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"disparity_range must be finite (lo, hi) with lo < hi, got {self.disparity_range!r}")
            object.__setattr__(self, "disparity_range", (lo, hi))
        for name in ("white", "dark", "grid"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, str(Path(getattr(self, name)).resolve()))
        if self.optics is not None:
            from .optics import MicroscopeOptics

            optics = MicroscopeOptics.from_dict(self.optics)           # checks the values (ValueError)
            object.__setattr__(self, "optics", None if optics.empty else optics.to_dict())
        if self.geometry is not None:
            object.__setattr__(self, "geometry", self.geometric_calibration().to_dict())
        self._check_stack_and_parallax()

    def _check_stack_and_parallax(self) -> None:
        """ValueError naming the keyword of a bad 'focal-stack' or 'parallax' option."""
        from .pipeline import STACK_UNITS
        from .pipeline.products import stack_problem
        from .render.viewpoints import PERSPECTIVE_INTERPOLATIONS

        lookup(STACK_UNITS, self.stack_units, param="stack_units")
        if self.focal_stack is not None:
            try:
                start, stop, n = self.focal_stack
                start, stop = float(start), float(stop)
                if isinstance(n, bool) or int(n) != n:
                    raise ValueError
            except (TypeError, ValueError):
                raise ValueError(f"focal_stack must be (start, stop, n) with an integer n, got {self.focal_stack!r}"
                                 ) from None
            problem = stack_problem(start, stop, int(n), self.stack_units)
            if problem is not None:
                raise ValueError(f"focal_stack {problem}")
            object.__setattr__(self, "focal_stack", (start, stop, int(n)))
        elif self.stack_units != "slope":
            raise ValueError(f"stack_units {self.stack_units!r} needs focal_stack (START and STOP in those units); "
                             "without it a focal stack spans each raw's refocusable range in slopes")
        if isinstance(self.frames, bool) or int(self.frames) != self.frames or self.frames < 1:
            raise ValueError(f"frames must be a positive integer, got {self.frames!r}")
        object.__setattr__(self, "frames", int(self.frames))
        if self.radius is not None and not (float(self.radius) >= 0 and math.isfinite(float(self.radius))):
            raise ValueError(f"radius must be a finite number >= 0 (view steps), got {self.radius!r}")
        if not (float(self.fps) > 0 and math.isfinite(float(self.fps))):
            raise ValueError(f"fps must be a finite number > 0, got {self.fps!r}")
        object.__setattr__(self, "fps", float(self.fps))
        lookup(dict.fromkeys(PERSPECTIVE_INTERPOLATIONS), self.interp, param="interp")
        if "parallax" in self.outputs and self.parallax_frames and self.bit_depth == 32:
            raise ValueError("bit_depth 32 (float EXR) cannot be held by the parallax frames (PNG): pass "
                             "parallax_frames=False or bit_depth 8 or 16")

    def _check_decoding(self) -> None:
        """ValueError naming the keyword of a decoding option :func:`plenodecode.decode` would refuse."""
        from .decoding import DEMOSAIC_METHODS, RESAMPLE_METHODS
        from .decoding.colour import DECODE_COLOURS

        lookup(DEMOSAIC_METHODS, self.demosaic, param="demosaic")
        lookup(RESAMPLE_METHODS, self.resample, param="resample")
        lookup(dict.fromkeys(DECODE_COLOURS), self.colour, param="colour")
        if self.n_views is not None and (isinstance(self.n_views, bool) or not isinstance(self.n_views, int)
                                         or self.n_views < 1 or self.n_views % 2 == 0):
            raise ValueError(f"n_views must be a positive odd integer, got {self.n_views!r}")

    def decode_options(self) -> dict[str, Any]:
        """The keywords of :func:`plenodecode.decode` these options set."""
        return {"demosaic": self.demosaic, "resample": self.resample, "n_views": self.n_views,
                "colour": self.colour, "hot_pixels": self.hot_pixels}

    def as_key_dict(self) -> dict[str, Any]:
        """The options as hashed into the task key.

        The database folder is made absolute; options of products not asked for are left out, so
        changing them does not redo finished raws; renamed fields keep their old names (:data:`RENAMED_FIELDS`).
        """
        d = {RENAMED_FIELDS.get(k, k): v for k, v in asdict(self).items()}
        d["outputs"] = list(self.outputs)
        from .calib.store import DEFAULT_DB

        d["db_dir"] = str(Path(self.database or DEFAULT_DB).resolve())     # None keyed as before it was searched
        from .io.depthio import DEFAULT_MIN_CONFIDENCE

        if d["min_confidence"] == DEFAULT_MIN_CONFIDENCE:
            d["min_confidence"] = None          # the default: the keys of runs before this option stay valid
        if d["disparity_range"] is not None:
            d["disparity_range"] = list(d["disparity_range"])
        for option, product in (("slope", "refocus"), ("depth_method", "depth"), ("lightfield_format", "lightfield"),
                                ("alpha", "refocus"), ("distance_m", "refocus"), ("min_confidence", "depth")):
            if product not in self.outputs or (option in ("alpha", "distance_m", "min_confidence")
                                               and d[option] is None):
                d.pop(option)      # unset alpha / distance_m keep the keys of earlier versions
        for option, default in (("cfa", None), ("black_level", None), ("white_level", None),
                                ("input_encoding", "linear"), ("white", None), ("dark", None), ("optics", None),
                                ("geometry", None), ("grid", None), ("self_calibrate", False),
                                ("demosaic", "malvar"), ("resample", "cubic"), ("n_views", None),
                                ("colour", "linear-srgb"), ("hot_pixels", True), ("aperture", 1.0),
                                ("disparity_range", None), ("focal_stack", None), ("stack_units", "slope"),
                                ("frames", 24), ("radius", None), ("fps", 12.0), ("interp", "linear"),
                                ("parallax_frames", True), ("metric", False), ("ply", False),
                                ("depth_focus_distance", None)):
            if d[option] == default:     # keys of runs before these options existed stay valid
                d.pop(option)
        for option, product in (("focal_stack", "focal-stack"), ("stack_units", "focal-stack"),
                                ("frames", "parallax"), ("radius", "parallax"), ("fps", "parallax"),
                                ("interp", "parallax"), ("parallax_frames", "parallax"), ("metric", "depth"),
                                ("ply", "depth"), ("depth_focus_distance", "depth")):
            if product not in self.outputs:
                d.pop(option, None)
        if d.get("focal_stack") is not None:
            d["focal_stack"] = list(d["focal_stack"])
        return d

    def geometric_calibration(self) -> Any:
        """``geometry`` as a :class:`~plenodecode.raymodel.GeometricCalibration` (None without one)."""
        from .raymodel import GeometricCalibration

        return None if self.geometry is None else GeometricCalibration.from_dict(self.geometry)

    def mosaic_options(self) -> Any:
        """The mosaic options as :class:`plenodecode.io.mosaic_levels.MosaicOptions` (ValueError naming a bad one)."""
        from .io.mosaic_levels import MosaicOptions

        return MosaicOptions(self.cfa, self.black_level, self.white_level, self.input_encoding,
                             dark_frame=None if self.dark is None else Path(self.dark).name)


#: What a raw's dark note names per product measured (:attr:`TaskResult.level_of`), as the single commands name it,
#: when the result does not say which file it measured (a run before :attr:`TaskResult.level_file`); others:
#: 'the <product>'.
MEASURED = {"views": "the centre view", "centre": "the centre view", "focal-stack": "the focal stack's middle slice",
            "parallax": "the parallax's middle frame"}
#: The picture measured of an output that holds several (:attr:`TaskResult.level_file`): 'the centre view of views/'.
MEASURED_IN = {"views": "the centre view", "focal-stack": "the middle slice", "parallax": "the middle frame"}


@dataclass(frozen=True)
class TaskResult:
    """What a worker reports for one raw (small: it travels back from the worker).

    Attributes
    ----------
    source : str
        The raw.
    status : str
        'done', 'skipped' (finished by an earlier run with the same key) or 'failed'.
    outputs : tuple of str
        Written products (files or folders), absolute paths.
    thumbnails : tuple of str or None
        8-bit PNG thumbnail of each output (same order), None where there is none.
    error : str or None
        One line (:func:`plenodecode.errors.one_line`, :func:`plenodecode.io.atomic.os_error_text`): the message
        of a data or file error, as the single commands print it; 'internal error: TypeName: message' for a bug.
    left_out : tuple of str
        Outputs asked for that this raw cannot serve and were not written, one line per reason
        ('centre: not for a focused-plenoptic (Raytrix) raw (...)'); the others were.
    seconds : float
        Wall time of the task on the worker.
    worker : str
        ``host:pid`` of the process that ran the task.
    worker_peak_mb : float or None
        Peak resident memory of that process so far (``ru_maxrss``), MB.
    level, level_of : float or None, str or None
        How bright the first picture written is (:func:`plenodecode.pipeline.image_level`: the 99.5th percentile of
        its middle image in linear light, full scale 1) and its product ('photo', 'views': the centre view, ...);
        None without a picture, or with an ``exposure`` chosen (the pictures are as asked).  The command line and
        the index page note a dark one (:meth:`dark_note`).
    level_file : str or None
        The output measured, as the index page captions it: its name in the raw's folder ('refocus_s+0.00.png',
        'views/', 'focal_stack/', 'parallax.gif').
    started : float
        When the task started on the worker (``time.time()``, s): the earliest task of each worker is the one
        that paid its imports and kernel loading (:meth:`BatchSummary.latency`).
    """

    source: str
    status: str
    outputs: tuple[str, ...] = ()
    thumbnails: tuple[str | None, ...] = ()
    error: str | None = None
    left_out: tuple[str, ...] = ()
    seconds: float = 0.0
    worker: str = ""
    worker_peak_mb: float | None = None
    started: float = 0.0
    level: float | None = None
    level_of: str | None = None
    level_file: str | None = None

    def dark_note(self, name: str | None = None) -> str | None:
        """The single commands' note (:func:`plenodecode.pipeline.dark_note`) when the first picture is dark, naming
        the file as the index page captions it: 'refocus_s+0.00.png is dark (...); --exposure auto brightens it ...',
        'the centre view of views/ is dark ...'; 'refocus_s+0.00.png of ``name``' when named; else None."""
        if self.level is None:
            return None
        from .pipeline import dark_note

        if self.level_file is None:     # the result of an earlier version: the product measured
            what = MEASURED.get(self.level_of or "", f"the {self.level_of}")
        else:
            part = MEASURED_IN.get(self.level_of or "")
            what = self.level_file if part is None else f"{part} of {self.level_file}"
        return dark_note(self.level, what if name is None else f"{what} of {name}")


@dataclass(frozen=True)
class BatchSummary:
    """All results of a batch, in input order, and the wall time of the run."""

    results: tuple[TaskResult, ...] = ()
    seconds: float = 0.0

    def count(self, status: str) -> int:
        """Number of results with ``status``."""
        return sum(r.status == status for r in self.results)

    @property
    def partial(self) -> tuple[TaskResult, ...]:
        """The done or skipped results that left out outputs asked for (:attr:`TaskResult.left_out`)."""
        return tuple(r for r in self.results if r.status != "failed" and r.left_out)

    @property
    def failed(self) -> tuple[TaskResult, ...]:
        """The failed results."""
        return tuple(r for r in self.results if r.status == "failed")

    def latency(self) -> dict[str, float | None]:
        """Start-up cost against steady state, from the decoded ('done') tasks.

        A worker's first task also pays for its imports and for loading (or compiling) the numba
        kernels; the others show the steady state.

        Returns
        -------
        dict
            ``first_task_s``: the longest first task of a worker; ``steady_task_s``: the median of the
            other tasks; ``steady_raws_per_s``: the throughput once every worker has finished its first task,
            the tasks started from then on over the time from then to the last task's end (None with fewer
            than two such tasks); ``worker_peak_mb``: the largest peak resident memory of a worker, MB.  None
            where there is no such task.
        """
        done = sorted((r for r in self.results if r.status == "done"), key=lambda r: r.started)
        first: dict[str, TaskResult] = {}           # each worker's first task
        rest: list[float] = []
        for r in done:
            if r.worker in first:
                rest.append(r.seconds)
            else:
                first[r.worker] = r
        rest.sort()
        steady = None
        if rest:
            mid = len(rest) // 2
            steady = rest[mid] if len(rest) % 2 else 0.5 * (rest[mid - 1] + rest[mid])
        peaks = [r.worker_peak_mb for r in self.results if r.worker_peak_mb is not None]
        return {"first_task_s": max((r.seconds for r in first.values()), default=None), "steady_task_s": steady,
                "steady_raws_per_s": self._steady_rate(done, first.values()),
                "worker_peak_mb": max(peaks) if peaks else None}

    @staticmethod
    def _steady_rate(done: list[TaskResult], firsts: Iterable[TaskResult]) -> float | None:
        """Tasks per second after start-up: ``n / (t_end - t_up)``, ``t_up`` the end of the last of the workers'
        first tasks ``firsts``, ``n`` the tasks of ``done`` started at or after it, ``t_end`` the last end."""
        up = max((r.started + r.seconds for r in firsts), default=None)
        if up is None:
            return None
        later = [r for r in done if r.started >= up]
        end = max((r.started + r.seconds for r in later), default=up)
        return len(later) / (end - up) if len(later) >= 2 and end > up else None

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (what ``summary.json`` holds)."""
        return {"format": SUMMARY_FORMAT, "version": 1, "seconds": self.seconds,
                "total": len(self.results), "done": self.count("done"), "skipped": self.count("skipped"),
                "failed": self.count("failed"), "left_out": len(self.partial), **self.latency(),
                "results": [asdict(r) for r in self.results]}


# ---------------------------------------------------------------------------- discovery
def find_raws(inputs: Iterable[str | os.PathLike], *, exclude: Iterable[str | os.PathLike] = ()) -> list[Path]:
    """Every raw under ``inputs`` (:func:`plenodecode.io.discovery.find_raws`), not searching batch output
    folders (those holding a :data:`DONE_MARKER`).

    Parameters
    ----------
    inputs : iterable of path-like
        Files (taken as given) and folders (searched recursively).
    exclude : iterable of path-like
        Folders not to search (e.g. the batch's own output folder).

    Returns
    -------
    list of Path
        In the order of ``inputs``, each folder's files sorted; duplicates removed.
    """
    from .io.discovery import find_raws as find

    return find(inputs, exclude=exclude, stop_marker=DONE_MARKER)


def output_names(files: Sequence[str | os.PathLike]) -> list[str]:
    """The output folder name of each raw: its file stem, made unique.

    Raws with the same stem in different folders get their folder path (relative to the
    folders' common ancestor) as a prefix, joined by ``__``: ``a/IMG_1.LFR`` and ``b/IMG_1.LFR`` ->
    ``a__IMG_1``, ``b__IMG_1`` (:func:`plenodecode.report.batch.clash_folders`, which the shown names take too);
    any name still repeated gets its suffix (``IMG_1.lfr`` -> ``IMG_1_lfr``).  Links are not followed: a link
    ``a.jpg -> IMG_1.jpg`` gives ``a``, the name the user gave.
    """
    from .report.batch import clash_folders

    paths = [Path(os.path.abspath(f)) for f in files]
    names = ["__".join((*folders, p.stem)) for p, folders in zip(paths, clash_folders(paths))]
    counts: dict[str, int] = {}
    for n in names:
        counts[n] = counts.get(n, 0) + 1
    # raws of one stem in one folder (IMG_1.lfr, IMG_1.jpg): their suffix
    names = [f"{n}_{p.suffix.lstrip('.').lower()}" if counts[n] > 1 else n for n, p in zip(names, paths)]
    counts = {}
    for n in names:
        counts[n] = counts.get(n, 0) + 1
    return [n if counts[n] == 1 else f"{n}_{i}" for i, n in enumerate(names)]


def task_key(path: str | os.PathLike, options: BatchOptions) -> str:
    """SHA-256 of the input's bytes followed by the options as canonical JSON.

    Equal keys mean the outputs would be equal (for the same calibration database and code).
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 22), b""):
            h.update(chunk)
    h.update(b"\0plenodecode-batch-options\0")
    h.update(json.dumps(options.as_key_dict(), sort_keys=True).encode())
    return h.hexdigest()


def outputs_to_replace(files: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
                       options: BatchOptions) -> list[Path]:
    """The output folders ``out_dir/<name>`` of ``files`` (:func:`output_names`) that a run would replace:
    each one that exists and is not a finished result of the same raw bytes and options (which a run
    skips), i.e. written with other options or inputs, or not by a batch at all.

    Returns
    -------
    list of Path
        In the order of ``files``; only the raws whose folder exists are read (their bytes hashed).
    """
    out = Path(out_dir)
    found = []
    for f, name in zip(files, output_names(files)):
        target = out / name
        if not target.exists():
            continue
        marker = _read_marker(target)
        try:
            same = marker is not None and marker.get("key") == task_key(f, options)
        except OSError:         # an unreadable raw fails in its task, for its reason
            same = True
        if not same:
            found.append(target)
    return found


def check_outputs_to_replace(files: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
                             options: BatchOptions) -> None:
    """Raise FileExistsError, in one line, when a run without ``overwrite`` would replace output folders
    (:func:`outputs_to_replace`): how many, the first three, and what to do."""
    found = outputs_to_replace(files, out_dir, options)
    if not found:
        return
    names = ", ".join(p.name for p in found[:3]) + (f" and {len(found) - 3} more" if len(found) > 3 else "")
    raise FileExistsError(f"{len(found)} of {len(files)} raws already have an output folder in {out_dir} ({names}) "
                          "from a run with other options or inputs, or not from a batch; pass --overwrite "
                          "(overwrite=True) to replace them, or choose another output folder")


# ------------------------------------------------------------------------------- tasks
def _worker_id() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _peak_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0   # KiB on Linux


def _read_marker(folder: Path) -> dict[str, Any] | None:
    try:
        doc = json.loads((folder / DONE_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def _skip_result(src: Path, target: Path, key: str, t0: float, started: float) -> TaskResult | None:
    done = _read_marker(target)
    if not done or done.get("key") != key:
        return None
    outs = [target / o for o in done.get("outputs", [])]
    if not outs or not all(o.exists() for o in outs):
        return None
    thumbs = tuple(None if t is None else str(target / t) for t in done.get("thumbnails", [None] * len(outs)))
    return TaskResult(str(src), "skipped", tuple(str(o) for o in outs), thumbs,
                      left_out=tuple(str(n) for n in done.get("left_out", [])), seconds=time.perf_counter() - t0,
                      worker=_worker_id(), worker_peak_mb=_peak_mb(),
                      started=started, level=done.get("level"), level_of=done.get("level_of"),
                      level_file=done.get("level_file"))


#: The file name of the raw the current task (thread) works on: its log lines start with it.
_TASK_RAW: contextvars.ContextVar[str | None] = contextvars.ContextVar("plenodecode_batch_raw", default=None)
#: Guards the record factory :func:`_logs_naming_raw` installs while tasks run (threads of a Dask worker).
_FACTORY_LOCK = threading.Lock()
_FACTORY_STATE: dict[str, Any] = {"tasks": 0, "base": None}


def _naming_factory(base: Callable[..., logging.LogRecord]) -> Callable[..., logging.LogRecord]:
    """A log record factory over ``base`` that starts the library's lines with the task's raw (:data:`_TASK_RAW`),
    unless they already name it (a line starting with the raw's whole path starts with its name instead)."""
    def factory(*args: Any, **kwargs: Any) -> logging.LogRecord:
        record = base(*args, **kwargs)
        raw = _TASK_RAW.get()
        if raw is not None and record.name.startswith("plenodecode.") and record.name != __name__:
            text = record.getMessage()
            head, sep, rest = text.partition(": ")
            if sep and head != raw and os.path.basename(head) == raw:   # the raw's whole path: its name
                record.msg, record.args = f"{raw}: {rest}", ()
            elif not text.startswith(f"{raw}:"):
                record.msg, record.args = f"{raw}: {text}", ()
        return record
    return factory


@contextlib.contextmanager
def _logs_naming_raw(raw: str):
    """Within: the library's log lines (warnings a worker prints) start with ``raw``, the raw's file name, so a
    batch's interleaved lines say which raw they are about.  The record factory is installed while any task
    runs in this process and the previous one restored after the last."""
    token = _TASK_RAW.set(raw)
    with _FACTORY_LOCK:
        if _FACTORY_STATE["tasks"] == 0:
            _FACTORY_STATE["base"] = logging.getLogRecordFactory()
            logging.setLogRecordFactory(_naming_factory(_FACTORY_STATE["base"]))
        _FACTORY_STATE["tasks"] += 1
    try:
        yield
    finally:
        _TASK_RAW.reset(token)
        with _FACTORY_LOCK:
            _FACTORY_STATE["tasks"] -= 1
            if _FACTORY_STATE["tasks"] == 0:
                logging.setLogRecordFactory(_FACTORY_STATE["base"])


def _lost_result(path: Path, exc: BaseException) -> TaskResult:
    """The 'failed' result of a task whose worker died (or whose result could not come back)."""
    return TaskResult(str(path), "failed", error=f"worker failed: {one_line(exc)}")


def process_raw(path: str | os.PathLike, out_dir: str | os.PathLike, options: BatchOptions, *,
                name: str | None = None, overwrite: bool = False, threads: int | None = None) -> TaskResult:
    """Decode one raw and write the requested outputs into ``out_dir/<name>`` (runs on a worker).

    Parameters
    ----------
    path : path-like
        The raw.
    out_dir : path-like
        Batch output folder (must exist).
    options : BatchOptions
    name : str, optional
        Output folder name (default: the raw's stem; see :func:`output_names`).
    overwrite : bool
        Redo the raw even when a previous run finished it with the same key, and replace a
        folder ``out_dir/<name>`` that a batch did not write.
    threads : int, optional
        Threads for decoding and rendering (default: all cores).

    Returns
    -------
    TaskResult
        Never raises for bad data: a :class:`~plenodecode.errors.PlenodecodeError` or an
        ``OSError`` becomes a 'failed' result carrying the one-line message; any other exception
        (a bug) too, with its traceback logged.
    """
    t0 = time.perf_counter()
    started = time.time()
    src = Path(path)
    with _logs_naming_raw(src.name):
        return _process_raw(src, Path(out_dir), options, name=name, overwrite=overwrite, threads=threads, t0=t0,
                            started=started)


def _process_raw(src: Path, out: Path, options: BatchOptions, *, name: str | None, overwrite: bool,
                 threads: int | None, t0: float, started: float) -> TaskResult:
    """:func:`process_raw`, its log lines naming the raw."""
    target = out / (name or src.stem)
    try:
        key = task_key(src, options)
        if not overwrite:
            skipped = _skip_result(src, target, key, t0, started)
            if skipped is not None:
                return skipped
            done = _read_marker(target) if target.exists() else None
            if target.exists() and (done is None or done.get("key") != key):
                why = "was not written by a batch run" if done is None else "holds a run with other options or inputs"
                raise FileExistsError(f"{target} exists and {why}; pass --overwrite (overwrite=True) to replace it")
        if threads is not None:
            limit_threads(threads)
        from .optics import MicroscopeOptics
        from .pipeline import open_raw

        raw = open_raw(src, mosaic=options.mosaic_options(), optics=MicroscopeOptics.from_dict(options.optics))
        _check_metadata(raw, options)       # what the metadata cannot serve fails now, before calibrating
        # the folder is staged under a temporary name and replaces ``target`` (checked above) only when complete
        with atomic_output(target, overwrite=True, folder=True) as staging:
            products, left_out, (level_of, level, level_file) = _write_products(raw, staging, options,
                                                                                 threads=threads)
            rel_out = [str(p.relative_to(staging)) for p, _ in products]
            rel_thumb = [None if t is None else str(t.relative_to(staging)) for _, t in products]
            marker = {"key": key, "source": str(src.resolve()), "outputs": rel_out, "thumbnails": rel_thumb,
                      "left_out": list(left_out), "options": options.as_key_dict(), "level": level,
                      "level_of": level_of, "level_file": level_file}
            (staging / DONE_MARKER).write_text(json.dumps(marker, indent=1), encoding="utf-8")
        return TaskResult(str(src), "done", tuple(str(target / o) for o in rel_out),
                          tuple(None if t is None else str(target / t) for t in rel_thumb), left_out=left_out,
                          seconds=time.perf_counter() - t0, worker=_worker_id(), worker_peak_mb=_peak_mb(),
                          started=started, level=level, level_of=level_of,
                          level_file=level_file)
    except (PlenodecodeError, OSError) as exc:
        log.info("%s failed: %s", src, exc)
        error = os_error_text(exc) if isinstance(exc, OSError) else one_line(exc)
        return TaskResult(str(src), "failed", error=error, seconds=time.perf_counter() - t0,
                          worker=_worker_id(), worker_peak_mb=_peak_mb(), started=started)
    except Exception as exc:  # a bug, not bad data: keep the batch going, keep the traceback in the log
        log.error("unexpected error on %s:\n%s", src, traceback.format_exc())
        return TaskResult(str(src), "failed", error=f"internal error: {one_line(exc)}",
                          seconds=time.perf_counter() - t0, worker=_worker_id(), worker_peak_mb=_peak_mb(),
                          started=started)


# ---------------------------------------------------------------------------- products
def _thumbnail(image: Any, path: Path, *, colour: str) -> Path:
    """8-bit PNG, longest side <= THUMB_SIZE (area-averaged), of a float image in [0, 1] of colour state
    ``colour`` (display-encoded by :func:`plenodecode.pipeline.display_encoding`)."""
    import cv2
    import numpy as np

    from .pipeline import write_image_file

    img = np.nan_to_num(np.asarray(image, np.float32), nan=0.0)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    h, w = img.shape[:2]
    scale = min(1.0, THUMB_SIZE / max(h, w))
    if scale < 1.0:
        img = cv2.resize(img, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    return write_image_file(path, np.clip(img, 0.0, 1.0), colour=colour, bit_depth=8)


def _check_metadata(raw: Any, options: BatchOptions) -> None:
    """Raise the MissingConstantsError of the first product of ``options.outputs`` that the metadata of ``raw`` (a
    RawCapture) cannot serve (:func:`plenodecode.pipeline.check_product`): an alpha, a focus distance, metric
    depth without the camera constants they need."""
    from .pipeline import check_product

    for product in options.outputs:
        try:
            check_product(raw, product, rectified=options.geometry is not None, **_check_options(product, options))
        except MissingConstantsError as exc:
            if exc.keyword not in ("metric", "points") or exc.missing != ("focus_distance_m",):
                raise
            raise MissingConstantsError(f"{exc}; pass --depth-focus-distance METRES (depth_focus_distance=) for "
                                        "every raw", keyword=exc.keyword, missing=exc.missing, source=exc.source,
                                        need=exc.need) from None


def _check_options(product: str, options: BatchOptions) -> dict[str, Any]:
    """The options of ``product`` that :func:`plenodecode.pipeline.check_product` checks against a raw's metadata."""
    if product == "focal-stack":
        return {"units": options.stack_units}
    if product == "depth":
        return {"metric": options.metric, "points": options.ply, "focus_distance": options.depth_focus_distance}
    return _image_product_options(product, options)


def _image_product_options(product: str, options: BatchOptions) -> dict[str, Any]:
    """Options of an image product of :data:`plenodecode.pipeline.PRODUCTS` taken from ``options``."""
    if product not in ("refocus", "photo"):
        return {}
    aperture = {} if options.aperture == 1.0 else {"aperture": options.aperture}
    if options.alpha is not None:
        return {"alpha": options.alpha, **aperture}
    if options.focus_distance is not None:
        return {"focus_distance": options.focus_distance, **aperture}
    return {"slope": options.slope, **aperture}


#: Outputs cut from the decoded views; a focused-plenoptic raw's have one pixel per lens
#: (:func:`_focused_views_left_out`).
VIEW_OUTPUTS = ("lightfield", "views", "centre", "refocus", "all-in-focus", "focal-stack", "parallax")


def _stack_options(src: Any, options: BatchOptions) -> dict[str, Any]:
    """The keywords of the 'focal-stack' product for ``src``: ``options.focal_stack``, else
    :data:`DEFAULT_STACK_SLICES` slopes over the raw's refocusable range (its decoded light field's geometry)."""
    if options.focal_stack is not None:
        start, stop, n = options.focal_stack
        return {"start": start, "stop": stop, "n": n, "units": options.stack_units}
    from .render.alpha import refocus_range

    lo, hi = refocus_range(src.lightfield)
    return {"start": lo, "stop": hi, "n": DEFAULT_STACK_SLICES, "units": "slope"}


def _raw_name(raw: Any) -> str:
    """The raw's file name, as a batch's one-line failures name it."""
    return Path(raw.path).name if raw.path else "this raw"


#: Why a focused-plenoptic (Raytrix) raw's batch leaves out its :data:`VIEW_OUTPUTS` (a note of its result).
FOCUSED_LEFT_OUT = ("not for a focused-plenoptic (Raytrix) raw (its views have one pixel per lens; --views-anyway "
                    "cuts them)")


def _focused_views_left_out(src: Any, options: BatchOptions) -> tuple[str, ...]:
    """The :data:`VIEW_OUTPUTS` of ``options.outputs`` a focused-plenoptic (Raytrix) raw leaves out, known before
    decoding: its decoded views have one pixel per lens (the real R42 crop: 22 x 31 px), as the commands refuse them
    (:func:`plenodecode.cli.common.refuse_focused_views`); none with ``options.views_anyway``.  When that is every
    output asked for, the raw fails in one line (DecodeError): it has nothing to write."""
    cut = tuple(o for o in options.outputs if o in VIEW_OUTPUTS)
    if not src.focused or not cut or options.views_anyway:
        return ()
    if len(cut) == len(options.outputs):
        raise DecodeError(f"{_raw_name(src.raw)} is a focused-plenoptic (Raytrix) raw: --outputs {','.join(cut)} "
                          "would cut its views, one pixel per lens; ask for photo (its total focus), total-focus or "
                          "depth (virtual depth), or pass --views-anyway")
    return cut


#: A refocus keyword of :func:`_image_product_options` -> the ``plenodecode batch`` option that set it.
FOCUS_OPTIONS = {"slope": "--slope", "alpha": "--alpha", "focus_distance": "--focus-distance"}


def _focus_option_error(product: str, options: BatchOptions, raw: Any, exc: ValueError) -> DecodeError:
    """The failure of one raw whose refocus option value it cannot serve (a slope past its picture): a plain
    one-line error naming the option and its value, not a bug's traceback."""
    keyword, value = next(iter(_image_product_options(product, options).items()))
    return DecodeError(f"{FOCUS_OPTIONS[keyword]} {value:g} does not suit {_raw_name(raw)}: {exc}")


def _slope_reach_error(src: Any, options: BatchOptions) -> tuple[str, ValueError, float] | None:
    """(product, error, largest |slope| the raw allows) of the first refocused product whose slope (``slope``,
    or ``alpha`` or ``focus_distance`` turned into one with the camera constants) moves the outermost views of the
    raw's light field past its whole picture (:func:`plenodecode.pipeline.products.check_focus_reach` on the
    decoded shape and geometry the calibration gives), else None."""
    from .decoding.rectify import decoded_shape
    from .pipeline.products import check_focus_reach, photo_focus
    from .render._common import slope_reach

    for product in options.outputs:
        if product not in ("refocus", "photo"):
            continue
        if product == "photo" and photo_focus(src.focused).get("total_focus"):
            continue
        try:
            check_focus_reach(src, product, **_image_product_options(product, options))
        except ValueError as exc:
            return product, exc, slope_reach(decoded_shape(src.calibration.grid, src.decode_options.get("n_views")))
    return None


def _check_focus_reach(src: Any, options: BatchOptions) -> None:
    """Refuse, before decoding, a slope, alpha or distance past the raw's picture (:func:`_slope_reach_error`), and
    a focal stack's (``options.focal_stack``): a DecodeError naming the option."""
    found = _slope_reach_error(src, options)
    if found is not None:
        raise _focus_option_error(found[0], options, src.raw, found[1])
    if "focal-stack" in options.outputs and options.focal_stack is not None:
        from .pipeline.products import check_focus_reach

        start, stop, n = options.focal_stack
        try:
            check_focus_reach(src, "focal-stack", start=start, stop=stop, n=n, units=options.stack_units)
        except ValueError as exc:
            raise DecodeError(f"--focal-stack {start:g}:{stop:g}:{n} does not suit {_raw_name(src.raw)}: {exc}"
                              ) from None


#: What a check of :func:`up_front_refusals` says of one raw: (reach, error) refused, None suits, False not applying.
Refusal = tuple[float, ValueError] | None | bool

#: The checks of :func:`up_front_refusals`, in the order ``plenodecode batch`` raises their errors.
UP_FRONT_CHECKS = ("constants", "dark", "slope", "outputs", "stack")


@dataclass(frozen=True)
class UpFront:
    """What :func:`up_front_refusals` found that no raw of a batch can serve (empty / None: some raw can).

    Attributes
    ----------
    constants : tuple of MissingConstantsError
        Of every readable raw, when not one has the camera constants ``alpha``, ``focus_distance``, ``metric``,
        ``ply`` or alpha stack units ask for (:func:`check_constants_for_any`).
    dark : str or None
        The ``dark`` frame suits no raw: it cannot be read, or it has another size or would leave the raw black (a
        white or scene frame; :func:`plenodecode.pipeline.read_dark_frame`), said for the first raw.
    slope, outputs, stack : str or None
        The error of :func:`check_slope_for_any`, :func:`check_outputs_for_any`, :func:`check_stack_for_any`.
    """

    constants: tuple[MissingConstantsError, ...] = ()
    dark: str | None = None
    slope: str | None = None
    outputs: str | None = None
    stack: str | None = None


def _checks_asked(options: BatchOptions) -> set[str]:
    """The :data:`UP_FRONT_CHECKS` that ``options`` give something to check."""
    asked = set()
    if (options.alpha is not None or options.focus_distance is not None or options.metric or options.ply
            or options.stack_units == "alpha"):
        asked.add("constants")
    if options.dark is not None:
        asked.add("dark")
    if (options.slope != 0 or options.alpha is not None or options.focus_distance is not None) and any(
            p in ("refocus", "photo") for p in options.outputs):
        asked.add("slope")
    if any(o in VIEW_OUTPUTS for o in options.outputs) and not options.views_anyway and options.grid is None:
        asked.add("outputs")
    if options.focal_stack is not None and "focal-stack" in options.outputs:
        asked.add("stack")
    return asked


def _slope_refusal(src: Any, options: BatchOptions) -> Refusal:
    """The slope check of one calibrated raw (:func:`_slope_reach_error`)."""
    found = _slope_reach_error(src, options)
    return None if found is None else (found[2], found[1])


def _stack_refusal(src: Any, options: BatchOptions) -> Refusal:
    """The focal-stack check of one calibrated raw: False for a focused raw that leaves the stack out."""
    if src.focused and not options.views_anyway:
        return False
    from .decoding.rectify import decoded_shape
    from .pipeline.products import check_focus_reach
    from .render._common import slope_reach

    start, stop, n = options.focal_stack
    try:
        check_focus_reach(src, "focal-stack", start=start, stop=stop, n=n, units=options.stack_units)
    except ValueError as exc:
        return slope_reach(decoded_shape(src.calibration.grid, src.decode_options.get("n_views"))), exc
    return None


def up_front_refusals(files: Sequence[str | os.PathLike], options: BatchOptions,
                      checks: Sequence[str] = UP_FRONT_CHECKS) -> UpFront:
    """Every check ``plenodecode batch`` makes before its first task, in one pass that reads each raw once.

    Each check of ``checks`` (:data:`UP_FRONT_CHECKS`) that ``options`` ask for is asked of the raws of ``files`` in
    turn until one raw suits it; the pass ends when every check is settled or the raws run out.  Raws that cannot be
    read (or, for the slope and focal-stack checks, calibrated) are passed over: their tasks fail for that reason.
    The slope and focal-stack checks choose each raw's calibration (nothing is decoded); a raw whose grid would come
    from self-calibrating its scene (an image mosaic without a white image) settles them as suiting, as that costs a
    scene's fit (its task checks it).  The ``dark`` frame is read once and asked of each raw.  The library's log is
    held back to errors meanwhile, so the tasks' warnings are not said twice.

    Returns
    -------
    UpFront
        Each check's refusal when no raw suits it.
    """
    from . import pipeline
    from .io.generic import is_bare_mosaic
    from .pipeline.needs import is_focused_raw

    asked = _checks_asked(options)
    pending = [c for c in checks if c in asked]
    # per check, what the raws read so far refused: MissingConstantsError ('constants'), a focused raw's name
    # ('outputs'), (reach, name, error) ('slope', 'stack'), the error ('dark'); cleared when a raw suits it
    found: dict[str, list[Any]] = {c: [] for c in UP_FRONT_CHECKS}
    refusal = {"slope": _slope_refusal, "stack": _stack_refusal}

    def settled(check: str) -> None:
        pending.remove(check)
        found[check].clear()

    mosaic = options.mosaic_options()
    dark = None
    if "dark" in pending:
        try:            # read once for every raw
            dark = pipeline.read_dark_frame(options.dark, mosaic)
        except PlenodecodeError as exc:         # no raw can use it
            found["dark"].append(str(exc))
            pending.remove("dark")
    for f, raw in _readable_raws(files, options) if pending else ():
        if "constants" in pending:
            try:
                _check_metadata(raw, options)
            except MissingConstantsError as exc:
                found["constants"].append(exc)
            else:
                settled("constants")
        if "dark" in pending:
            try:
                pipeline.read_dark_frame(dark, raw=raw)
            except ValueError as exc:           # DarkFrameMismatchError
                found["dark"].append(str(exc))
            else:
                settled("dark")
        if "outputs" in pending:
            if is_focused_raw(raw):
                found["outputs"].append(Path(f).name)
            else:
                settled("outputs")
        calibrated = [c for c in pending if c in refusal]
        if calibrated and options.white is None and is_bare_mosaic(raw):
            for c in calibrated:      # its grid would come from a fit to its scene: its task checks it
                settled(c)
        elif calibrated:
            try:
                src = pipeline.Source(raw=raw, calibration=pipeline.choose_calibration(
                    raw, grid=options.grid, database=options.database, white=options.white, mosaic=mosaic),
                    geometry=options.geometric_calibration(), decode_options=options.decode_options())
            except (PlenodecodeError, OSError, ValueError):
                src = None
            for c in calibrated if src is not None else ():
                try:
                    said = refusal[c](src, options)
                except (PlenodecodeError, OSError, ValueError):
                    continue
                if said is None:
                    settled(c)
                elif said is not False:
                    found[c].append((said[0], Path(f).name, said[1]))
        if not pending:
            break
    focused = found["outputs"]
    outputs = None
    if focused:
        cut = [o for o in options.outputs if o in VIEW_OUTPUTS]
        which = focused[0] if len(focused) == 1 else f"all {len(focused)} raws here"
        outputs = (f"{','.join(cut)}: no raw here can serve {'it' if len(cut) == 1 else 'them'}: {which} "
                   f"{'is a' if len(focused) == 1 else 'are'} focused-plenoptic (Raytrix) "
                   f"raw{'s' * (len(focused) != 1)}, whose views have one pixel per lens; ask for photo (total "
                   "focus), total-focus or depth (virtual depth), or pass --views-anyway")
    dark_found = found["dark"]
    dark_said = None if not dark_found else dark_found[0] if len(dark_found) == 1 else (
        f"{dark_found[0]} (the {len(dark_found)} raws here: none suits it)")
    return UpFront(constants=tuple(found["constants"]), dark=dark_said, outputs=outputs,
                   **{c: _worst(found[c]) if found[c] else None for c in refusal})


def _worst(refused: list[tuple[float, str, ValueError]]) -> str:
    """The error of the raw allowing the most of the refusals of a slope or focal-stack check, saying how many
    there were."""
    reach, name, exc = max(refused, key=lambda r: r[0])
    return str(exc) if len(refused) == 1 else f"{exc} (every one of the {len(refused)} raws; {name} allows the most)"


def check_slope_for_any(files: Sequence[str | os.PathLike], options: BatchOptions) -> None:
    """Raise ValueError when ``options.slope`` (or the slope of ``options.alpha`` or ``options.focus_distance``) is
    past the picture of every raw of ``files`` it applies to (a batch would fail them all), before any is decoded:
    the error :func:`~plenodecode.render._common.check_slope_reach` gives for the raw allowing the largest slope.
    A raw with no slope to suit (a Raytrix raw's total-focus photograph) suits; how the raws are read:
    :func:`up_front_refusals`, which makes this check with the others in one pass.
    """
    found = up_front_refusals(files, options, ("slope",)).slope
    if found:
        raise ValueError(found)


def check_stack_for_any(files: Sequence[str | os.PathLike], options: BatchOptions) -> None:
    """Raise ValueError when ``options.focal_stack`` is past the picture of every raw of ``files`` that writes a
    focal stack (:func:`plenodecode.pipeline.products.check_focus_reach`), before any is decoded: the error of the
    raw allowing the largest slope.  A focused-plenoptic raw that leaves the stack out
    (:func:`_focused_views_left_out`) is not counted; how the raws are read: :func:`up_front_refusals`."""
    found = up_front_refusals(files, options, ("stack",)).stack
    if found:
        raise ValueError(found)


def check_outputs_for_any(files: Sequence[str | os.PathLike], options: BatchOptions) -> None:
    """Raise ValueError when no raw of ``files`` can serve the view outputs asked for (:data:`VIEW_OUTPUTS`): every
    readable one is a focused-plenoptic (Raytrix) raw, whose views have one pixel per lens, and
    ``options.views_anyway`` is off.  A raw's metadata tells (:func:`plenodecode.pipeline.needs.is_focused_raw`;
    with ``options.grid`` given by hand nothing is checked); raws that cannot be read are passed over
    (:func:`up_front_refusals`)."""
    found = up_front_refusals(files, options, ("outputs",)).outputs
    if found:
        raise ValueError(found)


def check_constants_for_any(files: Sequence[str | os.PathLike], options: BatchOptions) -> list[MissingConstantsError]:
    """The MissingConstantsError of every readable raw of ``files`` (:func:`_check_metadata`) when not one of them
    has the constants ``options`` ask for (``alpha``, ``focus_distance``, ``metric``, ``ply``, alpha stack units), so
    that a batch would fail them all before decoding; [] as soon as one has them.  Raws that cannot be read are
    passed over (their tasks fail for that reason); nothing is calibrated or decoded (:func:`up_front_refusals`)."""
    return list(up_front_refusals(files, options, ("constants",)).constants)


def _readable_raws(files: Sequence[str | os.PathLike], options: BatchOptions
                   ) -> Iterator[tuple[str | os.PathLike, Any]]:
    """``(path, RawCapture)`` of every raw of ``files`` that can be read as the batch reads them (mosaic options,
    optics), without their warnings (the tasks read them again and say them); unreadable ones are passed over."""
    from . import pipeline
    from .optics import MicroscopeOptics
    from .pipeline.inputs import quieted

    mosaic = options.mosaic_options()
    with quieted(__name__.split(".")[0]):
        for f in files:
            try:
                raw = pipeline.open_raw(f, mosaic=mosaic, optics=MicroscopeOptics.from_dict(options.optics))
            except (PlenodecodeError, OSError, ValueError):
                continue
            yield f, raw


def _check_views(grid: Any, n_views: int | None, raw: Any) -> None:
    """Refuse, before decoding, ``n_views`` past the views per axis that see a micro-image of ``grid``: a
    DecodeError naming ``--views``, as ``plenodecode decode --views`` refuses it."""
    if n_views is not None and n_views > grid.max_views():
        raise DecodeError(f"--views {n_views} does not suit {_raw_name(raw)}: more than the {grid.max_views()} "
                          f"views per axis that see a micro-image (the default is {grid.n_views()})")


def _check_disparity_range(src: Any, options: BatchOptions) -> None:
    """Refuse, before decoding, ``options.disparity_range`` for a raw's 'depth' output as ``plenodecode depth``
    refuses ``--disparity-range``: for a focused-plenoptic (Raytrix) raw (its depth is virtual depth), and past the
    slope at which the outermost views still overlap the centre one
    (:func:`plenodecode.pipeline.products.check_disparity_reach`); a DecodeError naming the option."""
    rng = options.disparity_range
    if rng is None or "depth" not in options.outputs:
        return
    text = f"--disparity-range {rng[0]:g}:{rng[1]:g}"
    if src.focused:
        raise DecodeError(f"{text} does not suit {_raw_name(src.raw)}: a focused-plenoptic (Raytrix) raw's depth is "
                          "its virtual depth, searched over its lens types' range")
    from .pipeline.products import check_disparity_reach

    try:
        check_disparity_reach(src, rng)
    except ValueError as exc:
        raise DecodeError(f"{text} does not suit {_raw_name(src.raw)}: {exc}") from None


def depth_stem(rendered: Any) -> str:
    """File stem of a 'depth' output: 'virtual_depth' for a focused-plenoptic (Raytrix) raw's virtual depth,
    'depth' for metric depth, else 'disparity'."""
    if rendered.data.get("method") == "focused":
        return "virtual_depth"
    return "depth" if str(rendered.data.get("label", "")).startswith("depth") else "disparity"


def _write_products(raw: Any, folder: Path, options: BatchOptions, *, threads: int | None = None
                    ) -> tuple[list[tuple[Path, Path | None]], tuple[str, ...],
                               tuple[str | None, float | None, str | None]]:
    """Calibrate and decode ``raw`` and write ``options.outputs`` into ``folder``, all through
    :mod:`plenodecode.pipeline` (the same calibration policy, products, display encoding and writers as the
    single-purpose commands).

    Image outputs are 8/16-bit PNGs, display-encoded when the light field is linear (``bit_depth=32``: float
    EXR, linear); the light field itself is saved as it is; the 'views' folder is display-encoded like images.

    Returns
    -------
    written : list of (product path, thumbnail path or None)
        In the order of ``options.outputs``; a product that is the same image as an earlier one ('photo' and
        'refocus' at the same focus, 'photo' and 'total-focus' of a focused raw) is written once.
    left_out : tuple of str
        One line per reason an output asked for was not written ('centre,parallax: not for a focused-plenoptic
        (Raytrix) raw (...)'; :func:`_focused_views_left_out`), or empty.
    level : (str, float, str) or (None, None, None)
        The first picture product, its :func:`plenodecode.pipeline.image_level` (:attr:`TaskResult.level`), at
        the default exposure only, and its output's name in ``folder`` (:attr:`TaskResult.level_file`).
    """
    import numpy as np

    from . import pipeline
    from .io.depthio import DEFAULT_MIN_CONFIDENCE, colour_map_image

    mosaic = options.mosaic_options()
    dark = pipeline.read_dark_frame(options.dark, mosaic, raw=raw)     # its size checked before the calibration
    calibration = pipeline.choose_calibration(raw, grid=options.grid, database=options.database, white=options.white,
                                              self_calibrate=options.self_calibrate, mosaic=mosaic)
    _check_views(calibration.grid, options.n_views, raw)
    src = pipeline.Source(raw=raw, calibration=calibration, decode_options={
        "workers": threads, "dark": dark, **options.decode_options()},
        geometry=options.geometric_calibration())
    left_out = _focused_views_left_out(src, options)      # all three before the (lazy) decoding
    if left_out:
        options = replace(options, outputs=tuple(o for o in options.outputs if o not in left_out))
    _check_focus_reach(src, options)
    _check_disparity_range(src, options)
    bits = options.bit_depth
    thumbs = folder / THUMB_DIR
    thumbs.mkdir()
    written: list[tuple[Path, Path | None]] = []
    level: tuple[str | None, float | None, str | None] = (None, None, None)

    def measured(product: str, rendered: Any, output: str) -> None:
        nonlocal level
        # the first picture: how bright it is, at the default exposure only (a chosen one is as asked: no note)
        if level[0] is None and options.exposure == 0.0:
            level = (product, pipeline.image_level(rendered), output)

    def centre_thumbnail(name: str, lf: Any = None) -> Path:
        from .render import perspective

        lf = src.lightfield if lf is None else lf
        return _thumbnail(perspective(lf, *lf.centre_index), thumbs / f"{name}.png", colour=lf.colour)

    for product in options.outputs:
        if product == "lightfield":
            dest = pipeline.write_lightfield(src.lightfield, folder / LIGHTFIELD_NAMES[options.format],
                                             format=options.format, bit_depth=bits)
            written.append((dest, centre_thumbnail("lightfield")))
        elif product == "views":
            # the pictures 'plenodecode views' writes (view_VV_UU, views outside the micro-images black), with its
            # --exposure (one gain, from the centre view); the 'lightfield' output is the data as decoded
            rendered = pipeline.render_product(src, "views")
            measured(product, rendered, "views/")
            gain = pipeline.exposure_gain(rendered, options.exposure)
            pipeline.write_product(rendered, folder / "views", bit_depth=bits, exposure=math.log2(gain))
            lf = src.lightfield
            if gain != 1.0:
                lf = lf.replace(data=pipeline.expose(lf.data, lf.colour, gain))
            written.append((folder / "views", centre_thumbnail("views", lf)))
        elif product == "focal-stack":
            rendered = pipeline.render_product(src, "focal-stack", **_stack_options(src, options))
            measured(product, rendered, f"{FOCAL_STACK_DIR}/")
            gain = pipeline.exposure_gain(rendered, options.exposure)      # one gain for the stack and thumbnail
            pipeline.write_product(rendered, folder / FOCAL_STACK_DIR, bit_depth=bits, exposure=math.log2(gain))
            (_, aif), = [item for item in rendered.images if item[0] == "all_in_focus"]
            written.append((folder / FOCAL_STACK_DIR, _thumbnail(pipeline.expose(aif, rendered.colour, gain),
                                                                 thumbs / "focal_stack.png", colour=rendered.colour)))
        elif product == "parallax":
            try:
                rendered = pipeline.render_product(src, "parallax", frames=options.frames, radius=options.radius,
                                                   interp=options.interp)
            except ValueError as exc:       # a radius past this raw's view grid
                if options.radius is None:
                    raise
                raise DecodeError(f"--radius {options.radius:g} does not suit {_raw_name(raw)}: {exc}") from None
            measured(product, rendered, PARALLAX_NAME)
            gain = pipeline.exposure_gain(rendered, options.exposure)
            frames_dir = folder / PARALLAX_FRAMES_DIR if options.parallax_frames else None
            pipeline.write_parallax(rendered, folder / PARALLAX_NAME, fps=options.fps, frames_dir=frames_dir,
                                    bit_depth=bits, exposure=math.log2(gain))
            (_, first), *_ = rendered.images
            written.append((folder / PARALLAX_NAME, _thumbnail(pipeline.expose(first, rendered.colour, gain),
                                                               thumbs / "parallax.png", colour=rendered.colour)))
            if frames_dir is not None:
                written.append((frames_dir, None))
        elif product == "depth":
            rendered = pipeline.render_product(src, "depth", method=options.depth_method,
                                               disparity_range=options.disparity_range,
                                               **({"metric": True} if options.metric else {}),
                                               **({"points": True} if options.ply else {}),
                                               **({} if options.depth_focus_distance is None else
                                                  {"focus_distance": options.depth_focus_distance}))
            stem = depth_stem(rendered)
            threshold = DEFAULT_MIN_CONFIDENCE if options.min_confidence is None else options.min_confidence
            # the files 'plenodecode depth' writes: the PFM, EXR, colour-mapped PNG and confidence map, so the folder
            # holds a depth picture a viewer opens (a PFM alone does not); the PNGs first among the index's links
            dest, exr, *pictures = pipeline.write_depth(
                rendered, folder / f"{stem}.pfm", title=f"{_raw_name(raw)}: {rendered.data['method']}",
                min_confidence=threshold, ply=folder / f"{stem}.ply" if options.ply else None)
            dm = rendered.data["depthmap"]
            masked = dm.confidence < np.float32(threshold) if threshold > 0 else None
            # the colour map and range of the depth PNG ``plenodecode depth`` writes, with a colour bar; pixels
            # below min_confidence grey
            colours = colour_map_image(rendered.data["values"], label=rendered.data["label"], masked=masked,
                                       near=rendered.data.get("near"), **THUMB_FIGURE)
            written.append((dest, _thumbnail(colours, thumbs / f"{stem}.png", colour="srgb")))
            written.extend((p, None) for p in sorted(pictures + [exr], key=lambda p: p.suffix.lower() != ".png"))
        else:
            try:
                rendered = pipeline.render_product(src, product, **_image_product_options(product, options))
            except ValueError as exc:
                if product not in ("refocus", "photo"):
                    raise
                raise _focus_option_error(product, options, raw, exc) from None
            (stem, image), = rendered.images
            name = f"{stem}.{pipeline.default_extension(bits)}"
            if any(dest.name == name for dest, _ in written):
                # 'photo' is the 'refocus' at the same focus, or a focused raw's 'total-focus': one file
                log.info("%s: %s is the same image as an earlier output", product, name)
                continue
            measured(product, rendered, name)
            # one gain for the file and its thumbnail ('auto' measures the image once)
            gain = pipeline.exposure_gain(rendered, options.exposure)
            dest, = pipeline.write_product(rendered, folder / name, bit_depth=bits, exposure=math.log2(gain))
            shown = pipeline.expose(image, rendered.colour, gain)
            written.append((dest, _thumbnail(shown, thumbs / f"{stem}.png", colour=rendered.colour)))
    return written, ((f"{','.join(left_out)}: {FOCUSED_LEFT_OUT}",) if left_out else ()), level


# ------------------------------------------------------------------------------ runners
def _clean_stale(out: Path) -> None:
    """Remove what killed runs left in ``out``, never what a live run is writing.

    Temporaries and replaced folders of :mod:`plenodecode.io.atomic` (staging folders, summary files) go
    by :func:`~plenodecode.io.atomic.remove_stale_temporaries`, which knows their owner: a process of this
    host that no longer runs, or no change for a day.  Hidden leftovers of earlier versions, whose names
    carry no owner (``.<name>.partial`` and ``.<name>.old`` folders, ``.summary.json...tmp`` files), are
    removed outright.
    """
    remove_stale_temporaries(out)
    for p in out.iterdir():
        if not p.name.startswith(".") or is_temporary(p):
            continue
        if p.is_dir() and not p.is_symlink() and p.name.endswith((STAGING_SUFFIX, OLD_MARK)):
            log.info("removing %s left by an interrupted run", p)
            discard(p)
        elif p.is_file() and p.name.endswith(TEMP_MARK) and p.name[1:].startswith(SUMMARY_FILES):
            discard(p)


def run_batch(inputs: Sequence[str | os.PathLike], output: str | os.PathLike | None = None,
              options: BatchOptions | None = None, *, jobs: int | None = None, scheduler: str | Any | None = None,
              max_in_flight: int | None = None, overwrite: bool = False, progress: Progress = None,
              **renamed: Any) -> BatchSummary:
    """Process every raw under ``inputs`` into ``output`` (``out_dir`` of the module docstring).

    Parameters
    ----------
    inputs : sequence of path-like
        Raw files and folders (searched by :func:`find_raws`; ``output`` itself is excluded).
    output : path-like
        Output folder (created; ``plenodecode batch -o/--output``).  Its old name ``out_dir=`` still works, with a
        DeprecationWarning.
    options : BatchOptions, optional
    jobs : int, optional
        Local worker processes (default: all cores); ``jobs=1`` runs in this process.
        Ignored with ``scheduler``.
    scheduler : str or dask.distributed.Client, optional
        Address of a Dask scheduler (``tcp://host:8786``) or a Client: run the same tasks there.
    max_in_flight : int, optional
        Tasks submitted at once (default: 2 per worker).
    overwrite : bool
        Redo every raw, ignoring earlier results, and replace its folder.  Without it a run that would replace
        a folder (another run's options or inputs, or not a batch's) raises FileExistsError before any work.
    progress : callable(done, total), optional
        Called once with ``(0, total)`` and after every finished raw.

    Returns
    -------
    BatchSummary
        One result per raw in input order; failures carry their error, nothing is raised for bad files.

    Raises
    ------
    ValueError
        ``jobs``, ``max_in_flight`` or a malformed ``scheduler`` address.
    TypeError
        ``options`` is not a :class:`BatchOptions`.
    OSError
        ``output`` cannot be created (under a file, not writable), or the scheduler cannot be reached; before
        any raw is read and before the output folder is made.
    """
    from .deprecation import renamed_keywords

    given = renamed_keywords({**renamed, **({} if output is None else {"output": output})}, {"out_dir": "output"},
                             "run_batch")
    out_dir = given.pop("output", None)
    if given:
        raise TypeError(f"run_batch() got an unexpected keyword argument {next(iter(given))!r}")
    if out_dir is None:
        raise TypeError("run_batch() missing the output folder: pass output=")
    if jobs is not None and jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if max_in_flight is not None and max_in_flight < 1:
        raise ValueError(f"max_in_flight must be >= 1, got {max_in_flight}")
    options = options or BatchOptions()
    if not isinstance(options, BatchOptions):
        raise TypeError(f"options must be a BatchOptions, got {type(options).__name__} (BatchOptions(**it))")
    # an absolute database path: forked workers keep the working directory of their fork server's start
    # (none given: the working directory's calib/ when it has an index, else each raw's own, find_database)
    from .calib.store import find_database

    database = options.database if options.database is not None else find_database()
    options = replace(options, database=None if database is None else str(Path(database).resolve()))
    out = Path(out_dir).resolve()
    refuse_unwritable(out / SUMMARY_JSON)      # before any work (NotADirectoryError, PermissionError)
    # absolute, links not followed: a raw linked into a folder is read there, with the sidecar, Raytrix XML or
    # metadata.txt beside the link (as the single commands read it), not beside its target
    files = [Path(os.path.abspath(f)) for f in find_raws(inputs, exclude=[out])]
    if not overwrite:
        check_outputs_to_replace(files, out, options)
    if scheduler is None:
        jobs = min(jobs or os.cpu_count() or 1, max(1, len(files)))
    client = None
    if scheduler is not None:   # reached (or refused) before the output folder is made: a typo leaves nothing
        from .batch_workers import connect_scheduler

        client, own_client = connect_scheduler(scheduler)
    pool = None
    if scheduler is None and jobs > 1:     # the workers' modules load while this process prepares the batch
        from .batch_workers import start_pool

        pool, threads = start_pool(jobs, options.outputs)
    made = not out.exists()
    try:
        names = output_names(files)
        out.mkdir(parents=True, exist_ok=True)
        _clean_stale(out)
    except BaseException:
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        if client is not None and own_client:
            client.close()
        raise
    t0 = time.perf_counter()
    tasks = [(f, n) for f, n in zip(files, names)]
    task = functools.partial(process_raw, out_dir=str(out), options=options, overwrite=overwrite)
    try:
        if progress is not None:
            progress(0, len(files))
        if scheduler is not None:
            from .batch_workers import run_dask

            try:
                results = run_dask(tasks, task, _lost_result, options.outputs, client, max_in_flight, progress)
            finally:
                if own_client:
                    client.close()
        elif pool is not None:
            from .batch_workers import run_pool

            results = run_pool(pool, tasks, task, _lost_result, options.outputs, jobs, max_in_flight or 2 * jobs,
                               threads, progress)
        else:
            results = []
            for i, (f, n) in enumerate(tasks):
                results.append(process_raw(f, out, options, name=n, overwrite=overwrite))
                if progress is not None:
                    progress(i + 1, len(files))
    except BaseException:       # Ctrl-C: the raws finished stay (a new run resumes); nothing half-written does
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)   # (done already when run_pool was reached)
        _clean_stale(out)       # what the stopped workers were writing
        if made and not any(out.iterdir()):
            out.rmdir()         # nor the folder this run made
        raise
    summary = BatchSummary(tuple(results), time.perf_counter() - t0)
    log.info("batch: %d done, %d skipped, %d failed in %.1f s", summary.count("done"), summary.count("skipped"),
             summary.count("failed"), summary.seconds)
    return summary


# ------------------------------------------------------------------------------ summary
def check_summary_files(out_dir: str | os.PathLike) -> None:
    """Raise FileExistsError when ``summary.json`` or ``index.html`` in ``out_dir`` was not written by a batch.

    The batch's own summary and index describe the latest run and are replaced by the next one;
    files of the same name that something else wrote are never replaced (pass ``overwrite``).
    """
    from .report.batch import GENERATOR

    out = Path(out_dir)
    js, index = out / SUMMARY_JSON, out / INDEX_HTML
    if js.exists():
        try:
            ours = json.loads(js.read_text(encoding="utf-8")).get("format") == SUMMARY_FORMAT
        except (OSError, ValueError, AttributeError):
            ours = False
        if not ours:
            raise FileExistsError(f"{js} exists and was not written by a batch run; pass --overwrite "
                                  "(overwrite=True) or choose another output folder")
    if index.exists():
        try:
            with open(index, encoding="utf-8", errors="replace") as fh:
                ours = GENERATOR in fh.read(4096)
        except OSError:
            ours = False
        if not ours:
            raise FileExistsError(f"{index} exists and was not written by a batch run; pass --overwrite "
                                  "(overwrite=True) or choose another output folder")


def write_summary(summary: BatchSummary, out_dir: str | os.PathLike, *, overwrite: bool = False) -> tuple[Path, Path]:
    """Write ``summary.json`` and the HTML index (thumbnails and errors) into ``out_dir``.

    Both describe the latest run and replace those of an earlier batch run in that folder.

    Parameters
    ----------
    summary : BatchSummary
    out_dir : path-like
    overwrite : bool
        Also replace a ``summary.json`` / ``index.html`` that a batch did not write.

    Returns
    -------
    (Path, Path)
        ``summary.json`` and ``index.html``.

    Raises
    ------
    FileExistsError
        See :func:`check_summary_files`.
    """
    from .report.batch import write_batch_index

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if not overwrite:
        check_summary_files(out)
    js = write_text_atomic(out / SUMMARY_JSON, json.dumps(summary.to_dict(), indent=1), overwrite=True)
    html = write_batch_index(summary, out / INDEX_HTML, overwrite=True)
    return js, html


__all__ = ["BATCH_OUTPUTS", "MEASURED", "BatchOptions", "TaskResult", "BatchSummary", "find_raws", "output_names",
           "task_key", "outputs_to_replace", "check_outputs_to_replace", "check_slope_for_any", "check_stack_for_any",
           "check_outputs_for_any", "check_constants_for_any", "UP_FRONT_CHECKS", "UpFront", "up_front_refusals",
           "process_raw", "run_batch", "write_summary", "check_summary_files"]
