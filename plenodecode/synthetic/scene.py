"""Scenes of the synthetic generator: textured planes with (slanted) disparity, rasterised
textures, and the radiance along the rays of the forward model.

A scene is a list of :class:`Plane` s in decoded light-field coordinates ``(y, x)``
(decoded spatial samples, see :meth:`plenodecode.types.LensletGrid.decoded_sampling`).
Plane ``k`` has the disparity ``d_k(P) = d0 + gy * P_y + gx * P_x`` (decoded px per view
step, HCI convention) at its texture point ``P``; the ray of angular offset ``o`` at spatial
sample ``p`` hits it at ``P = p + d_k(P) * o``, i.e. (a 2 x 2 linear system, solved in
closed form by Sherman-Morrison)::

    q = p + d0 * o,     P = q + o * (g . q) / (1 - g . o)

The visible plane is the front-most (lowest ``depth_order``) whose support contains its
hit point; support rims are soft (alpha = smoothstep over the plane's ``rim``, by default
:data:`SUPPORT_EDGE` px, across the boundary, composited front to back), so occlusion edges are
band-limited like the textures.  The ground-truth disparity of a ray is that of the front-most plane
whose support *contains* its hit point (signed distance <= 0, i.e. coverage >= 0.5): a rim pixel takes
the side of the boundary its centre lies on.

Textures are band-limited random colour fields in linear sRGB: low-pass colour noise
(Gaussian, sigma 2.5 decoded px), smooth colour ramps and straight edges blurred by a
Gaussian of 1.2 px, desaturated where needed so camera RGB stays in [0.01, 1.15].  They live
on a raster with ``OVERSAMPLE`` samples per decoded pixel read by bilinear interpolation:
this interpolant *is* the texture, so the raw and the ground truth agree exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import cv2
import numpy as np
from scipy import ndimage
from scipy.special import erf

from .kernels import SUBSAMPLES, box_radiance_kernel

#: Raster samples per decoded pixel of the texture interpolant.
OVERSAMPLE = 4
#: Margin (decoded px) of the texture raster around the decoded field; hit points beyond
#: it read the raster's edge.
MARGIN = 12.0
#: Rec. 709 / sRGB luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])

SUPPORT_KINDS = {"all": 0, "rect": 1, "disk": 2, "stripes": 3}
#: Numbers each support kind takes (stripes: 4, or 8 with a bounding box).
_SUPPORT_SIZES = {"all": (0,), "rect": (4,), "disk": (3,), "stripes": (4, 8)}
#: Default width (decoded px) of the soft rim of a plane's support: coverage (alpha) is the
#: smoothstep of ``0.5 - signed_distance / rim``; 0.5 on the support's boundary.
SUPPORT_EDGE = 2.0
#: Columns of :attr:`Textures.prm`: a stripes support stores (cos, sin, width, period, phase, y0, x0, y1, x1).
_PRM_COLUMNS = 9
#: Half-size of the bounding box of a stripes support given without one (unbounded in practice).
_UNBOUNDED = 1e9


@dataclass(frozen=True)
class Plane:
    """One textured scene plane.

    Attributes
    ----------
    d0 : float
        Disparity at decoded ``(y, x) = (0, 0)`` (px per view step).
    gradient : (float, float)
        ``(dd/dy, dd/dx)`` per decoded pixel; non-zero for a slanted plane.
    support : tuple
        ``('all',)``, ``('rect', y0, x0, y1, x1)`` (``y0 <= y <= y1``, ``x0 <= x <= x1``),
        ``('disk', cy, cx, r)`` or ``('stripes', angle, width, period, phase[, y0, x0, y1, x1])``, in
        decoded coordinates of the texture point.  Stripes are parallel slats at ``angle`` degrees from
        the image rows (0: horizontal slats, 90: vertical); with the across coordinate
        ``u = y cos(angle) + x sin(angle)``, slat ``m`` (any integer) covers
        ``phase + m period <= u <= phase + m period + width``, optionally only inside the box
        ``y0 <= y <= y1``, ``x0 <= x <= x1``.  The rim is soft: coverage 0.5 on the boundary, 1 from
        ``rim / 2`` inside it.
    depth_order : int
        0 is the front-most; ties keep the list order.
    texture_seed : int
        Seed of the random texture.
    colour : (r, g, b) or None
        A constant linear-sRGB colour instead of a random texture (any values; negative
        camera values are clipped by the sensor).
    rim : float
        Width (decoded px) of the soft rim of the support, >= 0; 0 is a hard edge (coverage 1 inside,
        0 outside).  Thin structures (1 px slats) need a rim below 1 px.
    contrast : float
        Scale of the random texture about its mean colour, in (0, 1]: below 1 a weakly textured plane.
    """

    d0: float
    gradient: tuple[float, float] = (0.0, 0.0)
    support: tuple = ("all",)
    depth_order: int = 0
    texture_seed: int = 0
    colour: tuple[float, float, float] | None = None
    rim: float = SUPPORT_EDGE
    contrast: float = 1.0

    def __post_init__(self) -> None:
        sup = tuple(self.support)
        if not sup or sup[0] not in SUPPORT_KINDS:
            raise ValueError(f"support must start with one of {sorted(SUPPORT_KINDS)}, got {self.support!r}")
        sizes = _SUPPORT_SIZES[sup[0]]
        if len(sup) - 1 not in sizes:
            raise ValueError(f"support {sup[0]!r} takes {' or '.join(map(str, sizes))} numbers, got {sup!r}")
        if sup[0] == "stripes" and not (float(sup[3]) > float(sup[2]) > 0):
            raise ValueError(f"stripes support needs 0 < width < period, got {sup!r}")
        object.__setattr__(self, "support", (sup[0], *(float(v) for v in sup[1:])))
        if not (math.isfinite(self.rim) and self.rim >= 0):
            raise ValueError(f"rim must be a finite number >= 0, got {self.rim!r}")
        if not (0 < self.contrast <= 1):
            raise ValueError(f"contrast must be in (0, 1], got {self.contrast!r}")
        object.__setattr__(self, "rim", float(self.rim))
        object.__setattr__(self, "contrast", float(self.contrast))
        object.__setattr__(self, "gradient", (float(self.gradient[0]), float(self.gradient[1])))
        if self.colour is not None:
            object.__setattr__(self, "colour", tuple(float(c) for c in self.colour))

    def disparity_at(self, y: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Disparity of the plane at texture point ``(y, x)``."""
        return self.d0 + self.gradient[0] * np.asarray(y) + self.gradient[1] * np.asarray(x)

    def to_dict(self) -> dict[str, Any]:
        """The plane as a JSON-able dict; ``rim`` and ``contrast`` only when not the defaults (so older
        truth documents stay the same)."""
        d = {"d0": self.d0, "gradient": list(self.gradient), "support": list(self.support),
             "depth_order": self.depth_order, "texture_seed": self.texture_seed,
             "colour": None if self.colour is None else list(self.colour)}
        if self.rim != SUPPORT_EDGE:
            d["rim"] = self.rim
        if self.contrast != 1.0:
            d["contrast"] = self.contrast
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Plane":
        return cls(d0=float(d["d0"]), gradient=tuple(d.get("gradient", (0.0, 0.0))),
                   support=tuple(d.get("support", ("all",))), depth_order=int(d.get("depth_order", 0)),
                   texture_seed=int(d.get("texture_seed", 0)),
                   colour=None if d.get("colour") is None else tuple(d["colour"]),
                   rim=float(d.get("rim", SUPPORT_EDGE)), contrast=float(d.get("contrast", 1.0)))


@dataclass(frozen=True)
class Scene:
    """A list of planes (see :class:`Plane`) and a name."""

    planes: tuple[Plane, ...]
    name: str = "custom"

    def __post_init__(self) -> None:
        planes = tuple(self.planes)
        if not planes or not all(isinstance(p, Plane) for p in planes):
            raise ValueError("scene must hold at least one Plane")
        object.__setattr__(self, "planes", planes)

    def ordered(self) -> tuple[Plane, ...]:
        """Planes front to back (stable in list order)."""
        return tuple(sorted(self.planes, key=lambda p: p.depth_order))

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "planes": [p.to_dict() for p in self.planes]}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Scene":
        return cls(planes=tuple(Plane.from_dict(p) for p in d["planes"]), name=str(d.get("name", "custom")))


def as_scene(scene: Scene | Sequence[Plane] | Sequence[Mapping[str, Any]]) -> Scene:
    """Accept a Scene, a list of Planes or a list of plane dicts."""
    if isinstance(scene, Scene):
        return scene
    try:
        planes = tuple(p if isinstance(p, Plane) else Plane.from_dict(p) for p in scene)
    except (TypeError, KeyError) as exc:
        raise ValueError(f"scene must be a Scene or a list of planes, got {type(scene).__name__}: {exc}") from None
    return Scene(planes)


def default_scene(n_y: int, n_x: int, seed: int = 0) -> Scene:
    """Background (d = -0.5), a slanted plane (d 0.0 -> 0.6 left to right), a front disk (d = 0.9).

    Parameters
    ----------
    n_y, n_x : int
        Decoded field size ``(Y, X)``; the layout scales with it.
    seed : int
        Texture seeds are ``seed * 16 + k``.
    """
    y0, y1 = 0.14 * n_y, 0.86 * n_y
    x0, x1 = 0.06 * n_x, 0.52 * n_x
    slope = 0.6 / (x1 - x0)
    r = 0.2 * min(n_y, n_x)
    s = int(seed) * 16
    return Scene(name="default", planes=(
        Plane(d0=-0.5, support=("all",), depth_order=2, texture_seed=s + 0),
        Plane(d0=-slope * x0, gradient=(0.0, slope), support=("rect", y0, x0, y1, x1), depth_order=1,
              texture_seed=s + 1),
        Plane(d0=0.9, support=("disk", 0.5 * n_y, 0.72 * n_x, r), depth_order=0, texture_seed=s + 2),
    ))



def dot_chart(n_y: int, n_x: int, d: float = 0.0, *, seed: int = 0, density: float = 0.02) -> Scene:
    """A fronto-parallel chart at disparity ``d``: a textured plane under many small flat-coloured disks.

    The disks (radius 0.7 - 3 decoded px, random linear-sRGB colours in [0.05, 0.9]) have the soft rims of
    :data:`SUPPORT_EDGE`, whose spectrum reaches past the lenslet Nyquist frequency (about 30 % of the step at
    0.5 cycles/px, 8 % at 1 cycle/px), unlike the smooth random textures: a scene for resolution tests
    (super-resolved refocusing).  Every plane has disparity ``d``, so the photograph refocused at ``d`` is the
    centre view (:meth:`plenodecode.synthetic.Simulation.ground_truth_photograph`).

    Parameters
    ----------
    n_y, n_x : int
        Decoded field size ``(Y, X)``.
    d : float
        Disparity of the chart (px per view step).
    seed : int
        Seed of the layout and colours; the background texture seed is ``seed * 16``.
    density : float
        Disks per decoded pixel of the field.
    """
    rng = np.random.default_rng(seed)
    n = max(1, int(round(density * n_y * n_x)))
    cy = rng.uniform(-2.0, n_y + 1.0, n)
    cx = rng.uniform(-2.0, n_x + 1.0, n)
    r = rng.uniform(0.7, 3.0, n)
    col = rng.uniform(0.05, 0.9, (n, 3))
    disks = tuple(Plane(d0=float(d), support=("disk", cy[i], cx[i], r[i]), depth_order=0, colour=tuple(col[i]))
                  for i in range(n))
    return Scene(name="dot-chart", planes=(*disks, Plane(d0=float(d), depth_order=1, texture_seed=int(seed) * 16)))

# ---------------------------------------------------------------------------------------
# textures
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Textures:
    """Rasterised scene, ready for the kernels.

    Attributes
    ----------
    srgb : ndarray (K, C, Hr, Wr) float32
        Linear-sRGB texture of each plane in front-to-back order (C = 3, or 1 for mono).
    camera : ndarray (K, C, Hr, Wr) float32
        The same in camera RGB, ``M @ srgb`` with ``M = diag(1/wb) @ inv(ccm)``.
    y0, x0, scale : float
        Raster sample ``(r, c)`` sits at decoded ``(y0 + r / scale, x0 + c / scale)``.
    d0, gy, gx : ndarray (K,) float64
    kind : ndarray (K,) int64
        Support kind (0 all, 1 rect, 2 disk, 3 stripes); ``prm`` (K, 9) float64 its numbers (rect, disk:
        as in the support; stripes: cos, sin of the angle, width, period, phase, bounding box).
    rim : ndarray (K,) float64
        Width of each plane's soft rim (px).
    """

    srgb: np.ndarray
    camera: np.ndarray
    y0: float
    x0: float
    scale: float
    d0: np.ndarray
    gy: np.ndarray
    gx: np.ndarray
    kind: np.ndarray
    prm: np.ndarray
    rim: np.ndarray
    planes: tuple[Plane, ...] = field(default=())


def _random_texture(plane: Plane, ny: int, nx: int, y_min: float, x_min: float, mono: bool,
                    cam_matrix: np.ndarray) -> np.ndarray:
    """Linear-sRGB raster (C, ny, nx) float32 of one plane (see module docstring)."""
    channels = 1 if mono else 3
    if plane.colour is not None:
        col = np.asarray(plane.colour, np.float64)
        val = np.array([col @ LUMA]) if mono else col
        return np.broadcast_to(val[:, None, None], (channels, ny, nx)).astype(np.float32)
    rng = np.random.default_rng(plane.texture_seed)
    s = OVERSAMPLE
    # band-limited colour noise: white noise at one sample per decoded px, Gaussian
    # low-pass (sigma 2.5 px), normalised, cubic-upsampled to the raster
    cy, cx = ny // s + 4, nx // s + 4
    noise = rng.standard_normal((cy, cx, 3)).astype(np.float32)
    noise = ndimage.gaussian_filter(noise, sigma=(2.5, 2.5, 0), mode="wrap")
    noise /= noise.std(axis=(0, 1), keepdims=True)
    up = cv2.resize(noise, (cx * s, cy * s), interpolation=cv2.INTER_CUBIC)[:ny, :nx]
    yy = (y_min + np.arange(ny, dtype=np.float32) / s)[:, None]
    xx = (x_min + np.arange(nx, dtype=np.float32) / s)[None, :]
    span = max(ny, nx) / s
    base = rng.uniform(0.25, 0.55, 3)
    lum_noise = 0.10 * up[..., 0]
    img = np.empty((3, ny, nx), np.float32)
    ramps = rng.uniform(-0.15, 0.15, (3, 2)) / span
    # a few straight edges blurred by a Gaussian of 1.2 px (erf profile), random colours
    edges = []
    for _ in range(3):
        ang = rng.uniform(0, np.pi)
        n = np.array([np.cos(ang), np.sin(ang)], np.float32)
        c = rng.uniform(0.2, 0.8, 2) * [ny / s, nx / s] + [y_min, x_min]
        dist = (yy - c[0]) * n[0] + (xx - c[1]) * n[1]
        step = (0.5 * (1.0 + erf(dist / (1.2 * math.sqrt(2.0))))).astype(np.float32)
        edges.append((step, rng.uniform(-0.12, 0.12, 3)))
    chromas = (0.06 * up[..., 1], -0.03 * (up[..., 1] + up[..., 2]), 0.06 * up[..., 2])
    for ch in range(3):
        chroma = chromas[ch]
        img[ch] = base[ch] + ramps[ch, 0] * (yy - y_min) + ramps[ch, 1] * (xx - x_min) + lum_noise + chroma
        for step, amp in edges:
            img[ch] += amp[ch] * step
    img = np.clip(img, 0.03, 0.9)
    if plane.contrast != 1.0:
        mean = img.mean(axis=(1, 2), keepdims=True)
        img = (mean + plane.contrast * (img - mean)).astype(np.float32)
    if mono:
        return (LUMA[0] * img[0] + LUMA[1] * img[1] + LUMA[2] * img[2])[None].astype(np.float32)
    return _into_gamut(img, cam_matrix).astype(np.float32)


def _into_gamut(img: np.ndarray, m: np.ndarray, lo: float = 0.01, hi: float = 1.15) -> np.ndarray:
    """Desaturate towards the luminance just enough that camera RGB ``m @ img`` is in [lo, hi].

    ``img`` (3, H, W) linear sRGB.  Grey maps to camera RGB ``m.sum(1) * lum`` (> 0), so
    along ``lum + t * (img - lum)`` each camera channel is linear in ``t``; the largest
    ``t <= 1`` that keeps all three in range is taken per pixel.
    """
    lum = LUMA[0] * img[0] + LUMA[1] * img[1] + LUMA[2] * img[2]
    cam = [m[i, 0] * img[0] + m[i, 1] * img[1] + m[i, 2] * img[2] for i in range(3)]
    bad = np.zeros(lum.shape, bool)
    for c in cam:
        bad |= (c < lo) | (c > hi)
    if not bad.any():
        return img
    lb = lum[bad]
    t = np.ones(lb.shape, img.dtype)
    for i in range(3):
        c = cam[i][bad]
        g = m[i].sum() * lb
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(c < lo, np.minimum(t, (lo - g) / (c - g)), t)
            t = np.where(c > hi, np.minimum(t, (hi - g) / (c - g)), t)
    out = img.copy()
    out[:, bad] = lb[None] + np.clip(t, 0.0, 1.0)[None] * (img[:, bad] - lb[None])
    return out


def build_textures(scene: Scene, n_y: int, n_x: int, *, mono: bool, cam_matrix: np.ndarray,
                   margin: float = MARGIN) -> Textures:
    """Rasterise every plane of a scene over the decoded field ``(Y, X)`` plus ``margin``.

    Returns
    -------
    Textures
    """
    planes = scene.ordered()
    s = OVERSAMPLE
    y_min, x_min = -margin, -margin
    ny = int(math.ceil((n_y - 1 + 2 * margin) * s)) + 1
    nx = int(math.ceil((n_x - 1 + 2 * margin) * s)) + 1
    srgb = np.stack([_random_texture(p, ny, nx, y_min, x_min, mono, cam_matrix) for p in planes])
    if mono:
        camera = srgb
    else:
        camera = np.einsum("ij,kjyx->kiyx", cam_matrix.astype(np.float32), srgb).astype(np.float32)
    prm = np.zeros((len(planes), _PRM_COLUMNS))
    for k, p in enumerate(planes):
        prm[k] = _support_numbers(p.support)
    return Textures(
        srgb=srgb, camera=np.ascontiguousarray(camera), y0=y_min, x0=x_min, scale=float(s),
        d0=np.array([p.d0 for p in planes]), gy=np.array([p.gradient[0] for p in planes]),
        gx=np.array([p.gradient[1] for p in planes]),
        kind=np.array([SUPPORT_KINDS[p.support[0]] for p in planes], np.int64), prm=prm,
        rim=np.array([p.rim for p in planes]), planes=planes,
    )


def _support_numbers(support: tuple) -> np.ndarray:
    """The :attr:`Textures.prm` row (9,) float64 of a support (see :class:`Textures`)."""
    row = np.zeros(_PRM_COLUMNS)
    if support[0] != "stripes":
        row[: len(support) - 1] = support[1:]
        return row
    angle, width, period, phase = support[1:5]
    box = support[5:] if len(support) > 5 else (-_UNBOUNDED, -_UNBOUNDED, _UNBOUNDED, _UNBOUNDED)
    # exact 0 / 1 for the axis-aligned angles, so horizontal and vertical slat edges fall where asked
    cos, sin = (0.0 if abs(v) < 1e-12 else v for v in (math.cos(math.radians(angle)), math.sin(math.radians(angle))))
    row[:] = (cos, sin, width, period, phase, *box)
    return row


def front_disparity(tex: Textures, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Disparity of the visible plane along the central ray (``o = 0``) at decoded ``(y, x)``.

    Returns
    -------
    ndarray, broadcast shape, float32 (NaN where no plane is hit)
    """
    y, x = np.broadcast_arrays(np.asarray(y, np.float64), np.asarray(x, np.float64))
    out = np.full(y.shape, np.nan)
    for k in range(tex.d0.size - 1, -1, -1):        # back to front: front planes overwrite
        inside = _inside_np(tex.kind[k], tex.prm[k], y, x)
        out = np.where(inside, tex.d0[k] + tex.gy[k] * y + tex.gx[k] * x, out)
    return out.astype(np.float32)


def _inside_np(kind: int, prm: np.ndarray, py: np.ndarray, px: np.ndarray) -> np.ndarray:
    """Whether texture points ``(py, px)`` lie in a support (signed distance <= 0: coverage >= 0.5)."""
    if kind == 0:
        return np.ones(py.shape, bool)
    if kind == 1:
        return (py >= prm[0]) & (py <= prm[2]) & (px >= prm[1]) & (px <= prm[3])
    if kind == 2:
        return (py - prm[0]) ** 2 + (px - prm[1]) ** 2 <= prm[2] ** 2
    return stripes_signed_distance(prm, py, px) <= 0.0


def stripes_signed_distance(prm: np.ndarray, py: np.ndarray, px: np.ndarray) -> np.ndarray:
    """Signed distance (px; < 0 inside) of points ``(py, px)`` to a stripes support, the model of the kernel.

    With ``u = py cos + px sin``, ``c = u - phase - width / 2`` and ``r = c - period * round(c / period)``
    (the offset from the nearest slat's centre line), the distance to the slats is ``|r| - width / 2``; the
    bounding box cuts them as a rect support does (``max`` of the two signed distances, Euclidean outside
    a corner).

    Parameters
    ----------
    prm : ndarray (9,) float64
        A :attr:`Textures.prm` row of a stripes support.
    py, px : ndarray, same shape, float64

    Returns
    -------
    ndarray, float64
    """
    cos, sin, width, period, phase, y0, x0, y1, x1 = prm
    c = py * cos + px * sin - phase - 0.5 * width
    r = c - period * np.floor(c / period + 0.5)
    dy = np.maximum(y0 - py, py - y1)
    dx = np.maximum(x0 - px, px - x1)
    box = np.where((dy > 0) & (dx > 0), np.hypot(dy, dx), np.maximum(dy, dx))
    return np.maximum(np.abs(r) - 0.5 * width, box)


def box_radiance(tex: Textures, y, x, oa, ob, channel, *, space: str = "camera", box: float = 1.0) -> np.ndarray:
    """Mean radiance over the ``box`` x ``box`` square in ``o`` centred at ``(oa, ob)``, for decoded ``(y, x)``.

    ``box = 1`` is one sensor pixel (the raw's rule); ``box = 0`` samples the single ray.

    Parameters
    ----------
    tex : Textures
    y, x, oa, ob, channel : array_like, broadcastable
        Decoded spatial coordinate, lattice-frame angular offset (px), channel index.
    space : 'camera' or 'srgb'

    Returns
    -------
    ndarray, broadcast shape, float64
    """
    arrs = np.broadcast_arrays(*(np.asarray(v, np.float64) for v in (y, x, oa, ob)),
                               np.asarray(channel, np.int64))
    flat = [np.ascontiguousarray(a.ravel()) for a in arrs]
    out = np.empty(flat[0].size)
    raster = {"camera": tex.camera, "srgb": tex.srgb}[space]
    sub = SUBSAMPLES * float(box) if box > 0 else np.zeros(1)
    box_radiance_kernel(*flat, sub, raster, tex.y0, tex.x0, tex.scale, tex.d0, tex.gy, tex.gx, tex.kind,
                        tex.prm, tex.rim, out)
    return out.reshape(arrs[0].shape)


__all__ = ["Plane", "Scene", "as_scene", "default_scene", "dot_chart", "Textures", "build_textures", "front_disparity",
           "box_radiance", "stripes_signed_distance", "SUPPORT_EDGE", "SUPPORT_KINDS", "OVERSAMPLE", "MARGIN", "LUMA"]
