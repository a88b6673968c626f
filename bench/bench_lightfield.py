"""Light-field save/load per format, image writing and 16-bit mosaics at real sizes.

Light fields: F01-sized 9x9x381x382x3 float32 (141 MB + weight) for every format, and an
Illum-sized 15x15x434x625x3 (732 MB) for Zarr.  Content is a smooth scene with noise (so the
compressors see realistic data, not white noise).  Outputs go to a temporary folder.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from bench import Figure, measure
from plenodecode.io.generic import read_generic, write_mosaic
from plenodecode.io.images import read_image, write_animation, write_image
from plenodecode.io.lightfield import load_lightfield, save_lightfield
from plenodecode.types import LightField, RawCapture


def _lightfield(V: int, U: int, Y: int, X: int) -> LightField:
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:Y, 0:X].astype(np.float32)
    base = 0.5 + 0.4 * np.sin(xx / 17.0) * np.cos(yy / 23.0)
    data = np.empty((V, U, Y, X, 3), np.float32)
    for v in range(V):
        for u in range(U):
            shifted = np.roll(base, (v - V // 2, u - U // 2), axis=(0, 1))
            data[v, u] = shifted[..., None] * np.array([1.0, 0.8, 0.6], np.float32)
    data += rng.normal(0, 0.01, data.shape).astype(np.float32)
    np.clip(data, 0, 1, out=data)
    weight = np.broadcast_to(np.float32(1.0), data.shape[:4]).copy()
    weight[0, 0] = weight[-1, -1] = 0.2
    return LightField(data, weight, "linear-srgb", {"source": "bench"})


def run() -> list[Figure]:
    figs: list[Figure] = []
    with tempfile.TemporaryDirectory(dir=Path(__file__).parent) as tmp:
        root = Path(tmp)
        lf = _lightfield(9, 9, 381, 382)
        size = "9x9x381x382x3"
        for fmt, name, bits in (("zarr", "f01.zarr", 16), ("npy", "f01.npy", 32), ("mat", "f01.mat", 16),
                                ("views", "f01_views", 16), ("eslf", "f01_eslf.png", 16)):
            path = root / name
            _, t, peak = measure(lambda: save_lightfield(lf, path, format=fmt, bit_depth=bits, overwrite=True))
            figs.append(Figure(f"lightfield: save {fmt} {size} ({bits}-bit)", t, peak))
            _, t, peak = measure(lambda: load_lightfield(path), repeat=2)
            figs.append(Figure(f"lightfield: load {fmt} {size}", t, peak))
            _, t, peak = measure(lambda: load_lightfield(path, view=(4, 4)), repeat=3)
            figs.append(Figure(f"lightfield: load one view {fmt}", t, peak))
        del lf

        big = _lightfield(15, 15, 434, 625)
        path = root / "illum.zarr"
        _, t, peak = measure(lambda: save_lightfield(big, path, overwrite=True))
        figs.append(Figure("lightfield: save zarr Illum 15x15x434x625x3 (732 MB)", t, peak))
        _, t, peak = measure(lambda: load_lightfield(path))
        figs.append(Figure("lightfield: load zarr Illum 15x15x434x625x3", t, peak))
        _, t, peak = measure(lambda: load_lightfield(path, view=(7, 7)), repeat=3)
        figs.append(Figure("lightfield: load one view zarr Illum (one chunk)", t, peak, target_s=0.1))
        centre = big.data[7, 7].copy()
        frames = big.data[7, ::2].copy()
        del big

        rng = np.random.default_rng(1)
        mosaic = rng.integers(64, 1024, (5368, 7728)).astype(np.uint16)
        raw = RawCapture(mosaic, "GRBG", 64, 1023)
        _, t, peak = measure(lambda: write_mosaic(root / "illum.png", raw, overwrite=True))
        figs.append(Figure("images: write_mosaic 7728x5368 16-bit PNG + sidecar", t, peak))
        _, t, peak = measure(lambda: read_generic(root / "illum.png"), repeat=2)
        figs.append(Figure("images: read_generic 7728x5368 16-bit PNG mosaic", t, peak))
        _, t, peak = measure(lambda: write_image(root / "c.exr", centre, bit_depth=32, overwrite=True), repeat=3)
        figs.append(Figure("images: write_image 625x434x3 EXR float", t, peak))
        _, t, peak = measure(lambda: write_image(root / "c.png", centre, bit_depth=8, overwrite=True,
                                                 encode_srgb=True), repeat=3)
        figs.append(Figure("images: write_image 625x434x3 PNG 8-bit + sRGB encode", t, peak))
        _, t, peak = measure(lambda: read_image(root / "c.png"), repeat=3)
        figs.append(Figure("images: read_image 625x434x3 PNG 8-bit", t, peak))
        _, t, peak = measure(lambda: write_animation(root / "p.gif", frames, fps=10, overwrite=True))
        figs.append(Figure(f"images: write_animation GIF {len(frames)} frames 625x434", t, peak))
        _, t, peak = measure(lambda: write_animation(root / "p.webp", frames, fps=10, overwrite=True))
        figs.append(Figure(f"images: write_animation WebP {len(frames)} frames 625x434 (lossless)", t, peak))
    return figs


if __name__ == "__main__":  # pragma: no cover
    from bench import print_table

    print_table(run())
