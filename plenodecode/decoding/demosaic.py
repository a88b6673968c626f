"""Demosaicing restricted to each micro-image.

Every method takes a (normalised, devignetted) Bayer mosaic in which missing pixels are NaN, and an
optional label image (:func:`plenodecode.decoding.slice.lens_labels`).  A pixel is interpolated only
from pixels with the *same* label, so light never mixes across lenslet borders (the artefact
formats.md section 4.2 lists for LFToolbox, which demosaics the whole lenslet image).  Missing
neighbours are left out and the kernel renormalised over the rest: normalised convolution
(Knutsson & Westin, "Normalized and differential convolution", CVPR 1993) with a binary certainty.

Methods (``DEMOSAIC_METHODS``):

``'bilinear'``
    Bilinear interpolation of each channel from its own sites in the 3x3 neighbourhood
    (kernel ``[1 2 1; 2 4 2; 1 2 1] / 4`` restricted to the channel's sites).
``'malvar'``
    Gradient-corrected bilinear interpolation, Malvar, He & Cutler, "High-quality linear
    interpolation for demosaicing of Bayer-patterned color images", ICASSP 2004: the bilinear
    estimate plus a gain times the Laplacian of the channel present at the pixel (gains
    ``alpha = 1/2`` for G at R/B, ``beta = 5/8`` for R/B at G, ``gamma = 3/4`` for R at B and B at R,
    equations (1)-(3) and Fig. 2 of the paper).  The correction is applied only where its whole
    5x5 stencil lies in the same micro-image and has values; elsewhere the pixel stays bilinear.
    It is edge-aware in the sense of the paper: the cross-channel gradient keeps edges sharp.

A monochrome mosaic (``cfa=None``) gives one channel, with missing pixels filled from their
same-label neighbours.

The numba kernels are in :mod:`.demosaic_kernels`, imported on the first call, so that this module and its
registry stay light (the CLI lists the method names for its help).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..registry import lookup
from ..types import cfa_channel_map


def _prepare(mosaic: np.ndarray, labels: np.ndarray | None,
             interior: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if mosaic.ndim != 2:
        raise ValueError(f"mosaic must be 2-D, got shape {mosaic.shape}")
    x = np.ascontiguousarray(mosaic, np.float32)
    if labels is None:
        labels = np.zeros(x.shape, np.int32)
    elif labels.shape != x.shape:
        raise ValueError(f"labels must have the mosaic's shape {x.shape}, got {labels.shape}")
    if interior is None:
        interior = np.zeros(x.shape, np.bool_)
    elif interior.shape != x.shape or interior.dtype != np.bool_:
        raise ValueError(f"interior must be a bool array of shape {x.shape}")
    return x, np.ascontiguousarray(labels, np.int32), np.ascontiguousarray(interior)


def demosaic_bilinear(mosaic: np.ndarray, cfa: str | None, *, labels: np.ndarray | None = None,
                      out: np.ndarray | None = None, interior: np.ndarray | None = None) -> np.ndarray:
    """Bilinear demosaicing by normalised convolution within each label (see module docstring).

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), float32
        Bayer mosaic whose first row/column has the phase of ``cfa``; NaN = missing.
    cfa : str or None
    labels : ndarray, shape (H, W), int32, optional
        Micro-image label per pixel (-1 = none); None = one region.
    out : ndarray, shape (H, W, C), float32, optional
        Destination.
    interior : ndarray, shape (H, W), bool, optional
        Speed hint: pixels whose whole 5x5 window is inside the image and in their own micro-image
        (no label checks needed there).

    Returns
    -------
    ndarray, shape (H, W, 3) (or (H, W, 1) for monochrome), float32; NaN where nothing is known.
    """
    return _run(mosaic, cfa, labels, malvar=False, out=out, interior=interior)


def _run(mosaic: np.ndarray, cfa: str | None, labels: np.ndarray | None, *, malvar: bool,
         out: np.ndarray | None, interior: np.ndarray | None) -> np.ndarray:
    from .demosaic_kernels import MALVAR_DX, MALVAR_DY, WINDOW_INVERSE_SQUARED, bilinear_kernel

    x, labels, interior = _prepare(mosaic, labels, interior)
    nch = 1 if cfa is None else 3
    if out is None:
        out = np.empty((*x.shape, nch), np.float32)
    elif out.shape != (*x.shape, nch) or out.dtype != np.float32:
        raise ValueError(f"out must be float32 of shape {(*x.shape, nch)}, got {out.dtype} {out.shape}")
    bilinear_kernel(x, labels, interior, cfa_channel_map(cfa), nch, bool(malvar and nch == 3), MALVAR_DY, MALVAR_DX,
                    WINDOW_INVERSE_SQUARED, out)
    return out


def demosaic_malvar(mosaic: np.ndarray, cfa: str | None, *, labels: np.ndarray | None = None,
                    out: np.ndarray | None = None, interior: np.ndarray | None = None) -> np.ndarray:
    """Malvar-He-Cutler (ICASSP 2004) gradient-corrected demosaicing within each label.

    Parameters and returns as :func:`demosaic_bilinear`.
    """
    return _run(mosaic, cfa, labels, malvar=True, out=out, interior=interior)


#: name -> function(mosaic, cfa, *, labels, out, interior) -> (H, W, C) float32
DEMOSAIC_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "bilinear": demosaic_bilinear,
    "malvar": demosaic_malvar,
}


def demosaic(mosaic: np.ndarray, cfa: str | None, *, method: str = "malvar", labels: np.ndarray | None = None,
             out: np.ndarray | None = None, interior: np.ndarray | None = None) -> np.ndarray:
    """Demosaic a Bayer mosaic with a method of :data:`DEMOSAIC_METHODS`.

    Parameters
    ----------
    mosaic : ndarray, shape (H, W), float
        Mosaic (NaN = missing pixel).
    cfa : str or None
        Bayer pattern of the mosaic's upper-left 2x2 tile; None for monochrome.
    method : str
        Key of :data:`DEMOSAIC_METHODS`.
    labels : ndarray, shape (H, W), int32, optional
        Interpolate only within pixels of equal label (micro-images); -1 = outside every lens.
    out : ndarray, shape (H, W, C), float32, optional
        Destination.
    interior : ndarray, shape (H, W), bool, optional
        Pixels whose 5x5 window is known to lie in their own micro-image (a speed hint).

    Returns
    -------
    ndarray, shape (H, W, C), float32, C = 3 (1 for monochrome)
    """
    fn = lookup(DEMOSAIC_METHODS, method, param="demosaic method")
    return fn(mosaic, cfa, labels=labels, out=out, interior=interior)


__all__ = ["DEMOSAIC_METHODS", "demosaic", "demosaic_bilinear", "demosaic_malvar"]
