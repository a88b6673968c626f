"""Lytro I/O speed: full-size Illum LFR and F01 LFP reads (container parse + SHA-1 + unpack).

The inputs are generated once into ``bench/_cache/`` (random mosaics at full sensor size).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from bench import Figure, measure
from plenodecode.io.lytro import read_container, read_lytro, read_raw_pair, write_lfp, write_lfr, write_raw_pair
from plenodecode.io.packing import pack_10bit, unpack_10bit
from plenodecode.types import CameraMetadata, RawCapture

CACHE = Path(__file__).resolve().parent / "_cache"


def _capture(shape: tuple[int, int], bits: int, cfa: str, model: str) -> RawCapture:
    rng = np.random.default_rng(0)
    mosaic = rng.integers(0, 1 << bits, shape, dtype=np.uint16)
    cam = CameraMetadata(make="Lytro, Inc.", model=model, serial="B0000000000", zoom_step=0, focus_step=0,
                         pixel_pitch_m=1.4e-6, lens_pitch_m=2e-5 if bits == 10 else 1.38986e-5)
    black = 64 if bits == 10 else 168
    return RawCapture(mosaic, cfa, black, (1 << bits) - 1, cam)


def _inputs() -> dict[str, Path]:
    CACHE.mkdir(exist_ok=True)
    paths = {"lfr": CACHE / "illum_full.lfr", "lfp": CACHE / "f01_full.lfp", "pair": CACHE / "MOD_0000.RAW"}
    illum = None
    if not paths["lfr"].exists():
        illum = _capture((5368, 7728), 10, "GRBG", "ILLUM")
        write_lfr(paths["lfr"], illum)
    if not paths["pair"].exists():
        illum = illum or _capture((5368, 7728), 10, "GRBG", "B01")
        write_raw_pair(paths["pair"], illum)
    if not paths["lfp"].exists():
        write_lfp(paths["lfp"], _capture((3280, 3280), 12, "BGGR", "F01"))
    return paths


def run() -> list[Figure]:
    paths = _inputs()
    figures = []
    raw, t, peak = measure(lambda: read_lytro(paths["lfr"]), repeat=3)
    assert raw.shape == (5368, 7728)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    figures.append(Figure("io: read_lytro Illum .lfr 7728x5368 10-bit (SHA-1 on)", t, peak, target_s=0.3,
                          note=f"1-min load {load:.1f} on {os.cpu_count()} cores"))
    _, t, peak = measure(lambda: read_lytro(paths["lfr"], verify=False), repeat=3)
    figures.append(Figure("io: read_lytro Illum .lfr, verify=False", t, peak, target_s=0.3))
    _, t, peak = measure(lambda: read_container(paths["lfr"]), repeat=3)
    figures.append(Figure("io: read_container Illum .lfr (scan + SHA-1 only)", t, peak))
    buf = pack_10bit(raw.mosaic)
    _, t, peak = measure(lambda: unpack_10bit(buf, 5368, 7728), repeat=3)
    figures.append(Figure("io: unpack_10bit 51,854,880 B (in memory)", t, peak))
    _, t, peak = measure(lambda: pack_10bit(raw.mosaic), repeat=1)
    figures.append(Figure("io: pack_10bit 7728x5368", t, peak))
    del buf, raw
    raw, t, peak = measure(lambda: read_raw_pair(paths["pair"]), repeat=3)
    figures.append(Figure("io: read_raw_pair Illum MOD_0000.RAW + .TXT", t, peak, target_s=0.3))
    raw, t, peak = measure(lambda: read_lytro(paths["lfp"]), repeat=3)
    assert raw.shape == (3280, 3280)
    figures.append(Figure("io: read_lytro F01 .lfp 3280x3280 12-bit (SHA-1 on)", t, peak, target_s=0.3))
    return figures


if __name__ == "__main__":  # pragma: no cover
    from bench import print_table

    print_table(run())
