"""Hexagonal -> rectangular resampling of the lens lattice, with square output pixels.

The decoded sampling contract (:mod:`plenodecode.types`) puts output sample ``(y, x)`` at lattice
position ``a = y * step``, ``b = b0 + x * step`` with ``step = row_spacing``.  Output row ``y`` is
therefore exactly lens row ``y``, and only the position along the row falls between lenses:
lens ``j`` of row ``i`` sits at ``b = j * pitch + odd_row_shift * pitch * (i % 2)``.  On a hexagonal
lattice the barycentric interpolation on the triangle of the three nearest lenses degenerates, for a
point on a lens row, to 1-D interpolation between the two lenses of that row, so the resampling
is separable and exact in the lattice model: every output sample is a 1-D kernel along its lens
row at the fractional lens index ``t = (b - shift_i) / pitch``.  The aspect ratio is corrected
because the output step along the row equals the row spacing (``pitch * sqrt(3) / 2`` on a hex
grid), giving ``2 / sqrt(3)`` more samples per row than lenses (LFToolbox's 1-D "fast" dehex,
Dansereau et al. CVPR 2013, but here with the exact output grid and a cubic kernel).

Kernels (``RESAMPLE_METHODS``):

* ``'linear'``: tent kernel, 2 taps;
* ``'cubic'``: Keys (1981) cubic convolution with ``a = -0.5``, 4 taps; third-order accurate and
  interpolating, so it blurs less than linear and leaves no row-alternating softness.

A lens without a sample (zero weight, e.g. outside the sensor) is left out and the taps renormalised;
if one of the two nearest lenses is missing the sample falls back to the linear kernel.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit
from ..imaging import INTERPOLATION_TAPS, interpolation_taps
from ..registry import lookup
from ..types import LensletGrid


#: Row kernels: name -> number of taps (the kernels are :func:`plenodecode.imaging.interpolation_taps`).
RESAMPLE_METHODS = INTERPOLATION_TAPS


def row_taps(grid: LensletGrid, *, method: str = "cubic") -> tuple[np.ndarray, np.ndarray]:
    """Taps of the 1-D row kernel for the even and the odd lens rows.

    Parameters
    ----------
    grid : LensletGrid
    method : str
        Key of :data:`RESAMPLE_METHODS`.

    Returns
    -------
    idx : ndarray, shape (2, X, T), int32
        Lens column of each tap for output column ``x`` (row parity 0 / 1), clamped to ``[0, cols)``.
    w : ndarray, shape (2, X, T), float32
        Tap weights (sum to 1).
    """
    lookup(RESAMPLE_METHODS, method, param="resample method")
    s = grid.decoded_sampling()
    cols = grid.shape[1]
    x = np.arange(s["X"], dtype=np.float64)
    b = s["b0"] + x * s["step"]
    shift = grid.odd_row_shift * grid.pitch if grid.shape[0] > 1 else 0.0
    idx_all, w_all = [], []
    for parity in (0, 1):
        t = (b - shift * parity) / grid.pitch
        t = np.clip(t, 0.0, cols - 1.0)
        first, w = interpolation_taps(t, method)
        # edge lenses: fold out-of-range taps onto the nearest lens (replicate)
        idx = np.clip(first[:, None] + np.arange(w.shape[1]), 0, cols - 1)
        idx_all.append(idx.astype(np.int32))
        w_all.append(w)
    return np.stack(idx_all), np.stack(w_all)


# One signature, the destinations in any layout: the decoder passes a band of rows of the whole light field
# (strided) or, for a raw of one band, the whole of it (contiguous); without it each layout compiles once.
_RESAMPLE_SIGNATURE = ("void(f4[:, :, :, :, ::1], f4[:, :, :, ::1], i8[::1], i8[:, :, ::1], f4[:, :, ::1], b1[:, ::1], "
                       "i8[:, :, ::1], f4[:, :, ::1], f4[:, :, :, :, :], f4[:, :, :, :])")


@njit(_RESAMPLE_SIGNATURE, cache=True, nogil=True, fastmath=True, error_model="numpy")
def _resample_rows(samples, sweight, parity, idx, wts, contig, lidx, lwts, out, out_w):  # pragma: no cover - numba
    nv, nu, nr, nc, nch = samples.shape
    nx, nt = idx.shape[1], idx.shape[2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    for v in range(nv):
        for u in range(nu):
            for i in range(nr):
                p = parity[i]
                srow = samples[v, u, i]
                wrow = sweight[v, u, i]
                orow = out[v, u, i]
                owrow = out_w[v, u, i]
                n_pos = 0
                for j in range(nc):
                    if wrow[j] > 0.0:
                        n_pos += 1
                if n_pos == 0:                 # a view outside every lenslet disk on this row
                    for x in range(nx):
                        owrow[x] = zero
                        for c in range(nch):
                            orow[x, c] = zero
                    continue
                row_full = n_pos == nc         # every lens of the row has a sample
                for x in range(nx):
                    # fast path: consecutive taps that all have a sample (the kernel sums to 1): the plain sum
                    j0 = idx[p, x, 0]
                    full = nch == 3 and contig[p, x]
                    if full and not row_full:
                        for t in range(nt):
                            if not wrow[j0 + t] > 0.0:
                                full = False
                                break
                    # channel sums in scalars (nch is 1 or 3): no work array to allocate, nor to compile
                    a0 = zero
                    a1 = zero
                    a2 = zero
                    aw = zero
                    if full:
                        for t in range(nt):
                            wt = wts[p, x, t]
                            a0 += wt * srow[j0 + t, 0]
                            a1 += wt * srow[j0 + t, 1]
                            a2 += wt * srow[j0 + t, 2]
                            aw += wt * wrow[j0 + t]
                        orow[x, 0] = a0
                        orow[x, 1] = a1
                        orow[x, 2] = a2
                    else:
                        # general path: skip lenses without a sample and renormalise
                        norm = zero
                        for t in range(nt):
                            j = idx[p, x, t]
                            wt = wts[p, x, t]
                            sw = wrow[j]
                            aw += wt * sw
                            if sw > 0.0:
                                norm += wt
                                a0 += wt * srow[j, 0]
                                if nch == 3:
                                    a1 += wt * srow[j, 1]
                                    a2 += wt * srow[j, 2]
                        ja = lidx[p, x, 0]
                        jb = lidx[p, x, 1]
                        if norm > 0.5 and wrow[ja] > 0.0 and wrow[jb] > 0.0:
                            inv = np.float32(1.0) / norm
                            orow[x, 0] = a0 * inv
                            if nch == 3:
                                orow[x, 1] = a1 * inv
                                orow[x, 2] = a2 * inv
                        else:
                            # linear fallback among the two nearest lenses that have a sample
                            fa = lwts[p, x, 0] if wrow[ja] > 0.0 else zero
                            fb = lwts[p, x, 1] if wrow[jb] > 0.0 else zero
                            s = fa + fb
                            if s > 1e-6:
                                for c in range(nch):
                                    orow[x, c] = (fa * srow[ja, c] + fb * srow[jb, c]) / s
                            else:
                                for c in range(nch):
                                    orow[x, c] = zero
                    aw = aw if aw > zero else zero
                    owrow[x] = aw if aw < one else one


def hex_to_rect(samples: np.ndarray, weight: np.ndarray, grid: LensletGrid, *, first_row: int = 0,
                method: str = "cubic", out: np.ndarray | None = None,
                out_weight: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Resample per-lens samples onto the rectangular output grid (square pixels).

    Parameters
    ----------
    samples : ndarray, shape (V, U, R, K, C), float32
        Sample of every view under lens ``(first_row + r, k)`` (K = all lens columns).
    weight : ndarray, shape (V, U, R, K), float32
        Their weights; a lens with weight 0 has no sample.
    grid : LensletGrid
    first_row : int
        Global lens row of ``samples[:, :, 0]`` (sets the row parity).
    method : str
        Key of :data:`RESAMPLE_METHODS`.
    out, out_weight : ndarray, optional
        Destinations of shape (V, U, R, X, C) / (V, U, R, X) (e.g. a slice of the full light field).

    Returns
    -------
    data : ndarray, shape (V, U, R, X, C), float32
    weight : ndarray, shape (V, U, R, X), float32 in [0, 1]
    """
    nv, nu, nr, nc, nch = samples.shape
    if nc != grid.shape[1]:
        raise ValueError(f"samples must hold all {grid.shape[1]} lens columns, got {nc}")
    idx, wts = row_taps(grid, method=method)
    lidx, lwts = row_taps(grid, method="linear")
    nx = idx.shape[1]
    if out is None:
        out = np.empty((nv, nu, nr, nx, nch), np.float32)
    if out_weight is None:
        out_weight = np.empty((nv, nu, nr, nx), np.float32)
    parity = ((np.arange(nr) + first_row) % 2).astype(np.int64)
    contig = np.all(np.diff(idx, axis=-1) == 1, axis=-1)
    _resample_rows(samples, weight, parity, idx.astype(np.int64), wts, contig, lidx.astype(np.int64), lwts,
                   out, out_weight)
    return out, out_weight


def output_shape(grid: LensletGrid) -> tuple[int, int]:
    """Spatial size ``(Y, X)`` of the decoded light field (see :meth:`LensletGrid.decoded_sampling`)."""
    s = grid.decoded_sampling()
    return int(s["Y"]), int(s["X"])


__all__ = ["RESAMPLE_METHODS", "row_taps", "hex_to_rect", "output_shape"]
