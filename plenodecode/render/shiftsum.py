"""Shift-and-add refocusing: single photographs through OpenCV, focal stacks through a compiled kernel.

``E_s(y, x) = sum_{v,u} m_vu w_vu(y', x') L_vu(y', x') / sum_{v,u} m_vu w_vu(y', x')`` with
``(y', x') = (y - s a, x - s b)``, ``a = v - vc``, ``b = u - uc`` (design.md; the discrete form of Ng's
photographic imaging equation), ``m`` the aperture mask and ``w`` the light field's weight (1 when it has none).

The shift of view ``(v, u)`` is separable and its y part depends only on ``v``, its x part only on ``u``::

    E_s = sum_u  Sx(s b_u) [ sum_v Sy(s a_v) L_vu ]

Fewer than ``_TILED_MIN_SLOPES`` slopes (a photograph, a super-resolved fusion) of a light field of fewer than
``_TILED_MIN_SAMPLES`` samples (the bundled cameras, crops, small captures): per view column ``u``, every
view is padded once with its edge values (``cv2.copyMakeBorder``), and per slope its rows
``by[s, v] .. by[s, v] + Y + T - 1`` are filtered along y by the taps ``m_vu wy[s, v]`` (``cv2.filter2D``) and
summed over ``v``; the sum is filtered along x from column ``bx[s, u]`` by ``wx[s, u]`` (``cv2.sepFilter2D``)
and accumulated.  Nothing is compiled, so the first photograph after installing costs no compile time.

More slopes or a large light field: :mod:`.shiftsum_tiles`, a tiled numba kernel that reads the light field about once for all slopes
(about 3x less CPU than the OpenCV path for a 30-slice stack of a full Illum light field, 1.2-1.5 against
4.2-4.6 CPU s; one photograph 0.16-0.28 against 0.23-0.36, with a weight 0.24 against 0.65-0.72; it compiles
in 7-9 CPU s on first use; ``make bench`` compares the two).  Both give the same photographs to float32 rounding (``tests/render/test_refocus.py``).
Interpolation: linear, or Keys' cubic convolution (a = -0.5; Keys, IEEE TASSP 1981), exact at integer shifts.
"""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import cv2
import numpy as np

from ..imaging import INTERPOLATION_TAPS, interpolation_taps
from ..types import LightField
from ._common import (MIN_APERTURE_SHARE, aperture_mask, check_lightfield, check_slopes, check_upsample,
                      fill_empty_pixels)

log = logging.getLogger(__name__)

#: From this many slopes on, the compiled tiled kernel (:mod:`.shiftsum_tiles`) computes them in one pass.
_TILED_MIN_SLOPES = 8
#: ... and from this many samples V U Y X on (a full Illum light field has 61 M), even one photograph: there the
#: kernel saves 0.1-0.5 CPU s per photograph (3x with a weight), which repays its compile time within a session.
_TILED_MIN_SAMPLES = 16_000_000
#: Contiguous blocks of view columns the OpenCV path sums separately (on as many threads as OpenCV has, up to this).
_COLUMN_BLOCKS = 4


def _sum_shifted_views_opencv(data: np.ndarray, weight: np.ndarray | None, vmask: np.ndarray,
                              taps_y: tuple[np.ndarray, np.ndarray], taps_x: tuple[np.ndarray, np.ndarray],
                              chunks: int, step: Callable[[], None], empty: float = 0.0,
                              min_den: float = 1e-12) -> np.ndarray:
    """:func:`sum_shifted_views` by separable OpenCV filters (see the module docstring).

    The view columns are split in ``_COLUMN_BLOCKS`` contiguous blocks summed on up to ``cv2.getNumThreads()``
    threads (OpenCV releases the GIL), each block's partial sums added in block order: the blocks do not depend
    on the thread count, so neither does the float32 result (a batch worker capped to one thread writes the
    photograph the command line writes).  ``step()`` is called ``chunks`` times,
    from the calling thread: after each part of the columns with one thread, at the end with several.
    """
    nv, nu, ny, nx, nc = data.shape
    (by, wy), (bx, wx) = taps_y, taps_x
    ty, tx = wy.shape[-1], wx.shape[-1]
    ns = by.shape[0]
    cp = nc + 1 if weight is not None else nc          # weighted: channels premultiplied by w, then w itself
    # view padding (edge values) that every slope's reads stay inside
    top, bottom = max(0, -int(by.min())), max(0, int(by.max()) + ty - 1)
    left, right = max(0, -int(bx.min())), max(0, int(bx.max()) + tx - 1)
    width = left + nx + right
    one = np.ones(1, np.float32)
    ends = np.linspace(0, nu, chunks + 1).round().astype(int)[1:]     # the column after which step() is due

    def columns(u0: int, u1: int, report: Callable[[], None] = lambda: None) -> np.ndarray:
        acc = np.zeros((ns, ny, nx, cp), np.float32)
        column_sum = np.empty((ns, ny, width * cp), np.float32)
        filtered = np.empty((ny + ty - 1, width * cp), np.float32)
        for u in range(u0, u1):
            views = np.flatnonzero(vmask[:, u])
            column_sum.fill(0.0)
            for v in views:
                view = data[v, u]
                if weight is not None:             # (w L_0, .., w L_C-1, w): 4x faster than np.concatenate
                    w = weight[v, u]
                    view = cv2.merge([cv2.multiply(view, cv2.merge([w] * nc)).reshape(ny, nx, nc), w])
                padded = cv2.copyMakeBorder(np.ascontiguousarray(view, np.float32), top, bottom, left, right,
                                            cv2.BORDER_REPLICATE).reshape(top + ny + bottom, width * cp)
                for s in range(ns):
                    # y pass: filtered[i] = sum_t m_vu wy[s, v, t] padded[top + by[s, v] + i + t]
                    r0 = top + int(by[s, v])
                    kernel = (wy[s, v] * vmask[v, u]).reshape(ty, 1)
                    cv2.filter2D(padded[r0:r0 + ny + ty - 1], cv2.CV_32F, kernel, dst=filtered, anchor=(0, 0),
                                 borderType=cv2.BORDER_REPLICATE)
                    np.add(column_sum[s], filtered[:ny], out=column_sum[s])
            for s in range(ns if len(views) else 0):
                # x pass: acc[s, :, x] += sum_t wx[s, u, t] column_sum[s, :, left + bx[s, u] + x + t]
                c0 = left + int(bx[s, u])
                cols = column_sum[s].reshape(ny, width, cp)[:, c0:c0 + nx + tx - 1]
                shifted = cv2.sepFilter2D(np.ascontiguousarray(cols), cv2.CV_32F, wx[s, u], one, anchor=(0, 0),
                                          borderType=cv2.BORDER_REPLICATE)
                np.add(acc[s], shifted.reshape(ny, nx + tx - 1, cp)[:, :nx], out=acc[s])
            for _ in range(int(np.count_nonzero(ends == u + 1))):
                report()
        return acc

    blocks = np.linspace(0, nu, min(nu, _COLUMN_BLOCKS) + 1).round().astype(int)
    threads = min(len(blocks) - 1, max(1, cv2.getNumThreads()))
    if threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            parts = list(pool.map(columns, blocks[:-1].tolist(), blocks[1:].tolist()))
        for _ in range(chunks):
            step()
    else:
        parts = [columns(u0, u1, step) for u0, u1 in zip(blocks[:-1].tolist(), blocks[1:].tolist())]
    acc = parts[0]
    for part in parts[1:]:
        np.add(acc, part, out=acc)
    if weight is None:
        return np.multiply(acc, np.float32(1.0 / float(vmask.sum())), out=acc)
    den = acc[..., nc:]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > min_den, acc[..., :nc] / den, np.float32(empty)).astype(np.float32, copy=False)


def sum_shifted_views(lf: LightField, vmask: np.ndarray, taps_y: tuple[np.ndarray, np.ndarray],
                      taps_x: tuple[np.ndarray, np.ndarray], chunks: int = 1,
                      step: Callable[[], None] = lambda: None, empty: float = 0.0,
                      min_den: float = 1e-12) -> np.ndarray:
    """Shift-and-add with given separable taps, weight-normalised (see the module docstring).

    ``out[s, y, x] = sum_{v,u,t,r} m_vu w_vu L_vu(y + by[s,v] + t, x + bx[s,u] + r) wy[s,v,t] wx[s,u,r]``
    divided by the same sum without ``L`` when ``lf.weight`` is set, else multiplied by ``1 / sum(m)`` (so taps
    that sum to 1 per view give the plain mean).  Rows and columns outside a view take its edge value.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32, optional ``weight`` (V, U, Y, X).
    vmask : ndarray (V, U) float32
        Aperture weights ``m``.
    taps_y : (by, wy)
        ``by`` (S, V) int64 first source row offset, ``wy`` (S, V, T) float32 weights (T = 2 or 4).
    taps_x : (bx, wx)
        ``bx`` (S, U) int64, ``wx`` (S, U, T) float32, likewise along x.
    chunks : int
        The work is done in ``chunks`` parts, ``step()`` after each.
    empty, min_den : float
        The value of the pixels whose weight sum ``sum m w wy wx`` is at most ``min_den`` (that no view has data
        for); with no weight every pixel has data.

    Returns
    -------
    ndarray, shape (S, Y, X, C), float32
        Fewer than ``_TILED_MIN_SLOPES`` slopes of fewer than ``_TILED_MIN_SAMPLES`` samples: OpenCV; else the
        compiled tiled kernel (equal to float32 rounding).
    """
    data = lf.data
    if not (data.flags.c_contiguous and data.dtype == np.float32):
        log.debug("shift-sum: copying a non-contiguous or non-float32 light field")
        data = np.ascontiguousarray(data, np.float32)
    weight = None if lf.weight is None else np.ascontiguousarray(lf.weight, np.float32)
    if len(taps_y[0]) >= _TILED_MIN_SLOPES or data.size // data.shape[-1] >= _TILED_MIN_SAMPLES:
        from .shiftsum_tiles import sum_shifted_views_tiled

        return sum_shifted_views_tiled(data, weight, vmask, taps_y, taps_x, chunks, step, empty, min_den)
    return _sum_shifted_views_opencv(data, weight, vmask, taps_y, taps_x, chunks, step, empty, min_den)


def _shift_sum_phase(lf: LightField, slopes: np.ndarray, vmask: np.ndarray, interp: str,
                     offset: tuple[float, float], chunks: int,
                     step: Callable[[], None]) -> np.ndarray:
    """Shift-sum photographs sampled at ``(y + offset[0], x + offset[1])``; (S, Y, X, C) float32.

    The work is done in ``chunks`` parts, ``step()`` after each.
    """
    nv, nu = lf.shape[:2]
    vc, uc = lf.centre_index
    a = np.arange(nv, dtype=np.float64) - vc
    b = np.arange(nu, dtype=np.float64) - uc
    by, wy = interpolation_taps(offset[0] - slopes[:, None] * a[None, :], interp)       # (S, V), (S, V, T)
    bx, wx = interpolation_taps(offset[1] - slopes[:, None] * b[None, :], interp)       # (S, U), (S, U, T)
    return sum_shifted_views(lf, vmask, (by, wy), (bx, wx), chunks, step, empty=np.nan,
                             min_den=MIN_APERTURE_SHARE * float(vmask.sum()))


def shift_sum(lf: LightField, slopes: float | np.ndarray, *, aperture: float | np.ndarray = 1.0,
              upsample: int = 1, interp: str = "cubic",
              progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Shift-and-add refocusing at one or many slopes (the discrete form of Ng's photographic imaging equation).

    ``E_s(y, x) = sum_{v,u} m_vu w_vu(y', x') L_vu(y', x') / sum_{v,u} m_vu w_vu(y', x')`` with
    ``(y', x') = (y - s (v - vc), x - s (u - uc))``, ``m`` the aperture mask and ``w`` the light field's weight
    (1 when it has none).  Each view is shifted by separable interpolation, samples outside a view taking the
    nearest edge value.  A pixel that no view has data for (``sum m w`` below
    :data:`~plenodecode.render._common.MIN_APERTURE_SHARE` ``sum m``: the gaps a decode leaves at the frame's
    edge) takes the nearest pixel that has, up to :data:`~plenodecode.imaging.GAP_DEPTH_PX` away, else 0.  A few slopes of a small light field go through
    OpenCV, a focal stack or a large light field through one compiled pass over the data (see the module
    docstring); a photograph is the same to float32 rounding whatever other slopes are asked with
    it (exactly the same when the same path computes both).

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32, optional ``weight`` (V, U, Y, X).
    slopes : float or array_like (S,)
        Refocus slopes, spatial samples per view step.
    aperture : float or ndarray (V, U)
        See :func:`plenodecode.render.aperture_mask`.
    upsample : int
        Spatial upsampling factor ``k``: output sample ``(j, i)`` is the photograph at ``(j / k, i / k)``.
    interp : 'linear' or 'cubic'
        Sub-pixel interpolation of the shifted views (bilinear, or Keys bicubic).
    progress : callable(done, total), optional
        Called a few times per pass (``total`` steps in all).

    Returns
    -------
    ndarray, shape (S, k Y, k X, C), float32
    """
    check_lightfield(lf)
    s = check_slopes(slopes)
    k = check_upsample(upsample)
    if interp not in INTERPOLATION_TAPS:
        raise ValueError(f"interp must be one of {', '.join(INTERPOLATION_TAPS)}, got {interp!r}")
    vmask = aperture_mask(lf.shape[:2], aperture)
    _, _, ny, nx, nc = lf.shape
    chunks = 4 if progress is not None else 1
    total = chunks * k * k
    done = [0]

    def step() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    if k == 1:
        return fill_empty_pixels(_shift_sum_phase(lf, s, vmask, interp, (0.0, 0.0), chunks, step))
    out = np.empty((len(s), k * ny, k * nx, nc), np.float32)
    for py in range(k):
        for px in range(k):
            out[:, py::k, px::k] = _shift_sum_phase(lf, s, vmask, interp, (py / k, px / k), chunks, step)
    return fill_empty_pixels(out)


__all__ = ["shift_sum"]
