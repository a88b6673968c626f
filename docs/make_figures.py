"""Regenerate the decoding figures of the README (docs/img/) from the real data in ../shared/data.

    .venv/bin/python docs/make_figures.py [--overwrite]

* ``antleg_centre.png`` / ``antleg_views.png``: the light-field microscope capture
  (lf-microscopy-antleg), calibrated from its radiometry frame, decoded with white and dark frames:
  the centre view and every third view of the 27 x 27 (a 9 x 9 grid).
* ``f01_img1_centre.png`` / ``f01_img1_views.png``: the real Lytro F01 mosaic IMG_1.jpg (Tao et al.),
  decoded by the workflow of ``plenodecode decode IMG_1.jpg`` (CFA and levels by the sensor size,
  self-calibrated from the scene, no white image) to 9 x 9 views; the views grid shows every
  second view (5 x 5) at half size.
* ``r42_total_focus.png``: the Raytrix R42 crop rendered all-in-focus (focused plenoptic).
* ``refocus_modes.png``: the bundled sample ``sample_raws/illum-mini/scene.lfr`` (calibration database
  ``calib/``) through :mod:`plenodecode.pipeline`, as the commands render it: refocused near (alpha 1.015),
  far (alpha 0.992), by a click on the slanted plane (``--focus-at 0.25,0.5``) and all-in-focus, side by side.
  ``--only refocus`` makes just this one (it needs no shared data).

Display only: values are scaled by their 99.5th percentile and sRGB-encoded; the F01 JPEG has no
colour metadata, so its camera RGB is grey-world balanced for the picture.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "docs" / "img"


def display(img: np.ndarray, *, grey_world: bool = False) -> np.ndarray:
    """Linear image (H, W, C) -> [0, 1] for an sRGB-encoded 8-bit PNG."""
    a = np.asarray(img, np.float64)
    if a.ndim == 2:
        a = a[..., None]
    if grey_world and a.shape[-1] == 3:
        a = a * (a.mean() / np.maximum(a.reshape(-1, 3).mean(0), 1e-9))
    return np.clip(a / max(np.percentile(a, 99.5), 1e-9), 0.0, 1.0).astype(np.float32)


def view_grid(data: np.ndarray, step: int, gap: int = 2) -> np.ndarray:
    """Tile every ``step``-th view of (V, U, Y, X, C) into one image with ``gap`` px borders."""
    v_idx = list(range((data.shape[0] // 2) % step, data.shape[0], step))     # includes the centre view
    ny, nx, c = data.shape[2:]
    n = len(v_idx)
    out = np.zeros((n * ny + (n - 1) * gap, n * nx + (n - 1) * gap, c), data.dtype)
    for a, v in enumerate(v_idx):
        for b, u in enumerate(v_idx):
            out[a * (ny + gap):a * (ny + gap) + ny, b * (nx + gap):b * (nx + gap) + nx] = data[v, u]
    return out


def refocus_modes() -> np.ndarray:
    """Near, far, by click and all-in-focus photographs of the bundled Illum sample, rendered by the pipeline
    products the commands use, at 3x (nearest) with a 4 px gap: (Y, 4 X + gaps, 3) in [0, 1], linear."""
    from plenodecode.pipeline import open_source, render_product

    src = open_source(ROOT / "sample_raws" / "illum-mini" / "scene.lfr", database=ROOT / "calib")
    shape = src.lightfield.shape
    click = (0.25 * (shape[3] - 1), 0.5 * (shape[2] - 1))            # --focus-at 0.25,0.5: the slanted plane
    panels = [render_product(src, "refocus", alpha=1.015).images[0][1],
              render_product(src, "refocus", alpha=0.992).images[0][1],
              render_product(src, "refocus", focus_at=click).images[0][1],
              render_product(src, "all-in-focus").images[0][1]]
    scale = 1.0 / max(float(np.percentile(np.stack(panels), 99.5)), 1e-9)
    panels = [np.clip(p * scale, 0, 1).repeat(3, 0).repeat(3, 1) for p in panels]
    x, y = int(round(click[0] * 3)), int(round(click[1] * 3))
    panels[2][y - 4:y + 5, x - 1:x + 2] = panels[2][y - 1:y + 2, x - 4:x + 5] = (1.0, 1.0, 0.0)   # the click
    gap = np.ones((panels[0].shape[0], 4, 3), np.float32)
    return np.concatenate([panels[0], gap, panels[1], gap, panels[2], gap, panels[3]], axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--overwrite", action="store_true")
    ap.add_argument("--only", choices=["refocus"], default=None, help="Make one figure only.")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from plenodecode.calib import calibrate
    from plenodecode.decoding import decode
    from plenodecode.decoding.focused import render_total_focus
    from plenodecode.io import read_raw
    from plenodecode.io.images import write_image
    from plenodecode.io.raytrix import grid_from_raycalib, parse_raycalib, read_raytrix_rgb
    from plenodecode.pipeline import load_lightfield_input

    OUT.mkdir(parents=True, exist_ok=True)

    def save(name: str, img: np.ndarray) -> None:
        write_image(OUT / name, img, bit_depth=8, overwrite=args.overwrite, encode_srgb=True)
        print("wrote", OUT / name)

    save("refocus_modes.png", refocus_modes())
    if args.only:
        return

    # light-field microscope: square grid, white (radiometry) and dark frames
    d = DATA / "lf-microscopy-antleg"
    raw, white, dark = (read_raw(d / n) for n in ("light_field.png", "radiometry_frame.png", "dark_frame.tif"))
    lf = decode(raw, calibrate(white), white=white, dark=dark)
    save("antleg_centre.png", display(lf.centre_view()))
    save("antleg_views.png", display(view_grid(lf.data, 3)))

    # real F01 mosaic saved as JPEG: what `plenodecode decode IMG_1.jpg -o IMG_1.zarr` decodes (the README's
    # commands): CFA and levels by the sensor size, self-calibrated grid, no white, no colour metadata
    lf = load_lightfield_input(DATA / "lytro-f01-lenslet-jpg" / "IMG_1.jpg")
    save("f01_img1_centre.png", display(lf.centre_view(), grey_world=True))
    import cv2

    half = np.stack([[cv2.resize(lf.data[v, u], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
                      for u in range(lf.shape[1])] for v in range(lf.shape[0])])
    save("f01_img1_views.png", display(view_grid(half, 2, gap=3), grey_world=True))

    # Raytrix R42: focused plenoptic total focus
    png = DATA / "raytrix-r42" / "sc2_klein.png"
    rgb = read_raytrix_rgb(png).astype(np.float32) / 255.0
    grid = grid_from_raycalib(parse_raycalib(png.with_suffix(".xml")), rgb.shape[:2])
    tf = render_total_focus(rgb, grid)
    save("r42_total_focus.png", np.clip(tf.image, 0, 1) ** 2.2)       # the export is display-encoded already


if __name__ == "__main__":
    main()
