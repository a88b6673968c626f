"""The geometric-calibration step of the workflow: checkerboard captures on disk -> GeometryRun.

``plenodecode calibrate-geometry DIR`` and Python callers with paths go through
:func:`calibrate_geometry_files`: the captures in the folder (raws, as :func:`plenodecode.io.discovery.find_raws`
finds them, and saved light fields) are opened (:func:`~plenodecode.pipeline.open_input`); the raws are all
decoded with **one** lenslet calibration, chosen once for the first raw by
:func:`~plenodecode.pipeline.choose_calibration` (``--calibration``, ``--white``, ``--database`` as every
command), without rectification; then :func:`plenodecode.calib.geometry.captures.run_geometric_calibration`
detects, initialises and refines.  :func:`write_geometry_outputs` writes the calibration JSON (this
project's, or the toolbox's ``CalInfo.json`` layout) and the HTML report.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Sequence

from ..types import LightField
from .calibration import Calibration, choose_calibration
from .inputs import Progress, open_input
from .source import decode_raw

if TYPE_CHECKING:
    from ..calib.geometry.captures import GeometryRun
    from ..io.mosaic_levels import MosaicOptions



def geometry_captures(inputs: Sequence[str | os.PathLike]) -> list[Path]:
    """The capture files of a calibration set: folders are searched for raws
    (:func:`plenodecode.io.discovery.find_raws`, white images and ground truth left out) and saved light
    fields (top level, sorted); files are taken as given."""
    from ..io.discovery import find_raws
    from .inputs import LIGHTFIELD_EXTENSIONS

    found: list[Path] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found += find_raws([p])
            found += sorted(f for f in p.iterdir() if f.suffix.lower() in LIGHTFIELD_EXTENSIONS)
        else:
            found.append(p)
    return found


def _lightfields(paths: Sequence[Path], calibration_options: dict[str, Any], mosaic: MosaicOptions | None,
                 progress: Progress) -> Iterator[Any]:
    """Each capture as a light field, decoded on demand (one in memory at a time); the raws share the
    calibration chosen for the first and come with their lens samples, which the corners are fitted on
    (``(LightField, LensSamples)``, :func:`plenodecode.decoding.decode_samples`).  A file that cannot be read comes
    as its FormatError / MetadataError, which :func:`run_geometric_calibration` reports and skips."""
    from ..calib.geometry.captures import CAPTURE_DECODE
    from ..decoding import decode_samples
    from ..io.raytrix import is_rgb_export

    from ..errors import FormatError, MetadataError

    chosen: Calibration | None = None
    for n, path in enumerate(paths):
        try:
            item = open_input(path, mosaic=mosaic)
        except (FormatError, MetadataError) as exc:     # a damaged file among the captures: reported and skipped
            item = exc
        if isinstance(item, Exception):
            yield item
        elif isinstance(item, LightField):
            yield item
        else:
            if chosen is None:
                chosen = choose_calibration(item, mosaic=mosaic, **calibration_options)   # logs its choice
            if is_rgb_export(item):       # decoded plane by plane: no lens samples of its own
                yield decode_raw(item, chosen, **CAPTURE_DECODE)
            else:
                yield decode_samples(item, chosen.grid, white=chosen.white, **CAPTURE_DECODE)
        if progress is not None:
            progress(n + 1, len(paths))


def calibrate_geometry_files(inputs: Sequence[str | os.PathLike], board: Any, *,
                             grid: str | os.PathLike | None = None, white: str | os.PathLike | None = None,
                             database: str | os.PathLike | None = None, self_calibrate: bool = False,
                             mosaic: MosaicOptions | None = None, distortion: bool = True,
                             progress: Progress = None) -> GeometryRun:
    """Calibrate from the checkerboard captures in ``inputs`` (folders or files).

    Parameters
    ----------
    inputs : sequence of path-like
        Folders (searched by :func:`geometry_captures`) or capture files (raws or saved light fields).
    board : Board, (rows, cols, square_m) or 'ROWSxCOLSxSQUARE_M'
    grid, white, database, self_calibrate, mosaic
        How the raws are decoded (:func:`~plenodecode.pipeline.choose_calibration`), the same for all.
    distortion : bool
        Estimate the distortion.
    progress : callable(done, total), optional
        After each capture is opened and searched.

    Returns
    -------
    GeometryRun
        The calibration (``info['captures']`` are the file names) with detections and residuals.
    """
    from ..calib.geometry.captures import run_geometric_calibration
    from ..errors import CalibrationError

    paths = geometry_captures(inputs)
    if not paths:
        raise CalibrationError(f"no raws or light fields found in {', '.join(str(p) for p in inputs)}")
    options = {"grid": grid, "white": white, "database": database, "self_calibrate": self_calibrate}
    return run_geometric_calibration(_lightfields(paths, options, mosaic, progress), board,
                                     names=[p.name for p in paths], distortion=distortion)


def write_geometry_outputs(run: GeometryRun, output: str | os.PathLike, *, report: str | os.PathLike | None = None,
                           toolbox: bool = False, overwrite: bool = False) -> list[Path]:
    """Write the calibration (:func:`plenodecode.io.calinfo.save_geometric_calibration`; ``toolbox``: the
    Light Field Toolbox's ``CalInfo.json`` layout) and, if asked, the HTML report
    (:func:`plenodecode.report.geometry.write_geometry_report`).  Returns the paths written."""
    from ..io.calinfo import save_geometric_calibration

    written = [save_geometric_calibration(run.calibration, output, toolbox=toolbox, overwrite=overwrite)]
    if report is not None:
        from ..report.geometry import write_geometry_report

        written.append(write_geometry_report(run, report, overwrite=overwrite))
    return written
