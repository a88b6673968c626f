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
def _box_distance(y0, x0, y1, x1, py, px):
    """Signed distance of (py, px) to the box y0 <= y <= y1, x0 <= x <= x1 (Euclidean outside a corner)."""
    dy = max(y0 - py, py - y1)
    dx = max(x0 - px, px - x1)
    if dy > 0.0 and dx > 0.0:
        return math.sqrt(dy * dy + dx * dx)
    return max(dy, dx)


@njit(cache=True, inline="always")
def _coverage(kd, prm, k, py, px, width):
    """Alpha of plane k's support at texture point (py, px): smoothstep of the signed distance over the
    rim width[k]; a hard step when width[k] is 0.  Stripes: see ``scene.stripes_signed_distance``."""
    if kd == 0:
        return 1.0
    if kd == 1:
        sd = _box_distance(prm[k, 0], prm[k, 1], prm[k, 2], prm[k, 3], py, px)
    elif kd == 2:
        sd = math.sqrt((py - prm[k, 0]) ** 2 + (px - prm[k, 1]) ** 2) - prm[k, 2]
    else:
        c = py * prm[k, 0] + px * prm[k, 1] - prm[k, 4] - 0.5 * prm[k, 2]
        r = c - prm[k, 3] * math.floor(c / prm[k, 3] + 0.5)
        sd = max(abs(r) - 0.5 * prm[k, 2], _box_distance(prm[k, 5], prm[k, 6], prm[k, 7], prm[k, 8], py, px))
    if width[k] <= 0.0:
        return 1.0 if sd < 0.0 else (0.5 if sd == 0.0 else 0.0)
    t = 0.5 - sd / width[k]
    if t <= 0.0:
        return 0.0
    if t >= 1.0:
        return 1.0
    return t * t * (3.0 - 2.0 * t)


@njit(cache=True, inline="always")
def _ray(y, x, a, b, c, tex, y0, x0, scale, d0, gy, gx, kind, prm, width):
    """Radiance of channel c along the ray of lattice offset (a, b) at decoded (y, x).

    Planes are composited front to back with their support coverage as alpha; ``width`` (K,) holds each
    plane's rim.
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


__all__ = ["SUBSAMPLES", "box_radiance_kernel", "sensor_band_kernel"]
