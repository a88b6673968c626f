"""Benchmark of :func:`plenodecode.decoding.decode` on a full-size Illum raw (7728 x 5368).

The raw and white come from the synthetic generator and are cached in ``bench/_cache/``.
The baseline is a straightforward decoder run in the same process: demosaic the whole
lenslet image in float64 (OpenCV bilinear Bayer), divide by the white, then for every view
``scipy.ndimage.map_coordinates`` at every lens centre + view offset and again along the lens
rows for hex -> rect; one view after the other, one thread.
"""

from __future__ import annotations

import json
import os
import resource
import time
from pathlib import Path

import numpy as np

from . import Figure, measure, peak_rss_growth

CACHE = Path(__file__).resolve().parent / "_cache"


def _illum_inputs(seed: int = 1):
    """Full-size synthetic Illum raw + white + true grid (generated once, then cached)."""
    from plenodecode.types import CameraMetadata, LensletGrid, RawCapture

    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"illum_full_seed{seed}.npz"
    if not path.exists():
        from plenodecode.synthetic import simulate

        sim = simulate("illum", seed=seed)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, raw=sim.raw.mosaic, white=sim.white.mosaic, cfa=sim.raw.cfa, black=sim.raw.black,
                 white_level=sim.raw.white, grid=sim.grid.to_json(),
                 meta=json.dumps(sim.raw.metadata.to_dict()), wmeta=json.dumps(sim.white.metadata.to_dict()))
        tmp.replace(path)
    z = np.load(path)
    cfa = str(z["cfa"])
    raw = RawCapture(z["raw"], cfa, z["black"], z["white_level"], CameraMetadata.from_dict(json.loads(str(z["meta"]))))
    white = RawCapture(z["white"], cfa, z["black"], z["white_level"],
                       CameraMetadata.from_dict(json.loads(str(z["wmeta"]))))
    return raw, white, LensletGrid.from_json(str(z["grid"]))


def naive_decode(raw, white, grid, n_views: int | None = None) -> np.ndarray:
    """The baseline: whole-sensor float64 demosaic, then per view map_coordinates (no threads).

    Returns
    -------
    ndarray, shape (V, U, Y, X, 3), float32
    """
    import cv2
    from scipy import ndimage

    n = grid.n_views() if n_views is None else n_views
    x = raw.normalised().astype(np.float64)
    w = white.normalised().astype(np.float64)
    ratio = np.where(w > 0.05, x / np.maximum(w, 1e-6), 0.0)
    del x, w
    codes = {"RGGB": cv2.COLOR_BayerBG2RGB, "GRBG": cv2.COLOR_BayerGB2RGB,
             "GBRG": cv2.COLOR_BayerGR2RGB, "BGGR": cv2.COLOR_BayerRG2RGB}
    scale = 60000.0 / max(1e-6, float(np.percentile(ratio, 99.9)))
    rgb = cv2.cvtColor(np.clip(ratio * scale, 0, 65535).astype(np.uint16), codes[raw.cfa]).astype(np.float64) / scale
    del ratio
    s = grid.decoded_sampling()
    ny, nx = int(s["Y"]), int(s["X"])
    centres = grid.centres_2d()
    rows, cols = grid.shape
    e_row, e_col = grid.axes()
    shift = grid.odd_row_shift * grid.pitch
    b = s["b0"] + np.arange(nx) * s["step"]
    t = (b[None, :] - shift * (np.arange(rows)[:, None] % 2)) / grid.pitch       # (rows, X) lens index
    rr = np.broadcast_to(np.arange(rows, dtype=np.float64)[:, None], t.shape)
    out = np.empty((n, n, ny, nx, 3), np.float32)
    half = n // 2
    for v in range(n):
        for u in range(n):
            p = centres + (v - half) * e_row + (u - half) * e_col
            for c in range(3):
                lens = ndimage.map_coordinates(rgb[..., c], [p[..., 0].ravel(), p[..., 1].ravel()], order=1,
                                               mode="constant").reshape(rows, cols)
                out[v, u, ..., c] = ndimage.map_coordinates(lens, [rr, t], order=1, mode="nearest")
    return out


def run() -> list[Figure]:
    from plenodecode.decoding import decode, decode_timed

    raw, white, grid = _illum_inputs()
    decode(raw, grid, white=white, n_views=3)            # compile / load the numba kernels
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    t0, c0 = time.perf_counter(), time.process_time()
    lf = decode(raw, grid, white=white)                   # first run: fresh output pages
    first, cpu = time.perf_counter() - t0, time.process_time() - c0
    del lf
    lf, secs, traced = measure(lambda: decode(raw, grid, white=white), repeat=2)
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    shape = "x".join(map(str, lf.shape))
    del lf
    # the light field and the band buffers are mapped outside numpy's allocator, which tracemalloc does not see
    lf, rss_growth = peak_rss_growth(lambda: decode(raw, grid, white=white))
    del lf
    peak = max(traced, rss_growth)
    stages: dict[str, float] = {}
    decode_timed(raw, grid, white=white, timings=stages)   # warm run with per-stage thread CPU
    warm_cpu = stages["total cpu"]                          # CPU seconds of a warm run, all threads
    hex_stages: dict[str, float] = {}                       # the 2-D 'hex' resampling (warm: its design is cached)
    decode(raw, grid, white=white, n_views=3, resample="hex")
    decode_timed(raw, grid, white=white, resample="hex", timings=hex_stages)
    load = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    naive = naive_decode(raw, white, grid)
    naive_s, naive_cpu = time.perf_counter() - t0, time.process_time() - c0
    del naive
    return [
        Figure(name="decode full Illum 7728x5368 -> float32 LF", seconds=secs, peak_mb=peak, target_s=2.5,
               ratio=naive_s / secs, baseline="naive per-view map_coordinates",
               note=f"LF {shape}, best of 2 after a first run of {first:.2f} s; CPU {cpu:.1f} s first, "
                    f"{warm_cpu:.1f} s warm, {os.cpu_count()} cores at load {load:.1f}; peak = max(traced {traced:.0f}, "
                    f"RSS growth {rss_growth:.0f}) MB (target <= 2000), process max RSS {rss0:.0f} -> {rss1:.0f} MB"),
        Figure(name="decode full Illum, resample='hex' (2-D kernel, option)", seconds=hex_stages["wall"],
               ratio=warm_cpu / hex_stages["total cpu"], baseline="default 'cubic', CPU s",
               note=f"CPU {hex_stages['total cpu']:.1f} s warm (cubic {warm_cpu:.1f} s), of which hex->rect "
                    f"{hex_stages['hex->rect']:.1f} s (cubic {stages['hex->rect']:.1f} s)"),
        Figure(name="naive per-view map_coordinates decoder (baseline)", seconds=naive_s,
               note=f"float64 demosaic of the whole sensor, scipy per view, 1 thread; {naive_cpu:.1f} CPU s "
                    f"(on a loaded machine compare CPU s: {naive_cpu / warm_cpu:.1f}x the decode's)"),
    ] + [
        Figure(name=f"  decode stage: {k}", seconds=v,
               note=("thread CPU s summed over bands and threads (warm run)" if k not in ("total cpu", "wall")
                     else "process CPU s of the warm run" if k == "total cpu" else "wall s of the warm run")
               + ("; includes the colour matrix, applied to each sample" if k == "slice" else "")
               + ("; includes first writing the light field's pages" if k == "hex->rect" else ""))
        for k, v in stages.items()
    ]
