"""Compile (or load from the cache) every numba kernel once, group by group: ``plenodecode warmup``.

Each group runs the same library calls a command makes, on a small generated camera (a 'illum-mini'
raw cut to ``SHAPE``), so the kernels are compiled for the argument types the commands use and land in
the user cache directory (:mod:`plenodecode._numba`); later commands then load them instead of
compiling.  Groups, in order (each needs the one before):

``synthetic``   the forward model (:func:`plenodecode.synthetic.simulate`), which makes the inputs, and the
                checkerboard renderer (:func:`plenodecode.synthetic.board_lightfield`);
``calibration`` :func:`plenodecode.calib.calibrate` on the white image, the hot-pixel kernel of
                full-size whites, and self-calibration on the scene (``calibrate --scene``: the disk rims);
``decode``      :func:`plenodecode.pipeline.decode_raw` (devignette, demosaic, slice, hex -> rect);
``refocus``     shift-sum and Fourier-slice photographs and a shift-sum focal stack
                (:func:`plenodecode.pipeline.render_product`);
``depth``       the default depth method (cost volume, aggregation, occlusion);
``total-focus`` a focused-plenoptic ('raytrix') raw rendered all-in-focus.
"""

from __future__ import annotations

import time
from typing import Any, Callable

#: sensor rows x columns of the generated raws (large enough for a lattice fit, small enough to be quick)
SHAPE = (320, 448)

#: the groups of :func:`warmup`, in order
WARMUP_GROUPS = ("synthetic", "calibration", "decode", "refocus", "depth", "total-focus")


def _synthetic(state: dict[str, Any]) -> None:
    from .synthetic import board_lightfield, default_intrinsics, simulate

    state["sim"] = simulate("illum-mini", seed=0, shape=SHAPE)
    board_lightfield(default_intrinsics((3, 3, 8, 8)), (2, 2, 0.01), (0.0, 0.0, 0.4, 0.0, 0.0, 0.0), (3, 3, 8, 8))


def _calibration(state: dict[str, Any]) -> None:
    import numpy as np

    from .calib import calibrate
    from .calib.centroids import flatten
    from .calib.selfcal import calibrate_from_scene

    state["grid"] = calibrate([state["sim"].white])
    calibrate_from_scene(state["sim"].raw)
    # full-size whites repair hot pixels in a compiled kernel (small images go through OpenCV)
    flatten.fix_hot_pixels(np.zeros((1, flatten._KERNEL_MIN_PIXELS), np.float32))


def _decode(state: dict[str, Any]) -> None:
    from .pipeline import Calibration, decode_raw

    sim = state["sim"]
    state["lf"] = decode_raw(sim.raw, Calibration(state["grid"], sim.white, "warmup"))


def _refocus(state: dict[str, Any]) -> None:
    from .pipeline import Source, render_product
    from .render.shiftsum import _TILED_MIN_SLOPES

    src = Source(lightfield=state["lf"])
    for method in ("shift-sum", "fourier-slice"):
        render_product(src, "refocus", slope=0.25, method=method)
    # a focal stack: the compiled tiled shift-sum (a single photograph goes through OpenCV)
    render_product(src, "focal-stack", start=-0.5, stop=0.5, n=_TILED_MIN_SLOPES)


def _depth(state: dict[str, Any]) -> None:
    from .pipeline import Source, render_product

    render_product(Source(lightfield=state["lf"]), "depth")


def _total_focus(state: dict[str, Any]) -> None:
    from .pipeline import Calibration, Source, render_product
    from .synthetic import simulate

    sim = simulate("raytrix", seed=0, shape=SHAPE)
    render_product(Source(raw=sim.raw, calibration=Calibration(sim.grid, sim.white, "warmup")), "total-focus")


_STEPS: dict[str, Callable[[dict[str, Any]], None]] = {
    "synthetic": _synthetic, "calibration": _calibration, "decode": _decode,
    "refocus": _refocus, "depth": _depth, "total-focus": _total_focus,
}


def warmup(report: Callable[[str, float], None] | None = None) -> dict[str, float]:
    """Run every group of :data:`WARMUP_GROUPS` once; return group -> wall seconds.

    Parameters
    ----------
    report : callable(group, seconds), optional
        Called after each group (the CLI prints one line per group).
    """
    state: dict[str, Any] = {}
    seconds = {}
    for group in WARMUP_GROUPS:
        t0 = time.perf_counter()
        _STEPS[group](state)
        seconds[group] = time.perf_counter() - t0
        if report is not None:
            report(group, seconds[group])
    return seconds


__all__ = ["SHAPE", "WARMUP_GROUPS", "warmup"]
