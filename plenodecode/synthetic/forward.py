"""Simulating a capture: :func:`simulate` (scene raw + white image + ground truth) and
:func:`simulate_white` (a white image and the true grid) of a preset camera.

The forward model is described in :mod:`plenodecode.synthetic`; this module resolves the
preset and its overrides, seeds the random streams, builds the scene's textures and runs the
sensor model (or, for a focused preset, :func:`~plenodecode.synthetic.focused.simulate_focused`).
"""

from __future__ import annotations

import numpy as np

from ..types import CameraMetadata, LensletGrid, LightField, RawCapture
from .focused import simulate_focused
from .lattice import make_grid
from .presets import Preset, get_preset
from .scene import as_scene, build_textures, default_scene, front_disparity
from .sensor import BAND_ROWS, Progress, levels, render_sensor
from .truth import Simulation, finite_range, ideal_lightfield


def _metadata(p: Preset, grid: LensletGrid, *, white: bool, seed: int, offset: tuple[float, float]) -> CameraMetadata:
    wb = None
    if p.wb_gains is not None:
        gains = (1.0, 1.0, 1.0, 1.0) if white else p.wb_gains
        wb = dict(zip(("r", "gr", "gb", "b"), (float(g) for g in gains)))
    return CameraMetadata(
        make=p.make, model=p.model, serial=p.serial, zoom_step=p.zoom_step, focus_step=p.focus_step,
        exposure_s=p.exposure_s, iso=p.iso, wb_gains=wb, ccm=p.ccm,
        pixel_pitch_m=p.pixel_pitch_m, lens_pitch_m=grid.pitch * p.pixel_pitch_m, mla_rotation=grid.rotation,
        mla_offset_m=(offset[1] * p.pixel_pitch_m, offset[0] * p.pixel_pitch_m, p.mla_gap_m),
        mla_scale=(1.0, 1.0), focal_length_m=p.focal_length_m, f_number=p.f_number, is_white_image=white,
        extra={"synthetic": {"preset": p.name, "seed": int(seed), "generator": "plenodecode.io.synthetic"}},
    )


def _resolve(preset: str | Preset, pitch, rotation, offset, shape) -> tuple[Preset, LensletGrid, tuple[float, float]]:
    p = get_preset(preset)
    off = tuple(float(v) for v in (p.offset if offset is None else offset))
    grid = make_grid(p, pitch=pitch, rotation=rotation, offset=off, shape=shape)
    return p, grid, off  # type: ignore[return-value]


def _rngs(seed: int) -> dict[str, np.random.Generator]:
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    names = ("scene", "raw", "white")
    return {n: np.random.default_rng(s) for n, s in zip(names, np.random.SeedSequence(int(seed)).spawn(len(names)))}


def simulate_white(preset: str | Preset, *, seed: int = 0, pitch: float | None = None,
                   rotation: float | None = None, offset: tuple[float, float] | None = None,
                   noise: bool = True, shape: tuple[int, int] | None = None,
                   progress: Progress = None) -> tuple[RawCapture, LensletGrid]:
    """A white (flat-field) image of a preset camera and its true lenslet grid.

    Each pixel is ``black + (white - black) * exposure * vignetting(q) * D(o)`` plus noise,
    where ``D`` is the box-averaged disk response (:func:`disk_response`) at the pixel's
    lattice offset ``o`` from its nearest lens, the same in every CFA channel.

    Parameters
    ----------
    preset : str or Preset
        A key of :data:`PRESETS`.
    seed : int
        Seed of the noise (``np.random.SeedSequence(seed)``); same seed, same image.
    pitch, rotation, offset : optional
        Override the preset's lens pitch (px), grid rotation (rad) and lattice anchor
        shift from the sensor centre ((row, col) px).
    noise : bool
        False: no shot/read noise and no hot pixels (values only rounded).
    shape : (H, W), optional
        Override the sensor size.
    progress : callable(done, total), optional
        Called after each band of rows.

    Returns
    -------
    white : RawCapture
        ``mosaic`` (H, W) uint16, ``metadata.is_white_image`` True, WB gains 1.
    grid : LensletGrid
        The true grid (see :func:`make_grid`).
    """
    p, grid, off = _resolve(preset, pitch, rotation, offset, shape)
    rng = _rngs(seed)["white"] if noise else None
    mosaic = render_sensor(grid, p, None, rng, progress)
    black, white = levels(p)
    raw = RawCapture(mosaic=mosaic, cfa=p.cfa, black=black, white=white,
                     metadata=_metadata(p, grid, white=True, seed=seed, offset=off))
    return raw, grid


def _scene_truth(p: Preset, grid: LensletGrid, scene, seed: int):
    """The scene (default, builder or given), its textures and its disparity over the decoded field."""
    smp = grid.decoded_sampling()
    ny, nx = int(smp["Y"]), int(smp["X"])
    if scene is None:
        sc = default_scene(ny, nx, seed)
    else:
        sc = as_scene(scene(ny, nx, seed) if callable(scene) else scene)
    tex = build_textures(sc, ny, nx, mono=p.mono, cam_matrix=p.camera_matrix())
    yy, xx = np.meshgrid(np.arange(ny, dtype=np.float64), np.arange(nx, dtype=np.float64), indexing="ij")
    return sc, tex, front_disparity(tex, yy, xx)


def simulate(preset: str | Preset, *, seed: int = 0, pitch: float | None = None, rotation: float | None = None,
             offset: tuple[float, float] | None = None, noise: bool = True, scene=None,
             shape: tuple[int, int] | None = None, progress: Progress = None) -> Simulation:
    """Simulate a scene raw, its white image and the ground truth.

    The forward model of :mod:`plenodecode.synthetic` (Ng et al. 2005): each pixel records the
    box-averaged camera-RGB radiance of its CFA channel along the rays ``(o, y, x)`` of its
    lenslet, times the disk response, the vignetting and the exposure; then noise.

    Parameters
    ----------
    preset : str or Preset
        A key of :data:`PRESETS`.
    seed : int
        Seeds the default scene's textures and the noise.
    pitch, rotation, offset, shape :
        Overrides, as in :func:`simulate_white`.
    noise : bool
        False: no shot/read noise, no hot pixels.
    scene : Scene, list of Plane, list of plane dicts or callable, optional
        Planes in decoded coordinates (see :class:`plenodecode.synthetic.scene.Plane`), or a builder
        ``(n_y, n_x, seed) -> Scene`` called with the decoded size (e.g. a value of
        :data:`plenodecode.synthetic.thin.THIN_SCENES`; unfocused presets only);
        default :func:`plenodecode.synthetic.scene.default_scene` for the decoded size.
    progress : callable(done, total), optional

    Returns
    -------
    Simulation
    """
    p, grid, off = _resolve(preset, pitch, rotation, offset, shape)
    rngs = _rngs(seed)
    if p.focused:
        if callable(scene):
            raise ValueError(f"a scene builder (decoded-size scene) needs an unfocused preset, got {p.name!r}")
        return simulate_focused(p, grid, off, seed=seed, rngs=rngs if noise else None, scene=scene,
                                metadata=lambda white: _metadata(p, grid, white=white, seed=seed, offset=off),
                                progress=progress)
    sc, tex, disp = _scene_truth(p, grid, scene, seed)
    total = 2 * ((grid.sensor_shape[0] + BAND_ROWS - 1) // BAND_ROWS)
    half = total // 2

    def prog(offset_done: int):
        if progress is None:
            return None
        return lambda d, t: progress(offset_done + d, total)

    mosaic = render_sensor(grid, p, tex, rngs["raw"] if noise else None, prog(0))
    white_mosaic = render_sensor(grid, p, None, rngs["white"] if noise else None, prog(half))
    black, white = levels(p)
    raw = RawCapture(mosaic=mosaic, cfa=p.cfa, black=black, white=white,
                     metadata=_metadata(p, grid, white=False, seed=seed, offset=off))
    wcap = RawCapture(mosaic=white_mosaic, cfa=p.cfa, black=black, white=white,
                      metadata=_metadata(p, grid, white=True, seed=seed, offset=off))
    return Simulation(raw=raw, white=wcap, grid=grid, disparity=disp, scene=sc, preset=p, seed=int(seed),
                      noise=bool(noise), textures=tex)


def simulate_ideal(preset: str | Preset, *, seed: int = 0, scene=None, pitch: float | None = None,
                   rotation: float | None = None, offset: tuple[float, float] | None = None,
                   shape: tuple[int, int] | None = None, n_views: int | None = None,
                   progress: Progress = None) -> tuple[LightField, np.ndarray]:
    """The ideal (noise-free, lens-free) light field and the disparity of a scene, without rendering the raw.

    The same as ``simulate(...).ground_truth_lightfield(n_views)`` and ``simulate(...).disparity`` (arguments
    as :func:`simulate`), at a fraction of the cost: the benchmark's ground-truth scenes.

    Returns
    -------
    lightfield : LightField
        data (V, U, Y, X, C) float32 (see :meth:`Simulation.ground_truth_lightfield`).
    disparity : ndarray (Y, X) float32
    """
    p, grid, off = _resolve(preset, pitch, rotation, offset, shape)
    _rngs(seed)                     # checks the seed as simulate does
    if p.focused:
        raise ValueError(f"simulate_ideal needs an unfocused preset, got {p.name!r}")
    _, tex, disp = _scene_truth(p, grid, scene, seed)
    lf = ideal_lightfield(tex, grid, p, _metadata(p, grid, white=False, seed=seed, offset=off), seed=int(seed),
                          disparity_range=finite_range(disp), n_views=n_views, progress=progress)
    return lf, disp


__all__ = ["simulate", "simulate_ideal", "simulate_white"]
