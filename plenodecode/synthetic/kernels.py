"""Compiled (numba) kernels of the forward model: the radiance along a ray through the scene
planes, its mean over a pixel box, and a band of sensor rows.

They are kept in one module on purpose: numba's on-disk cache of a kernel is invalidated only
when the kernel's own file changes, so a kernel that inlines another (``_ray`` into both public
kernels) must live in the same file.  The pure-numpy counterparts and the documented models are
:func:`plenodecode.synthetic.scene.box_radiance`, :func:`plenodecode.synthetic.lattice.assign_pixels`,
:func:`plenodecode.synthetic.sensor.disk_response` and :func:`plenodecode.synthetic.sensor.vignetting`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .._numba import njit

#: Sub-sample offsets (px, in the lattice frame) of the rule that averages over a pixel box:
#: 2 x 2 Gauss-Legendre points, exact for polynomials up to degree 3 per axis.  The kernels
#: take it as their ``sub`` argument.
SUBSAMPLES = np.array([-0.5 / math.sqrt(3.0), 0.5 / math.sqrt(3.0)])


@njit(cache=True, inline="always")
def _bilinear(tex, k, c, py, px, y0, x0, scale):
    hr = tex.shape[2]
    wr = tex.shape[3]
    fy = (py - y0) * scale
    fx = (px - x0) * scale
    fy = min(max(fy, 0.0), hr - 1.0)
    fx = min(max(fx, 0.0), wr - 1.0)
    iy = min(int(fy), hr - 2)
    ix = min(int(fx), wr - 2)
    wy = fy - iy
    wx = fx - ix
    top = tex[k, c, iy, ix] * (1.0 - wx) + tex[k, c, iy, ix + 1] * wx
    bot = tex[k, c, iy + 1, ix] * (1.0 - wx) + tex[k, c, iy + 1, ix + 1] * wx
    return top * (1.0 - wy) + bot * wy


@njit(cache=True, inline="always")
def _coverage(kd, prm, k, py, px, width):
    """Alpha of plane k's support at texture point (py, px): smoothstep of the signed distance."""
    if kd == 0:
        return 1.0
    if kd == 1:
        dy = max(prm[k, 0] - py, py - prm[k, 2])
        dx = max(prm[k, 1] - px, px - prm[k, 3])
        if dy > 0.0 and dx > 0.0:
            sd = math.sqrt(dy * dy + dx * dx)
        else:
            sd = max(dy, dx)
    else:
        sd = math.sqrt((py - prm[k, 0]) ** 2 + (px - prm[k, 1]) ** 2) - prm[k, 2]
    t = 0.5 - sd / width
    if t <= 0.0:
        return 0.0
    if t >= 1.0:
        return 1.0
    return t * t * (3.0 - 2.0 * t)


@njit(cache=True, inline="always")
def _ray(y, x, a, b, c, tex, y0, x0, scale, d0, gy, gx, kind, prm, width):
    """Radiance of channel c along the ray of lattice offset (a, b) at decoded (y, x).

    Planes are composited front to back with their support coverage as alpha.
    """
    acc = 0.0
    trans = 1.0
    for k in range(d0.size):
        qy = y + d0[k] * a
        qx = x + d0[k] * b
        go = gy[k] * a + gx[k] * b
        t = (gy[k] * qy + gx[k] * qx) / (1.0 - go)
        py = qy + a * t
        px = qx + b * t
        alpha = _coverage(kind[k], prm, k, py, px, width)
        if alpha > 0.0:
            acc += trans * alpha * _bilinear(tex, k, c, py, px, y0, x0, scale)
            trans *= 1.0 - alpha
            if trans <= 0.0:
                break
    return acc


@njit(parallel=True, cache=True)
def box_radiance_kernel(y, x, oa, ob, ch, sub, tex, y0, x0, scale, d0, gy, gx, kind, prm, width, out):
    """Mean radiance over the box in o (product rule ``sub`` x ``sub``) of each ray (flat arrays)."""
    n = y.size
    m = sub.size
    norm = 1.0 / (m * m)
    for i in numba.prange(n):
        acc = 0.0
        for si in range(m):
            for sj in range(m):
                acc += _ray(y[i], x[i], oa[i] + sub[si], ob[i] + sub[sj], ch[i], tex, y0, x0, scale,
                            d0, gy, gx, kind, prm, width)
        out[i] = acc * norm


@njit(cache=True, inline="always")
def _disk(r, radius, edge, falloff):
    t = (r - (radius - 0.5 * edge)) / edge
    if t <= 0.0:
        e = 1.0
    elif t >= 1.0:
        return 0.0
    else:
        e = 0.5 * (1.0 + math.cos(math.pi * t))
    f = 1.0 - falloff * (r / radius) ** 2
    return max(f, 0.0) * e


@njit(parallel=True, cache=True)
def sensor_band_kernel(r0, out, origin_r, origin_c, cos_t, sin_t, pitch, rs, shift, hexagonal, a0, b0, step,
                 radius, edge, falloff, sub, vig_cy, vig_cx, vig_k, exposure, chmap,
                 with_scene, tex, y0, x0, scale, d0, gy, gx, kind, prm, width):
    """Signal (fraction of the black..white range) of sensor rows r0 .. r0 + out.shape[0].

    The compiled twin of ``assign_pixels`` + ``disk_response`` + ``vignetting`` (+ the box
    radiance of the pixel's CFA channel when ``with_scene``) of :mod:`plenodecode.synthetic.sensor`.
    """
    h, w = out.shape
    m = sub.size
    norm = 1.0 / (m * m)
    reach = math.sqrt(2.0) * np.abs(sub).max()
    sub2 = 2.0 * np.mean(sub * sub)
    for rr in numba.prange(h):
        row = r0 + rr
        pr = row - origin_r
        for col in range(w):
            pc = col - origin_c
            a = pr * cos_t - pc * sin_t
            b = pr * sin_t + pc * cos_t
            if hexagonal:
                i_lo = math.floor(a / rs)
                best = 1e300
                bi = 0.0
                bj = 0.0
                for di in range(2):
                    ic = i_lo + di
                    bs = shift * pitch * (ic - 2.0 * math.floor(ic / 2.0))
                    jc = np.rint((b - bs) / pitch)
                    da = a - ic * rs
                    db = b - jc * pitch - bs
                    d2 = da * da + db * db
                    if d2 < best:
                        best = d2
                        bi = ic
                        bj = jc
                i = bi
                j = bj
            else:
                i = np.rint(a / rs)
                j = np.rint(b / pitch)
            ak = i * rs
            bk = j * pitch + shift * pitch * (i - 2.0 * math.floor(i / 2.0))
            oa = a - ak
            ob = b - bk
            r_c = math.hypot(oa, ob)
            if r_c >= radius + 0.5 * edge + reach:
                dsk = 0.0
            elif r_c + reach <= radius - 0.5 * edge:
                # every sub-sample on the flat part: the mean of r^2 over the rule is r_c^2 + 2 * E[sub^2]
                dsk = 1.0 - falloff * (r_c * r_c + sub2) / (radius * radius)
            else:
                dsk = 0.0
                for si in range(m):
                    for sj in range(m):
                        dsk += _disk(math.hypot(oa + sub[si], ob + sub[sj]), radius, edge, falloff)
                dsk *= norm
            rho2 = (row - vig_cy) ** 2 + (col - vig_cx) ** 2
            sig = exposure * dsk / (1.0 + vig_k * rho2) ** 2
            if with_scene and sig > 0.0:
                y = (ak - a0) / step
                x = (bk - b0) / step
                c = chmap[row % 2, col % 2]
                acc = 0.0
                for si in range(m):
                    for sj in range(m):
                        acc += _ray(y, x, oa + sub[si], ob + sub[sj], c, tex, y0, x0, scale, d0, gy, gx, kind,
                                    prm, width)
                sig *= acc * norm
            out[rr, col] = sig


@njit(cache=True, inline="always")
def _board_point(n0, n1, n2, n3, h, distortion, rot, trans, square):
    """Board-frame point ``(x_b, y_b) / square`` hit by the ray of sample ``(n0, n1, n2, n3)``; NaN for a miss."""
    k1, k2, k3, b1, b2 = distortion[0], distortion[1], distortion[2], distortion[3], distortion[4]
    s = h[0, 0] * n0 + h[0, 1] * n1 + h[0, 2] * n2 + h[0, 3] * n3 + h[0, 4]
    t = h[1, 0] * n0 + h[1, 1] * n1 + h[1, 2] * n2 + h[1, 3] * n3 + h[1, 4]
    cu = h[2, 0] * n0 + h[2, 1] * n1 + h[2, 2] * n2 + h[2, 3] * n3 + h[2, 4] - b1
    cv = h[3, 0] * n0 + h[3, 1] * n1 + h[3, 2] * n2 + h[3, 3] * n3 + h[3, 4] - b2
    r2 = cu * cu + cv * cv
    f = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    du = f * cu + b1
    dv = f * cv + b2
    along = du * rot[0, 2] + dv * rot[1, 2] + rot[2, 2]
    if abs(along) <= 1e-12:
        return math.nan, math.nan
    z = ((trans[0] - s) * rot[0, 2] + (trans[1] - t) * rot[1, 2] + trans[2] * rot[2, 2]) / along
    if not z > 0.0:
        return math.nan, math.nan
    hx = s + z * du - trans[0]
    hy = t + z * dv - trans[1]
    hz = z - trans[2]
    return ((hx * rot[0, 0] + hy * rot[1, 0] + hz * rot[2, 0]) / square,
            (hx * rot[0, 1] + hy * rot[1, 1] + hz * rot[2, 1]) / square)


@njit(cache=True, inline="always")
def _board_level(x, y, rows, cols, margin, levels):
    """Radiance at board point ``(x, y)`` (in squares): dark / light square, light margin, grey beyond."""
    if not (-1.0 - margin <= x < cols + margin and -1.0 - margin <= y < rows + margin):
        return levels[2]
    if -1.0 <= x < cols and -1.0 <= y < rows and (math.floor(x) + math.floor(y)) % 2 == 0:
        return levels[0]
    return levels[1]


@njit(parallel=True, cache=True)
def board_radiance_kernel(samples, offsets, h, distortion, rot, trans, rows, cols, square, margin, levels, out):
    """Mean checkerboard radiance over each sample's footprint: the compiled twin of
    :func:`plenodecode.synthetic.checkerboard.board_radiance_numpy` (samples (N, 4), offsets (M, 4),
    ``H`` (5, 5), distortion (5,), board rotation (3, 3) and translation (3,), levels (dark, light, grey),
    an integer ``margin``).

    Shortcut: the radiance is constant on every unit cell ``(floor x, floor y)`` of the board plane (square
    boundaries, margin and outline are on integer lines).  The footprint's hit points lie within
    ``e = 1.25 sum_c |P(n + w_c e_c) - P(n)|`` of the centre's ``P(n)`` (``w_c`` the largest offset along
    sample axis ``c``: the map is near-affine over one footprint, 1.25 covers its curvature); when that box
    stays inside one cell, the mean is that cell's level and the sub-samples are skipped.
    """
    n = samples.shape[0]
    m = offsets.shape[0]
    reach = np.empty(4)
    for c in range(4):
        reach[c] = max(abs(offsets[:, c].min()), abs(offsets[:, c].max()))
    for p in numba.prange(n):
        n0, n1, n2, n3 = samples[p, 0], samples[p, 1], samples[p, 2], samples[p, 3]
        x0, y0 = _board_point(n0, n1, n2, n3, h, distortion, rot, trans, square)
        if math.isfinite(x0):
            ex = 0.0
            ey = 0.0
            for c in range(4):
                x, y = _board_point(n0 + (reach[0] if c == 0 else 0.0), n1 + (reach[1] if c == 1 else 0.0),
                                    n2 + (reach[2] if c == 2 else 0.0), n3 + (reach[3] if c == 3 else 0.0),
                                    h, distortion, rot, trans, square)
                ex += abs(x - x0)
                ey += abs(y - y0)
            ex *= 1.25
            ey *= 1.25
            if (math.isfinite(ex) and math.isfinite(ey) and math.floor(x0 - ex) == math.floor(x0 + ex)
                    and math.floor(y0 - ey) == math.floor(y0 + ey)):
                out[p] = _board_level(x0, y0, rows, cols, margin, levels)
                continue
        acc = 0.0
        for q in range(m):
            x, y = _board_point(samples[p, 0] + offsets[q, 0], samples[p, 1] + offsets[q, 1],
                                samples[p, 2] + offsets[q, 2], samples[p, 3] + offsets[q, 3],
                                h, distortion, rot, trans, square)
            acc += _board_level(x, y, rows, cols, margin, levels) if math.isfinite(x) else levels[2]
        out[p] = acc / m

__all__ = ["SUBSAMPLES", "box_radiance_kernel", "sensor_band_kernel", "board_radiance_kernel"]
