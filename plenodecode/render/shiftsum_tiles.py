"""Shift-and-add refocusing of many slopes per pass over the light field: the compiled, tiled kernel.

:func:`plenodecode.render.shiftsum.sum_shifted_views` hands focal stacks (``_TILED_MIN_SLOPES`` slopes or more)
to :func:`sum_shifted_views_tiled`; single photographs go through OpenCV and never compile this kernel.

``E_s(y, x) = sum_{v,u} m_vu w_vu(y', x') L_vu(y', x') / sum_{v,u} m_vu w_vu(y', x')`` with
``(y', x') = (y - s a, x - s b)``, ``a = v - vc``, ``b = u - uc`` (design.md; the discrete form of Ng's
photographic imaging equation), ``m`` the aperture mask and ``w`` the light field's weight (1 when it has none).

The shift of view ``(v, u)`` is separable and its y part depends only on ``v``, its x part only on ``u``::

    E_s = sum_u  Sx(s b_u) [ sum_v Sy(s a_v) L_vu ]

so each output tile is computed as

1. *y pass* (per view column ``u`` and slope ``s``): the 2 or 4 interpolation taps of every view row ``v``
   along y, summed over ``v`` into one buffer (the bulk of the work: ``S V U`` 1-D filters);
2. *x pass*: that buffer shifted along x by ``s b_u`` and added to the tile's accumulator (``S U`` filters).

Work is split in output tiles (``_ROWS`` rows x ``_COLS`` pixels, narrower along the left and right borders),
handed in blocks to a pool of threads (the kernel releases the GIL; one serial kernel compiles in about half the
time of a ``parallel=True`` one).  Per view column ``u``, a tile reads the source rows and columns that any of its
slopes needs (in place for inner tiles; otherwise copied into a small buffer with the edges replicated, and
premultiplied by the weight) and computes every slope from them, so the light field is read about twice (the
margins of the slope range) whatever the number of slopes.  The y pass combines two views and four output rows
per step (their source rows overlap), which halves the loads per multiply-add.  Interpolation: linear, or Keys'
cubic convolution (a = -0.5; Keys, IEEE TASSP 1981), exact at integer shifts.
"""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np

from .._numba import njit, run_in_blocks

log = logging.getLogger(__name__)

#: Output rows per tile.
_ROWS = 16
#: Output pixels per tile row.
_COLS = 256
#: Least width of the tile columns along the left and right borders.
_EDGE_COLS = 64
#: Bytes of a tile's accumulator (all slopes of a group); more slopes are split into groups.
_ACC_BYTES = 2 << 20

# multiply-adds may be fused (FMA); nothing is reassociated, so results do not depend on the tiling
_FM = {"contract"}


# ---------------------------------------------------------------------------------------------------------------
# inner loops (inlined): y taps of one or two views into 4 or 1 output rows, x taps of one row
# ---------------------------------------------------------------------------------------------------------------
@njit(cache=True, fastmath=_FM)
def _y_rows4(tmp, i, src, o, p, rl, wa, wb, n, nt, pair):
    """``tmp[i + r, :n] += sum_t wa[t] src[o + (r + t) rl :] (+ the same for wb, p)`` for r = 0..3."""
    d0 = tmp[i]
    d1 = tmp[i + 1]
    d2 = tmp[i + 2]
    d3 = tmp[i + 3]
    if nt == 4:
        a0, a1, a2, a3 = wa[0], wa[1], wa[2], wa[3]
        x0 = src[o:o + n]
        x1 = src[o + rl:o + rl + n]
        x2 = src[o + 2 * rl:o + 2 * rl + n]
        x3 = src[o + 3 * rl:o + 3 * rl + n]
        x4 = src[o + 4 * rl:o + 4 * rl + n]
        x5 = src[o + 5 * rl:o + 5 * rl + n]
        x6 = src[o + 6 * rl:o + 6 * rl + n]
        if pair:
            b0, b1, b2, b3 = wb[0], wb[1], wb[2], wb[3]
            y0 = src[p:p + n]
            y1 = src[p + rl:p + rl + n]
            y2 = src[p + 2 * rl:p + 2 * rl + n]
            y3 = src[p + 3 * rl:p + 3 * rl + n]
            y4 = src[p + 4 * rl:p + 4 * rl + n]
            y5 = src[p + 5 * rl:p + 5 * rl + n]
            y6 = src[p + 6 * rl:p + 6 * rl + n]
            for j in range(n):
                p0, p1, p2, p3, p4, p5, p6 = x0[j], x1[j], x2[j], x3[j], x4[j], x5[j], x6[j]
                q0, q1, q2, q3, q4, q5, q6 = y0[j], y1[j], y2[j], y3[j], y4[j], y5[j], y6[j]
                d0[j] += (a0 * p0 + a1 * p1 + a2 * p2 + a3 * p3) + (b0 * q0 + b1 * q1 + b2 * q2 + b3 * q3)
                d1[j] += (a0 * p1 + a1 * p2 + a2 * p3 + a3 * p4) + (b0 * q1 + b1 * q2 + b2 * q3 + b3 * q4)
                d2[j] += (a0 * p2 + a1 * p3 + a2 * p4 + a3 * p5) + (b0 * q2 + b1 * q3 + b2 * q4 + b3 * q5)
                d3[j] += (a0 * p3 + a1 * p4 + a2 * p5 + a3 * p6) + (b0 * q3 + b1 * q4 + b2 * q5 + b3 * q6)
        else:
            for j in range(n):
                p0, p1, p2, p3, p4, p5, p6 = x0[j], x1[j], x2[j], x3[j], x4[j], x5[j], x6[j]
                d0[j] += a0 * p0 + a1 * p1 + a2 * p2 + a3 * p3
                d1[j] += a0 * p1 + a1 * p2 + a2 * p3 + a3 * p4
                d2[j] += a0 * p2 + a1 * p3 + a2 * p4 + a3 * p5
                d3[j] += a0 * p3 + a1 * p4 + a2 * p5 + a3 * p6
    else:
        a0, a1 = wa[0], wa[1]
        x0 = src[o:o + n]
        x1 = src[o + rl:o + rl + n]
        x2 = src[o + 2 * rl:o + 2 * rl + n]
        x3 = src[o + 3 * rl:o + 3 * rl + n]
        x4 = src[o + 4 * rl:o + 4 * rl + n]
        if pair:
            b0, b1 = wb[0], wb[1]
            y0 = src[p:p + n]
            y1 = src[p + rl:p + rl + n]
            y2 = src[p + 2 * rl:p + 2 * rl + n]
            y3 = src[p + 3 * rl:p + 3 * rl + n]
            y4 = src[p + 4 * rl:p + 4 * rl + n]
            for j in range(n):
                p0, p1, p2, p3, p4 = x0[j], x1[j], x2[j], x3[j], x4[j]
                q0, q1, q2, q3, q4 = y0[j], y1[j], y2[j], y3[j], y4[j]
                d0[j] += (a0 * p0 + a1 * p1) + (b0 * q0 + b1 * q1)
                d1[j] += (a0 * p1 + a1 * p2) + (b0 * q1 + b1 * q2)
                d2[j] += (a0 * p2 + a1 * p3) + (b0 * q2 + b1 * q3)
                d3[j] += (a0 * p3 + a1 * p4) + (b0 * q3 + b1 * q4)
        else:
            for j in range(n):
                p0, p1, p2, p3, p4 = x0[j], x1[j], x2[j], x3[j], x4[j]
                d0[j] += a0 * p0 + a1 * p1
                d1[j] += a0 * p1 + a1 * p2
                d2[j] += a0 * p2 + a1 * p3
                d3[j] += a0 * p3 + a1 * p4


@njit(cache=True, fastmath=_FM)
def _y_row1(d, src, o, p, rl, wa, wb, n, nt, pair):
    """One output row of :func:`_y_rows4`."""
    if nt == 4:
        a0, a1, a2, a3 = wa[0], wa[1], wa[2], wa[3]
        x0 = src[o:o + n]
        x1 = src[o + rl:o + rl + n]
        x2 = src[o + 2 * rl:o + 2 * rl + n]
        x3 = src[o + 3 * rl:o + 3 * rl + n]
        if pair:
            b0, b1, b2, b3 = wb[0], wb[1], wb[2], wb[3]
            y0 = src[p:p + n]
            y1 = src[p + rl:p + rl + n]
            y2 = src[p + 2 * rl:p + 2 * rl + n]
            y3 = src[p + 3 * rl:p + 3 * rl + n]
            for j in range(n):
                d[j] += (a0 * x0[j] + a1 * x1[j] + a2 * x2[j] + a3 * x3[j]) + \
                        (b0 * y0[j] + b1 * y1[j] + b2 * y2[j] + b3 * y3[j])
        else:
            for j in range(n):
                d[j] += a0 * x0[j] + a1 * x1[j] + a2 * x2[j] + a3 * x3[j]
    else:
        a0, a1 = wa[0], wa[1]
        x0 = src[o:o + n]
        x1 = src[o + rl:o + rl + n]
        if pair:
            b0, b1 = wb[0], wb[1]
            y0 = src[p:p + n]
            y1 = src[p + rl:p + rl + n]
            for j in range(n):
                d[j] += (a0 * x0[j] + a1 * x1[j]) + (b0 * y0[j] + b1 * y1[j])
        else:
            for j in range(n):
                d[j] += a0 * x0[j] + a1 * x1[j]


@njit(cache=True, fastmath=_FM)
def _x_taps(dst, src, step, w, t0, nt, n):
    """``dst[j] += sum_{t < nt} w[t0 + t] src[t step + j]`` for ``j < n`` (``nt`` in 1..4)."""
    if nt == 1:
        w0 = w[t0]
        for j in range(n):
            dst[j] += w0 * src[j]
    elif nt == 2:
        w0, w1 = w[t0], w[t0 + 1]
        s1 = src[step:step + n]
        for j in range(n):
            dst[j] += w0 * src[j] + w1 * s1[j]
    elif nt == 3:
        w0, w1, w2 = w[t0], w[t0 + 1], w[t0 + 2]
        s1 = src[step:step + n]
        s2 = src[2 * step:2 * step + n]
        for j in range(n):
            dst[j] += w0 * src[j] + w1 * s1[j] + w2 * s2[j]
    else:
        w0, w1, w2, w3 = w[t0], w[t0 + 1], w[t0 + 2], w[t0 + 3]
        s1 = src[step:step + n]
        s2 = src[2 * step:2 * step + n]
        s3 = src[3 * step:3 * step + n]
        for j in range(n):
            dst[j] += w0 * src[j] + w1 * s1[j] + w2 * s2[j] + w3 * s3[j]


@njit(cache=True, fastmath=_FM)
def _copy_weighted(dst, src, wrow, xa, i0, i1, width, nx, nc):
    """``dst[xx (C+1) + c] = src[x C + c] w[x]``, ``dst[xx (C+1) + C] = w[x]`` with ``x = clip(xa + xx, 0, nx-1)``
    for ``xx < width``; the columns ``i0 <= xx < i1`` are inside the row."""
    cp = nc + 1
    for xx in range(i0):
        w = wrow[0]
        for c in range(nc):
            dst[xx * cp + c] = src[c] * w
        dst[xx * cp + nc] = w
    if nc == 3:                          # the common case, written out so that the loop vectorises
        d = dst[i0 * 4:i1 * 4]
        sv = src[(xa + i0) * 3:(xa + i1) * 3]
        wv = wrow[xa + i0:xa + i1]
        for j in range(i1 - i0):
            w = wv[j]
            d[4 * j] = sv[3 * j] * w
            d[4 * j + 1] = sv[3 * j + 1] * w
            d[4 * j + 2] = sv[3 * j + 2] * w
            d[4 * j + 3] = w
    else:
        for xx in range(i0, i1):
            w = wrow[xa + xx]
            for c in range(nc):
                dst[xx * cp + c] = src[(xa + xx) * nc + c] * w
            dst[xx * cp + nc] = w
    for xx in range(i1, width):
        w = wrow[nx - 1]
        for c in range(nc):
            dst[xx * cp + c] = src[(nx - 1) * nc + c] * w
        dst[xx * cp + nc] = w


# ---------------------------------------------------------------------------------------------------------------
# the kernel
# ---------------------------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True, fastmath=_FM)
def _shift_sum_kernel(data, weight, nc, vmask, bx, wx, tx0, tx1, by, wy, nb, xcuts, sg, task0, task1, inv_n, empty,
                      min_den, out):
    """Shift-sum photographs of the tiles ``task0 <= task < task1`` (see the module docstring).

    data (V, U, Y, X*C) f32; weight (V, U, Y, X) f32 or (0, 0, 0, 0); vmask (V, U) f32 aperture weights;
    bx (S, U) i64, wx (S, U, T) f32: x tap ``t`` of view column ``u`` at slope ``s`` reads ``x + bx + t``,
    ``tx0 <= t < tx1`` being its non-zero taps; by (S, V), wy (S, V, T) likewise along y (all taps used);
    nb: tile rows; xcuts (i64): tile column ``j`` covers pixels ``xcuts[j] .. xcuts[j+1]``; sg: slopes per group;
    inv_n: 1 / sum(vmask) (no weight); empty: the value of a pixel whose weight sum is at most min_den;
    out (S, Y, X*C) f32, every pixel of the tasks' tiles written.
    Task order: slope group fastest, then tile row, then tile column.
    """
    nv, nu, ny, nxc = data.shape
    nx = nxc // nc
    ns, nt = wx.shape[0], wx.shape[2]
    has_w = weight.shape[0] > 0
    cp = nc + 1 if has_w else nc          # weighted: channels premultiplied by w, then w itself
    n_yb = (ny + nb - 1) // nb
    n_g = (ns + sg - 1) // sg
    flat = data.reshape(nv * nu * ny * nxc)
    for task in range(task0, task1):
        g = task % n_g
        yb = (task // n_g) % n_yb
        xt = task // (n_g * n_yb)
        s0 = g * sg
        s1 = min(ns, s0 + sg)
        y0 = yb * nb
        nby = min(nb, ny - y0)
        x0 = xcuts[xt]
        nxp = xcuts[xt + 1] - x0
        # source rows per view row v (union over the group's slopes): buffer rows off[v] .. off[v+1]
        ya = np.empty(nv, np.int64)
        off = np.empty(nv + 1, np.int64)
        off[0] = 0
        for v in range(nv):
            lo = by[s0, v]
            hi = by[s0, v]
            for s in range(s0 + 1, s1):
                lo = min(lo, by[s, v])
                hi = max(hi, by[s, v])
            ya[v] = y0 + lo
            off[v + 1] = off[v] + nby + nt - 1 + hi - lo
        # source columns per view column u: xa[u] .. xa[u] + width[u]
        xa = np.empty(nu, np.int64)
        wmax = 0
        for u in range(nu):
            lo = bx[s0, u]
            hi = bx[s0, u]
            for s in range(s0 + 1, s1):
                lo = min(lo, bx[s, u])
                hi = max(hi, bx[s, u])
            xa[u] = x0 + lo
            wmax = max(wmax, nxp + nt - 1 + hi - lo)
        rl = wmax * cp
        buf = np.empty(off[nv] * rl, np.float32)
        acc = np.zeros((s1 - s0, nby, nxp * cp), np.float32)
        tmp = np.empty((nby, (nxp + nt - 1) * cp), np.float32)
        views = np.empty(nv, np.int64)
        wa = np.empty(nt, np.float32)
        wb = np.empty(nt, np.float32)
        for u in range(nu):
            nvu = 0
            for v in range(nv):
                if vmask[v, u] != 0.0:
                    views[nvu] = v
                    nvu += 1
            if nvu == 0:
                continue
            # 1. rows of views (v, u): read in place when every row and column is inside the image (and there is
            #    no weight), else copied, edges replicated, into buf
            direct = not has_w and xa[u] >= 0 and xa[u] + wmax <= nx
            for k in range(nvu):
                v = views[k]
                if ya[v] < 0 or ya[v] + off[v + 1] - off[v] > ny:
                    direct = False
            i0 = min(max(-xa[u], 0), wmax)                  # buffer columns [i0, i1) are inside the image
            i1 = max(min(nx - xa[u], wmax), i0)
            for k in range(0 if direct else nvu):
                v = views[k]
                for r in range(off[v + 1] - off[v]):
                    ys = min(max(ya[v] + r, 0), ny - 1)
                    src = data[v, u, ys]
                    dst = buf[(off[v] + r) * rl:(off[v] + r + 1) * rl]
                    if has_w:
                        _copy_weighted(dst, src, weight[v, u, ys], xa[u], i0, i1, wmax, nx, nc)
                    else:
                        for xx in range(i0):
                            for c in range(nc):
                                dst[xx * cp + c] = src[c]
                        nn = (i1 - i0) * cp
                        d = dst[i0 * cp:i0 * cp + nn]
                        sv = src[(xa[u] + i0) * nc:(xa[u] + i0) * nc + nn]
                        for j in range(nn):
                            d[j] = sv[j]
                        for xx in range(i1, wmax):
                            for c in range(nc):
                                dst[xx * cp + c] = src[(nx - 1) * nc + c]
            for s in range(s0, s1):
                a0, a1 = tx0[s, u], tx1[s, u]
                n1 = (nxp + a1 - a0 - 1) * cp               # columns the x pass reads
                c0 = (x0 + bx[s, u] + a0 - xa[u]) * cp
                # 2. y pass: tmp[i] = sum_v m_vu sum_t wy[s, v, t] row(v, y0 + i + by[s, v] + t)
                for i in range(nby):
                    tmp[i, :n1] = 0.0
                for k in range(0, nvu, 2):
                    pair = k + 1 < nvu
                    va = views[k]
                    vb = views[k + 1] if pair else va
                    for t in range(nt):
                        wa[t] = wy[s, va, t] * vmask[va, u]
                        wb[t] = wy[s, vb, t] * vmask[vb, u]
                    if direct:
                        src = flat
                        step = nxc
                        o = ((va * nu + u) * ny + y0 + by[s, va]) * nxc + xa[u] * nc + c0
                        p = ((vb * nu + u) * ny + y0 + by[s, vb]) * nxc + xa[u] * nc + c0
                    else:
                        src = buf
                        step = rl
                        o = (off[va] + y0 + by[s, va] - ya[va]) * rl + c0
                        p = (off[vb] + y0 + by[s, vb] - ya[vb]) * rl + c0
                    i = 0
                    while i + 4 <= nby:
                        _y_rows4(tmp, i, src, o + i * step, p + i * step, step, wa, wb, n1, nt, pair)
                        i += 4
                    while i < nby:
                        _y_row1(tmp[i], src, o + i * step, p + i * step, step, wa, wb, n1, nt, pair)
                        i += 1
                # 3. x pass into the accumulator
                for i in range(nby):
                    _x_taps(acc[s - s0, i], tmp[i], cp, wx[s, u], a0, a1 - a0, nxp * cp)
        # 4. normalise into the output
        for s in range(s0, s1):
            for i in range(nby):
                arow = acc[s - s0, i]
                orow = out[s, y0 + i, x0 * nc:(x0 + nxp) * nc]
                if has_w:
                    for x in range(nxp):
                        den = arow[x * cp + nc]
                        if den > min_den:
                            inv = 1.0 / den
                            for c in range(nc):
                                orow[x * nc + c] = arow[x * cp + c] * inv
                        else:
                            for c in range(nc):
                                orow[x * nc + c] = empty
                else:
                    for j in range(nxp * nc):
                        orow[j] = arow[j] * inv_n


def _nonzero_taps(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and one-past-last non-zero tap along the last axis (a zero row gives (0, 1))."""
    nz = w != 0
    nz[..., 0] |= ~nz.any(-1)
    first = np.argmax(nz, -1)
    last = w.shape[-1] - np.argmax(nz[..., ::-1], -1)
    return first.astype(np.int64), last.astype(np.int64)


def _column_cuts(n: int, edge: int, size: int) -> np.ndarray:
    """Tile boundaries over ``0 .. n``: ``[0, edge)``, tiles of ``size`` (the last one shorter), ``[n - edge, n)``;
    one or two tiles when ``n < 2 edge + size``."""
    if n < 2 * edge + size:
        return np.array([0, n] if n <= size else [0, n // 2, n], np.int64)
    return np.concatenate([[0], np.arange(edge, n - edge, size), [n - edge, n]]).astype(np.int64)


def sum_shifted_views_tiled(data: np.ndarray, weight: np.ndarray | None, vmask: np.ndarray,
                            taps_y: tuple[np.ndarray, np.ndarray], taps_x: tuple[np.ndarray, np.ndarray],
                            chunks: int = 1, step: Callable[[], None] = lambda: None,
                            empty: float = 0.0, min_den: float = 1e-12) -> np.ndarray:
    """The compiled, tiled shift-and-add with given separable taps, weight-normalised (see the module docstring).

    ``out[s, y, x] = sum_{v,u,t,r} m_vu w_vu L_vu(y + by[s,v] + t, x + bx[s,u] + r) wy[s,v,t] wx[s,u,r]``
    divided by the same sum without ``L`` when ``weight`` is given, else multiplied by ``1 / sum(m)``.  Rows and
    columns outside a view take its edge value.  Arguments and result as
    :func:`plenodecode.render.shiftsum.sum_shifted_views` (``T`` = 2 or 4, the same along y and x).

    Parameters
    ----------
    data : ndarray (V, U, Y, X, C) float32, C-contiguous
    weight : ndarray (V, U, Y, X) float32 or None
    vmask : ndarray (V, U) float32
    taps_y, taps_x : (first (S, V) or (S, U) int64, weights (S, V, T) or (S, U, T) float32)
    chunks : int
        The tiles are computed in ``chunks`` rounds, ``step()`` after each; within a round, blocks of tiles go
        to ``numba.get_num_threads()`` threads (:func:`plenodecode._numba.run_in_blocks`).
    empty, min_den : float
        The value of the pixels whose weight sum is at most ``min_den`` (that no view has data for).

    Returns
    -------
    ndarray, shape (S, Y, X, C), float32
    """
    nv, nu, ny, nx, nc = data.shape
    by, wy = taps_y
    bx, wx = taps_x
    flat = data.reshape(nv, nu, ny, nx * nc)
    has_w = weight is not None
    weight = np.ascontiguousarray(weight, np.float32) if has_w else np.zeros((0, 0, 0, 0), np.float32)
    by, bx = np.ascontiguousarray(by, np.int64), np.ascontiguousarray(bx, np.int64)
    wy, wx = np.ascontiguousarray(wy, np.float32), np.ascontiguousarray(wx, np.float32)
    tx0, tx1 = _nonzero_taps(wx)
    ns = by.shape[0]
    cp = nc + (1 if has_w else 0)
    # tile columns: narrow ones along the left and right borders, where shifted reads leave the image (copied
    # with edges replicated), _COLS wide ones inside (read in place when no weight)
    edge = max(_EDGE_COLS, -int(bx.min()), int(bx.max()) + wx.shape[-1] - 1)
    xcuts = _column_cuts(nx, edge, _COLS)
    sg = int(max(1, min(ns, _ACC_BYTES // (4 * _ROWS * int(np.diff(xcuts).max()) * cp))))
    n_tasks = -(-ny // _ROWS) * (len(xcuts) - 1) * -(-ns // sg)
    out = np.empty((ns, ny, nx * nc), np.float32)
    inv_n = np.float32(1.0 / float(vmask.sum()))
    bounds = np.linspace(0, n_tasks, chunks + 1).round().astype(int)
    for c0, c1 in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        run_in_blocks(lambda t0, t1: _shift_sum_kernel(flat, weight, nc, vmask, bx, wx, tx0, tx1, by, wy, _ROWS,
                                                       xcuts, sg, c0 + t0, c0 + t1, inv_n,
                                                       np.float32(empty), np.float32(min_den), out),
                     c1 - c0)
        step()
    return out.reshape(ns, ny, nx, nc)


__all__ = ["sum_shifted_views_tiled"]
