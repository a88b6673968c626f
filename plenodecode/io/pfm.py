"""Portable Float Map (PFM) reading and writing, as the HCI benchmark toolkit uses it.

Format: ``"Pf"`` (1 channel) or ``"PF"`` (3 channels), newline, ``"W H"``, newline, a scale
whose sign gives the byte order (negative = little-endian), newline, then float32 rows
stored **bottom-up**.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import FormatError
from .atomic import write_bytes_atomic


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a PFM file (OpenCV's PFM decoder; the header is checked first for a clear error).

    OpenCV undoes the bottom-up row order and the byte order, and divides the samples by the magnitude
    of the scale field (1 in the files the HCI toolkit and :func:`write_pfm` write).

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3), float32
        Rows top-down; colour in RGB order.
    """
    import cv2

    p = Path(path)
    try:
        with open(p, "rb") as fh:
            kind = fh.readline().strip()
            dims = fh.readline().split()
            float(fh.readline().strip())
            payload = len(fh.read())
        channels = {b"Pf": 1, b"PF": 3}[kind]
        width, height = int(dims[0]), int(dims[1])
    except (KeyError, ValueError, IndexError, OSError) as exc:
        raise FormatError(f"{p}: not a PFM file ({exc.__class__.__name__}: {exc})") from exc
    if not (0 < width <= 1 << 16 and 0 < height <= 1 << 16):
        raise FormatError(f"{p}: PFM declares an impossible size {width}x{height}")
    if payload < 4 * width * height * channels:
        raise FormatError(f"{p}: PFM payload has {payload} bytes, {4 * width * height * channels} expected for "
                          f"{width}x{height}x{channels}")
    img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FormatError(f"{p}: OpenCV could not decode this PFM file")
    if channels == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return np.ascontiguousarray(img, np.float32)


def write_pfm(path: str | os.PathLike, image: np.ndarray, *, overwrite: bool = False) -> Path:
    """Write a (H, W) or (H, W, 3) array as little-endian PFM (rows bottom-up), atomically.

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = Path(path)
    img = np.asarray(image, np.float32)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise ValueError(f"image must have shape (H, W) or (H, W, 3), got {img.shape}")
    kind = b"Pf" if img.ndim == 2 else b"PF"
    header = kind + b"\n" + f"{img.shape[1]} {img.shape[0]}\n-1.0\n".encode()
    return write_bytes_atomic(p, [header, np.ascontiguousarray(img[::-1], "<f4").tobytes()], overwrite=overwrite)
