"""Camera RGB -> linear sRGB.

The camera pipeline of Lytro metadata (formats.md sections 2-4, LFToolbox ``LFColourCorrect``)::

    srgb_linear = CCM @ diag(gains) @ camera_rgb

with ``gains = (r, (gr + gb) / 2, b)`` from ``CameraMetadata.wb_gains`` and ``CCM`` the camera's
``ccm`` (rows sum to 1, so a white-balanced neutral stays neutral).  No clipping and no display
encoding: the result stays linear and may exceed 1 in highlights; encoding is export's job.
The matrix is applied as one float32 matrix product over all pixels (:func:`apply_matrix`).
"""

from __future__ import annotations

import logging
from typing import Mapping

import numpy as np

from ..types import CameraMetadata, LightField

log = logging.getLogger(__name__)

#: colour states :func:`plenodecode.decoding.decode` can produce
DECODE_COLOURS = ("linear-srgb", "camera")


#: Pixels per slab of :func:`apply_matrix` (768 kB of float32 RGB: stays in cache).
_MATRIX_ROWS = 1 << 16


def white_balance_gains(metadata: CameraMetadata) -> np.ndarray | None:
    """White-balance gains ``(r, g, b)``; ``g = mean(gr, gb)`` when both greens are given.

    Returns
    -------
    ndarray, shape (3,), float64, or None when the metadata has none.
    """
    g: Mapping[str, float] | None = metadata.wb_gains
    if not g:
        return None
    try:
        if "g" in g:
            green = float(g["g"])
        else:
            greens = [float(g[k]) for k in ("gr", "gb") if k in g]
            green = float(np.mean(greens)) if greens else 1.0
        gains = np.array([float(g["r"]), green, float(g["b"])])
    except (KeyError, TypeError, ValueError):
        return None
    if not np.all(np.isfinite(gains)) or np.any(gains <= 0):
        return None
    return gains


def colour_matrix(metadata: CameraMetadata) -> np.ndarray | None:
    """The 3x3 matrix ``CCM @ diag(gains)`` taking camera RGB to linear sRGB.

    Missing gains count as 1 (LFToolbox does the same for Illum); a missing or malformed CCM gives None.

    Returns
    -------
    ndarray, shape (3, 3), float64, or None
    """
    if metadata.ccm is None:
        return None
    ccm = np.asarray(metadata.ccm, np.float64)
    if ccm.shape != (3, 3) or not np.all(np.isfinite(ccm)):
        return None
    gains = white_balance_gains(metadata)
    if gains is None:
        log.info("no white-balance gains in the metadata; using 1, 1, 1")
        gains = np.ones(3)
    return ccm @ np.diag(gains)


def apply_matrix(data: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Apply a 3x3 matrix to the last axis of ``data``: ``out[..., i] = sum_j matrix[i, j] data[..., j]``.

    One float32 matrix product (``(N, 3) @ matrix.T``) over all pixels, in slabs of
    :data:`_MATRIX_ROWS` pixels (cache-sized; a float64 input is converted a slab at a time).

    Parameters
    ----------
    data : ndarray, shape (..., 3), float32 (other real dtypes are converted)
    matrix : ndarray, shape (3, 3)

    Returns
    -------
    ndarray, same shape, float32 (a new array)
    """
    if data.shape[-1] != 3:
        raise ValueError(f"data must have 3 channels in its last axis, got shape {data.shape}")
    m = np.asarray(matrix, np.float64)
    if m.shape != (3, 3):
        raise ValueError(f"matrix must have shape (3, 3), got {m.shape}")
    mt = np.ascontiguousarray(m.T, np.float32)
    out = np.empty(data.shape, np.float32)
    flat_out = out.reshape(-1, 3)
    flat_in = data.reshape(-1, 3)                  # a view when data is contiguous
    for r0 in range(0, flat_in.shape[0], _MATRIX_ROWS):
        r1 = min(r0 + _MATRIX_ROWS, flat_in.shape[0])
        np.matmul(np.asarray(flat_in[r0:r1], np.float32), mt, out=flat_out[r0:r1])
    return out


def to_linear_srgb(lf: LightField, metadata: CameraMetadata | None = None) -> LightField:
    """Convert a camera-RGB light field to linear sRGB.

    Parameters
    ----------
    lf : LightField
        ``colour == 'camera'``, C = 3.
    metadata : CameraMetadata, optional
        Source of gains and CCM; default: ``lf.geometry.camera``.

    Returns
    -------
    LightField with ``colour == 'linear-srgb'``.
    """
    from ..errors import MetadataError

    if lf.colour != "camera":
        raise ValueError(f"lf must be in camera colour, got {lf.colour!r}")
    if lf.data.shape[-1] != 3:
        raise ValueError("lf must have 3 channels")
    if metadata is None:
        metadata = lf.geometry.camera or CameraMetadata()
    m = colour_matrix(metadata)
    if m is None:
        raise MetadataError("expected a colour matrix (ccm) in the camera metadata, found none; "
                            "keep the light field in camera colour or pass metadata with a ccm")
    provenance = {**lf.provenance, "colour_matrix": m.tolist()}
    return lf.replace(data=apply_matrix(lf.data, m), colour="linear-srgb", metadata=provenance, geometry=lf.geometry)


__all__ = ["DECODE_COLOURS", "white_balance_gains", "colour_matrix", "apply_matrix",
           "to_linear_srgb"]
