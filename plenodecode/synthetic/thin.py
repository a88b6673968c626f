"""Thin-structure scenes of the synthetic generator: combs of thin near slats in front of a far plane,
and near surfaces with narrow slits showing a far plane (issue 20).

Every scene is a 2 x 2 layout of panels over the decoded field, one per thin width of
:data:`THIN_WIDTHS` (1, 2, 3 and 5 px: top-left, top-right, bottom-left, bottom-right):

* ``slats``: in each panel, near slats of width ``w`` with ``SPACING`` = 6 px gaps (period ``w + 6``) in
  front of a far plane that fills the field (the slats end at the panel's edges);
* ``slits``: the near surface covers the whole field except slits of width ``w`` (near bands of
  ``SPACING`` px between them); the far plane shows through the slits only.  The panels of the near
  surface overlap by 1 px so that their seams do not leak the far plane.

The disparity jump ``j`` (0.5, 1 or 2 px per view step, :data:`THIN_JUMPS`) puts the far plane at
``-j / 2`` and the near structure at ``+j / 2``.  The slats run horizontally (``h``, 0 deg), vertically
(``v``, 90 deg) or obliquely (``o``, :data:`OBLIQUE_DEG`); the far plane is textured (``tex``) or weakly
textured (``weak``, texture contrast :data:`WEAK_CONTRAST`).  The near planes have a rim of
:data:`THIN_RIM` px (instead of the default 2 px) so that a 1 px slat is opaque along its centre line;
axis-aligned slat and panel edges sit on half-integers, between pixel centres, so every centre-view pixel
of a horizontal or vertical scene is wholly inside or outside a slat.  The ground-truth disparity of a
pixel is that of the front-most plane whose support holds its central ray's hit point
(:func:`plenodecode.synthetic.scene.front_disparity`).

:data:`THIN_SCENES` maps a name ``'<kind>-<orientation>-j<jump>-<background>'`` (e.g.
``'slats-o-j1-weak'``) to its builder ``(n_y, n_x, seed) -> Scene``, which
:func:`plenodecode.synthetic.simulate` accepts as ``scene=``.
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:   # the module itself imports no numba / OpenCV: the CLI lists THIN_SCENES in its help
    from .scene import Scene

#: Widths (decoded px) of the thin slats or slits, one panel each.
THIN_WIDTHS = (1.0, 2.0, 3.0, 5.0)
#: Disparity jumps (px per view step) between the far plane and the near structure.
THIN_JUMPS = (0.5, 1.0, 2.0)
#: Orientation name -> slat angle (deg from the image rows).
OBLIQUE_DEG = 30.0
THIN_ORIENTATIONS = {"h": 0.0, "v": 90.0, "o": OBLIQUE_DEG}
#: Width (px) of the wide part of the pattern: the gaps between slats, the near bands between slits.
SPACING = 6.0
#: Rim (px) of the near planes' supports.
THIN_RIM = 0.5
#: Texture contrast of a weakly textured far plane.
WEAK_CONTRAST = 0.25
THIN_KINDS = ("slats", "slits")
THIN_BACKGROUNDS = ("tex", "weak")


def _panels(n_y: int, n_x: int, overlap: float) -> list[tuple[float, float, float, float]]:
    """Boxes ``(y0, x0, y1, x1)`` of the 2 x 2 panels; outer sides reach far past the field, inner sides
    on the half-integer nearest the middle, widened by ``overlap`` px."""
    far = 1e4
    ym, xm = round(n_y / 2) - 0.5, round(n_x / 2) - 0.5
    rows = ((-far, ym + overlap), (ym - overlap, far))
    cols = ((-far, xm + overlap), (xm - overlap, far))
    return [(r[0], c[0], r[1], c[1]) for r in rows for c in cols]


def thin_scene(n_y: int, n_x: int, seed: int = 0, *, kind: str = "slats", orientation: str = "v",
               jump: float = 1.0, background: str = "tex") -> "Scene":
    """A thin-structure scene (see the module docstring) for a decoded field of ``(n_y, n_x)`` px.

    Parameters
    ----------
    n_y, n_x : int
        Decoded field size ``(Y, X)``; the panels split it in four.
    seed : int
        Texture seeds are ``seed * 16 + k`` (k = 0 the far plane, 1..4 the panels).
    kind : 'slats' or 'slits'
    orientation : 'h', 'v' or 'o'
    jump : float
        Disparity of the near structure minus that of the far plane (px per view step), > 0.
    background : 'tex' or 'weak'

    Returns
    -------
    Scene
        Named ``'<kind>-<orientation>-j<jump>-<background>'``; depth order 0 the near panels, 1 the far plane.
    """
    if kind not in THIN_KINDS:
        raise ValueError(f"kind must be one of {THIN_KINDS}, got {kind!r}")
    if orientation not in THIN_ORIENTATIONS:
        raise ValueError(f"orientation must be one of {tuple(THIN_ORIENTATIONS)}, got {orientation!r}")
    if background not in THIN_BACKGROUNDS:
        raise ValueError(f"background must be one of {THIN_BACKGROUNDS}, got {background!r}")
    if not jump > 0:
        raise ValueError(f"jump must be > 0, got {jump!r}")
    from .scene import Plane, Scene

    angle = THIN_ORIENTATIONS[orientation]
    s = int(seed) * 16
    near, far = 0.5 * jump, -0.5 * jump
    planes = [Plane(d0=far, support=("all",), depth_order=1, texture_seed=s,
                    contrast=WEAK_CONTRAST if background == "weak" else 1.0)]
    for k, (width, box) in enumerate(zip(THIN_WIDTHS, _panels(n_y, n_x, 1.0 if kind == "slits" else 0.0))):
        slat, period = (width, width + SPACING) if kind == "slats" else (SPACING, width + SPACING)
        # a slat edge on -0.5: half-integer edges for the axis-aligned angles
        planes.append(Plane(d0=near, support=("stripes", angle, slat, period, -0.5, *box), depth_order=0,
                            texture_seed=s + 1 + k, rim=THIN_RIM))
    return Scene(planes=tuple(planes), name=thin_scene_name(kind, orientation, jump, background))


def thin_scene_name(kind: str, orientation: str, jump: float, background: str) -> str:
    """``'<kind>-<orientation>-j<jump>-<background>'``, the jump without a trailing ``.0``."""
    return f"{kind}-{orientation}-j{jump:g}-{background}"


#: Scene name -> builder ``(n_y, n_x, seed) -> Scene`` of every combination of kind, orientation, jump and
#: background (36 scenes).
THIN_SCENES: dict[str, Callable[..., "Scene"]] = {
    thin_scene_name(k, o, j, b): partial(thin_scene, kind=k, orientation=o, jump=j, background=b)
    for k in THIN_KINDS for o in THIN_ORIENTATIONS for j in THIN_JUMPS for b in THIN_BACKGROUNDS
}

__all__ = ["THIN_SCENES", "THIN_WIDTHS", "THIN_JUMPS", "THIN_ORIENTATIONS", "THIN_KINDS", "THIN_BACKGROUNDS",
           "SPACING", "THIN_RIM", "WEAK_CONTRAST", "OBLIQUE_DEG", "thin_scene", "thin_scene_name"]
