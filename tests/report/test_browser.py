"""The HTML reports in a real browser (issue 7, item 5): headless Debian Chromium renders them
without console errors, and the screenshot is not blank (skipped when chromium is absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tests.conftest import browser_screenshot

from plenodecode.io.images import read_image, write_image

SIZE = (1280, 1600)  # browser window (width, height) = screenshot size


def _colour_stats(png: Path) -> tuple[np.ndarray, dict[str, float]]:
    """The screenshot as (H, W, 3) uint8 and its blankness statistics."""
    img = read_image(png)
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] in (3, 4), (img.dtype, img.shape)
    rgb = img[..., :3]
    flat = rgb.reshape(-1, 3).astype(np.int64)
    distinct = len(np.unique((flat[:, 0] << 16) | (flat[:, 1] << 8) | flat[:, 2]))
    return rgb, {"std": float(rgb.std()), "distinct": float(distinct),
                 "inked": float(np.mean(np.any(flat < 240, axis=1)))}


def _count(rgb: np.ndarray, colour: tuple[int, int, int], tol: int = 0) -> int:
    return int(np.all(np.abs(rgb.astype(np.int64) - np.array(colour)) <= tol, axis=-1).sum())


def test_calibration_report_renders_in_chromium(tmp_path):
    """Measured: 0 console lines, std ~52, ~13000 distinct colours, 21 % of pixels inked, ~2200 red
    marker pixels; the same page with its figures' data URIs broken gives std 24, 499 colours,
    5 % inked and no red, so every threshold below fails on a page whose figures do not render."""
    from plenodecode.calib import calibrate
    from plenodecode.synthetic import simulate_white
    from plenodecode.report.calibration import write_calibration_report

    raw, _ = simulate_white("f01-mini", seed=4, shape=(260, 320), rotation=0.003, offset=(0.4, -0.2))
    grid = calibrate(raw)
    html = write_calibration_report(grid, raw, tmp_path / "report.html")
    png = tmp_path / "report.png"
    console = browser_screenshot(html, png, size=SIZE)
    assert console == [], console
    assert png.is_file()
    rgb, st = _colour_stats(png)
    assert rgb.shape[:2] == (SIZE[1], SIZE[0])
    assert st["std"] > 35 and st["distinct"] > 3000 and st["inked"] > 0.10, st
    # the overlay figure is drawn: its red '+' markers (#ff3030) are on screen
    assert _count(rgb, (255, 48, 48), tol=40) > 200


def _thumbnail(path: Path, colour: tuple[int, int, int]) -> Path:
    img = np.empty((96, 128, 3), np.uint8)
    img[:] = colour
    return write_image(path, img, bit_depth=8)


def test_batch_index_renders_in_chromium(tmp_path):
    """A hand-built BatchSummary: two decoded raws with thumbnails and one failure."""
    from plenodecode.batch import BatchSummary, TaskResult
    from plenodecode.report.batch import write_batch_index

    out = tmp_path / "out"
    colours = {"a": (20, 160, 90), "b": (200, 120, 30), "c": (40, 70, 210)}
    results = []
    for name, products in (("scene_a", ("a", "b")), ("scene_b", ("c",))):
        folder = out / name
        outputs, thumbs = [], []
        for prod in products:
            o = folder / f"{prod}.png"
            _thumbnail(o, colours[prod])
            outputs.append(str(o))
            thumbs.append(str(_thumbnail(folder / "thumbs" / f"{prod}.png", colours[prod])))
        results.append(TaskResult(source=str(tmp_path / f"{name}.lfr"), status="done", outputs=tuple(outputs),
                                  thumbnails=tuple(thumbs), seconds=1.5, worker="host:1"))
    results.append(TaskResult(source=str(tmp_path / "broken.lfr"), status="failed",
                              error="broken.lfr is not an LFP container", seconds=0.1))
    html = write_batch_index(BatchSummary(results=tuple(results), seconds=3.2), out / "index.html")
    png = tmp_path / "index.png"
    console = browser_screenshot(html, png, size=SIZE)
    assert console == [], console
    rgb, st = _colour_stats(png)
    assert rgb.shape[:2] == (SIZE[1], SIZE[0])
    assert st["std"] > 10 and st["distinct"] > 200 and st["inked"] > 0.03, st
    # every thumbnail is loaded through its relative link and drawn (160 px wide, aspect kept: ~120 rows)
    for prod, c in colours.items():
        assert _count(rgb, c, tol=2) > 0.8 * 160 * 120, prod


def test_batch_index_lists_outputs_without_a_picture_as_file_links_under_the_thumbnails(tmp_path):
    """The parallax frames folder and a point cloud were empty figures (a bare caption beside the pictures).  They are
    now file links on one 'also:' line under the thumbnails (a folder with a trailing '/'); a raw's left-out outputs
    are said on its card and in the page's head line."""
    import re

    from plenodecode.batch import BatchSummary, TaskResult
    from plenodecode.report.batch import write_batch_index

    out = tmp_path / "out"
    folder = out / "scene"
    (folder / "parallax_frames").mkdir(parents=True)
    gif, ply = folder / "parallax.gif", folder / "depth.ply"
    gif.write_bytes(b"GIF89a")
    ply.write_text("ply\n")
    thumb = _thumbnail(folder / "thumbs" / "parallax.png", (200, 120, 30))
    r = TaskResult(source=str(tmp_path / "scene.lfr"), status="done", outputs=(str(gif), str(folder /
                   "parallax_frames"), str(ply)), thumbnails=(str(thumb), None, None), seconds=1.0,
                   left_out=("centre: not for a focused-plenoptic (Raytrix) raw (...)",))
    html = write_batch_index(BatchSummary(results=(r,), seconds=1.0), out / "index.html")
    page = html.read_text()
    assert page.count("<figure>") == 1 and "<figcaption>parallax.gif</figcaption>" in page
    assert re.search(r'class="files">also: <a href="scene/parallax_frames">parallax_frames/</a> &middot; '
                     r'<a href="scene/depth.ply">depth.ply</a></div>', page), page
    assert "left out: centre: not for a focused-plenoptic" in page and "<b>1</b> left out outputs it" in page
    assert browser_screenshot(html, tmp_path / "index.png", size=SIZE) == []
