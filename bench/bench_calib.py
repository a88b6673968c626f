"""Benchmark of :func:`plenodecode.calib.calibrate` on full-size white images (issue #3: Illum <= 2 s),
and of self-calibration from scene raws.

The white images come from the synthetic generator (``simulate_white('illum')``, 7728 x 5368,
and ``simulate_white('f01')``, 3280 x 3280) and are cached in ``bench/_cache/``.  The Illum white
is also timed with one numba / OpenCV thread, which is what the calibration gets when another
process keeps the second of two cores busy.  The notes give the CPU time of one run
(``time.process_time``, all threads) and the accuracy against the true grid (RMS over lenses
fully on the sensor, pitch error).
"""

from __future__ import annotations

import json
import math
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from . import Figure, measure

CACHE = Path(__file__).resolve().parent / "_cache"


def _white(preset: str, seed: int = 0):
    """Full-size synthetic white image + true grid (generated once, then cached)."""
    from plenodecode.types import CameraMetadata, LensletGrid, RawCapture

    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"calib_{preset}_white_seed{seed}.npz"
    if not path.exists():
        from plenodecode.synthetic import simulate_white

        raw, grid = simulate_white(preset, seed=seed)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, mosaic=raw.mosaic, cfa=str(raw.cfa), black=raw.black, white=raw.white,
                 meta=json.dumps(raw.metadata.to_dict()), grid=grid.to_json())
        tmp.replace(path)
    z = np.load(path)
    cfa = str(z["cfa"])
    raw = RawCapture(z["mosaic"], None if cfa == "None" else cfa, z["black"], z["white"],
                     CameraMetadata.from_dict(json.loads(str(z["meta"]))))
    return raw, LensletGrid.from_json(str(z["grid"]))


def _accuracy(grid, truth) -> str:
    from scipy.spatial import cKDTree

    H, W = truth.sensor_shape
    t = truth.centres()
    R = truth.radius
    full = (t[:, 0] - R >= -0.5) & (t[:, 0] + R <= H - 0.5) & (t[:, 1] - R >= -0.5) & (t[:, 1] + R <= W - 0.5)
    d, _ = cKDTree(grid.centres()).query(t[full])
    rot = abs(((grid.rotation - truth.rotation) + math.pi / 2) % math.pi - math.pi / 2)
    return (f"{int(full.sum())} lenses, RMS {np.sqrt(np.mean(d ** 2)):.4f} px, max {d.max():.4f} px, "
            f"pitch err {abs(grid.pitch - truth.pitch):.1e} px, rot err {rot:.1e} rad")


@contextmanager
def _threads(n: int | None):
    """Limit numba and OpenCV to ``n`` threads inside the block (None: leave them)."""
    import cv2
    import numba

    if n is None:
        yield
        return
    old_nb, old_cv = numba.get_num_threads(), cv2.getNumThreads()
    numba.set_num_threads(n)
    cv2.setNumThreads(n)
    try:
        yield
    finally:
        numba.set_num_threads(old_nb)
        cv2.setNumThreads(old_cv)


def _cpu_seconds(fn) -> float:
    c0 = time.process_time()
    fn()
    return time.process_time() - c0


def run() -> list[Figure]:
    from plenodecode.calib import calibrate, calibrate_from_scene
    from plenodecode.synthetic import simulate

    figures = []
    for preset, target, threads in (("illum", 2.0, None), ("illum", 2.0, 1), ("f01", None, None)):
        white, truth = _white(preset)
        with _threads(threads):
            calibrate(white)  # warm-up: numba cache load, FFT plans
            grid, seconds, peak = measure(lambda: calibrate(white), repeat=3)
            cpu = _cpu_seconds(lambda: calibrate(white))
        label = "one thread" if threads == 1 else "all threads"
        figures.append(Figure(f"calibrate: full-size {preset} white {white.shape[1]}x{white.shape[0]}, {label}",
                              seconds, peak, target_s=target,
                              note=f"CPU {cpu:.2f} s; {_accuracy(grid, truth)}"))
    for preset in ("illum-mini", "square"):
        sim = simulate(preset, seed=1)
        calibrate_from_scene(sim.raw)
        grid, seconds, peak = measure(lambda: calibrate_from_scene(sim.raw), repeat=2)
        cpu = _cpu_seconds(lambda: calibrate_from_scene(sim.raw))
        ref = calibrate_from_scene(sim.raw, method="dog")
        figures.append(Figure(f"self-calibrate ('rim'): {preset} scene {sim.raw.shape[1]}x{sim.raw.shape[0]}",
                              seconds, peak, note=f"CPU {cpu:.2f} s; {_accuracy(grid, sim.grid)}; intensity "
                                                  f"peaks ('dog'): {_accuracy(ref, sim.grid).split(', ')[1]}"))
    return figures
