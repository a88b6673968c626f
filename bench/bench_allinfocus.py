"""All-in-focus quality and time (issue 19, item 3): PSNR against the generator's noise-free centre view.

Scenes: the illum-mini default scene (background, slanted plane, front disk; 15 x 15 x 87 x 125) of seeds 1
and 2, as (i) the ideal light field plus Gaussian noise (sigma 0.02, linear) and (ii) its simulated raw
decoded by the pipeline (demosaicing, resampling, sensor noise, dark border views).  The truth is
``sim.ground_truth_lightfield()``'s centre view (noise-free).  PSNR (peak 1) overall and in the band within
3 px of a depth edge (``|morphological gradient of sim.disparity| > 0.1`` dilated 3 times), a 5 px border
excluded, for: the centre view alone; the focal-stack method (the default before); the depth-guided default
(depth 'fast'); the same with 'costvolume' depth, with the true disparity, and without its photo-consistency
weight (visibility only).

The time rows render a full-size (Lytro Illum) 15 x 15 x 434 x 625 light field (:mod:`bench.bench_render`'s)
both ways: the choice of the ``refocus --focal-stack`` command's all_in_focus image.
"""

from __future__ import annotations

import time

import numpy as np

from . import Figure, measure

NOISE = 0.02
SEEDS = (1, 2)
BAND_PX = 3
BORDER = 5


def psnr(img: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    """``10 log10(1 / MSE)`` over ``mask`` (linear values, peak 1)."""
    return float(10 * np.log10(1.0 / np.mean((img - truth)[mask] ** 2)))


def edge_band(disparity: np.ndarray, width: int = BAND_PX, jump: float = 0.1) -> np.ndarray:
    """Pixels within ``width`` px of a depth edge: a 3 x 3 disparity range above ``jump``, dilated ``width``
    times (3 x 3 cross)."""
    import scipy.ndimage as ndi

    edge = ndi.morphological_gradient(disparity, size=3) > jump
    return ndi.binary_dilation(edge, iterations=width)


def scenes():
    """(name, light field, truth (Y, X, C), disparity) for each seed: noisy ideal and decoded."""
    from plenodecode.decoding import decode
    from plenodecode.synthetic import simulate

    for seed in SEEDS:
        sim = simulate("illum-mini", seed=seed)
        ideal = sim.ground_truth_lightfield()
        truth = ideal.centre_view()
        rng = np.random.default_rng(seed)
        noisy = ideal.replace(data=ideal.data + rng.normal(0, NOISE, ideal.shape).astype(np.float32))
        yield f"seed {seed} ideal + noise {NOISE}", noisy, truth, sim.disparity
        lf = decode(sim.raw, sim.grid, white=sim.white)
        lf = lf.replace(metadata={**lf.metadata, "disparity_range": list(sim.disparity_range)})
        yield f"seed {seed} decoded raw", lf, truth, sim.disparity


def quality_figures() -> list[Figure]:
    from plenodecode.render import all_in_focus

    figs = []
    for name, lf, truth, disparity in scenes():
        inner = np.zeros(disparity.shape, bool)
        inner[BORDER:-BORDER, BORDER:-BORDER] = True
        band = inner & edge_band(disparity)
        methods = {
            "(a) centre view": lambda: lf.centre_view(),
            "(b) focal-stack (before)": lambda: all_in_focus(lf, method="focal-stack"),
            "(c) depth, 'fast' (default)": lambda: all_in_focus(lf),
            "    depth, 'costvolume'": lambda: all_in_focus(lf, depth_method="costvolume"),
            "    depth, visibility only": lambda: all_in_focus(lf, consistency=0.0),
            "    depth, true disparity": lambda: all_in_focus(lf, depth=disparity),
        }
        for label, fn in methods.items():
            t0 = time.perf_counter()
            img = fn()
            seconds = time.perf_counter() - t0
            scores = f"PSNR {psnr(img, truth, inner):5.2f} dB, edge band {psnr(img, truth, band):5.2f} dB"
            figs.append(Figure(f"aif {name}: {label}", seconds, note=scores))
    return figs


def time_figures() -> list[Figure]:
    from plenodecode.render import all_in_focus, focal_stack
    from plenodecode.render.allinfocus import all_in_focus_from_stack

    from .bench_render import STACK, make_lightfield

    lf = make_lightfield()
    size = "x".join(map(str, lf.shape))
    stack, t_stack, _ = measure(lambda: focal_stack(lf, STACK), memory=False)
    _, t_from_stack, _ = measure(lambda: all_in_focus_from_stack(lf, stack, STACK), memory=False)
    del stack
    _, t_depth, peak = measure(lambda: all_in_focus(lf))
    return [Figure(f"aif {size}: 30-slice stack + all-in-focus from it", t_stack + t_from_stack,
                   note=f"stack {t_stack:.1f} s, all-in-focus {t_from_stack:.1f} s (refocus --focal-stack)"),
            Figure(f"aif {size}: depth-guided (fast depth + render)", t_depth, peak,
                   note=f"{t_depth / t_from_stack:.1f}x the all-in-focus step of the stack")]


def run() -> list[Figure]:
    return quality_figures() + time_figures()


if __name__ == "__main__":  # pragma: no cover
    from . import print_table

    print_table(run())
