"""Benchmark of :func:`plenodecode.calib.calibrate` on full-size white images (issue #3: Illum <= 2 s),
and of self-calibration from scene raws.

The white images come from the synthetic generator (``simulate_white('illum')``, 7728 x 5368,
and ``simulate_white('f01')``, 3280 x 3280) and are cached in ``bench/_cache/``.  The Illum white
is also timed with one numba / OpenCV thread, which is what the calibration gets when another
process keeps the second of two cores busy.  The notes give the CPU time of one run
(``time.process_time``, all threads) and the accuracy against the true grid (RMS over lenses
fully on the sensor, pitch error).

:func:`kernel_figures` compares the numba kernels of centre detection with the library calls that
would replace them, 3 runs each on a full-size 5368 x 7728 float32 lenslet image; a kernel stays
in the package only while it is the faster one (ratio > 1).  Window maxima (``cv2.dilate``) and the
contrast image ``I / L - 1`` (``cv2.divide``) replaced their kernels that way: on this input the
window-maxima kernel was no faster (0.10 s CPU each on one thread; 0.21 s against 0.16 s wall on two)
and the contrast kernel was slower (0.26 s against 0.15 s).
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


#: Full-size Illum sensor (rows, cols) and its lenslet pitch (px) for the kernel comparison.
ILLUM_SHAPE = (5368, 7728)
ILLUM_PITCH = 14.3


def _lenslet_image(shape: tuple[int, int] = ILLUM_SHAPE, pitch: float = ILLUM_PITCH, seed: int = 0) -> np.ndarray:
    """Hexagonal lenslet pattern (sum of three cosines at 60 degrees, clipped and squared) with
    vignetting, Gaussian noise (sigma 0.02) and 0.01 % hot pixels; (H, W) float32, white level ~1."""
    rng = np.random.default_rng(seed)
    y = np.arange(shape[0], dtype=np.float32)[:, None]
    x = np.arange(shape[1], dtype=np.float32)[None, :]
    k = np.float32(2 * math.pi / (pitch * math.sqrt(3) / 2))
    img = np.zeros(shape, np.float32)
    for a in (0.0, math.pi / 3, 2 * math.pi / 3):
        img += np.cos(k * (x * np.float32(math.cos(a)) + y * np.float32(math.sin(a))))
    img = np.maximum(img, 0) ** 2 / 9
    r2 = ((y - shape[0] / 2) ** 2 + (x - shape[1] / 2) ** 2) / np.float32(shape[0] ** 2 + shape[1] ** 2)
    img *= 1 - r2
    img += rng.normal(0, 0.02, shape).astype(np.float32)
    hot = rng.integers(0, img.size, img.size // 10_000)
    img.flat[hot] += 0.8
    return img


def kernel_figures(repeat: int = 3) -> list[Figure]:
    """Each numba kernel of centre detection against the library call that does the same job."""
    from plenodecode.calib.centroids import contrast, flatten, peaks

    img = _lenslet_image()
    size = f"{img.shape[1]}x{img.shape[0]}"
    g = peaks.smooth_for_peaks(img, ILLUM_PITCH)
    half = max(1, int(math.floor(0.4 * ILLUM_PITCH)))
    figures = []

    def pair(name: str, kernel, library, library_name: str) -> None:
        kernel(), library()  # warm-up: numba cache load
        _, t_kernel, _ = measure(kernel, repeat=repeat, memory=False)
        _, t_library, _ = measure(library, repeat=repeat, memory=False)
        figures.append(Figure(f"{name} (numba) {size}", t_kernel, ratio=t_library / t_kernel,
                              baseline=f"{library_name} {t_library:.3f} s"))

    pair("calib: fix_hot_pixels", lambda: flatten.fix_hot_pixels(img),
         lambda: flatten.fix_hot_pixels_reference(img), "cv2.dilate/erode")
    rr, cc = np.nonzero(peaks.window_maxima(g, half, 8))
    pair(f"calib: window_contrast at {len(rr)} peaks", lambda: peaks.window_contrast(g, rr, cc, half),
         lambda: peaks.window_contrast_reference(g, rr, cc, half), "cv2.erode")
    _, t, _ = measure(lambda: peaks.window_maxima(g, half, 8), repeat=repeat, memory=False)
    figures.append(Figure(f"calib: window_maxima (cv2.dilate {2 * half + 1}x{2 * half + 1}) {size}", t))
    _, t, _ = measure(lambda: contrast.devignette(img, ILLUM_PITCH), repeat=repeat, memory=False)
    figures.append(Figure(f"calib: devignette (local mean + cv2.divide) {size}", t))
    return figures


def run() -> list[Figure]:
    from plenodecode.calib import calibrate, calibrate_from_scene
    from plenodecode.synthetic import simulate

    figures = kernel_figures()
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
