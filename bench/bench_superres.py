"""Refocused photographs at 2x the lenslet resolution against the generator's exact 2x ground truth.

For planes at disparity d (the generator's :func:`~plenodecode.synthetic.scene.dot_chart`: small flat-coloured
disks whose soft rims carry detail past the lenslet Nyquist frequency, and its smooth random texture), the 2x
photograph refocused at slope d is compared with ``Simulation.ground_truth_photograph(2)`` by

* PSNR (peak 1, linear sRGB, a border of 12 output pixels left out);
* MTF50: the frequency (cycles per lenslet pixel; the 2x grid reaches 1.0) where the transfer
  ``Re sum E conj(G) / sum |G|^2`` over rings of the 2D spectrum (``E`` of the photograph, ``G`` of the truth,
  luma, Hann-windowed, means removed) first falls below 0.5; "> 1" when it never does.  The cross-spectrum
  ignores errors uncorrelated with the truth (noise), so it measures lost contrast, not noise.

Methods: ``bicubic`` = OpenCV's INTER_CUBIC kernel (a = -0.75) applied to the 1x photograph, sampled on the same
grid as the others (output ``(j, i)`` at lenslet ``(j / 2, i / 2)``; ``cv2.resize`` would put its samples a
quarter of a lenslet pixel off); ``per-view`` = :func:`~plenodecode.render.shift_sum` with ``upsample=2`` (each
view interpolated at the fine positions, then averaged: what ``refocus(upsample=2)`` did before);
``fused`` = :func:`~plenodecode.render.superres.fuse_views` (what it does now).

Sources: the noise-free ground-truth light field of the f01-mini preset (9 x 9 views), and raws of the f01-mini
(hex lattice, Bayer) and square (square lattice, monochrome, 27 x 27 views) presets with noise, decoded with their
white image and true grid (the real path).
"""

from __future__ import annotations

import sys
import time

import cv2
import numpy as np

from . import Figure, measure

SLOPES = (0.0, 0.3, 0.5, -0.5)
BORDER = 12
#: (name, preset, sensor shape, decoded?, noise?)
SOURCES = (
    ("ground-truth LF, f01-mini", "f01-mini", (656, 656), False, False),
    ("decoded raw, f01-mini, noise", "f01-mini", (656, 656), True, True),
    ("decoded raw, square, noise", "square", (1100, 1100), True, True),
)


def bicubic_upsample(img: np.ndarray, k: int) -> np.ndarray:
    """OpenCV's bicubic interpolation (INTER_CUBIC, a = -0.75) of (Y, X, C) float32 at ``(j / k, i / k)``."""
    ny, nx, nc = img.shape
    m = np.float32([[1.0 / k, 0, 0], [0, 1.0 / k, 0]])
    out = cv2.warpAffine(img, m, (k * nx, k * ny), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                         borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(k * ny, k * nx, nc)


def psnr(img: np.ndarray, truth: np.ndarray, border: int = BORDER) -> float:
    """Peak signal-to-noise ratio (peak 1) of (Y, X, C) images, ``border`` pixels left out."""
    inner = (slice(border, -border), slice(border, -border))
    err = np.mean((img[inner].astype(np.float64) - truth[inner]) ** 2)
    return float(10 * np.log10(1.0 / err))


def transfer(img: np.ndarray, truth: np.ndarray, k: int, border: int = BORDER,
             width: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Ring-averaged transfer ``Re sum E conj(G) / sum |G|^2`` of luma; (frequencies in cycles per lenslet pixel,
    transfer), rings ``width`` wide up to ``k / 2``."""
    def spectrum(a: np.ndarray) -> np.ndarray:
        g = a[border:-border, border:-border].astype(np.float64).mean(axis=-1)
        g = g - g.mean()
        win = np.hanning(g.shape[0])[:, None] * np.hanning(g.shape[1])[None, :]
        return np.fft.fft2(g * win)

    e, g = spectrum(img), spectrum(truth)
    ny, nx = e.shape
    f = np.hypot(np.fft.fftfreq(ny)[:, None], np.fft.fftfreq(nx)[None, :]) * k      # cycles per lenslet px
    edges = np.arange(0.0, k / 2 + 1e-9, width)
    ring = np.digitize(f, edges) - 1
    ok = ring < len(edges) - 1
    cross = np.bincount(ring[ok], (e * np.conj(g)).real[ok], len(edges) - 1)
    power = np.bincount(ring[ok], (np.abs(g) ** 2)[ok], len(edges) - 1)
    return 0.5 * (edges[:-1] + edges[1:]), cross / np.maximum(power, 1e-30)


def mtf50(img: np.ndarray, truth: np.ndarray, k: int) -> float:
    """First frequency (cycles per lenslet pixel) where :func:`transfer` falls below 0.5 (inf if never)."""
    f, t = transfer(img, truth, k)
    below = np.flatnonzero(t < 0.5)
    if below.size == 0:
        return float("inf")
    i = int(below[0])
    if i == 0:
        return float(f[0])
    return float(f[i - 1] + (t[i - 1] - 0.5) / (t[i - 1] - t[i]) * (f[i] - f[i - 1]))


def nyquist_energy(img: np.ndarray, sigma: float = 2.0) -> np.ndarray:
    """Local energy of a (k Y, k X, C) photograph at the fine grid's Nyquist frequencies, (k Y, k X) float64.

    The luma ``g`` is demodulated by ``(-1)^j``, ``(-1)^i`` and ``(-1)^(j+i)`` (moving the (pi, 0), (0, pi) and
    (pi, pi) components to 0) and low-passed by a Gaussian of ``sigma`` fine pixels::

        N(j, i) = sum_m (G_sigma * (m g))(j, i)^2

    A pattern of period 2 (each output phase a different average) shows as ``N``; smooth content does not (its
    demodulated spectrum lies near pi, where the Gaussian is < 1 %).
    """
    g = img.astype(np.float64).mean(axis=-1)
    rows = 1.0 - 2.0 * (np.arange(g.shape[0]) % 2)[:, None]
    cols = 1.0 - 2.0 * (np.arange(g.shape[1]) % 2)[None, :]
    return sum(cv2.GaussianBlur(g * m, (0, 0), sigma) ** 2 for m in (rows, cols, rows * cols))


def checker_ratio(lf, disparity: np.ndarray, s: float, k: int = 2) -> float:
    """Mean :func:`nyquist_energy` of the fused ``k``x photograph refocused at ``s`` over the out-of-focus
    pixels (``|d - s| > 0.5``, ``disparity`` (Y, X) the scene's true disparity, a border of 12 output pixels left
    out) divided by that of bicubic upsampling of the 1x photograph (which has no such pattern)."""
    from plenodecode.render import refocus
    from plenodecode.render.superres import fuse_views

    inner = (slice(BORDER, -BORDER), slice(BORDER, -BORDER))
    far = np.kron(np.abs(disparity - s) > 0.5, np.ones((k, k), bool))[inner]
    fused = nyquist_energy(fuse_views(lf, s, upsample=k)[0])[inner]
    bicubic = nyquist_energy(bicubic_upsample(refocus(lf, slope=s), k))[inner]
    return float(fused[far].mean() / bicubic[far].mean())


def simulate_case(preset: str, shape: tuple[int, int], d: float, *, decoded: bool, noise: bool,
                  scene: str = "dot-chart"):
    """(light field, 1x truth, 2x truth) of a fronto-parallel scene at disparity ``d``."""
    import plenodecode.synthetic as syn
    from plenodecode.decoding import decode

    grid = syn.make_grid(syn.get_preset(preset), shape=shape)
    smp = grid.decoded_sampling()
    planes = (syn.dot_chart(int(smp["Y"]), int(smp["X"]), d, seed=1) if scene == "dot-chart"
              else [syn.Plane(d, texture_seed=3)])
    sim = syn.simulate(preset, noise=noise, shape=shape, scene=planes)
    lf = decode(sim.raw, sim.grid, white=sim.white) if decoded else sim.ground_truth_lightfield()
    return lf, sim.ground_truth_photograph(1), sim.ground_truth_photograph(2)


def compare(lf, truth2: np.ndarray, d: float, k: int = 2) -> dict[str, tuple[float, float]]:
    """PSNR and MTF50 of the three methods (module docstring): name -> (psnr, mtf50)."""
    from plenodecode.render import refocus, shift_sum
    from plenodecode.render.superres import fuse_views

    out = {
        "bicubic": bicubic_upsample(refocus(lf, slope=d), k),
        "per-view": shift_sum(lf, d, upsample=k)[0],
        "fused": fuse_views(lf, d, upsample=k)[0],
    }
    return {name: (psnr(img, truth2), mtf50(img, truth2, k)) for name, img in out.items()}


def _mtf(v: float) -> str:
    return " > 1" if not np.isfinite(v) else f"{v:4.2f}"


def print_checker_ratios() -> None:
    """Out-of-focus pattern of the fused 2x photograph (:func:`checker_ratio`) on the default generated scene
    (background d = -0.5, slanted plane 0 -> 0.6, disk 0.9)."""
    import plenodecode.synthetic as syn
    from plenodecode.decoding import decode

    lines = ["out-of-focus Nyquist energy, fused / bicubic (default scene; 1 = no pattern):"]
    for name, preset, shape, decoded, noise in SOURCES:
        sim = syn.simulate(preset, noise=noise, shape=shape)
        lf = decode(sim.raw, sim.grid, white=sim.white) if decoded else sim.ground_truth_lightfield()
        ratios = "  ".join(f"s = {s:+.1f}: {checker_ratio(lf, sim.disparity, s):5.2f}" for s in (0.9, 0.3, -0.5))
        lines.append(f"  {name:30s} {ratios}")
    print("\n".join(lines), file=sys.stderr, flush=True)


def run() -> list[Figure]:
    from plenodecode.render.superres import fuse_views

    rows = []
    cases = [(name, preset, shape, dec, noise, "dot-chart") for name, preset, shape, dec, noise in SOURCES]
    cases.insert(1, ("ground-truth LF, f01-mini", "f01-mini", (656, 656), False, False, "texture"))
    for name, preset, shape, decoded, noise, scene in cases:
        for d in SLOPES:
            lf, _, truth2 = simulate_case(preset, shape, d, decoded=decoded, noise=noise, scene=scene)
            rows.append((name, scene, "x".join(map(str, lf.shape[:4])), d, compare(lf, truth2, d)))
    head = (f"{'source':30s} {'scene':9s} {'V x U x Y x X':13s} {'d':>5s} | {'PSNR dB: bicubic':>16s} {'per-view':>8s} "
            f"{'fused':>6s} {'gain':>5s} | {'MTF50: bicubic':>14s} {'per-view':>8s} {'fused':>5s}")
    lines = [head, "-" * len(head)]
    for name, scene, shape, d, r in rows:
        (pb, mb), (pv, mv), (pf, mf) = r["bicubic"], r["per-view"], r["fused"]
        lines.append(f"{name:30s} {scene:9s} {shape:13s} {d:5.2f} | {pb:16.2f} {pv:8.2f} {pf:6.2f} {pf - pb:+5.2f} | "
                     f"{_mtf(mb):>14s} {_mtf(mv):>8s} {_mtf(mf):>5s}")
    print("\n".join(lines), file=sys.stderr, flush=True)
    print_checker_ratios()

    lf, _, _ = simulate_case("f01-mini", (656, 656), 0.5, decoded=True, noise=True)
    fuse_views(lf, 0.5, upsample=2)                          # compile outside the timings
    from plenodecode.render import refocus

    _, t_bic, _ = measure(lambda: bicubic_upsample(refocus(lf, slope=0.5), 2), repeat=3, memory=False)
    _, t, peak = measure(lambda: fuse_views(lf, 0.5, upsample=2), repeat=3)
    size = "x".join(map(str, lf.shape))
    gains = [f"{r['fused'][0] - r['bicubic'][0]:+.1f}" for n, s, _, d, r in rows if n.startswith("decoded") and d]
    return [Figure(f"superres: 2x fused photograph, {size}", t, peak, ratio=t_bic / t,
                   baseline="1x refocus + bicubic", note=f"PSNR gain, decoded |d| >= 0.3: {' '.join(gains)} dB")]


if __name__ == "__main__":  # pragma: no cover
    from . import print_table

    print_table(run())
