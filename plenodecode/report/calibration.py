"""Calibration report: one self-contained HTML page to judge a fitted lenslet grid.

Contents: the fitted parameters; zoomed overlays of the detected disk centres and the lattice at
the sensor centre and at each corner; a map and a histogram of the residuals (measured centre
minus grid centre); the vignetting profile (mean white level against the distance from the
sensor centre); and warnings (lenses not found, high residuals, a scene used as a white).
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..io.atomic import check_destination
from ..types import LensletGrid, RawCapture
from . import html as H

log = logging.getLogger(__name__)

#: Residual (px) above which a lens counts as badly placed in the warnings.
HIGH_RESIDUAL_PX = 0.5
#: Fraction of fully visible lenses without a detected disk above which a warning is shown.
MISSING_WARN_FRACTION = 0.02


def _measure(grid: LensletGrid, white: RawCapture | Sequence[RawCapture]) -> dict[str, Any]:
    """Flattened white, detected centres and their residuals against the grid."""
    from scipy.spatial import cKDTree

    from ..calib import centroids as C

    raws = [white] if isinstance(white, RawCapture) else list(white)
    img = None
    for r in raws:
        f = C.flatten_white(r, equalise=r.cfa is not None)
        img = f if img is None else img + f
    img = img / np.float32(len(raws))
    contrast = C.devignette(img, grid.pitch)
    peaks, _ = C.detect_peaks(contrast, grid.pitch)
    cen, ok = C.refine_peaks(contrast, peaks, grid.pitch)
    cen = cen[ok]
    centres = grid.centres()
    d, idx = cKDTree(centres).query(cen) if len(cen) else (np.zeros(0), np.zeros(0, int))
    assigned = d < 0.3 * grid.pitch
    res = np.full((len(cen), 2), np.nan)
    res[assigned] = cen[assigned] - centres[idx[assigned]]
    H_, W_ = grid.sensor_shape
    R = grid.radius
    full = ((centres[:, 0] - R >= -0.5) & (centres[:, 0] + R <= H_ - 0.5)
            & (centres[:, 1] - R >= -0.5) & (centres[:, 1] + R <= W_ - 0.5))
    # "found": an integer disk peak near the lens (sub-pixel centres need a full window, so they
    # are missing for lenses hugging the border)
    all_peaks, _ = C.detect_peaks(contrast, grid.pitch, margin=1)
    found = np.zeros(len(centres), bool)
    if len(all_peaks):
        dp, ip = cKDTree(centres).query(all_peaks.astype(np.float64))
        found[ip[dp < 0.3 * grid.pitch]] = True
    return {"img": img, "centres": cen, "residuals": res, "assigned": assigned, "grid_centres": centres,
            "full": full, "found": found}


def _overlay_figure(grid: LensletGrid, m: dict[str, Any]) -> Any:
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    img = m["img"]
    h, w = img.shape
    half = max(12, int(round(3.5 * grid.pitch)))
    spots = [("top left", half, half), ("top right", half, w - 1 - half), ("centre", h // 2, w // 2),
             ("bottom left", h - 1 - half, half), ("bottom right", h - 1 - half, w - 1 - half)]
    fig, axes = plt.subplots(1, 5, figsize=(17, 3.8))
    gc = m["grid_centres"]
    cen = m["centres"]
    for ax, (name, r, c) in zip(axes, spots):
        r0, r1 = max(0, r - half), min(h, r + half + 1)
        c0, c1 = max(0, c - half), min(w, c + half + 1)
        vmax = float(np.percentile(img[r0:r1, c0:c1], 99.5)) or 1.0  # per panel: vignetted corners stay visible
        ax.imshow(img[r0:r1, c0:c1], cmap="gray", vmin=0, vmax=vmax, extent=(c0 - 0.5, c1 - 0.5, r1 - 0.5, r0 - 0.5),
                  interpolation="nearest")
        sel = (gc[:, 0] >= r0) & (gc[:, 0] < r1) & (gc[:, 1] >= c0) & (gc[:, 1] < c1)
        ax.scatter(gc[sel, 1], gc[sel, 0], s=60, facecolors="none", edgecolors="#2b8cff", linewidths=1.2,
                   label="grid")
        if len(cen):
            sel = (cen[:, 0] >= r0) & (cen[:, 0] < r1) & (cen[:, 1] >= c0) & (cen[:, 1] < c1)
            ax.plot(cen[sel, 1], cen[sel, 0], "+", color="#ff3030", ms=7, mew=1.2, label="detected")
        ax.set_title(f"{name} (rows {r0}-{r1 - 1})", fontsize=9)
        ax.set_xlim(c0 - 0.5, c1 - 0.5)
        ax.set_ylim(r1 - 0.5, r0 - 0.5)
        ax.tick_params(labelsize=7)
    axes[0].legend(loc="lower left", fontsize=7, framealpha=0.8)
    fig.tight_layout()
    return fig


def _residual_figure(grid: LensletGrid, m: dict[str, Any]) -> Any:
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    a = m["assigned"]
    cen, res = m["centres"][a], m["residuals"][a]
    mag = np.hypot(res[:, 0], res[:, 1]) if len(res) else np.zeros(0)
    h, w = grid.sensor_shape
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(14, 5), gridspec_kw={"width_ratios": [1.6, 1]})
    if len(mag):
        top = max(float(np.percentile(mag, 99)), 1e-3)
        hb = ax0.hexbin(cen[:, 1], cen[:, 0], C=mag, gridsize=min(60, max(10, int(math.sqrt(len(mag)) // 2))),
                        reduce_C_function=np.mean, cmap="viridis", vmin=0, vmax=top)
        fig.colorbar(hb, ax=ax0, label="mean |residual| (px)")
        ax1.hist(mag, bins=60, range=(0, max(top * 1.5, 0.05)), color="#4477aa")
        ax1.axvline(float(np.sqrt(np.mean(mag ** 2))), color="k", ls="--", lw=1, label="RMS")
        ax1.legend(fontsize=8)
    ax0.set_xlim(0, w)
    ax0.set_ylim(h, 0)
    ax0.set_aspect("equal")
    ax0.set_title("residual map: detected centre - grid centre", fontsize=10)
    ax0.set_xlabel("sensor column (px)")
    ax0.set_ylabel("sensor row (px)")
    ax1.set_title("residual histogram", fontsize=10)
    ax1.set_xlabel("|residual| (px)")
    ax1.set_ylabel("lenses")
    fig.tight_layout()
    return fig


def vignetting_profile(img: np.ndarray, *, bins: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Mean of an image against the distance from its centre.

    Returns
    -------
    radius : ndarray (bins,) float64, bin centres in px
    mean : ndarray (bins,) float64, NaN for empty bins
    """
    h, w = img.shape
    step = max(1, int(math.sqrt(h * w / 2e6)))
    sub = img[::step, ::step].astype(np.float64)
    rr, cc = np.mgrid[0:h:step, 0:w:step]
    r = np.hypot(rr - (h - 1) / 2, cc - (w - 1) / 2).ravel()
    edges = np.linspace(0, r.max() + 1e-9, bins + 1)
    k = np.clip(np.digitize(r, edges) - 1, 0, bins - 1)
    s = np.bincount(k, weights=sub.ravel(), minlength=bins)
    n = np.bincount(k, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s / n
    return 0.5 * (edges[:-1] + edges[1:]), np.where(n > 0, mean, np.nan)


def _vignetting_figure(m: dict[str, Any]) -> Any:
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    r, mean = vignetting_profile(m["img"])
    fig, ax = plt.subplots(figsize=(7, 3.5))
    peak = np.nanmax(mean) if np.isfinite(mean).any() else 1.0
    ax.plot(r, mean / peak, "-o", ms=3, color="#aa5522")
    ax.set_xlabel("distance from the sensor centre (px)")
    ax.set_ylabel("mean white level (relative)")
    ax.set_ylim(0, 1.05)
    ax.grid(alpha=0.3)
    ax.set_title("vignetting profile", fontsize=10)
    fig.tight_layout()
    return fig


def calibration_warnings(grid: LensletGrid, m: dict[str, Any]) -> list[str]:
    """Human-readable warnings about a calibration (missing lenses, high residuals, bad input)."""
    out = [str(w) for w in grid.info.get("warnings", [])]
    full = m["full"]
    missing = full & ~m["found"]
    if full.sum() and missing.sum() / full.sum() > MISSING_WARN_FRACTION:
        out.append(f"{int(missing.sum())} of {int(full.sum())} fully visible lenses ({missing.sum() / full.sum():.1%}) "
                   "show no detectable disk (dust, dead lenses or dark corners); the lattice places them")
    a = m["assigned"]
    if a.sum():
        mag = np.hypot(*m["residuals"][a].T)
        high = mag > HIGH_RESIDUAL_PX
        if high.mean() > 0.01:
            out.append(f"{int(high.sum())} lenses ({high.mean():.1%}) are more than {HIGH_RESIDUAL_PX} px from the "
                       "grid; check the residual map for distortion or a wrong white image")
        rms = float(np.sqrt(np.mean(mag ** 2)))
        if rms > 0.1:
            out.append(f"RMS residual {rms:.3f} px is high for a white image (expected < 0.1 px)")
    else:
        out.append("no lens disk could be detected in the white image")
    return out


def write_calibration_report(grid: LensletGrid, white: Any, path: str | os.PathLike, *,
                             overwrite: bool = False, title: str | None = None) -> Path:
    """Write one self-contained HTML report of a calibration.

    Parameters
    ----------
    grid : LensletGrid
        The fitted grid.
    white : RawCapture, path or sequence of them
        The white image(s) the grid was fitted on.
    path : path
        Output ``.html`` (written to a temporary name, then renamed).
    overwrite : bool
        Replace an existing file.
    title : str, optional

    Returns
    -------
    Path

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    """
    p = check_destination(path, overwrite)
    from ..calib import _as_raws

    raws = _as_raws(white)
    m = _measure(grid, raws)
    a = m["assigned"]
    mag = np.hypot(*m["residuals"][a].T) if a.sum() else np.zeros(0)
    inf = grid.info
    params = [
        ("lattice", grid.lattice),
        ("pitch (along rows)", f"{grid.pitch:.5f} px"),
        ("row spacing", f"{grid.row_spacing:.5f} px ({grid.row_spacing / grid.pitch:.5f} x pitch)"),
        ("rotation", f"{grid.rotation:.6f} rad ({math.degrees(grid.rotation):.4f} deg)"),
        ("origin (lens 0, 0)", f"row {grid.origin[0]:.3f}, col {grid.origin[1]:.3f}"),
        ("odd row shift", f"{grid.odd_row_shift:+.1f} pitch"),
        ("lenses (rows x cols)", f"{grid.shape[0]} x {grid.shape[1]} = {grid.shape[0] * grid.shape[1]}"),
        ("sensor (H x W)", f"{grid.sensor_shape[0]} x {grid.sensor_shape[1]}"),
        ("disk radius", f"{grid.radius:.3f} px"),
        ("fit RMS residual", "n/a" if grid.residual_rms is None else f"{grid.residual_rms:.4f} px"),
        ("refined lenses", str(int(np.isfinite(grid.refined[..., 0]).sum())) if grid.refined is not None else "0"),
        ("disks detected (report)", f"{int(a.sum())} ({int(m['found'][m['full']].sum())} of "
                                    f"{int(m['full'].sum())} fully visible lenses)"),
        ("residual RMS / 95th pct (report)",
         f"{float(np.sqrt(np.mean(mag ** 2))) if len(mag) else float('nan'):.4f} / "
         f"{float(np.percentile(mag, 95)) if len(mag) else float('nan'):.4f} px"),
    ]
    for key in ("camera_model", "serial", "zoom_step", "focus_step", "source", "n_whites", "method", "binning"):
        if inf.get(key) is not None:
            params.append((key.replace("_", " "), str(inf[key])))
    warnings = calibration_warnings(grid, m)
    notes = H.notes_html(warnings) if warnings else H.notes_html(["no problems found"], kind="ok")
    parts = [
        H.section("Warnings", notes),
        H.section("Fitted parameters", H.table_html(params, header=("parameter", "value"))),
        H.section("Detected centres and lattice",
                  H.figure_html(_overlay_figure(grid, m), "red +: detected disk centres; blue circles: grid centres "
                                                          "(refined where measured), at the corners and the centre")),
        H.section("Residuals", H.figure_html(_residual_figure(grid, m), "detected minus grid centre, every lens")),
        H.section("Vignetting", H.figure_html(_vignetting_figure(m), "mean normalised white level against radius")),
    ]
    src = inf.get("source") or (raws[0].path if raws else None) or "(given in memory)"
    doc = H.page(title or "plenodecode calibration report", parts, subtitle=f"white image: {src}")
    out = H.write_html(p, doc, overwrite=overwrite)
    log.info("calibration report written to %s", out)
    return out


__all__ = ["write_calibration_report", "calibration_warnings", "vignetting_profile"]
