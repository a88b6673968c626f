"""The decoder: raw lenslet mosaic + LensletGrid -> LightField ``(V, U, Y, X, C)`` (:func:`decode`).

The pipeline and the output size it produces are described in :mod:`plenodecode.decoding`.
"""

from __future__ import annotations

import logging
import mmap
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import CalibrationError, DecodeError
from ..raymodel import GeometricCalibration
from ..registry import lookup
from ..types import BARE_MOSAIC_KEY, LensletGrid, LightField, RawCapture
from . import colour as _colour
from . import devignette as _dv
from .demosaic import DEMOSAIC_METHODS
from .demosaic import demosaic as _demosaic
from .devignette import DEFAULT_FLOOR, normalise, relative_white, repair_hot_pixels
from .rectify import decoded_geometry, rectify
from .resample import HEX_CONTEXT, RESAMPLE_METHODS, hex_to_rect, output_shape
from .slice import VIEW_EDGES, lens_labels, plan_bands, safe_radius, sample_lenses, usable_pixels, view_offsets

log = logging.getLogger(__name__)

#: default demosaicing method of :func:`decode`
DEFAULT_DEMOSAIC = "malvar"


def _as_plane(img, name: str, raw: RawCapture):
    """Validate a white or dark image; returns (array, black, white levels) or raises."""
    if img is None:
        return None
    if isinstance(img, (str, os.PathLike)):        # a path, as calibrate() takes one
        from ..io import read_raw
        img = read_raw(img)
    if isinstance(img, RawCapture):
        arr, black, white = img.mosaic, img.black, img.white
    elif isinstance(img, np.ndarray):
        arr, black, white = img, raw.black, raw.white
    else:
        raise ValueError(f"{name} must be a RawCapture, an ndarray or a path, got {type(img).__name__}")
    if arr.ndim != 2 or arr.shape != raw.shape:
        raise DecodeError(f"{name} image must have the raw's size {raw.shape[1]}x{raw.shape[0]}, "
                          f"found {'x'.join(map(str, arr.shape[::-1]))}; pass the {name} frame of this camera")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise DecodeError(f"{name} image must be finite, found NaN or inf values; repair or replace the {name} frame")
    if arr.dtype.kind not in "uif":
        raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
    return arr, black, white


#: A dark frame must leave the raw at least this share of its range at its brightest 0.1 % once subtracted (the
#: ant leg's dark frame leaves 13 %, its radiometry frame given as the dark none: an all-black light field).
DARK_LEAVES_MIN = 0.01


def refuse_bright_dark(dark: np.ndarray, raw: RawCapture, name: str = "the frame given as dark") -> None:
    """Raise :class:`~plenodecode.errors.DarkFrameMismatchError` (a ValueError) when subtracting ``dark`` (H, W),
    in sensor units, would leave ``raw`` black: a white, a scene or the raw itself given as the dark frame.

    ``--dark`` and ``decode(raw, grid, dark=...)`` share it; ``name`` is what the message calls the frame.
    """
    from ..errors import DarkFrameMismatchError

    step = max(1, int(np.sqrt(raw.mosaic.size / 2e6)))          # ~2 Mpx are plenty for a percentile
    rest = raw.mosaic[::step, ::step].astype(np.float32) - dark[::step, ::step]
    span = float(np.max(raw.white) - np.min(raw.black)) or 1.0
    top = float(np.percentile(rest, 99.9))
    if top <= DARK_LEAVES_MIN * span:
        raise DarkFrameMismatchError(
            f"{name} is no dark frame for {os.path.basename(raw.path) if raw.path else 'this raw'}: subtracted "
            f"from it, the brightest 0.1 % keep {max(top, 0.0) / span:.1%} of the range, a black picture (a white "
            "or scene frame, or the raw itself?); pass the frame taken with no light")


#: Arrays at least this large (bytes) are mapped by :func:`small_page_empty`, smaller ones by ``np.empty``.
SMALL_PAGE_MIN_BYTES = 1 << 24


def small_page_empty(shape: tuple[int, ...], dtype) -> np.ndarray:
    """An uninitialised array in ordinary (4 kB) pages: ``np.empty`` without transparent huge pages.

    numpy asks Linux for transparent huge pages on every large array (``madvise(MADV_HUGEPAGE)``);
    where the kernel compacts memory on demand for such regions (``defrag = madvise``, the default),
    the first touch of a fresh gigabyte-sized light field stalls in compaction: a full Illum decode
    spent 2.3-2.5 CPU s in hex -> rect (where the output is first written) instead of 1.05 s
    (``bench/bench_decode.py``, fresh processes).  A private anonymous ``mmap`` is not advised, so it
    gets ordinary pages, faulted in by the band threads as they write.  The array owns the mapping
    (through its ``base``); it is unmapped when the last view of it goes.

    Parameters
    ----------
    shape : tuple of int
    dtype : numpy dtype

    Returns
    -------
    ndarray, C-contiguous, writable, contents undefined (zeros in practice).
    """
    dtype = np.dtype(dtype)
    n = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if n < SMALL_PAGE_MIN_BYTES or not hasattr(mmap, "MAP_ANONYMOUS"):
        return np.empty(shape, dtype)
    buf = mmap.mmap(-1, n, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    return np.frombuffer(buf, dtype).reshape(shape)


class _Scratch:
    """Per-thread work buffers reused from band to band.

    Fresh multi-megabyte arrays are page-faulted on first touch; reusing one buffer per name and
    thread keeps that cost to the first band (and :func:`small_page_empty` keeps it free of huge-page
    compaction).
    """

    def __init__(self) -> None:
        self._local = threading.local()

    def get(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        bufs = self._local.__dict__.setdefault("bufs", {})
        dtype = np.dtype(dtype)
        n = int(np.prod(shape)) * dtype.itemsize
        buf = bufs.get(name)
        if buf is None or buf.size < n:
            buf = small_page_empty((n,), np.uint8)
            bufs[name] = buf
        return buf[:n].view(dtype).reshape(shape)


def _check_views(n_views: int | None, grid: LensletGrid) -> int:
    if n_views is None:
        return grid.n_views()
    if not isinstance(n_views, (int, np.integer)) or n_views < 1 or n_views % 2 == 0:
        raise ValueError(f"n_views must be a positive odd integer, got {n_views!r}")
    if n_views > grid.max_views():
        raise ValueError(f"n_views {n_views} is more than the {grid.max_views()} views per axis that see a "
                         f"micro-image: the lenses are {grid.pitch:.2f} px apart and a view step is one sensor pixel")
    return int(n_views)


def decode(raw: RawCapture, grid: LensletGrid, *, white: RawCapture | np.ndarray | None = None,
           dark: RawCapture | np.ndarray | None = None, demosaic: str = DEFAULT_DEMOSAIC,
           colour: str = "linear-srgb", n_views: int | None = None, hot_pixels: bool | str = True,
           resample: str = "cubic", floor: float = DEFAULT_FLOOR, workers: int | None = None,
           progress: Callable[[int, int], None] | None = None, geometry: GeometricCalibration | None = None,
           view_edges: str = "renormalise") -> LightField:
    """Decode a raw lenslet image into a 4D light field.

    Parameters
    ----------
    raw : RawCapture
        The scene raw (uint16 mosaic with its levels and metadata).
    grid : LensletGrid
        Lenslet grid of this camera (same sensor size).
    white : RawCapture, ndarray (H, W) or path, optional
        White image taken with the same zoom/focus: devignetting and the sample weights.  A bare
        uint16 array uses the raw's levels; a float array is taken as already normalised.  Without a
        white, nothing is devignetted and the weight is the lenslet disk of ``grid.radius``.
    dark : RawCapture, ndarray (H, W) or path, optional
        Dark frame in sensor units, subtracted from raw and white pixel by pixel instead of the black
        level (microscopes).
    demosaic : str
        Key of :data:`DEMOSAIC_METHODS` (ignored for monochrome sensors).
    colour : {'linear-srgb', 'camera'}
        'linear-srgb' applies white balance and the camera's colour matrix; when the metadata has no
        colour matrix the light field stays in camera colour and a warning is logged.
    n_views : int, optional
        Views per angular axis (odd); default ``grid.n_views()``.
    hot_pixels : bool or 'isolated'
        Repair hot pixels (:func:`plenodecode.decoding.devignette.repair_hot_pixels`); 'isolated' repairs only the
        raw's pixels that are also brighter than their 8 adjacent ones once divided by the white (``isolated=True``:
        sharp scene edges on the micro-images' rims are left alone; geometric calibration uses it).
    resample : str
        Hex -> rect kernel, key of :data:`plenodecode.decoding.resample.RESAMPLE_METHODS`: ``'cubic'`` (along
        each lens row), ``'linear'``, or ``'hex'`` (2-D on the lattice: no row-alternating zipper on vertical
        edges, about 1.5x the decode's CPU time).
    floor : float
        Pixels receiving less than ``floor`` of their lens's peak white are treated as missing.
    workers : int, optional
        Threads (default: all cores).
    progress : callable(done, total), optional
        Called after each band of lens rows.
    geometry : GeometricCalibration, optional
        Rectify the decoded light field with this geometric calibration
        (:func:`plenodecode.decoding.rectify.rectify`: undistorted pinhole views, ``geometry.ray_model``
        set); its ``lf_shape`` must be the decoded ``(V, U, Y, X)``.
    view_edges : {'renormalise', 'extrapolate'}
        How a view's sample near the micro-image's edge is made (:data:`plenodecode.decoding.slice.VIEW_EDGES`):
        'renormalise' (default, the fast one) moves the outer views up to a third of a view step inwards;
        'extrapolate' keeps every view at its nominal offset (geometric calibration uses it), at about 6x
        the CPU of the slicing step (2.4x the whole decode's, full Illum raw).

    Returns
    -------
    LightField
        ``data`` (V, U, Y, X, C) float32 (C = 3, or 1 for monochrome), ``weight`` (V, U, Y, X)
        float32 in [0, 1], linear; sizes as in the module docstring.

    Raises
    ------
    CalibrationError
        The grid was fitted on another sensor size; ``geometry`` is for another light-field shape.
    DecodeError
        White or dark frame of the wrong size or with NaNs.
    DarkFrameMismatchError
        (a ValueError too) ``dark`` would leave the raw black: a white or scene frame (:func:`refuse_bright_dark`).
    """
    return decode_timed(raw, grid, white=white, dark=dark, demosaic=demosaic, colour=colour, n_views=n_views,
                        hot_pixels=hot_pixels, resample=resample, floor=floor, workers=workers,
                        progress=progress, timings=None, geometry=geometry,
                        view_edges=view_edges)


def decode_timed(raw: RawCapture, grid: LensletGrid, *, timings: dict[str, float] | None, **kw) -> LightField:
    """:func:`decode` that also adds each stage's thread CPU seconds (summed over bands) to ``timings``.

    For benchmarks: keys 'levels', 'hot pixels', 'labels', 'white', 'demosaic', 'slice', 'hex->rect',
    plus 'total cpu' and 'wall'.  ``timings=None`` times nothing.
    """
    return _decode(raw, grid, timings=timings, **kw)


@dataclass(frozen=True)
class LensSamples:
    """Every view's samples on the lens lattice, before hex -> rect resampling (:func:`decode_samples`).

    Attributes
    ----------
    data : ndarray, shape (V, U, R, K, C), float32
        Sample of view ``(v, u)`` under lens ``(r, k)`` (the slicer's output, colour matrix applied).
    weight : ndarray, shape (V, U, R, K), float32
        Its weight (the white's share of its bilinear footprint inside the lens; 0 = no sample).
    position : ndarray, shape (R, K, 2), float64
        ``(x, y)`` of lens ``(r, k)`` in the decoded view's pixel coordinates (pixel centres at integers):
        ``x = (k p + s (r mod 2) - b0) / step``, ``y = r`` (``p`` pitch, ``s`` odd-row shift, ``b0`` and
        ``step`` of :meth:`LensletGrid.decoded_sampling`), the same for every view.
    """

    data: np.ndarray
    weight: np.ndarray
    position: np.ndarray


def lens_positions(grid: LensletGrid) -> np.ndarray:
    """``(x, y)`` of every lens in the decoded views' pixel coordinates, (R, K, 2) float64 (:class:`LensSamples`)."""
    s = grid.decoded_sampling()
    rows, cols = grid.shape
    shift = grid.odd_row_shift * grid.pitch if rows > 1 else 0.0
    r, k = np.mgrid[0:rows, 0:cols].astype(np.float64)
    x = (k * grid.pitch + shift * (r % 2) - s["b0"]) / s["step"]
    return np.stack([x, r], axis=-1)


def decode_samples(raw: RawCapture, grid: LensletGrid, **kw) -> tuple[LightField, LensSamples]:
    """:func:`decode` that also hands out every view's samples on the lens lattice (:class:`LensSamples`).

    Takes :func:`decode`'s keywords but ``geometry`` (the samples are not rectified); the light field is
    the one :func:`decode` returns with them.  For fits that want the data where it was measured (geometric
    calibration's corner fit) rather than interpolated by the hex -> rect step.  The samples take about the
    light field's memory again.
    """
    if kw.get("geometry") is not None:
        raise ValueError("decode_samples does not rectify: pass geometry=None")
    kw.pop("geometry", None)
    store: dict = {}
    lf = _decode(raw, grid, timings=None, samples_out=store, **kw)
    return lf, LensSamples(data=store["data"], weight=store["weight"], position=lens_positions(grid))


def _decode(raw: RawCapture, grid: LensletGrid, *, white=None, dark=None, demosaic: str = DEFAULT_DEMOSAIC,
            colour: str = "linear-srgb", n_views=None, hot_pixels: bool | str = True, resample: str = "cubic",
            floor: float = DEFAULT_FLOOR, workers=None, progress=None, timings=None, geometry=None,
            view_edges: str = "renormalise", samples_out: dict | None = None) -> LightField:
    # samples_out: when a dict, filled with the per-lens samples of every band (decode_samples)
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    if not isinstance(raw, RawCapture):
        raise ValueError(f"raw must be a RawCapture, got {type(raw).__name__}")
    if not isinstance(grid, LensletGrid):
        raise ValueError(f"grid must be a LensletGrid, got {type(grid).__name__}")
    if tuple(grid.sensor_shape) != tuple(raw.shape):
        raise CalibrationError(
            f"the lenslet grid was fitted on a {grid.sensor_shape[1]}x{grid.sensor_shape[0]} sensor but the raw is "
            f"{raw.shape[1]}x{raw.shape[0]} (width x height); pass the grid calibrated from this camera's white images")
    lookup(DEMOSAIC_METHODS, demosaic, param="demosaic")
    extrapolate = lookup(VIEW_EDGES, view_edges, param="view_edges")
    if isinstance(hot_pixels, str) and hot_pixels != "isolated":
        raise ValueError(f"hot_pixels must be True, False or 'isolated', got {hot_pixels!r}")
    isolated = isinstance(hot_pixels, str)
    if colour not in _colour.DECODE_COLOURS:
        raise ValueError(f"colour must be one of {_colour.DECODE_COLOURS}, got {colour!r}")
    lookup(RESAMPLE_METHODS, resample, param="resample")
    if not 0.0 < floor < 1.0:
        raise ValueError(f"floor must be in (0, 1), got {floor}")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    nv = _check_views(n_views, grid)
    white_p = _as_plane(white, "white", raw)
    dark_p = _as_plane(dark, "dark", raw)
    if dark_p is not None:
        path = dark if isinstance(dark, (str, os.PathLike)) else getattr(dark, "path", None)
        refuse_bright_dark(dark_p[0], raw, os.path.basename(path) if path else "the frame given as dark")
    # a bare mosaic without a white image is self-calibrated, and the pipeline says then, once, that it is not
    # devignetted and stays in camera RGB (pipeline.calibration); any other raw without them is warned about here
    expected = logging.INFO if BARE_MOSAIC_KEY in raw.metadata.extra and white_p is None else logging.WARNING
    if white_p is None:
        log.log(expected, "no white image: the raw is not devignetted; weights come from the lenslet disk radius")

    cfa = raw.cfa
    nch = 1 if cfa is None else 3
    matrix = None
    colour_state = "camera"
    if nch == 3 and colour == "linear-srgb":
        matrix = _colour.colour_matrix(raw.metadata)
        if matrix is None:
            log.log(expected, "the raw's metadata has no colour matrix (ccm): the light field stays in camera RGB")
        else:
            colour_state = "linear-srgb"
    elif nch == 1 and colour == "linear-srgb":
        colour_state = "camera"

    ny, nx = output_shape(grid)
    h, w = raw.shape
    cols = grid.shape[1]
    centres = grid.centres_2d()
    offsets = view_offsets(grid, nv)
    # Voronoi circumradius: pitch / sqrt(3) on a hex lattice, pitch / sqrt(2) on a square one
    reach = (0.6 if grid.lattice == "hex" else 0.72) * max(grid.pitch, grid.row_spacing) + 1.0
    inner_r = safe_radius(grid)
    window = int(round(grid.pitch)) + 2
    context = HEX_CONTEXT if resample == "hex" else 0       # lens rows sampled beyond a band's own ones
    bands = plan_bands(grid, max_pixels=1_500_000, margin=4, context=context)

    data = small_page_empty((nv, nv, ny, nx, nch), np.float32)
    weight = small_page_empty((nv, nv, ny, nx), np.float32)
    if samples_out is not None:
        n_rows = grid.shape[0]
        samples_out["data"] = np.zeros((nv, nv, n_rows, cols, nch), np.float32)
        samples_out["weight"] = np.zeros((nv, nv, n_rows, cols), np.float32)

    scratch = _Scratch()
    black = np.asarray(raw.black)
    level = np.asarray(raw.white)

    lock = threading.Lock()

    def tick(name: str, t0: float) -> float:
        t1 = time.thread_time()
        if timings is not None:
            with lock:
                timings[name] = timings.get(name, 0.0) + (t1 - t0)
        return t1

    def run_band(band) -> int:
        r0, r1 = band.r0, band.r1
        t = time.thread_time()
        if r1 <= r0:                     # lens rows entirely off the sensor
            data[:, :, band.i0:band.i1] = 0.0
            weight[:, :, band.i0:band.i1] = 0.0
            return 0
        shape = (r1 - r0, w)
        buf = scratch.get
        dark_b = None if dark_p is None else dark_p[0][r0:r1]
        x = normalise(raw.mosaic[r0:r1], black, level, dark=dark_b, out=buf("x", shape, np.float32))
        t = tick("levels", t)
        wn = None
        if white_p is not None:
            arr, wb, ww = white_p
            if arr.dtype.kind == "f":
                wn = arr[r0:r1].astype(np.float32)
            else:
                wn = normalise(arr[r0:r1], wb, ww, dark=dark_b, out=buf("white", shape, np.float32))
            if hot_pixels:
                wn, _ = repair_hot_pixels(wn, out=buf("white_fixed", shape, np.float32),
                                          flags=buf("hot", shape, np.bool_))
        t = tick("white", t)
        n_hot = 0
        if hot_pixels:
            x, n_hot = repair_hot_pixels(x, out=buf("x_fixed", shape, np.float32), flags=buf("hot", shape, np.bool_),
                                         isolated=isolated, white=wn)
        t = tick("hot pixels", t)
        ext = centres[band.e0:band.e1] - np.array([r0, 0.0])
        labels, dist = lens_labels(ext, shape, reach, out=(buf("labels", shape, np.int32),
                                                           buf("dist", shape, np.float32)))
        t = tick("labels", t)
        rel = buf("rel", shape, np.float32)
        if wn is not None:
            relative_white(wn, cfa, window=window, out=rel)
            x = _dv.devignette(x, wn, rel, floor=floor, out=buf("ratio", shape, np.float32))
        else:
            np.subtract(np.float32(grid.radius + 0.5), dist, out=rel)
            np.clip(rel, 0.0, 1.0, out=rel)
            x[rel < floor] = np.nan
        t = tick("white", t)
        interior = buf("interior", shape, np.bool_)
        np.less(dist, np.float32(inner_r - 3.0), out=interior)     # 5x5 window inside the own cell
        interior[:2], interior[-2:], interior[:, :2], interior[:, -2:] = False, False, False, False
        img = _demosaic(x, cfa, method=demosaic, labels=labels, interior=interior,
                        out=buf("rgb", (*shape, nch), np.float32))
        t = tick("demosaic", t)
        usable = None                   # sample_lenses: every channel of a pixel with a value
        if extrapolate:
            measured = np.isfinite(x, out=buf("measured", shape, np.bool_))
            usable = usable_pixels(labels, measured, cfa, out=buf("usable", shape, np.uint8))
        s0, s1 = max(0, band.i0 - context), min(grid.shape[0], band.i1 + context)
        own = centres[s0:s1] - np.array([r0, 0.0])
        nr = s1 - s0
        samples, sw = sample_lenses(img, rel, labels, own, offsets, first_label=(s0 - band.e0) * cols,
                                    label_cols=cols, matrix=matrix, safe_radius=inner_r, usable=usable,
                                    view_edges=view_edges,
                                    out=(buf("samples", (nv, nv, nr, cols, nch), np.float32),
                                         buf("sample_w", (nv, nv, nr, cols), np.float32)))
        t = tick("slice", t)
        if samples_out is not None:
            samples_out["data"][:, :, band.i0:band.i1] = samples[:, :, band.i0 - s0:band.i1 - s0]
            samples_out["weight"][:, :, band.i0:band.i1] = sw[:, :, band.i0 - s0:band.i1 - s0]
        hex_to_rect(samples, sw, grid, first_row=s0, method=resample, context=(band.i0 - s0, s1 - band.i1),
                    out=data[:, :, band.i0:band.i1], out_weight=weight[:, :, band.i0:band.i1])
        tick("hex->rect", t)
        return n_hot

    # bands write disjoint output rows; the numba kernels and OpenCV release the GIL
    n_workers = min(workers or os.cpu_count() or 1, len(bands))
    n_hot = 0
    if n_workers == 1:
        for k, b in enumerate(bands):
            n_hot += run_band(b)
            if progress is not None:
                progress(k + 1, len(bands))
    else:
        with ThreadPoolExecutor(max_workers=n_workers) as pool:
            futures = [pool.submit(run_band, b) for b in bands]
            for k, fut in enumerate(as_completed(futures)):
                n_hot += fut.result()
                if progress is not None:
                    progress(k + 1, len(bands))
    if n_hot:
        log.info("repaired %d hot pixels", n_hot)
    if timings is not None:
        timings["total cpu"] = timings.get("total cpu", 0.0) + time.process_time() - t_cpu
        timings["wall"] = timings.get("wall", 0.0) + time.perf_counter() - t_wall

    calibration = geometry
    s = grid.decoded_sampling()
    geometry = decoded_geometry(raw, grid)
    provenance = {
        "decoded_sampling": {k: float(v) for k, v in s.items()},
        "n_views": nv,
        "lattice": grid.lattice,
        "colour_matrix": None if matrix is None else np.asarray(matrix).tolist(),
        "demosaic": demosaic if nch == 3 else None,
        "resample": resample,
        "view_edges": view_edges,
        "devignetted": white_p is not None,
        "dark_subtracted": dark_p is not None,
        "hot_pixels_repaired": int(n_hot),
    }
    lf = LightField(data=data, weight=weight, colour=colour_state, metadata=provenance, geometry=geometry)
    return lf if calibration is None else rectify(lf, calibration)


__all__ = ["decode", "decode_timed", "decode_samples", "LensSamples", "lens_positions", "DEMOSAIC_METHODS",
           "RESAMPLE_METHODS", "DEFAULT_DEMOSAIC"]
