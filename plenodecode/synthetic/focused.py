"""Focused plenoptic camera (plenoptic 2.0) for the 'raytrix' preset.

Model (Lumsdaine & Georgiev 2009; Perwass & Wietzke 2012, "Single lens 3D-camera with
extended depth-of-field"): the main lens forms a virtual image (VI) of the scene in front
of the micro-lens array; each micro-lens, at distance ``B`` from the sensor, re-images the
VI onto the sensor, inverted and reduced by the *virtual depth* ``v = a / B`` (``a`` the
distance of the VI point from the MLA).  The chief ray through lens ``k`` (centre ``c_k``,
sensor px) makes the pixel at sensor offset ``o`` from ``c_k`` see the VI point::

    X = c_k - v * o              (lateral VI position, sensor px)

Scene planes are given in texture units ``u = X / texel_px`` with ``Plane.d0`` (+ gradient)
the virtual depth ``v`` instead of a disparity, so the ray hits plane ``k`` where
``u = c_k / texel + v(u) * (-o / texel)``: the unfocused kernel with ``o -> -o / texel``.
Along a ray the surface nearest the MLA (smallest ``v``: the nearest object) is seen
first; planes are listed front-first by ``depth_order``.

Multi-focus MLA: three interleaved lens types (:func:`~plenodecode.synthetic.lattice.raytrix_lens_types`)
focused at virtual depths ``type_focus``.  A VI point at depth ``v`` seen through a lens
focused at ``v_f`` is blurred on the sensor by a disc of diameter ``D * |1/v - 1/v_f|``
(``D`` = lens pitch, px; thin-lens geometry), modelled as a Gaussian of sigma = diameter / 4
applied to the micro-image, with the lens's ``v`` taken along its central ray (one blur per
micro-image: an approximation at occlusion edges inside a micro-image).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping

import cv2
import numpy as np

from ..types import LensletGrid, RawCapture, cfa_channel_map
from .lattice import assign_pixels, lens_types_at
from .scene import Plane, Scene, as_scene, box_radiance, build_textures, front_disparity
from .sensor import levels, render_sensor
from .truth import Simulation

#: Gaussian blur levels (px) between which the per-lens blur is interpolated.
BLUR_LEVELS = np.array([0.0, 0.35, 0.7, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0])


def default_focused_scene(h: int, w: int, texel: float, seed: int = 0) -> Scene:
    """Background at v = 5.0, a slanted plane v 2.6 -> 3.8 (left to right), a front disk at v = 2.2.

    Coordinates in texture units (``sensor px / texel``) of the VI over an (h, w) sensor.
    """
    ny, nx = h / texel, w / texel
    y0, y1 = 0.15 * ny, 0.85 * ny
    x0, x1 = 0.08 * nx, 0.5 * nx
    slope = 1.2 / (x1 - x0)
    s = int(seed) * 16
    return Scene(name="default-focused", planes=(
        Plane(d0=5.0, support=("all",), depth_order=2, texture_seed=s + 0),
        Plane(d0=2.6 - slope * x0, gradient=(0.0, slope), support=("rect", y0, x0, y1, x1), depth_order=1,
              texture_seed=s + 1),
        Plane(d0=2.2, support=("disk", 0.5 * ny, 0.72 * nx, 0.2 * min(ny, nx)), depth_order=0, texture_seed=s + 2),
    ))


def simulate_focused(p, grid: LensletGrid, offset, *, seed: int, rngs: Mapping[str, Any] | None, scene,
                     metadata: Callable[[bool], Any], progress=None):
    """Focused-plenoptic raw + white + truth (see the module docstring); returns a Simulation."""
    h, w = grid.sensor_shape
    texel = float(p.texel_px)
    sc = default_focused_scene(h, w, texel, seed) if scene is None else as_scene(scene)
    vmax = max(abs(pl.d0) + abs(pl.gradient[0]) * h / texel + abs(pl.gradient[1]) * w / texel for pl in sc.planes)
    margin = (grid.pitch / 2 + 2) * vmax / texel + 4
    n_y, n_x = int(math.ceil(h / texel)) + 1, int(math.ceil(w / texel)) + 1
    tex = build_textures(sc, n_y, n_x, mono=p.mono, cam_matrix=p.camera_matrix(), margin=margin)
    n_ch = tex.camera.shape[1]

    rr, cc = np.meshgrid(np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64), indexing="ij")
    lens = assign_pixels(grid, rr, cc)
    ak = lens.i * grid.row_spacing
    bk = lens.j * grid.pitch + grid.odd_row_shift * grid.pitch * np.mod(lens.i, 2)
    ck = grid.lattice_to_sensor(ak, bk)                     # (H, W, 2) lens centre of each pixel
    o_r, o_c = rr - ck[..., 0], cc - ck[..., 1]
    uy, ux = ck[..., 0] / texel, ck[..., 1] / texel
    # virtual depth along each lens's central ray, and its blur for the lens's type
    v_lens = front_disparity(tex, uy, ux).astype(np.float64)
    focus = np.asarray(p.type_focus, np.float64)[lens_types_at(grid, lens.i, lens.j)]
    sigma = grid.pitch * np.abs(1.0 / v_lens - 1.0 / focus) / 4.0
    sigma = np.clip(np.nan_to_num(sigma, nan=0.0), 0.0, BLUR_LEVELS[-1])
    k = np.clip(np.searchsorted(BLUR_LEVELS, sigma, side="right") - 1, 0, BLUR_LEVELS.size - 2)
    t = (sigma - BLUR_LEVELS[k]) / (BLUR_LEVELS[k + 1] - BLUR_LEVELS[k])
    radiance = np.empty((n_ch, h, w))
    for c in range(n_ch):
        sharp = box_radiance(tex, uy, ux, -o_r / texel, -o_c / texel, c, space="camera", box=1.0 / texel)
        stack = [sharp] + [cv2.GaussianBlur(sharp, (0, 0), s, borderType=cv2.BORDER_REFLECT) for s in BLUR_LEVELS[1:]]
        stack = np.stack(stack)
        lo = np.take_along_axis(stack, k[None], 0)[0]
        hi = np.take_along_axis(stack, (k + 1)[None], 0)[0]
        radiance[c] = lo * (1 - t) + hi * t
    if p.cfa is None:
        gain = radiance[0]
    else:
        chan = cfa_channel_map(p.cfa)[np.arange(h)[:, None] % 2, np.arange(w)[None, :] % 2]
        gain = np.take_along_axis(radiance, chan[None].astype(np.int64), 0)[0]

    noise = rngs is not None
    mosaic = render_sensor(grid, p, None, rngs["raw"] if noise else None, progress, gain=gain)
    white_m = render_sensor(grid, p, None, rngs["white"] if noise else None, None)
    black, white = levels(p)
    raw = RawCapture(mosaic=mosaic, cfa=p.cfa, black=black, white=white, metadata=metadata(False))
    wcap = RawCapture(mosaic=white_m, cfa=p.cfa, black=black, white=white, metadata=metadata(True))

    # truth on the VI grid at one sample per sensor px (X = pixel position)
    vy, vx = rr / texel, cc / texel
    vdepth = front_disparity(tex, vy, vx)
    total = np.stack([box_radiance(tex, vy, vx, 0.0, 0.0, c, space="srgb", box=0.0) for c in range(n_ch)], -1)
    centres = grid.centres_2d()
    lens_v = front_disparity(tex, centres[..., 0] / texel, centres[..., 1] / texel)
    truth = {
        "lens_type": grid.lens_type, "lens_virtual_depth": lens_v.astype(np.float32),
        "virtual_depth": vdepth.astype(np.float32), "total_focus": total.astype(np.float32),
        "type_focus": np.asarray(p.type_focus, np.float64), "texel_px": np.float64(texel),
        "blur_sigma": sigma.astype(np.float32),
    }
    disparity = (grid.pitch / vdepth).astype(np.float32)
    return Simulation(raw=raw, white=wcap, grid=grid, disparity=disparity, scene=sc, preset=p, seed=int(seed),
                      noise=noise, truth=truth, textures=tex)


__all__ = ["BLUR_LEVELS", "default_focused_scene", "simulate_focused"]
