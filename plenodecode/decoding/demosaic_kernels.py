"""The numba kernels of :mod:`plenodecode.decoding.demosaic` (imported on its first call).

The maths (normalised convolution within each micro-image; Malvar, He & Cutler, ICASSP 2004) is
described in :mod:`plenodecode.decoding.demosaic`; :func:`bilinear_kernel` runs it for every pixel.

It is one function with no compiled helpers: the general path and its wide search are written out in the
pixel loop, once each.  A helper compiled on its own, or inlined by numba's IR inlining, cost more compiling
(the general path as an ``inline='always'`` helper and the search as a called one: 2.2 CPU s on a cold decode;
written out: 1.4 CPU s) and the per-pixel calls cost run time (a full Illum demosaic: 1.2 -> 0.75 CPU s).
"""

from __future__ import annotations

import numpy as np

from .._numba import njit

#: LLVM fast-math flags without 'nnan'/'ninf': NaN marks missing pixels and must stay testable
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


#: inverse squared distance of every tap of the 5x5 window (centre unused)
WINDOW_INVERSE_SQUARED = np.array([[1.0 / (dy * dy + dx * dx) if (dy or dx) else 0.0 for dx in range(-2, 3)]
                  for dy in range(-2, 3)], np.float32)


#: the 8 taps of Malvar's 5x5 stencils around a pixel: 4 diagonals, 2 along the row, 2 along the column
MALVAR_DY = np.array([-1, -1, 1, 1, 0, 0, -2, 2], np.int64)
MALVAR_DX = np.array([-1, 1, -1, 1, -2, 2, 0, 0], np.int64)


@njit(cache=True, nogil=True, fastmath=FAST, error_model="numpy")
def bilinear_kernel(x, labels, interior, cmap, nch, malvar, mdy, mdx, winv, out):  # pragma: no cover - numba
    """Bilinear (optionally Malvar-corrected) demosaicing of every pixel, within its label; writes ``out``.

    Parameters
    ----------
    x : ndarray (H, W) float32
        Mosaic, NaN = missing.
    labels : ndarray (H, W) int32
        Micro-image label per pixel, -1 = none (the output is NaN there).
    interior : ndarray (H, W) bool
        Pixels whose whole 5x5 window is inside the image and in their own micro-image.
    cmap : ndarray (2, 2) int
        Channel of each Bayer phase (:func:`plenodecode.types.cfa_channel_map`).
    nch : int
        3, or 1 for monochrome.
    malvar : bool
        Add Malvar-He-Cutler's Laplacian corrections (ICASSP 2004, eqs. (1)-(3)).
    mdy, mdx : ndarray (8,) int64
        :data:`MALVAR_DY`, :data:`MALVAR_DX`.
    winv : ndarray (5, 5) float32
        :data:`WINDOW_INVERSE_SQUARED`.
    out : ndarray (H, W, nch) float32
        Destination.
    """
    # In a Bayer 3x3 window every site of a given colour other than the centre is at the same
    # distance (cross or diagonal), so the bilinear kernel restricted to one colour is a plain mean.
    # Fast path: away from the border, when the 3x3 window has this pixel's label and values, the
    # means (and Malvar's corrections where his whole stencil has them too) are written out per Bayer
    # phase; otherwise (or if a tap is NaN, which the result then shows) the general per-tap path runs.
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
                same = interior[y, xx]          # the 3x3 window in this micro-image
                ring = same                     # and the 4 taps 2 px away (Malvar's stencil)
                if not same:
                    same = (labels[y - 1, xx - 1] == lab and labels[y - 1, xx] == lab and labels[y - 1, xx + 1] == lab
                            and labels[y, xx - 1] == lab and labels[y, xx + 1] == lab
                            and labels[y + 1, xx - 1] == lab and labels[y + 1, xx] == lab
                            and labels[y + 1, xx + 1] == lab)
                    ring = (same and malvar and labels[y - 2, xx] == lab and labels[y + 2, xx] == lab
                            and labels[y, xx - 2] == lab and labels[y, xx + 2] == lab)
                if same:
                    v0 = x[y, xx]
                    vn = x[y - 1, xx]
                    vs = x[y + 1, xx]
                    vw = x[y, xx - 1]
                    ve = x[y, xx + 1]
                    diag = x[y - 1, xx - 1] + x[y - 1, xx + 1] + x[y + 1, xx - 1] + x[y + 1, xx + 1]
                    own = cmap[y & 1, xx & 1]
                    # Malvar's correction needs the whole stencil in this micro-image and known; without it
                    # the pixel stays bilinear, as on the general path
                    correct = False
                    row2 = np.float32(0.0)
                    col2 = np.float32(0.0)
                    if malvar and ring:
                        row2 = x[y, xx - 2] + x[y, xx + 2]
                        col2 = x[y - 2, xx] + x[y + 2, xx]
                        correct = row2 == row2 and col2 == col2
                    if own == 1:
                        g = v0
                        hm = half * (vw + ve)
                        vm = half * (vn + vs)
                        if correct:
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
                        if correct:
                            d = v0 - q * (row2 + col2)
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
            # general path: every tap checked for its label and its value
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
                continue
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
            # (the search written once, in a loop over the channels: each copy of it cost numba ~0.2 CPU s of compiling)
            if not (v0 != v0 and n0 == 0 and n1 == 0 and n2 == 0):
                for k in range(3):
                    known = r if k == 0 else (g if k == 1 else b)
                    if known == known:
                        continue
                    # channel k from its same-label sites in the 5x5 window, weighted by inverse squared distance
                    acc = zero
                    wacc = zero
                    for dy in range(-2, 3):
                        yy = y + dy
                        if yy < 0 or yy >= h:
                            continue
                        for dx in range(-2, 3):
                            xq = xx + dx
                            if cmap[yy & 1, xq & 1] != k or xq < 0 or xq >= w or (dy == 0 and dx == 0):
                                continue
                            if labels[yy, xq] != lab:
                                continue
                            val = x[yy, xq]
                            if val != val:
                                continue
                            wgt = winv[dy + 2, dx + 2]
                            acc += wgt * val
                            wacc += wgt
                    found = acc / wacc if wacc > zero else nan
                    if k == 0:
                        r = found
                    elif k == 1:
                        g = found
                    else:
                        b = found
                    if found != found:      # the channels after it stay unknown: the pixel ends all-NaN
                        break
            else:
                r = nan
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


__all__ = ["FAST", "WINDOW_INVERSE_SQUARED", "MALVAR_DY", "MALVAR_DX", "bilinear_kernel"]
