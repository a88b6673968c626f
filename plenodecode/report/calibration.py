"""Calibration report: one self-contained HTML page to judge a lenslet grid by what its source can show.

The header names the grid's source (``grid.info['source_kind']``, one of
:data:`plenodecode.calib.grid.SOURCE_KINDS`) and gives a verdict -- good, check or bad -- from
rules stated on the page:

* **white image(s)** (and grids of unknown origin checked against white images): the RMS and
  the disks of the white image measured against the grid (lenses more than 0.5 px off, disks
  near no lens, lenses without a disk); where the centres depart from the regular lattice mostly
  by a smooth field (optics bending the lens array's image, which the decoder follows through each
  lens's measured centre: :func:`smooth_part`), the RMS is judged by what is left about it;
* **self-calibration**: what a scene can show -- the RMS compared with the spread that
  scene-based centre detection has, the local misfit of the lattice, the fraction of lenses
  found and the smooth departure of the centres from the lattice, which a self-calibrated grid does not
  follow (:data:`SELFCAL_RULES`, thresholds measured on generated scenes and the real captures);
* **the camera's own calibration file** (Raytrix XML) used as given: no residual judgement, the
  grid is drawn on the image only (and a refit on the image, when asked for, is reported as such).

The header gives one accuracy figure: against white images, the lens-centre accuracy
(:data:`ACCURACY_DEFINITION`: where the decoder cuts each micro-image against its disk, the residual histogram's
line); otherwise the lattice RMS (:data:`RMS_DEFINITION`), which ``plenodecode calibrate`` prints
(:func:`rms_text`) and a white image's page names as such; a camera's file used as given has none, and its headline
says the grid is drawn on the image to check by eye.  Further contents: fitted parameters, zoomed overlays at the
sensor centre and
corners, residual map and histogram, and (white images) the vignetting profile.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..io.atomic import check_destination
from ..types import LensletGrid, RawCapture
from . import html as H

log = logging.getLogger(__name__)

#: The lattice fit's RMS, shown on the report and in the CLI's summary line.
RMS_DEFINITION = ("lattice RMS: root-mean-square distance between the measured micro-image centres and the fitted "
                  "regular lattice, px, over the inlier lenses")
#: The headline of a grid checked against white images: how far the centres the decoder uses are from the disks.
ACCURACY_DEFINITION = ("lens-centre accuracy: root-mean-square distance between the lens centres the decoder uses "
                       "(the lattice, or each lens's measured centre where the fit kept one) and the disks of the "
                       "white image, detected again at full resolution, px, over every disk near a lens")
#: Verdicts, from best to worst.
LEVELS = ("good", "check", "bad")
#: Residual (px) above which a lens of a white image counts as off the grid.
HIGH_RESIDUAL_PX = 0.5
#: Fraction of the white image's disks allowed to be off the grid by more than HIGH_RESIDUAL_PX.
HIGH_RESIDUAL_FRACTION = 0.01
#: Fraction of fully visible lenses without a detected disk above which a white image is flagged.
MISSING_WARN_FRACTION = 0.02
#: White images: RMS (px) up to which a fit is good / to check (sample white images fit at 0.03-0.04 px).
WHITE_RMS_PX = (0.1, 0.25)
#: Self-calibration rules: quantity -> (good up to / from, check up to / from), see SELFCAL_BASIS.
SELFCAL_RULES = {
    "rms_pitch": (0.08, 0.125),        # RMS / pitch, at most
    "misfit_pitch": (0.05, 0.10),      # local misfit / pitch, at most
    "found": (0.5, 0.2),               # fraction of the inner lenses found, at least
    "smooth_pitch": (0.05, 0.15),      # largest smooth departure of the centres from the lattice / pitch, at most
}
#: How the self-calibration thresholds were derived (printed on the report).
SELFCAL_BASIS = (
    "Thresholds measured on generated scenes with known grids (f01-mini and illum-mini, 3 seeds each, "
    "with and without noise, and as 8-bit JPEG q80): the fitted grids were 0.002-0.013 px from the truth "
    "while the detections scattered with RMS 0.005-0.016 pitch (RMS / (sqrt 2 x robust sigma) 1.06-1.15: "
    "noise-like), local misfit 0.003-0.008 pitch, 88-98 % of the lenses found; the real F01 JPEGs give RMS "
    "0.04-0.05 pitch, local misfit 0.02-0.035 pitch, 80-86 % found.  Grids moved off the fit by a known "
    "amount (0.3 px shift, 0.1 % and 0.3 % pitch, 1 mrad rotation) read local misfits equal to their true "
    "RMS error (0.30, 0.52, 1.57, 0.52 px).  RMS up to 0.08 pitch keeps the 4-sigma inlier cut "
    "(4 RMS / sqrt 2 = 0.23 pitch) inside the 0.25-pitch window in which a centre is assigned to a lens.  "
    "A smooth field (cubic in the lens indices) fitted to the rim centres reads at most 0.005 pitch on the sample "
    "scenes, 0.03-0.035 pitch on the F01 JPEGs and 0.09 pitch (2.5 px) on the ant-leg microscope scene, whose "
    "radiometry frame shows a relay-lens distortion of 2.4 px: the self-calibrated lattice is up to 3 px off there.")


@dataclass(frozen=True)
class Check:
    """One judged quantity of a report: what, its value, the rule, and the level reached."""

    quantity: str
    value: str
    rule: str
    level: str
    note: str = ""


def _level(value: float, good: float, check: float, *, higher_is_better: bool = False) -> str:
    if not math.isfinite(value):
        return "check"
    if higher_is_better:
        return "good" if value >= good else "check" if value >= check else "bad"
    return "good" if value <= good else "check" if value <= check else "bad"


def source_kind(grid: LensletGrid) -> str:
    """The grid's ``info['source_kind']``; 'grid-file' when it carries none (a grid of unknown origin)."""
    from ..calib.grid import SOURCE_KINDS
    kind = grid.info.get("source_kind")
    return kind if kind in SOURCE_KINDS else "grid-file"


def smooth_part(grid: LensletGrid, rms: float | None) -> dict[str, float] | None:
    """:func:`plenodecode.calib.grid.smooth_distortion` of ``grid`` when it explains an RMS above the white images'
    good limit (what is left is less than half of it), else None."""
    from ..calib.grid import smooth_distortion

    if rms is None or rms <= WHITE_RMS_PX[0]:
        return None
    smooth = smooth_distortion(grid)
    return smooth if smooth is not None and smooth["rest_rms_px"] < rms / 2 else None


def angle_text(rad: float) -> str:
    """``'-0.00487 rad (-0.279 deg)'``: an angle as the report, ``calibrate`` and ``info`` print it (0.00001 rad,
    0.001 deg; a rotation that rounds to zero, or the Raytrix XML's -0.0, prints as 0, never -0)."""
    r, d = round(float(rad), 5) + 0.0, round(math.degrees(float(rad)), 3) + 0.0      # + 0.0 turns -0.0 into 0.0
    return f"{r:.5f} rad ({d:.3f} deg)"


def refitted(grid: LensletGrid) -> bool:
    """Whether ``--refine`` moved the grid on the image: ``info['refit']`` holds a refit, not the record of a
    skipped one (``method`` 'none', with its ``reason``)."""
    rf = grid.info.get("refit")
    return isinstance(rf, dict) and rf.get("method") != "none"


def rms_text(grid: LensletGrid) -> str:
    """The one RMS figure as shown by the report and ``plenodecode calibrate`` (:data:`RMS_DEFINITION`), with
    what is left about a smooth distortion of the lens array's image when that explains it (:func:`smooth_part`)."""
    if source_kind(grid) == "camera-file" and not refitted(grid):
        return "n/a (grid used as given)"
    if grid.residual_rms is None:
        return "n/a"
    smooth = smooth_part(grid, grid.residual_rms)
    return f"{grid.residual_rms:.3f} px" + ("" if smooth is None else f" ({smooth['rest_rms_px']:.3f} px about a "
                                                                      f"smooth distortion of up to "
                                                                      f"{smooth['max_px']:.2f} px)")


def _white_measure(grid: LensletGrid, raws: Sequence[RawCapture]) -> dict[str, Any]:
    """Flattened white, disks detected as for a white image and their residuals against the grid's centres (the
    measured ones where the grid has them, as the decoder uses)."""
    from scipy.spatial import cKDTree

    from ..calib import centroids as C

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
    return {"img": img, "centres": cen, "residuals": res, "assigned": assigned, "lens": idx, "grid_centres": centres,
            "full": full, "found": found}


def _scene_measure(grid: LensletGrid, raws: Sequence[RawCapture]) -> dict[str, Any]:
    """Flattened scene and its disks measured by their rims at every lens (as self-calibration does)."""
    from ..calib.selfcal import scene_centres, scene_image

    img = scene_image(raws[0])[0]
    centres = grid.centres()
    cen, lens = scene_centres(img, grid)
    res = cen - centres[lens]
    return {"img": img, "centres": cen, "residuals": res, "assigned": np.ones(len(cen), bool), "lens": lens,
            "grid_centres": centres}


def _image_measure(grid: LensletGrid, raws: Sequence[RawCapture]) -> dict[str, Any]:
    """The image and the grid, no detection (grids used as given)."""
    from ..calib import centroids as C

    img = C.flatten_white(raws[0], equalise=raws[0].cfa is not None) if raws else None
    return {"img": img, "centres": np.zeros((0, 2)), "residuals": np.zeros((0, 2)), "assigned": np.zeros(0, bool),
            "lens": np.zeros(0, int), "grid_centres": grid.centres()}


#: Overlay panels, in a 2 x 3 layout: name, (row, col) of the panel, where it looks (0: top / left, 1: centre,
#: 2: bottom / right); the free slot (1, 1) holds the legend, clear of the image.
_OVERLAY_SPOTS = (("top left", (0, 0), (0, 0)), ("centre", (0, 1), (1, 1)), ("top right", (0, 2), (0, 2)),
                  ("bottom left", (1, 0), (2, 0)), ("bottom right", (1, 2), (2, 2)))
#: Overlay markers in units of the pitch: the arm of a detected centre's '+' and the radius of the grid centre's dot
#: (the grid's circles are drawn at its disk radius, the micro-image's outline the decoder uses).
OVERLAY_CROSS_PITCH = 0.2
OVERLAY_DOT_PITCH = 0.06


def _overlay_figure(grid: LensletGrid, m: dict[str, Any]) -> tuple[Any, dict[str, float]]:
    """The image at its corners and centre (7 pitches across each) with the grid drawn on it in image units: a circle
    of the disk radius and a dot at every grid centre, a '+' at every detected centre, so the markers keep their size
    against the micro-images whatever the pitch.

    Returns the figure and its marker sizes in px of the image: ``pitch``, ``circle_radius``, ``cross_arm``,
    ``dot_radius``, and ``legend_overlap`` (area of the legend over the panels, display px^2: 0)."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.collections import EllipseCollection, LineCollection

    img = m["img"]
    h, w = img.shape
    half = max(12, int(round(3.5 * grid.pitch)))
    gc = m["grid_centres"]
    cen = m["centres"]
    sizes = {"pitch": float(grid.pitch), "circle_radius": float(grid.radius),
             "cross_arm": OVERLAY_CROSS_PITCH * grid.pitch, "dot_radius": OVERLAY_DOT_PITCH * grid.pitch}
    fig, axes = plt.subplots(2, 3, figsize=(12, 8.6))
    for name, (i, j), (py, px) in _OVERLAY_SPOTS:
        ax = axes[i, j]
        r = (half, h // 2, h - 1 - half)[py]
        c = (half, w // 2, w - 1 - half)[px]
        r0, r1 = max(0, r - half), min(h, r + half + 1)
        c0, c1 = max(0, c - half), min(w, c + half + 1)
        vmax = float(np.percentile(img[r0:r1, c0:c1], 99.5)) or 1.0  # per panel: vignetted corners stay visible
        ax.imshow(img[r0:r1, c0:c1], cmap="gray", vmin=0, vmax=vmax, extent=(c0 - 0.5, c1 - 0.5, r1 - 0.5, r0 - 0.5),
                  interpolation="nearest")
        pad = grid.radius
        sel = (gc[:, 0] >= r0 - pad) & (gc[:, 0] < r1 + pad) & (gc[:, 1] >= c0 - pad) & (gc[:, 1] < c1 + pad)
        xy = gc[sel][:, ::-1]
        for diameter, style in ((2 * sizes["circle_radius"], {"facecolors": "none", "edgecolors": "#2b8cff",
                                                              "linewidths": 1.3}),
                                (2 * sizes["dot_radius"], {"facecolors": "#2b8cff", "edgecolors": "none"})):
            ax.add_collection(EllipseCollection(diameter, diameter, 0.0, units="xy", offsets=xy,
                                                offset_transform=ax.transData, **style))
        if len(cen):
            sel = (cen[:, 0] >= r0) & (cen[:, 0] < r1) & (cen[:, 1] >= c0) & (cen[:, 1] < c1)
            a = sizes["cross_arm"]
            y, x = cen[sel, 0], cen[sel, 1]
            arms = np.concatenate([np.stack([np.stack([x - a, y], 1), np.stack([x + a, y], 1)], 1),
                                   np.stack([np.stack([x, y - a], 1), np.stack([x, y + a], 1)], 1)])
            ax.add_collection(LineCollection(arms, colors="#ff3030", linewidths=1.4))
        ax.set_title(f"{name} (rows {r0}-{r1 - 1}, cols {c0}-{c1 - 1})", fontsize=10)
        ax.set_xlim(c0 - 0.5, c1 - 0.5)
        ax.set_ylim(r1 - 0.5, r0 - 0.5)
        ax.tick_params(labelsize=8)
    key = axes[1, 1]
    key.axis("off")
    handles = [plt.Line2D([], [], ls="none", marker="o", ms=14, mfc="none", mec="#2b8cff", mew=1.3,
                          label=f"grid lens: disk of radius {grid.radius:.1f} px\n(pitch {grid.pitch:.2f} px)"),
               plt.Line2D([], [], ls="none", marker="o", ms=4, color="#2b8cff", label="grid lens centre")]
    if len(cen):
        handles.append(plt.Line2D([], [], ls="none", marker="+", ms=12, mew=1.4, color="#ff3030",
                                  label="detected disk centre"))
    legend = key.legend(handles=handles, loc="center", fontsize=10, frameon=False, handletextpad=1.0,
                        labelspacing=1.2)
    fig.tight_layout()
    fig.canvas.draw()
    lb = legend.get_window_extent()
    overlap = 0.0
    for ax in axes.flat:
        if ax is key:
            continue
        ab = ax.get_window_extent()
        dx = min(lb.x1, ab.x1) - max(lb.x0, ab.x0)
        dy = min(lb.y1, ab.y1) - max(lb.y0, ab.y0)
        overlap += max(dx, 0.0) * max(dy, 0.0)
    sizes["legend_overlap"] = float(overlap)
    return fig, sizes


def _residual_figure(grid: LensletGrid, m: dict[str, Any], line: tuple[str, float | None]) -> Any:
    """Residual map and histogram of the detected centres; ``line``: (label, px) of the dashed RMS line (px None:
    the RMS of the residuals drawn)."""
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
        rms = float(np.sqrt(np.mean(mag ** 2))) if line[1] is None else line[1]
        ax1.axvline(rms, color="k", ls="--", lw=1, label=f"{line[0]} {rms:.3f} px")
        ax1.legend(fontsize=8)
    ax0.set_xlim(0, w)
    ax0.set_ylim(h, 0)
    ax0.set_aspect("equal")
    ax0.set_title("residual map: detected centre - grid centre (as decoded)", fontsize=10)
    ax0.set_xlabel("sensor column (px)")
    ax0.set_ylabel("sensor row (px)")
    ax1.set_title("residual histogram", fontsize=10)
    ax1.set_xlabel("|residual| (px)")
    ax1.set_ylabel("lenses")
    fig.tight_layout()
    return fig


def vignetting_profile(img: np.ndarray, centres: np.ndarray | None = None, *,
                       bins: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Brightness of an image against the distance from its centre.

    With ``centres`` the image is read at the lens centres only (nearest pixel) and each bin gives the median of its
    lenses: the gaps between the disks and the unlit border around a lens array, which an average over all
    pixels mixes in (a dip where a radius first reaches a dark border, a zigzag where a bin is narrower than a
    lens), do not count.  Without ``centres`` every pixel counts (the mean).

    Parameters
    ----------
    img : ndarray (H, W), float
    centres : ndarray (N, 2) float64, optional
        Lens centres (row, col) in px, e.g. those with a disk in a white image.
    bins : int

    Returns
    -------
    radius : ndarray (bins,) float64, bin centres in px
    value : ndarray (bins,) float64, NaN for empty bins
    """
    h, w = img.shape
    if centres is not None:
        c = np.asarray(centres, np.float64).reshape(-1, 2)
        ij = np.rint(c).astype(np.int64)
        on = (ij[:, 0] >= 0) & (ij[:, 0] < h) & (ij[:, 1] >= 0) & (ij[:, 1] < w)
        vals = img[ij[on, 0], ij[on, 1]].astype(np.float64)
        r = np.hypot(c[on, 0] - (h - 1) / 2, c[on, 1] - (w - 1) / 2)
    else:
        step = max(1, int(math.sqrt(h * w / 2e6)))
        rr, cc = np.mgrid[0:h:step, 0:w:step]
        vals = img[::step, ::step].astype(np.float64).ravel()
        r = np.hypot(rr - (h - 1) / 2, cc - (w - 1) / 2).ravel()
    edges = np.linspace(0, (r.max() if len(r) else 0.0) + 1e-9, bins + 1)
    k = np.clip(np.digitize(r, edges) - 1, 0, bins - 1)
    if centres is None:
        s = np.bincount(k, weights=vals, minlength=bins)
        n = np.bincount(k, minlength=bins)
        with np.errstate(invalid="ignore", divide="ignore"):
            value = np.where(n > 0, s / n, np.nan)
    else:
        value = np.array([np.median(vals[k == b]) if np.any(k == b) else np.nan for b in range(bins)])
    return 0.5 * (edges[:-1] + edges[1:]), value


def _vignetting_figure(m: dict[str, Any]) -> tuple[Any, str]:
    """The vignetting profile of a white image at its lenses with a disk; returns the figure and its caption
    (the edge's level in % of the centre's, in words)."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    r, value = vignetting_profile(m["img"], m["grid_centres"][m["found"]])
    ok = np.isfinite(value)
    fig, ax = plt.subplots(figsize=(7, 3.5))
    peak = float(np.nanmax(value)) if ok.any() and np.nanmax(value) > 0 else 1.0
    ax.plot(r[ok], 100.0 * value[ok] / peak, "-o", ms=3, color="#aa5522")
    ax.set_xlabel("distance of the lens from the sensor centre (px)")
    ax.set_ylabel("white level at the lens centre (%)")
    ax.set_ylim(0, 105)
    ax.grid(alpha=0.3)
    ax.set_title("vignetting profile", fontsize=10)
    fig.tight_layout()
    caption = "white level at the centre of each lens with a disk, median per distance, % of the brightest"
    if ok.sum() >= 2:
        centre = float(value[ok][0])
        edge, at = float(value[ok][-1]), float(r[ok][-1])
        if centre > 0:
            caption += f"; the outermost lenses ({at:.0f} px from the centre) get {100.0 * edge / centre:.0f} % of " \
                       "the light of the central ones"
    return fig, caption


def _judge_white(grid: LensletGrid, m: dict[str, Any], kind: str) -> tuple[list[Check], float | None]:
    """Checks of a grid against white image(s); returns them and the lens-centre accuracy
    (:data:`ACCURACY_DEFINITION`, px; None without a disk near a lens)."""
    from ..calib.grid import SMOOTH_FIELD_DEGREE

    checks: list[Check] = []
    a = m["assigned"]
    n_det = len(a)
    mag = np.hypot(*m["residuals"][a].T) if a.sum() else np.zeros(0)
    accuracy = float(np.sqrt(np.mean(mag ** 2))) if len(mag) else None
    if accuracy is not None:
        checks.append(Check("lens-centre accuracy (RMS)", f"{accuracy:.3f} px over {len(mag)} disks",
                            f"good <= {WHITE_RMS_PX[0]} px, check <= {WHITE_RMS_PX[1]} px (white images)",
                            _level(accuracy, *WHITE_RMS_PX),
                            "" if accuracy <= WHITE_RMS_PX[0] else
                            f"the lens centres the decoder uses are {accuracy:.3f} px RMS from the disks of the white "
                            f"image (expected < {WHITE_RMS_PX[0]} px)"))
    rms = grid.residual_rms if kind == "white-image" else None
    smooth = smooth_part(grid, rms)
    if smooth is not None:
        # the centres depart from the regular lattice mostly by a smooth field (optics bending the lens array's
        # image), which the decoder follows through each lens's measured centre: judged by what is left
        rest = smooth["rest_rms_px"]
        checks.append(Check("fit to a regular lattice (lattice RMS)",
                            f"{rms:.3f} px; {rest:.3f} px about a smooth distortion of the lens "
                            f"array's image of up to {smooth['max_px']:.2f} px",
                            f"good <= {WHITE_RMS_PX[0]} px, check <= {WHITE_RMS_PX[1]} px (white images) about a "
                            f"smooth field (degree {SMOOTH_FIELD_DEGREE} in the lens indices), which the decoder "
                            "follows: it uses each lens's measured centre",
                            _level(rest, *WHITE_RMS_PX),
                            "" if rest <= WHITE_RMS_PX[0] else f"the lens centres scatter by {rest:.3f} px about a "
                                                               f"smooth distortion (expected < {WHITE_RMS_PX[0]} px)"))
    elif rms is not None:
        checks.append(Check("fit to a regular lattice (lattice RMS)", f"{rms:.3f} px",
                            f"good <= {WHITE_RMS_PX[0]} px, check <= {WHITE_RMS_PX[1]} px (white images)",
                            _level(rms, *WHITE_RMS_PX),
                            "" if rms <= WHITE_RMS_PX[0] else f"lattice RMS {rms:.3f} px is high for a white "
                                                              f"image (expected < {WHITE_RMS_PX[0]} px)"))
    if not n_det:
        checks.append(Check("disks detected", "0", "a white image shows every lens's disk", "bad",
                            "no lens disk could be detected in the white image"))
        return checks, accuracy
    near = a.mean()
    fitted = grid.info.get("n_detected") if kind == "white-image" else None
    # this check detects the disks again, at full resolution; the fit's own count (binned) differs by a few
    why = "" if fitted in (None, n_det) else (f" (detected again for this check, at full resolution; the fit's "
                                              f"detection{_binned(grid)} found {fitted})")
    checks.append(Check("detected disks near a grid lens", f"{near:.1%} of {n_det}{why}",
                        "good >= 99 %, check >= 90 % (within 0.3 pitch)", _level(near, 0.99, 0.90,
                                                                                 higher_is_better=True),
                        "" if near >= 0.99 else f"{n_det - int(a.sum())} of {n_det} disks of the white image "
                                                 "lie near no grid lens: the grid does not match this white image"))
    if len(mag):
        high = float(np.mean(mag > HIGH_RESIDUAL_PX))
        ok = high <= HIGH_RESIDUAL_FRACTION
        checks.append(Check(f"lenses more than {HIGH_RESIDUAL_PX} px off", f"{high:.1%}",
                            f"good <= {HIGH_RESIDUAL_FRACTION:.0%}", "good" if ok else "bad",
                            "" if ok else f"{int(np.sum(mag > HIGH_RESIDUAL_PX))} lenses ({high:.1%}) are more than "
                                          f"{HIGH_RESIDUAL_PX} px from the grid; check the residual map for "
                                          "distortion or a wrong white image"))
    full = m["full"]
    missing = full & ~m["found"]
    frac = float(missing.sum() / full.sum()) if full.sum() else 0.0
    ok = frac <= MISSING_WARN_FRACTION
    checks.append(Check("fully visible lenses without a disk", f"{int(missing.sum())} of {int(full.sum())} "
                        f"({frac:.1%})", f"good <= {MISSING_WARN_FRACTION:.0%}", "good" if ok else "check",
                        "" if ok else f"{int(missing.sum())} of {int(full.sum())} fully visible lenses ({frac:.1%}) "
                                      "show no detectable disk (dust, dead lenses or dark corners); the lattice "
                                      "places them"))
    return checks, accuracy


def _binned(grid: LensletGrid) -> str:
    """``' at binning 2'`` for a grid fitted on a binned white image (``grid.info['binning']`` > 1), else ''."""
    b = grid.info.get("binning")
    return f" at binning {b}" if isinstance(b, int) and b > 1 else ""


#: Labels of ``grid.info`` keys in the parameters table (else the key in words, '_' as ' ', a '_px' key's unit in
#: its value).
INFO_LABELS = {"n_detected": "disks detected by the fit", "n_fit": "disks the fit kept (inliers)",
               "n_whites": "white images", "binning": "binning of the fit's detection",
               "method": "how the centres were measured", "rim_radius_px": "disk rim radius (fitted)"}
#: ``grid.info['method']`` in words (the method's name, which the Python API takes, in brackets).
METHOD_WORDS = {"dog": "peaks of the disks' brightness, difference-of-Gaussians fit (dog)",
                "parabolic": "peaks of the disks' brightness, 3-point parabola (parabolic)",
                "rim": "circles fitted to the disks' rims (rim)"}


def info_row(key: str, value: Any) -> tuple[str, str]:
    """A ``grid.info`` entry as a row a person reads: ``('disk rim radius (fitted)', '3.994 px')`` for
    ``rim_radius_px`` (:data:`INFO_LABELS`, :data:`METHOD_WORDS`); whole floats print whole (zoom step -312)."""
    unit = " px" if key.endswith("_px") else ""
    label = INFO_LABELS.get(key, key[:-3] if unit else key).replace("_", " ")
    if key == "method":
        text = METHOD_WORDS.get(str(value), str(value))
    elif key == "binning" and isinstance(value, int) and value > 1:
        text = f"{value} ({value} x {value} pixels summed)"
    elif isinstance(value, float):
        text = f"{value:.0f}" if value.is_integer() and not unit else f"{value:.3f}"
    else:
        text = str(value)
    return label, text + unit


def scene_smooth_field(grid: LensletGrid, m: dict[str, Any]) -> dict[str, float] | None:
    """The smooth part of a scene's rim centres' departure from a self-calibrated lattice
    (:func:`plenodecode.calib.grid.smooth_field`, lenses scene texture moves rejected): ``max_px`` and the sensor
    ``row``, ``col`` of the lens where it is largest; None without enough lenses."""
    from ..calib.grid import smooth_field

    ok = np.all(np.isfinite(m["residuals"]), axis=1)
    ij = np.stack(np.unravel_index(m["lens"][ok], grid.shape), axis=1)
    fitted = smooth_field(ij, m["residuals"][ok], k_sigma=4.0)
    if fitted is None:
        return None
    mag = np.hypot(*fitted[0].T)
    at = m["grid_centres"][m["lens"][ok][int(np.argmax(mag))]]
    return {"max_px": float(mag.max()), "row": float(at[0]), "col": float(at[1])}


def _judge_selfcal(grid: LensletGrid, m: dict[str, Any] | None = None) -> list[Check]:
    """Checks of a self-calibrated grid from its fit statistics (``grid.info``) and, with the scene's rim centres
    ``m``, the smooth departure of the centres from the lattice, which a self-calibrated grid does not follow."""
    inf = grid.info
    p = grid.pitch
    checks = []
    rms = grid.residual_rms
    if rms is not None:
        sigma = inf.get("fit_sigma_px")
        tail = f"; RMS / (sqrt 2 x robust sigma) = {rms / (math.sqrt(2) * sigma):.2f}, ~1 when noise-like" \
            if sigma else ""
        g, c = SELFCAL_RULES["rms_pitch"]
        lv = _level(rms / p, g, c)
        checks.append(Check("lattice RMS", f"{rms:.3f} px = {rms / p:.3f} pitch{tail}",
                            f"good <= {g} pitch, check <= {c} pitch (expected spread of scene-based centres)", lv,
                            "" if lv == "good" else f"the detected centres scatter by {rms / p:.3f} pitch about the "
                                                    "lattice, more than scene-based detection does"))
    mis = inf.get("fit_local_misfit_px")
    if mis is not None and math.isfinite(mis):
        g, c = SELFCAL_RULES["misfit_pitch"]
        lv = _level(mis / p, g, c)
        checks.append(Check("local misfit (blocks of 5 x 5 lenses, detection noise removed)",
                            f"{mis:.3f} px = {mis / p:.3f} pitch", f"good <= {g} pitch, check <= {c} pitch", lv,
                            "" if lv == "good" else f"the lattice sits {mis:.2f} px off the detected centres "
                                                    "locally: check the residual map"))
    found = inf.get("fraction_found")
    if found is not None:
        g, c = SELFCAL_RULES["found"]
        lv = _level(found, g, c, higher_is_better=True)
        checks.append(Check("lenses found (inliers, of the lenses a pitch inside the sensor)",
                            f"{found:.1%} of {inf.get('n_lenses_inner')}", f"good >= {g:.0%}, check >= {c:.0%}", lv,
                            "" if lv == "good" else f"only {found:.0%} of the lenses were found in the scene (dark "
                                                    "or featureless regions); the lattice is extrapolated there"))
    field = scene_smooth_field(grid, m) if m is not None and len(m["centres"]) else None
    if field is not None:
        g, c = SELFCAL_RULES["smooth_pitch"]
        f = field["max_px"]
        lv = _level(f / p, g, c)
        checks.append(Check("smooth departure of the centres from the lattice (largest)",
                            f"{f:.2f} px = {f / p:.3f} pitch, at row {field['row']:.0f}, col {field['col']:.0f}",
                            f"good <= {g} pitch, check <= {c} pitch", lv,
                            "" if lv == "good" else
                            f"the lens centres depart from the regular lattice by a smooth field of up to {f:.1f} px "
                            f"(near row {field['row']:.0f}, col {field['col']:.0f}), as when a relay lens bends the "
                            "lens array's image; a self-calibrated grid places every lens on the lattice, so those "
                            "lenses are decoded that far off their centre: calibrate with a white image (a "
                            "microscope's radiometry frame), whose fit follows the field lens by lens"))
    return checks


@dataclass(frozen=True)
class Judgement:
    """The verdict of a calibration report.

    Attributes
    ----------
    verdict : 'good', 'check', 'bad', or 'as given' (nothing judged)
    checks : list of Check
    warnings : list of str
        The grid's own warnings and one line per check below 'good'.
    rms : float or None
        The lattice RMS recorded by the calibration (:data:`RMS_DEFINITION`), px; None for a grid used as given
        or of unknown origin.
    accuracy : float or None
        The lens-centre accuracy measured against the white images given (:data:`ACCURACY_DEFINITION`), px: the
        report's headline where there is one.
    """

    verdict: str
    checks: list[Check]
    warnings: list[str]
    rms: float | None
    accuracy: float | None = None


def judge_calibration(grid: LensletGrid, m: dict[str, Any] | None = None) -> Judgement:
    """Verdict of a calibration by what its source can show.

    Parameters
    ----------
    grid : LensletGrid
    m : dict, optional
        The measurement of the images given: white images (white-image grids and grids of unknown origin) or the
        scene's rim centres (self-calibration, for the smooth departure from the lattice).

    Returns
    -------
    Judgement
    """
    kind = source_kind(grid)
    warnings = [str(w) for w in grid.info.get("warnings", [])]
    rms, accuracy = grid.residual_rms, None
    if kind == "camera-file":
        return Judgement("as given", [], warnings, rms if refitted(grid) else None)
    if kind == "self-calibration":
        checks = _judge_selfcal(grid, m)
    elif m is not None and "found" in m:
        checks, accuracy = _judge_white(grid, m, kind)
    else:
        checks = []
    warnings += [c.note for c in checks if c.level != "good" and c.note]
    levels = [c.level for c in checks] + (["check"] if grid.info.get("warnings") else [])
    verdict = max(levels, key=LEVELS.index) if levels else "as given"
    return Judgement(verdict, checks, warnings, rms, accuracy)


def _headline(grid: LensletGrid, j: Judgement, m: dict[str, Any] | None) -> tuple[str, str]:
    """The verdict box's line -- the verdict and one accuracy figure: a white image's lens-centre accuracy
    (:data:`ACCURACY_DEFINITION`), else the lattice RMS (:func:`rms_text`), else (a camera's file used as given) what
    the page shows instead -- and the line under it naming the lattice RMS where the accuracy is the headline (a
    white image's fit: the figure ``plenodecode calibrate`` prints)."""
    if source_kind(grid) == "camera-file" and not refitted(grid):
        # nothing was fitted, so there is no RMS to give: say what the page offers instead
        drawn = ("its grid is drawn on the image below (Lattice on the image) to check by eye"
                 if m is not None and m["img"] is not None else "no image was given to draw its grid on")
        return (f"verdict: {j.verdict}; the camera's own calibration, used without a fit (so no lattice RMS): "
                f"{drawn}"), ""
    if j.accuracy is None:
        return f"verdict: {j.verdict}; lattice RMS {rms_text(grid)}", ""
    n = int(m["assigned"].sum()) if m is not None else 0
    head = (f"verdict: {j.verdict}; lens-centre accuracy {j.accuracy:.3f} px RMS (the lens centres the decoder uses, "
            f"measured against {n} disks of the white image)")
    if j.rms is None:
        return head, ""
    tail = (f", measured on the fit's detection{_binned(grid)}" if smooth_part(grid, j.rms) is None else
            "; the decoder follows that distortion lens by lens, so the lens-centre accuracy is what decoding sees")
    return head, f"Fit to a regular lattice: lattice RMS {rms_text(grid)}{tail} ('plenodecode calibrate' prints it)."


def _files(paths: Sequence[Any]) -> str:
    names = [str(q) for q in paths if q]
    return ", ".join(names) if names else "(given in memory)"


def source_line(grid: LensletGrid, raws: Sequence[RawCapture], grid_path: Path | None = None) -> str:
    """One line naming where the grid comes from (the report's subtitle)."""
    from ..calib.grid import SOURCE_KINDS

    kind = source_kind(grid)
    inf = grid.info
    files = inf.get("sources") or ([inf["source"]] if inf.get("source") else [r.path for r in raws])
    if kind in ("white-image", "self-calibration"):
        line = f"{SOURCE_KINDS[kind]}: {_files(files)}"
    elif kind == "camera-file":
        line = f"{SOURCE_KINDS[kind]}: the RayCalibData of {_files(files)}"
        if refitted(grid):
            line += f", refitted on the image ({inf['refit'].get('method', '?')})"
        elif "refit" in inf:
            line += "; the refit on the image was skipped"
    else:
        line = f"{SOURCE_KINDS[kind]}" if grid_path is None else f"grid JSON {grid_path} (no record of how it was made)"
        if raws:
            line += f"; checked against {_files([r.path for r in raws])}"
    if grid_path is not None and kind != "grid-file":
        line = f"grid JSON {grid_path}, {line}"
    return "source: " + line


def _params(grid: LensletGrid) -> list[tuple[str, str]]:
    from ..calib.grid import SOURCE_KINDS

    inf = grid.info
    rows = [
        ("lattice", grid.lattice),
        ("pitch (along rows)", f"{grid.pitch:.5f} px"),
        ("row spacing", f"{grid.row_spacing:.5f} px ({grid.row_spacing / grid.pitch:.5f} x pitch)"),
        ("rotation", angle_text(grid.rotation)),
        ("origin (lens 0, 0)", f"row {grid.origin[0]:.3f}, col {grid.origin[1]:.3f}"),
        *([("odd row shift", f"{grid.odd_row_shift:+.1f} pitch")] if grid.lattice == "hex" else []),  # 0: square
        ("lenses (rows x cols)", f"{grid.shape[0]} x {grid.shape[1]} = {grid.shape[0] * grid.shape[1]}"),
        ("sensor (H x W)", f"{grid.sensor_shape[0]} x {grid.sensor_shape[1]}"),
        ("disk radius", f"{grid.radius:.3f} px"),
        ("lenses with their own measured centre",
         str(int(np.isfinite(grid.refined[..., 0]).sum())) if grid.refined is not None else "0"),
        ("source", SOURCE_KINDS[source_kind(grid)]),
    ]
    if grid.lens_type is not None:
        types, counts = np.unique(np.asarray(grid.lens_type), return_counts=True)
        rows.append(("lens types", ", ".join(f"type {t}: {c}" for t, c in zip(types, counts))))
    if refitted(grid):
        rf = inf["refit"]
        rows.append(("refit on the image", ", ".join(f"{k} {v}" for k, v in rf.items() if k != "change")))
    elif "refit" in inf:
        rows.append(("refit on the image", f"skipped: {inf['refit'].get('reason', 'no reason recorded')}"))
    for key in ("camera_model", "serial", "zoom_step", "focus_step", "n_whites", "method", "binning", "rim_radius_px",
                "n_detected", "n_fit"):
        if inf.get(key) is not None:
            rows.append(info_row(key, inf[key]))
    return rows


def write_calibration_report(grid: LensletGrid | str | os.PathLike, white: Any, path: str | os.PathLike, *,
                             overwrite: bool = False, title: str | None = None) -> Path:
    """Write one self-contained HTML report of a calibration, judged by what its source can show.

    Parameters
    ----------
    grid : LensletGrid or path of a grid JSON
        The grid; its ``info['source_kind']`` (:data:`plenodecode.calib.grid.SOURCE_KINDS`) chooses
        how it is judged (module docstring); a grid without one is checked against ``white``.
    white : RawCapture, path, sequence of them, or None
        The images the grid came from: white image(s), the scene of a self-calibration, or the
        Raytrix image (drawn under its grid).
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

    grid_path = None
    if not isinstance(grid, LensletGrid):
        grid_path = Path(grid)
        grid = LensletGrid.from_json(grid_path.read_text())
    raws = [] if white is None else _as_raws(white)
    kind = source_kind(grid)
    m = None
    if raws:
        m = (_scene_measure if kind == "self-calibration" and grid.info.get("method") == "rim" else
             _image_measure if kind == "camera-file" else _white_measure)(grid, raws)
    j = judge_calibration(grid, m)
    head, also = _headline(grid, j, m)
    box = H.notes_html([head], kind="ok" if j.verdict in ("good", "as given") else "warn")
    box += f'<p class="muted">{H.escape(also)}</p>' if also else ""
    notes = (H.notes_html(j.warnings) if j.warnings else "" if j.verdict == "as given" else
             H.notes_html(["no problems found"], kind="ok"))
    if kind == "camera-file":
        how = ("The camera's own calibration is used as given: plenodecode did not measure it, so there is no "
               "residual or off-grid judgement; the figure draws the grid on the image for a visual check."
               + (" The refit on the image is the one measurement made (see the parameters)." if refitted(grid)
                  else " The refit on the image (--refine) was skipped (see the note above): the grid is the "
                       "calibration file's." if "refit" in grid.info else ""))
        judged = f"<p>{H.escape(how)}</p>"
    else:
        rows = [(c.quantity, c.value, c.rule, c.level) for c in j.checks]
        judged = (H.table_html(rows, header=("quantity", "value", "rule", "level")) if rows else
                  "<p>No image to check the grid against.</p>")
        defined = ([ACCURACY_DEFINITION] if j.accuracy is not None else []) + \
            ([RMS_DEFINITION] if j.accuracy is None or j.rms is not None else [])
        judged += "".join(f'<p class="muted">{H.escape(d)}.</p>' for d in defined)
        if kind == "self-calibration":
            judged += (f'<p class="muted">Self-calibration is judged by what a scene can show: the scatter of the '
                       f"detected centres about the lattice, the lattice's local misfit, the lenses found, and "
                       f"how far the centres depart smoothly from the lattice. "
                       f"{H.escape(SELFCAL_BASIS)}</p>")
    parts = [H.section("Verdict", box, notes), H.section("How this grid is judged", judged),
             H.section("Grid parameters (as given)" if kind == "camera-file" else "Fitted parameters", H.table_html(_params(grid), header=("parameter", "value")))]
    if m is not None and m["img"] is not None:
        detected = "red +: detected disk centres; " if len(m["centres"]) else ""
        fig, sizes = _overlay_figure(grid, m)
        parts.append(H.section("Lattice on the image", H.figure_html(
            fig, f"{detected}blue circles: the grid's lenses, drawn at the disk radius the decoder uses, with a dot "
                 "at each centre; at the corners and the centre of the image",
            data={f"{k.replace('_', '-')}-px" if k != "legend_overlap" else "legend-overlap": f"{v:.3f}"
                  for k, v in sizes.items()})))
        if len(m["centres"]):
            if kind == "self-calibration":
                what = ("disk rims fitted at every lens as self-calibration measures them, lenses the fit rejected "
                        "included; the dashed line is the lattice RMS, over the fit's inliers")
                line = ("lattice RMS", j.rms)
            else:   # against the centres the decoder uses (measured where a smooth distortion moves them)
                what = ("the disks of the white image, detected again at full resolution, against the lens centres the "
                        "decoder uses; the dashed line is the lens-centre accuracy")
                line = ("lens-centre accuracy", j.accuracy)
            parts.append(H.section("Residuals", H.figure_html(_residual_figure(grid, m, line),
                                                                f"detected minus grid centre ({what})")))
        if kind not in ("self-calibration", "camera-file"):
            parts.append(H.section("Vignetting", H.figure_html(*_vignetting_figure(m))))
    doc = H.page(title or "plenodecode calibration report", parts, subtitle=source_line(grid, raws, grid_path))
    out = H.write_html(p, doc, overwrite=overwrite)
    log.info("calibration report written to %s", out)
    return out


__all__ = ["write_calibration_report", "judge_calibration", "source_kind", "source_line", "rms_text", "refitted",
           "scene_smooth_field",
           "vignetting_profile", "Check", "Judgement", "RMS_DEFINITION", "ACCURACY_DEFINITION", "SELFCAL_RULES",
           "SELFCAL_BASIS", "LEVELS"]
