"""Exception tree of plenodecode.

Every error the library raises on bad data derives from :class:`PlenodecodeError`;
messages say what was expected, what was found and what to do.  Bad arguments
raise :class:`ValueError` naming the parameter.
"""

from __future__ import annotations


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


class RefocusConstantsError(MetadataError):
    """Ng's alpha was asked of an input whose metadata lacks the camera constants that turn it into a slope.

    Attributes
    ----------
    keyword : str
        The option that asked for alpha: 'alpha' (a refocus) or 'units' (a focal stack in alpha units).
    missing : tuple of str
        The constants not found (names of :data:`plenodecode.render.alpha.REFOCUS_CONSTANTS`).
    source : str
        The input, as the message names it.
    """

    def __init__(self, message: str, *, keyword: str, missing: tuple[str, ...], source: str) -> None:
        super().__init__(message)
        self.keyword, self.missing, self.source = keyword, tuple(missing), source


class DecodeError(PlenodecodeError):
    """A raw cannot be decoded with the given grid or options."""


__all__ = ["PlenodecodeError", "FormatError", "MetadataError", "CalibrationError", "GeometryMismatchError",
           "RefocusConstantsError", "DecodeError"]
