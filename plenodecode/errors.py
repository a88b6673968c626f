"""Exception tree of plenodecode.

Every error the library raises on bad data derives from :class:`PlenodecodeError`;
messages say what was expected, what was found and what to do.  Bad arguments
raise :class:`ValueError` naming the parameter.
"""

from __future__ import annotations

import logging
from typing import Any

#: How the command line shows a log line on stderr, in the command and in its batch workers: ``warning: ...`` as
#: its ``note: ...`` and ``error: ...`` lines (:func:`log_format`); with ``-v`` / ``-vv`` also the module that logs.
LOG_FORMAT = "%(levelname)s %(name)s: %(message)s"


class _LowerLevelName(logging.Formatter):
    """:data:`LOG_FORMAT`'s record with its level name in lower case ('warning'), as the command's own lines."""

    def format(self, record: logging.LogRecord) -> str:
        level = record.levelname            # other handlers of the record keep their own form
        record.levelname = level.lower()
        try:
            return super().format(record)
        finally:
            record.levelname = level


def configure_logging(level: int, *, stream: Any = None, force: bool = False) -> None:
    """Log at ``level`` to ``stream`` (stderr) in the command line's form: ``'warning: IMG_1.jpg: ...'``, and
    below WARNING (``-v``, ``-vv``) ``'info plenodecode.depth.pipeline: ...'`` (the module is what a developer
    reading a verbose log wants; a user meeting a warning does not)."""
    handler = logging.StreamHandler(stream)
    handler.setFormatter(_LowerLevelName("%(levelname)s: %(message)s" if level >= logging.WARNING else LOG_FORMAT))
    logging.basicConfig(level=level, handlers=[handler], force=force)


class PlenodecodeError(Exception):
    """Base class of every data error raised by plenodecode."""


class FormatError(PlenodecodeError):
    """A file is not in the format it claims to be (magic, lengths, sizes, checksums)."""


class MetadataError(PlenodecodeError):
    """Metadata is missing, unparsable, or inconsistent with the data."""


class CalibrationError(PlenodecodeError):
    """No usable lenslet grid: bad white image, wrong camera, failed fit."""


class GeometryMismatchError(CalibrationError):
    """A geometric calibration (``--geometry``) made for light fields of another shape."""


class MissingConstantsError(MetadataError):
    """A product asks of an input a camera constant its metadata lacks: alpha (Ng's film depth -> slope), a
    focus distance in metres, metric depth (:func:`plenodecode.pipeline.needs.check_product`).

    Attributes
    ----------
    keyword : str
        The option that asked: 'alpha' (a refocus), 'units' (a focal stack in alpha units), 'focus_distance' (a
        refocus at a distance), 'metric' or 'points' (metric depth).
    missing : tuple of str
        The constants not found (names of :data:`plenodecode.render.alpha.REFOCUS_CONSTANTS`, or
        'focus_distance_m'); empty when the message names the options that supply them.
    source : str
        The input, as the message names it.
    need : str
        What needs the constants, as a phrase ("alpha (Ng's film depth -> slope)", "metric depth", ...).
    reason : str
        Why, as the message says it without the input's name and without ``instead`` (default: the message).
    instead : str or None
        The request that serves instead, in the library's words and as the message ends ('refocus by slope
        instead'), which the command line says in its options ('use --slope S ... instead'); None when there is
        none, or the message says what to do itself.
    """

    def __init__(self, message: str, *, keyword: str, missing: tuple[str, ...], source: str, need: str,
                 reason: str | None = None, instead: str | None = None) -> None:
        super().__init__(message)
        self.keyword, self.missing, self.source, self.need = keyword, tuple(missing), source, need
        self.reason, self.instead = message if reason is None else reason, instead


class DecodeError(PlenodecodeError):
    """A raw cannot be decoded with the given grid or options."""


class DarkFrameMismatchError(DecodeError, ValueError):
    """A dark frame (``--dark``) of another size than the raw, or one that would leave it black (a white or scene
    frame), found before any work; a ValueError too, as ``decode(dark=...)`` is a bad argument then."""


class LevelOptionError(MetadataError):
    """A typed ``--black-level`` / ``--white-level`` (``option``) the mosaic's samples cannot have, found as soon as
    the file is read: the CLI makes it a usage error naming the option."""

    def __init__(self, message: str, option: str) -> None:
        super().__init__(message)
        self.option = option


def one_line(exc: BaseException) -> str:
    """One line for a table or log that gives a failure one line (a batch's rows): the message of the library's
    errors (:class:`PlenodecodeError`, which say what to do), as ``plenodecode RAW`` prints them after ``error:``;
    ``'TypeName: message'`` of any other exception (a bug, a worker lost), where the type is the clue.  (An
    ``OSError`` reads as the command line says it, :func:`plenodecode.io.atomic.os_error_text`, which knows the
    temporary names.)"""
    text = str(exc).strip() if isinstance(exc, PlenodecodeError) else f"{type(exc).__name__}: {exc}".strip()
    return text.splitlines()[0] if text else type(exc).__name__


__all__ = ["LOG_FORMAT", "configure_logging", "PlenodecodeError", "FormatError", "MetadataError", "CalibrationError",
           "GeometryMismatchError", "MissingConstantsError", "DecodeError", "DarkFrameMismatchError",
           "LevelOptionError", "one_line"]
