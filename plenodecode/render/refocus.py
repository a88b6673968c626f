"""Refocusing a light field: shift-sum and Fourier slice, and the alpha <-> slope conversion.

Slope (design.md): ``E_s(y, x) = mean_{v,u} L[v, u](y - s (v - vc), x - s (u - uc))`` with ``s`` in spatial
samples per view step; a surface of disparity ``d`` is sharpest at ``s = d``.

From Ng's alpha to a slope
--------------------------
Ng's photographic imaging equation (Fourier Slice Photography, SIGGRAPH 2005) images a virtual film at
``alpha * F`` as ``E(x') ~ integral L_F(u (1 - 1/alpha) + x'/alpha, u) du``, with ``x`` (m) on the microlens
plane and ``u`` (m) on the main-lens aperture.  Dropping the magnification ``1/alpha``, the ray through ``u`` is
read ``u (1 - 1/alpha)`` metres away from the output position.

1. Aperture: ``D = focal_length_m / f_number``.  With f-number matched lenslets the aperture's image fills one lens
   pitch (``pitch_px`` pixels), so one pixel behind a lenslet sees ``D / pitch_px`` metres of aperture and one view
   step sees ``du = -D * view_step_px / pitch_px`` (the lenslet inverts the aperture, hence the minus).
2. Space: ``pitch_px`` pixels under the lenses span ``lens_pitch_m``, so a spatial sample (``spatial_step_px``
   pixels of the lattice) is ``dx = lens_pitch_m * spatial_step_px / pitch_px`` metres.
3. View ``a = v - vc`` is read at ``x + a du (1 - 1/alpha) / dx`` samples, i.e. ``x - s a`` with
   ``s = K (1 - 1/alpha)``, ``K = |du| / dx = (focal_length_m / f_number) * view_step_px /
   (lens_pitch_m * spatial_step_px)``; ``pitch_px`` cancels.
4. Check of the sign: a point closer than the focused plane images behind the microlenses, so it is refocused at
   ``alpha > 1`` and appears in view ``a`` displaced by ``-d a`` with ``d > 0``: the disparity of design.md.
5. Inverse: ``alpha = 1 / (1 - s / K)``, defined for ``s < K`` (``s -> K`` is a film plane at infinity).

Constants and where they are read: ``focal_length_m``, ``f_number``, ``lens_pitch_m`` from
``lf.metadata['camera']`` (``CameraMetadata.to_dict()``; ``lens_pitch_m`` falls back to
``calibration['pitch'] * camera['pixel_pitch_m']``), ``spatial_step_px`` and ``view_step_px`` from
``lf.metadata`` (``spatial_step_px`` falls back to ``calibration['row_spacing']``, the decoded sampling step).
Every constant can be passed as a keyword, which wins over the metadata.
"""

from __future__ import annotations

import logging
import math
from typing import Any, Callable, Mapping

import numba
import numpy as np
from numba import njit, prange

from ..errors import MetadataError
from ..types import LightField

log = logging.getLogger(__name__)

#: Constants of :func:`slope_per_alpha_unit` (keyword overrides of :func:`alpha_to_slope`).
REFOCUS_CONSTANTS = ("focal_length_m", "f_number", "lens_pitch_m", "spatial_step_px", "view_step_px")

#: Interpolation kernels of the shift-sum: name -> number of taps.
INTERPOLATIONS = {"linear": 2, "cubic": 4}


# ---------------------------------------------------------------------------------------------------------------
# alpha <-> slope
# ---------------------------------------------------------------------------------------------------------------
def refocus_constants(lf: LightField | None = None, **overrides: float) -> dict[str, float]:
    """The camera constants of the alpha <-> slope conversion (see the module docstring).

    Parameters
    ----------
    lf : LightField, optional
        Source of the constants (``metadata['camera']``, ``metadata['calibration']``, ``metadata``).
    **overrides : float
        Any of :data:`REFOCUS_CONSTANTS`; wins over the metadata.

    Returns
    -------
    dict
        Every name of :data:`REFOCUS_CONSTANTS` -> float.

    Raises
    ------
    MetadataError
        A constant is neither in the metadata nor among the keywords.
    ValueError
        An unknown keyword, or a constant that is not a positive number.
    """
    unknown = set(overrides) - set(REFOCUS_CONSTANTS)
    if unknown:
        raise ValueError(f"unknown refocus constant(s) {sorted(unknown)}; valid: {', '.join(REFOCUS_CONSTANTS)}")
    meta: Mapping[str, Any] = lf.metadata if lf is not None else {}
    camera = meta.get("camera") or {}
    calib = meta.get("calibration") or {}
    found: dict[str, Any] = {
        "focal_length_m": camera.get("focal_length_m"),
        "f_number": camera.get("f_number"),
        "lens_pitch_m": camera.get("lens_pitch_m"),
        "spatial_step_px": meta.get("spatial_step_px"),
        "view_step_px": meta.get("view_step_px"),
    }
    if found["lens_pitch_m"] is None and calib.get("pitch") and camera.get("pixel_pitch_m"):
        found["lens_pitch_m"] = float(calib["pitch"]) * float(camera["pixel_pitch_m"])
    if found["spatial_step_px"] is None and calib.get("row_spacing"):
        found["spatial_step_px"] = float(calib["row_spacing"])
    found.update({k: v for k, v in overrides.items() if v is not None})
    out = {}
    for name in REFOCUS_CONSTANTS:
        value = found[name]
        if value is None:
            raise MetadataError(
                f"alpha needs the camera constant '{name}', which the light field's metadata does not have; "
                f"pass {name}=... or use a slope instead of alpha")
        value = float(value)
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f"{name} must be a positive number, got {value}")
        out[name] = value
    return out


def slope_per_alpha_unit(lf: LightField | None = None, **constants: float) -> float:
    """``K`` of ``s = K (1 - 1/alpha)``: ``(focal_length_m / f_number) * view_step_px / (lens_pitch_m *
    spatial_step_px)``.

    Parameters and errors as :func:`refocus_constants`.
    """
    c = refocus_constants(lf, **constants)
    aperture_m = c["focal_length_m"] / c["f_number"]
    return aperture_m * c["view_step_px"] / (c["lens_pitch_m"] * c["spatial_step_px"])


def alpha_to_slope(alpha: float | np.ndarray, lf: LightField | None = None, **constants: float) -> float | np.ndarray:
    """Ng's relative film depth ``alpha`` -> refocus slope ``s = K (1 - 1/alpha)`` (px per view step).

    Parameters
    ----------
    alpha : float or array_like
        Relative film depth, > 0; 1 is the focus as captured.
    lf : LightField, optional
        Source of the camera constants (see the module docstring).
    **constants : float
        Overrides of :data:`REFOCUS_CONSTANTS`.

    Returns
    -------
    float or ndarray (float64)
    """
    a = np.asarray(alpha, np.float64)
    if not np.all(a > 0):
        raise ValueError(f"alpha must be > 0, got {alpha}")
    s = slope_per_alpha_unit(lf, **constants) * (1.0 - 1.0 / a)
    return float(s) if s.ndim == 0 else s


def slope_to_alpha(slope: float | np.ndarray, lf: LightField | None = None, **constants: float) -> float | np.ndarray:
    """Inverse of :func:`alpha_to_slope`: ``alpha = 1 / (1 - s / K)``, for slopes ``s < K``."""
    k = slope_per_alpha_unit(lf, **constants)
    s = np.asarray(slope, np.float64)
    if not np.all(s < k):
        raise ValueError(f"slope must be < {k:.4g} (a film plane at infinity) for this camera, got {slope}")
    a = 1.0 / (1.0 - s / k)
    return float(a) if a.ndim == 0 else a


# ---------------------------------------------------------------------------------------------------------------
# shared helpers
# ---------------------------------------------------------------------------------------------------------------
def aperture_mask(shape: tuple[int, int], aperture: float | np.ndarray = 1.0) -> np.ndarray:
    """Per-view weights of a synthetic aperture.

    Parameters
    ----------
    shape : (V, U)
        Angular size of the light field.
    aperture : float or ndarray (V, U)
        A float ``r`` in (0, 1] keeps the views inside a circle of radius ``r`` times the distance from the
        centre view to the corner view (normalised per axis, so 1 = all views, ``1/sqrt(2)`` = the inscribed disk);
        or a boolean / non-negative float mask over the views.

    Returns
    -------
    ndarray, shape (V, U), float32
        Weight of each view (0 = unused).
    """
    nv, nu = shape
    if isinstance(aperture, (bool, np.bool_)) or (np.ndim(aperture) == 0 and not isinstance(aperture, np.ndarray)):
        if isinstance(aperture, (bool, np.bool_)):
            raise ValueError(f"aperture must be a radius in (0, 1] or a (V, U) mask, got {aperture!r}")
        r = float(aperture)
        if not (0 < r <= 1):
            raise ValueError(f"aperture radius must be in (0, 1], got {r}")
        vc, uc = nv // 2, nu // 2
        dv = (np.arange(nv) - vc) / max(vc, nv - 1 - vc, 1)
        du = (np.arange(nu) - uc) / max(uc, nu - 1 - uc, 1)
        rho = np.hypot(dv[:, None], du[None, :]) / math.sqrt(2.0)
        return (rho <= r + 1e-9).astype(np.float32)
    m = np.asarray(aperture)
    if m.shape != (nv, nu):
        raise ValueError(f"aperture mask must have shape (V, U) = {(nv, nu)}, got {m.shape}")
    m = m.astype(np.float32)
    if not np.all(np.isfinite(m)) or np.any(m < 0) or not np.any(m > 0):
        raise ValueError("aperture mask must be finite, non-negative and select at least one view")
    return m


def check_lightfield(lf: Any) -> LightField:
    """Raise ValueError unless ``lf`` is a :class:`LightField`."""
    if not isinstance(lf, LightField):
        raise ValueError(f"lf must be a plenodecode LightField, got {type(lf).__name__}")
    return lf


def _tap_weights(t: np.ndarray, interp: str) -> tuple[np.ndarray, np.ndarray]:
    """Taps sampling a row at ``x + t`` for every ``x``.

    Parameters
    ----------
    t : ndarray (...,) float64
        Sub-pixel offsets.
    interp : 'linear' or 'cubic'
        Linear, or Keys' cubic convolution (a = -0.5; Keys 1981), exact at integer offsets.

    Returns
    -------
    base : ndarray (...,) int64
        Offset of the first tap: tap ``k`` reads ``x + base + k``.
    weights : ndarray (..., T) float32
    """
    i = np.floor(t)
    f = t - i
    if interp == "linear":
        return i.astype(np.int64), np.stack([1.0 - f, f], -1).astype(np.float32)
    if interp == "cubic":
        a = -0.5

        def near(x):  # |x| <= 1
            return (a + 2) * x**3 - (a + 3) * x**2 + 1

        def far(x):  # 1 < |x| < 2
            return a * x**3 - 5 * a * x**2 + 8 * a * x - 4 * a

        w = np.stack([far(1 + f), near(f), near(1 - f), far(2 - f)], -1)
        return (i - 1).astype(np.int64), w.astype(np.float32)
    raise ValueError(f"interp must be one of {', '.join(INTERPOLATIONS)}, got {interp!r}")


# ---------------------------------------------------------------------------------------------------------------
# shift-sum kernels (numba)
# ---------------------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _axpy_taps(acc, src, base, w, nx, c):
    """``acc[x*c + k] += sum_t w[t] * src[clip(x + base + t, 0, nx-1)*c + k]`` (all taps in one pass).

    Interior columns (every tap inside the row) run as one fused, vectorised loop for 2 or 4 taps.
    """
    nt = w.shape[0]
    lo = min(max(-base, 0), nx)
    hi = min(max(nx - base - (nt - 1), lo), nx)
    for x in range(lo):
        for t in range(nt):
            xs = min(max(x + base + t, 0), nx - 1)
            for k in range(c):
                acc[x * c + k] += w[t] * src[xs * c + k]
    for x in range(hi, nx):
        for t in range(nt):
            xs = min(max(x + base + t, 0), nx - 1)
            for k in range(c):
                acc[x * c + k] += w[t] * src[xs * c + k]
    if hi <= lo:
        return
    dst = acc[lo * c:hi * c]
    n = dst.shape[0]
    o = (lo + base) * c
    if nt == 2:
        s0 = src[o:o + n]
        s1 = src[o + c:o + c + n]
        w0, w1 = w[0], w[1]
        for j in range(n):
            dst[j] += w0 * s0[j] + w1 * s1[j]
    elif nt == 4:
        s0 = src[o:o + n]
        s1 = src[o + c:o + c + n]
        s2 = src[o + 2 * c:o + 2 * c + n]
        s3 = src[o + 3 * c:o + 3 * c + n]
        w0, w1, w2, w3 = w[0], w[1], w[2], w[3]
        for j in range(n):
            dst[j] += w0 * s0[j] + w1 * s1[j] + w2 * s2[j] + w3 * s3[j]
    else:
        for t in range(nt):
            st = src[o + t * c:o + t * c + n]
            wt = w[t]
            for j in range(n):
                dst[j] += wt * st[j]


@njit(cache=True, inline="always")
def _axpy_rows(acc, rows, w):
    """``acc[j] += sum_t w[t] * rows[t, j]`` (2 or 4 rows fused in one vectorised loop)."""
    nt, n = rows.shape
    if nt == 2:
        r0, r1 = rows[0], rows[1]
        w0, w1 = w[0], w[1]
        for j in range(n):
            acc[j] += w0 * r0[j] + w1 * r1[j]
    elif nt == 4:
        r0, r1, r2, r3 = rows[0], rows[1], rows[2], rows[3]
        w0, w1, w2, w3 = w[0], w[1], w[2], w[3]
        for j in range(n):
            acc[j] += w0 * r0[j] + w1 * r1[j] + w2 * r2[j] + w3 * r3[j]
    else:
        for t in range(nt):
            rt = rows[t]
            wt = w[t]
            for j in range(n):
                acc[j] += wt * rt[j]


@njit(parallel=True, cache=True)
def _shift_sum_kernel(data, weight, vmask, base_x, taps_x, base_y, taps_y, nx, nc, block, num, den):
    """Separable shift-and-add of every view, for every slope, in one parallel pass over blocks of output rows.

    For an output block, for each view row ``v``: shift the needed source rows of the views ``(v, u)`` along x
    and sum them over ``u`` (per slope) into a block buffer, then interpolate that buffer along y and add it to
    the output.  The views' rows are read once per block for all slopes.

    data (V, U, Y, X*C) f32; weight (V, U, Y, X) f32 or (0, 0, 0, 0); vmask (V, U) f32;
    base_x (S, U) i64, taps_x (S, U, T) f32: tap ``t`` of view column ``u`` reads ``x + base_x + t``;
    base_y (S, V) i64, taps_y (S, V, T) f32 likewise along y; ``block`` output rows per task;
    num (S, Y, X*C) and den (S, Y, X) (or (0, 0, 0)) f32, zero on entry, accumulated.
    """
    nv, nu, ny, nxc = data.shape
    ns, nt = taps_x.shape[0], taps_x.shape[2]
    has_w = weight.shape[0] > 0
    nblocks = (ny + block - 1) // block
    for ib in prange(nblocks):
        y0 = ib * block
        nb = min(ny, y0 + block) - y0
        nr = nb + nt - 1
        rx = np.empty((ns, nr, nxc), np.float32)
        rw = np.empty((ns, nr, nx if has_w else 0), np.float32)
        tmp = np.empty(nxc, np.float32)
        wt = np.empty(nt, np.float32)
        for v in range(nv):
            used = False
            for u in range(nu):
                if vmask[v, u] != 0.0:
                    used = True
            if not used:
                continue
            rx[:] = 0.0
            if has_w:
                rw[:] = 0.0
            lo = base_y[0, v]
            hi = base_y[0, v]
            for s in range(1, ns):
                lo = min(lo, base_y[s, v])
                hi = max(hi, base_y[s, v])
            for yy in range(y0 + lo, y0 + hi + nr):
                ys = min(max(yy, 0), ny - 1)
                for u in range(nu):
                    m = vmask[v, u]
                    if m == 0.0:
                        continue
                    row = data[v, u, ys]
                    if has_w:
                        wrow = weight[v, u, ys]
                        for x in range(nx):
                            for k in range(nc):
                                tmp[x * nc + k] = row[x * nc + k] * wrow[x]
                    for s in range(ns):
                        r = yy - y0 - base_y[s, v]
                        if r < 0 or r >= nr:
                            continue
                        for t in range(nt):
                            wt[t] = taps_x[s, u, t] * m
                        if has_w:
                            _axpy_taps(rx[s, r], tmp, base_x[s, u], wt, nx, nc)
                            _axpy_taps(rw[s, r], wrow, base_x[s, u], wt, nx, 1)
                        else:
                            _axpy_taps(rx[s, r], row, base_x[s, u], wt, nx, nc)
            for s in range(ns):
                for i in range(nb):
                    # rows i .. i + nt - 1 of the block buffer are consecutive: a y-tap is a stride of one row
                    _axpy_rows(num[s, y0 + i], rx[s, i:i + nt], taps_y[s, v])
                    if has_w:
                        _axpy_rows(den[s, y0 + i], rw[s, i:i + nt], taps_y[s, v])


@njit(parallel=True, cache=True)
def _normalise(num, den, c, out):
    """``out[s, y, x*c + k] = num[...] / den[s, y, x]`` (0 where den <= 0)."""
    ns, ny, nxc = num.shape
    nx = nxc // c
    for y in prange(ny):
        for s in range(ns):
            for x in range(nx):
                d = den[s, y, x]
                inv = 1.0 / d if d > 1e-12 else 0.0
                for k in range(c):
                    out[s, y, x * c + k] = num[s, y, x * c + k] * inv


# ---------------------------------------------------------------------------------------------------------------
# shift-sum
# ---------------------------------------------------------------------------------------------------------------
def _shift_sum_phase(lf: LightField, slopes: np.ndarray, vmask: np.ndarray, interp: str,
                     offset: tuple[float, float], progress: Callable[[int], None] | None) -> np.ndarray:
    """Shift-sum photographs sampled at ``(y + offset[0], x + offset[1])``; (S, Y, X, C) float32."""
    nv, nu, ny, nx, nc = lf.shape
    vc, uc = lf.centre_index
    data = lf.data
    if not data.flags.c_contiguous:
        log.debug("shift-sum: copying a non-contiguous light field")
        data = np.ascontiguousarray(data)
    data = data.reshape(nv, nu, ny, nx * nc)
    has_w = lf.weight is not None
    weight = np.ascontiguousarray(lf.weight, np.float32) if has_w else np.zeros((0, 0, 0, 0), np.float32)
    a = np.arange(nv, dtype=np.float64) - vc
    b = np.arange(nu, dtype=np.float64) - uc
    base_x, taps_x = _tap_weights(offset[1] - slopes[:, None] * b[None, :], interp)       # (S, U), (S, U, T)
    base_y, taps_y = _tap_weights(offset[0] - slopes[:, None] * a[None, :], interp)       # (S, V), (S, V, T)
    ns = len(slopes)
    num = np.zeros((ns, ny, nx * nc), np.float32)
    den = np.zeros((ns, ny, nx), np.float32) if has_w else np.zeros((0, 0, 0), np.float32)
    # ~4 blocks of output rows per thread, handed out dynamically (robust when cores are shared)
    block = max(8, -(-ny // (4 * max(1, numba.get_num_threads()))))
    with numba.parallel_chunksize(1):
        _shift_sum_kernel(data, weight, vmask, base_x, taps_x, np.ascontiguousarray(base_y),
                          np.ascontiguousarray(taps_y), nx, nc, block, num, den)
    if progress is not None:
        progress(nv)
    if has_w:
        out = np.empty_like(num)
        _normalise(num, den, nc, out)
        num = out
    else:
        num *= np.float32(1.0 / float(vmask.sum()))
    return num.reshape(ns, ny, nx, nc)


def shift_sum(lf: LightField, slopes: float | np.ndarray, *, aperture: float | np.ndarray = 1.0,
              upsample: int = 1, interp: str = "cubic",
              progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Shift-and-add refocusing (the discrete form of Ng's photographic imaging equation).

    ``E_s(y, x) = sum_{v,u} m_vu w_vu(y', x') L_vu(y', x') / sum_{v,u} m_vu w_vu(y', x')`` with
    ``(y', x') = (y - s (v - vc), x - s (u - uc))``, ``m`` the aperture mask and ``w`` the light field's weight
    (1 when it has none).  Each view is shifted by separable interpolation (x then y, summed per view row), with
    samples outside a view taking the nearest edge value.  All slopes are computed in one pass over the data.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32, optional ``weight`` (V, U, Y, X).
    slopes : float or array_like (S,)
        Refocus slopes, spatial samples per view step.
    aperture : float or ndarray (V, U)
        See :func:`aperture_mask`.
    upsample : int
        Spatial upsampling factor ``k``: output sample ``(j, i)`` is the photograph at ``(j / k, i / k)``.
    interp : 'linear' or 'cubic'
        Sub-pixel interpolation of the shifted views (bilinear, or Keys bicubic).
    progress : callable(done, total), optional

    Returns
    -------
    ndarray, shape (S, k Y, k X, C), float32
    """
    check_lightfield(lf)
    s = np.atleast_1d(np.asarray(slopes, np.float64)).ravel()
    if not np.all(np.isfinite(s)):
        raise ValueError(f"slopes must be finite, got {slopes}")
    k = int(upsample)
    if k < 1 or k != upsample:
        raise ValueError(f"upsample must be a positive integer, got {upsample}")
    if interp not in INTERPOLATIONS:
        raise ValueError(f"interp must be one of {', '.join(INTERPOLATIONS)}, got {interp!r}")
    vmask = aperture_mask(lf.shape[:2], aperture)
    nv, _, ny, nx, nc = lf.shape
    total = nv * k * k
    done = [0]

    def step(n: int) -> None:
        done[0] += n
        if progress is not None:
            progress(done[0], total)

    if k == 1:
        return _shift_sum_phase(lf, s, vmask, interp, (0.0, 0.0), step)
    out = np.empty((len(s), k * ny, k * nx, nc), np.float32)
    for py in range(k):
        for px in range(k):
            out[:, py::k, px::k] = _shift_sum_phase(lf, s, vmask, interp, (py / k, px / k), step)
    return out


def _fourier_slice(lf: LightField, slopes: float | np.ndarray, **kw: Any) -> np.ndarray:
    """Registry entry of 'fourier-slice' (imports :mod:`plenodecode.render.fourier` on first use)."""
    from .fourier import fourier_slice

    return fourier_slice(lf, slopes, **kw)


#: Refocusing methods: name -> ``fn(lf, slopes, *, aperture, upsample, progress, **kw) -> (S, Y', X', C)``.
REFOCUS_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "shift-sum": shift_sum,
    "fourier-slice": _fourier_slice,
}


def get_method(method: str) -> Callable[..., np.ndarray]:
    """The function of a refocus method; ValueError listing the valid names otherwise."""
    try:
        return REFOCUS_METHODS[method]
    except (KeyError, TypeError):
        raise ValueError(f"method must be one of {', '.join(REFOCUS_METHODS)}, got {method!r}") from None


def split_constants(kw: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Split keywords into refocus constants (:data:`REFOCUS_CONSTANTS`) and the rest."""
    const = {k: v for k, v in kw.items() if k in REFOCUS_CONSTANTS}
    return const, {k: v for k, v in kw.items() if k not in REFOCUS_CONSTANTS}


def refocus(lf: LightField, *, slope: float | None = None, alpha: float | None = None, method: str = "shift-sum",
            aperture: float | np.ndarray = 1.0, upsample: int = 1,
            progress: Callable[[int, int], None] | None = None, **kw: Any) -> np.ndarray:
    """Refocus a light field at a slope or at Ng's relative film depth alpha.

    Parameters
    ----------
    lf : LightField
        ``data`` (V, U, Y, X, C) float32; the photograph is weight-normalised when ``lf.weight`` is set.
    slope : float, optional
        Spatial samples per view step (design.md); a surface of disparity ``d`` is sharp at ``slope = d``.
    alpha : float, optional
        Relative film depth (Ng 2005); converted by :func:`alpha_to_slope` with the camera constants of ``lf``
        (keywords ``focal_length_m``, ``f_number``, ``lens_pitch_m``, ``spatial_step_px``, ``view_step_px``
        override them).  Exactly one of ``slope`` and ``alpha``.
    method : str
        A key of :data:`REFOCUS_METHODS`: 'shift-sum' (direct, bicubic by default) or 'fourier-slice' (Ng 2005;
        the first call computes and caches a 4D transform, several seconds for a full-size light field, after
        which each photograph is cheap: worth it for many photographs of one light field).
    aperture : float or ndarray (V, U)
        Synthetic aperture: a radius in (0, 1] (1 = all views) or a mask over the views (:func:`aperture_mask`).
    upsample : int
        Spatial upsampling factor.
    progress : callable(done, total), optional
    **kw
        Refocus constants, then method options (shift-sum: ``interp``; fourier-slice: ``oversample``,
        ``kernel_width``, ``pad``).

    Returns
    -------
    ndarray, shape (upsample Y, upsample X, C), float32
    """
    check_lightfield(lf)
    if (slope is None) == (alpha is None):
        raise ValueError("pass exactly one of slope and alpha")
    const, opts = split_constants(kw)
    if alpha is not None:
        slope = alpha_to_slope(float(alpha), lf, **const)
    elif const:
        raise ValueError(f"camera constants {sorted(const)} only apply with alpha")
    fn = get_method(method)
    return fn(lf, float(slope), aperture=aperture, upsample=upsample, progress=progress, **opts)[0]
