"""Geometric calibration report: one self-contained HTML page for ``plenodecode calibrate-geometry --report``.

Contents: the board and the overall RMS ray reprojection error (m, the cost of Dansereau et al. 2013)
and pixel error; ``H`` (0-based samples) and the distortion ``[k1 k2 k3 b1 b2]``; a table per capture
(views used, distance and tilt of the board, RMS in mm and px); the corner reprojection errors per
capture (distribution of the ray distances, and the pixel error vectors); the distortion field (the
correction of the measured directions over the central view, in pixels of that view); the captures
skipped and why.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..io.atomic import check_destination
from ..raymodel import DISTORTION_NAMES, correct_directions, measured_rays, rotation_matrix
from . import html as H

if TYPE_CHECKING:
    from ..calib.geometry.captures import GeometryRun

#: Arrows per axis of the distortion field plot.
FIELD_ARROWS = 15


def _capture_rows(run: GeometryRun) -> list[tuple]:
    rows = []
    for c, (name, found) in enumerate(zip(run.names, run.corners)):
        pose = run.calibration.poses[c]
        normal = rotation_matrix(pose[3:])[:, 2]
        tilt = math.degrees(math.acos(min(1.0, abs(normal[2]))))
        rows.append((name, f"{found.count} / {found.searched}", f"{pose[2]:.3f}", f"{tilt:.1f}",
                     f"{run.errors.rms_m(c) * 1e3:.4f}", f"{run.errors.rms_px(c):.3f}"))
    return rows


def _coverage_rows(info: dict) -> list[tuple[str, str]]:
    cover = info.get("coverage")
    if not cover:
        return []
    return [("field covered by the boards", f"{100 * cover['area']:.0f} % of the central view's area; corners up "
                                            f"to {100 * cover['radius']:.0f} % of the field's radius"),
            ("distortion extrapolated over", f"{100 * cover['beyond_radius']:.0f} % of the field (beyond the "
                                             "largest radius a corner reached)")]


def _coverage_note(info: dict) -> str:
    cover = info.get("coverage")
    if not cover or not info.get("distortion_estimated") or cover["beyond_radius"] <= 0:
        return ""
    return H.notes_html([f"The boards' corners reached {100 * cover['radius']:.0f} % of the field's radius: over "
                         f"the outer {100 * cover['beyond_radius']:.0f} % of the field the distortion is "
                         "extrapolated from the inner part, not measured (k2 and k3 can trade off there). "
                         "Add captures with the board in the image's corners to measure it."])


def errors_figure(run: GeometryRun):
    """Left: distribution of the point-to-ray distances (mm) per capture; right: pixel error vectors."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    n = len(run.names)
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, max(3.5, 0.28 * n + 1.5)),
                                      gridspec_kw={"width_ratios": [1.4, 1]})
    data = [run.errors.ray_m[run.errors.capture == c] * 1e3 for c in range(n)]
    left.boxplot(data, orientation="horizontal", showfliers=True, flierprops={"markersize": 2})
    left.set_yticks(range(1, n + 1), run.names)
    left.invert_yaxis()
    left.set_xlabel("point-to-ray distance (mm)")
    left.set_title("ray reprojection error per capture")
    cmap = plt.get_cmap("tab20")
    for c in range(n):
        e = run.errors.pixel[run.errors.capture == c]
        right.scatter(e[:, 0], e[:, 1], s=2, alpha=0.5, color=cmap(c % 20), label=run.names[c] if n <= 12 else None)
    limit = max(1e-3, float(np.percentile(np.abs(run.errors.pixel), 99.5)) * 1.1)
    right.set_xlim(-limit, limit)
    right.set_ylim(limit, -limit)
    right.set_aspect("equal")
    right.axhline(0, color="0.6", lw=0.5)
    right.axvline(0, color="0.6", lw=0.5)
    right.set_xlabel("projected - detected k (px)")
    right.set_ylabel("projected - detected l (px)")
    right.set_title("corner reprojection errors (all views)")
    if n <= 12:
        right.legend(fontsize=7, markerscale=4, loc="upper right")
    fig.tight_layout()
    return fig


def distortion_figure(run: GeometryRun):
    """Quiver (needs a non-zero distortion) of the direction correction ``correct_directions(theta) - theta`` over the central view,
    in pixels of that view (``du / H22``, ``dv / H33``); colour = its length."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    cal = run.calibration
    V, U, Y, X = cal.lf_shape
    k, l = np.meshgrid(np.linspace(0, X - 1, FIELD_ARROWS), np.linspace(0, Y - 1, FIELD_ARROWS))
    samples = np.stack([np.full(k.shape, (U - 1) / 2), np.full(k.shape, (V - 1) / 2), k, l], axis=-1)
    measured = measured_rays(cal.intrinsics, samples)[..., 2:]
    shift = correct_directions(measured, cal.distortion) - measured
    dk, dl = shift[..., 0] / cal.intrinsics[2, 2], shift[..., 1] / cal.intrinsics[3, 3]
    length = np.hypot(dk, dl)
    fig, ax = plt.subplots(figsize=(6.5, 6.5 * Y / max(X, 1) + 0.6))
    quiver = ax.quiver(k, l, dk, dl, length, angles="xy", cmap="viridis", pivot="tail")
    fig.colorbar(quiver, ax=ax, label="correction (px of the central view)", shrink=0.8)
    ax.set_xlim(-0.05 * X, 1.05 * X)
    ax.set_ylim(1.05 * Y, -0.05 * Y)
    ax.set_aspect("equal")
    ax.set_xlabel("k (spatial column)")
    ax.set_ylabel("l (spatial row)")
    ax.set_title(f"largest correction {length.max():.2f} px (arrow lengths relative)", fontsize=10)
    fig.tight_layout()
    return fig


def geometry_report_html(run: GeometryRun) -> str:
    """The report page (a complete HTML document)."""
    cal = run.calibration
    info = cal.info
    summary = H.table_html([
        ("board", run.board.describe()),
        ("captures used", f"{len(run.names)} ({sum(c.count for c in run.corners)} views with the whole board)"),
        ("captures skipped", str(len(run.skipped))),
        ("light-field shape (V, U, Y, X)", " x ".join(str(v) for v in cal.lf_shape)),
        ("RMS ray reprojection error", f"{info['rms_ray_m'] * 1e3:.4f} mm (initial estimate "
                                       f"{info['initial_rms_ray_m'] * 1e3:.4f} mm)"),
        ("RMS corner reprojection error", f"{info['rms_px']:.3f} px"),
        *_coverage_rows(info),
    ])
    h_rows = [[f"{v:+.6e}" for v in row] for row in cal.intrinsics]
    intrinsics = H.table_html(h_rows, header=["i", "j", "k", "l", "1"])
    distortion = H.table_html([[f"{v:+.5g}" for v in cal.distortion]], header=list(DISTORTION_NAMES))
    parts = [
        H.section("Summary", summary,
                  '<p class="muted">Ray reprojection error: the 3-D distance (m) between each checkerboard corner, '
                  "placed by its fitted pose, and the ray of every sample that sees it (Dansereau, Pizarro &amp; "
                  "Williams, CVPR 2013); pixel error: the corner projected into its view minus where it was "
                  "detected.</p>"),
        H.section("Intrinsics H", intrinsics,
                  '<p class="muted">[s, t, u, v, 1] = H [i, j, k, l, 1] for 0-based samples of lf.data[j, i, l, k]; '
                  "re-centred (the central sample is the ray 0) with the reference plane through the central "
                  "view's centre of projection (H[0, 2] = 0).</p>"),
        H.section("Distortion", distortion,
                  '<p class="muted">theta = (1 + k1 r^2 + k2 r^4 + k3 r^6)(theta_m - b) + b, r = |theta_m - b|, '
                  "on the measured direction theta_m = (u, v) (the toolbox's convention).</p>",
                  H.figure_html(distortion_figure(run), "Direction correction over the central view.")
                  if np.any(cal.distortion != 0) else H.notes_html(["no distortion: not estimated, or zero"]),
                  _coverage_note(info)),
        H.section("Per capture", H.table_html(_capture_rows(run), header=[
            "capture", "views (used / searched)", "distance tz (m)", "tilt (deg)", "RMS ray (mm)", "RMS (px)"]),
            H.figure_html(errors_figure(run), "Corner reprojection errors per capture.")),
    ]
    if run.skipped:
        parts.append(H.section("Skipped captures", H.table_html(run.skipped, header=["capture", "why"])))
    else:
        parts.append(H.section("Skipped captures", H.notes_html(["none: the board was found in every capture"],
                                                                kind="ok")))
    return H.page("Geometric calibration", parts, subtitle=str(info.get("method", "")))


def write_geometry_report(run: GeometryRun, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write the report (atomically); FileExistsError when ``path`` exists and not ``overwrite``."""
    check_destination(path, overwrite)
    return H.write_html(path, geometry_report_html(run), overwrite=overwrite)
