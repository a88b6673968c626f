"""Benchmark of the synthetic generator :mod:`plenodecode.synthetic`.

* full-size ``illum`` (7728 x 5368): scene raw + white image, no ground-truth light field
  (target <= 60 s; rows are rendered in bands of ``BAND_ROWS``, so memory stays bounded);
* ``illum-mini`` scene + white, and its 15 x 15 ground-truth light field;
* the white image alone, compiled kernel against the plain-numpy reference model
  (``assign_pixels`` + ``disk_response`` + ``vignetting``, the functions the tests check the
  kernel with) on ``illum-mini``;
* the checkerboard radiance kernel against its numpy model on the rays of one F01 calibration raw,
  and a calibration set of 12 F01 raws (target <= 60 s).

The first call compiles the numba kernels (cached on disk afterwards); a warm-up on a tiny
sensor runs before any timing.
"""

from __future__ import annotations

import numpy as np

from . import Figure, measure


def _numpy_white(preset: str) -> np.ndarray:
    from plenodecode import synthetic as syn

    p = syn.PRESETS[preset]
    grid = syn.make_grid(p)
    h, w = grid.sensor_shape
    rr, cc = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    lens = syn.assign_pixels(grid, rr, cc)
    sig = (syn.disk_response(lens.oa, lens.ob, grid.radius, edge_px=p.edge_px, falloff=p.disk_falloff)
           * syn.vignetting(rr, cc, (h, w), p.vignette_corner, p.sensor_shape) * p.exposure)
    return np.rint(p.black + sig * (p.white - p.black)).astype(np.uint16)


def run() -> list[Figure]:
    from plenodecode import synthetic as syn

    syn.simulate("illum", shape=(64, 64))                      # compile / load the kernels
    figures = []
    sim, t, peak = measure(lambda: syn.simulate("illum", seed=1))
    h, w = sim.raw.shape
    figures.append(Figure(f"synthetic: simulate illum {w}x{h} (raw + white)", t, peak, target_s=60.0,
                          note=f"{2 * h * w / t / 1e6:.1f} Mpx/s"))
    del sim
    sim, t, peak = measure(lambda: syn.simulate("illum-mini", seed=1), repeat=3)
    figures.append(Figure("synthetic: simulate illum-mini 1544x1072 (raw + white)", t, peak))
    lf, t, peak = measure(lambda: sim.ground_truth_lightfield(), repeat=1)
    figures.append(Figure("synthetic: ground-truth LF illum-mini " + "x".join(map(str, lf.shape)), t, peak))
    _, t_ref, _ = measure(lambda: _numpy_white("illum-mini"), memory=False)
    (white, _), t_fast, peak = measure(lambda: syn.simulate_white("illum-mini", noise=False), repeat=3)
    same = np.array_equal(white.mosaic, _numpy_white("illum-mini"))
    figures.append(Figure("synthetic: white illum-mini, noise-free", t_fast, peak, ratio=t_ref / t_fast,
                          baseline="numpy reference model",
                          note="bit-identical" if same else "DIFFERS from the reference"))
    (white, _), t, peak = measure(lambda: syn.simulate_white("illum", seed=1))
    figures.append(Figure("synthetic: white illum 7728x5368 with noise", t, peak, target_s=30.0))
    figures.extend(_checkerboard())
    return figures


def _checkerboard() -> list[Figure]:
    """The board radiance kernel against its numpy model on the rays of one F01 calibration raw, and a set of 12."""
    from plenodecode.decoding.rectify import decoded_shape
    from plenodecode.raymodel import Board, GeometricCalibration
    from plenodecode.synthetic import checkerboard as cb
    from plenodecode.synthetic import make_grid

    grid = cb.pipeline_grid(make_grid("f01", shape=cb.set_sensor_shape("f01")))
    lf_shape = decoded_shape(grid)
    camera = GeometricCalibration(cb.default_intrinsics(lf_shape), [0.1, -0.2, 0.0, 0.003, -0.001], lf_shape=lf_shape)
    board, pose = Board(6, 8, 0.0036), (-0.012, -0.009, 0.45, 0.35, -0.45, 0.08)
    h, w = grid.sensor_shape
    rows, cols = np.meshgrid(np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64), indexing="ij")
    samples = cb.pixel_samples(grid, rows, cols, lf_shape[0]).reshape(-1, 4)
    samples = samples[np.hypot(samples[:, 0] - 4.0, samples[:, 1] - 4.0) < 5.6]
    offsets = cb.footprint_offsets(4)
    args = (camera.intrinsics, camera.distortion, board, pose)
    cb.board_radiance(*args, samples[:10], offsets)                       # compile / load the kernel
    fast, t_fast, peak = measure(lambda: cb.board_radiance(*args, samples, offsets), repeat=3)
    slow, t_slow, _ = measure(lambda: cb.board_radiance_numpy(*args, samples, offsets), memory=False)
    same = np.abs(fast - slow).max() < 1e-12
    figures = [Figure(f"synthetic: board radiance, {len(samples) / 1e6:.2f} M samples x 64 rays", t_fast, peak,
                      ratio=t_slow / t_fast, baseline="numpy model",
                      note="equal to 1e-12" if same else "DIFFERS from the numpy model")]
    _, t, peak = measure(lambda: cb.simulate_checkerboard_set("f01", board, 12, seed=1))
    figures.append(Figure("synthetic: checkerboard set, 12 F01 raws " + "x".join(map(str, grid.sensor_shape)), t,
                          peak, target_s=60.0))
    return figures

