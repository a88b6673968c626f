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
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numba import njit

from ..types import cfa_channel_map


#: LLVM fast-math flags without 'nnan'/'ninf': NaN marks missing pixels and must stay testable
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


#: inverse squared distance of every tap of the 5x5 window (centre unused)
_WINV = np.array([[1.0 / (dy * dy + dx * dx) if (dy or dx) else 0.0 for dx in range(-2, 3)]
                  for dy in range(-2, 3)], np.float32)


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy", inline="always")
def _search(x, labels, cmap, lab, y, xx, h, w, k, winv):  # pragma: no cover - numba
    """Channel ``k`` at (y, xx) from its same-label sites in the 5x5 window (inverse squared distance)."""
    acc = np.float32(0.0)
    wacc = np.float32(0.0)
    for dy in range(-2, 3):
        yy = y + dy
        if yy < 0 or yy >= h:
            continue
        ry = yy & 1
        for dx in range(-2, 3):
            xq = xx + dx
            if cmap[ry, xq & 1] != k or xq < 0 or xq >= w or (dy == 0 and dx == 0):
                continue
            if labels[yy, xq] != lab:
                continue
            val = x[yy, xq]
            if val != val:
                continue
            wgt = winv[dy + 2, dx + 2]
            acc += wgt * val
            wacc += wgt
    return acc / wacc if wacc > 0.0 else np.float32(np.nan)


#: the 8 taps of Malvar's 5x5 stencils around a pixel: 4 diagonals, 2 along the row, 2 along the column
_MDY = np.array([-1, -1, 1, 1, 0, 0, -2, 2], np.int64)
_MDX = np.array([-1, 1, -1, 1, -2, 2, 0, 0], np.int64)


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def _bilinear(x, labels, interior, cmap, nch, malvar, mdy, mdx, winv, out):  # pragma: no cover - numba
    # In a Bayer 3x3 window every site of a given colour other than the centre is at the same
    # distance (cross or diagonal), so the bilinear kernel restricted to one colour is a plain mean.
    # Fast path: away from the border, when every tap of the stencil has this pixel's label and a
    # value, the means and Malvar's corrections are written out per Bayer phase; otherwise (or if
    # a tap is NaN, which the result then shows) the general per-tap path below runs.
    h, w = x.shape
    nan = np.float32(np.nan)
    q = np.float32(0.25)
    half = np.float32(0.5)
    for y in range(h):
        inner_row = y >= 2 and y < h - 2
        for xx in range(w):
            lab = labels[y, xx]
            if lab < 0:
                for k in range(nch):
                    out[y, xx, k] = nan
                continue
            if nch == 3 and inner_row and xx >= 2 and xx < w - 2:
                same = interior[y, xx]
                if not same:
                    same = (labels[y - 1, xx - 1] == lab and labels[y - 1, xx] == lab and labels[y - 1, xx + 1] == lab
                            and labels[y, xx - 1] == lab and labels[y, xx + 1] == lab
                            and labels[y + 1, xx - 1] == lab and labels[y + 1, xx] == lab
                            and labels[y + 1, xx + 1] == lab)
                    if same and malvar:
                        same = (labels[y - 2, xx] == lab and labels[y + 2, xx] == lab
                                and labels[y, xx - 2] == lab and labels[y, xx + 2] == lab)
                if same:
                    v0 = x[y, xx]
                    vn = x[y - 1, xx]
                    vs = x[y + 1, xx]
                    vw = x[y, xx - 1]
                    ve = x[y, xx + 1]
                    diag = x[y - 1, xx - 1] + x[y - 1, xx + 1] + x[y + 1, xx - 1] + x[y + 1, xx + 1]
                    own = cmap[y & 1, xx & 1]
                    if own == 1:
                        g = v0
                        hm = half * (vw + ve)
                        vm = half * (vn + vs)
                        if malvar:
                            row2 = x[y, xx - 2] + x[y, xx + 2]
                            col2 = x[y - 2, xx] + x[y + 2, xx]
                            # G site: beta * (G - (diag + along2 - across2 / 2) / 5), eq. (2)
                            hm += np.float32(0.625) * (v0 - (diag + row2 - half * col2) * np.float32(0.2))
                            vm += np.float32(0.625) * (v0 - (diag + col2 - half * row2) * np.float32(0.2))
                        if cmap[y & 1, (xx + 1) & 1] == 0:
                            r = hm
                            b = vm
                        else:
                            b = hm
                            r = vm
                    else:
                        g = q * (vn + vs + vw + ve)
                        other = q * diag
                        if malvar:
                            d = v0 - q * (x[y, xx - 2] + x[y, xx + 2] + x[y - 2, xx] + x[y + 2, xx])
                            g += half * d                        # alpha, eq. (1)
                            other += np.float32(0.75) * d        # gamma, eq. (3)
                        if own == 0:
                            r = v0
                            b = other
                        else:
                            b = v0
                            r = other
                    tot = r + g + b
                    if tot == tot:
                        out[y, xx, 0] = r
                        out[y, xx, 1] = g
                        out[y, xx, 2] = b
                        continue
            _general(x, labels, interior, cmap, nch, malvar, mdy, mdx, winv, out, y, xx, lab)


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy", inline="always")
def _general(x, labels, interior, cmap, nch, malvar, mdy, mdx, winv, out, y, xx, lab):  # pragma: no cover - numba
    """One pixel by the general path: every tap checked for its label and its value."""
    h, w = x.shape
    nan = np.float32(np.nan)
    zero = np.float32(0.0)
    s0 = zero
    s1 = zero
    s2 = zero
    n0 = zero
    n1 = zero
    n2 = zero
    chk = not interior[y, xx]       # interior pixels: whole 5x5 window in this micro-image
    for t in range(9):
        if t == 4:
            continue
        yy = y + t // 3 - 1
        xq = xx + t % 3 - 1
        if chk and (yy < 0 or yy >= h or xq < 0 or xq >= w or labels[yy, xq] != lab):
            continue
        v = x[yy, xq]
        if v != v:
            continue
        k = cmap[yy & 1, xq & 1]
        if k == 0:
            s0 += v
            n0 += 1.0
        elif k == 1:
            s1 += v
            n1 += 1.0
        else:
            s2 += v
            n2 += 1.0
    v0 = x[y, xx]
    own = cmap[y & 1, xx & 1]
    if nch == 1:
        out[y, xx, 0] = v0 if v0 == v0 else (s0 / n0 if n0 > 0 else nan)
        return
    r = s0 / n0 if n0 > 0 else nan
    g = s1 / n1 if n1 > 0 else nan
    b = s2 / n2 if n2 > 0 else nan
    if v0 == v0:
        if own == 0:
            r = v0
        elif own == 1:
            g = v0
        else:
            b = v0
    # channels still unknown: wider search, unless nothing at all is known in the 3x3
    # window (a pixel of the dark gap between lenses stays unknown, which saves the search
    # where it cannot help); a pixel ends all-known or all-NaN
    if v0 != v0 and n0 == 0 and n1 == 0 and n2 == 0:
        r = nan
    elif r != r:
        r = _search(x, labels, cmap, lab, y, xx, h, w, 0, winv)
    if r == r and g != g:
        g = _search(x, labels, cmap, lab, y, xx, h, w, 1, winv)
    if r == r and g == g and b != b:
        b = _search(x, labels, cmap, lab, y, xx, h, w, 2, winv)
    if r != r or g != g or b != b:
        r = nan
        g = nan
        b = nan
    elif malvar and v0 == v0:
        # Malvar-He-Cutler gradient correction, only with the whole stencil in this micro-image
        diag = zero
        row2 = zero
        col2 = zero
        ok = True
        for t in range(8):
            if own != 1 and t < 4:
                continue
            yy = y + mdy[t]
            xq = xx + mdx[t]
            if chk and (yy < 0 or yy >= h or xq < 0 or xq >= w or labels[yy, xq] != lab):
                ok = False
                break
            v = x[yy, xq]
            if v != v:
                ok = False
                break
            if t < 4:
                diag += v
            elif t < 6:
                row2 += v
            else:
                col2 += v
        if ok:
            if own == 1:
                # G site: beta * (G - (diag + along2 - across2 / 2) / 5), eq. (2)
                dh = np.float32(0.625) * (v0 - (diag + row2 - np.float32(0.5) * col2) * np.float32(0.2))
                dv = np.float32(0.625) * (v0 - (diag + col2 - np.float32(0.5) * row2) * np.float32(0.2))
                if cmap[y & 1, (xx + 1) & 1] == 0:
                    r += dh
                    b += dv
                else:
                    b += dh
                    r += dv
            else:
                d = v0 - np.float32(0.25) * (row2 + col2)
                g += np.float32(0.5) * d           # alpha, eq. (1)
                if own == 0:
                    b += np.float32(0.75) * d      # gamma, eq. (3)
                else:
                    r += np.float32(0.75) * d
    out[y, xx, 0] = r
    out[y, xx, 1] = g
    out[y, xx, 2] = b


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
    x, labels, interior = _prepare(mosaic, labels, interior)
    nch = 1 if cfa is None else 3
    if out is None:
        out = np.empty((*x.shape, nch), np.float32)
    elif out.shape != (*x.shape, nch) or out.dtype != np.float32:
        raise ValueError(f"out must be float32 of shape {(*x.shape, nch)}, got {out.dtype} {out.shape}")
    _bilinear(x, labels, interior, cfa_channel_map(cfa), nch, bool(malvar and nch == 3), _MDY, _MDX, _WINV, out)
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
    fn = DEMOSAIC_METHODS.get(method)
    if fn is None:
        raise ValueError(f"demosaic method must be one of {sorted(DEMOSAIC_METHODS)}, got {method!r}")
    return fn(mosaic, cfa, labels=labels, out=out, interior=interior)


__all__ = ["DEMOSAIC_METHODS", "demosaic", "demosaic_bilinear", "demosaic_malvar"]
