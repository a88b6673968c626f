"""Regenerate the report screenshots the README links to (headless Debian Chromium).

    python docs/make_screenshots.py            # from the repository root; about 30 s

Writes ``docs/img/calibration_report.png`` (the calibration report of the Illum-like sample white
image in ``sample_raws/illum-mini``) and ``docs/img/batch_index.png`` (the index page of a batch run
over the sample raws plus one corrupt file, so a failure card shows too).  Each page is rendered at
1280 px wide and downscaled to 1000 px (area averaging) to keep the files small.  Everything else is
written to a temporary folder and removed.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "img"
WIDTH = 1000


def screenshot(html: Path, png: Path, *, size: tuple[int, int]) -> None:
    """Render ``html`` in headless chromium at ``size`` (width, height) and save a PNG."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        sys.exit("chromium is not installed (Debian: apt-get install chromium)")
    with tempfile.TemporaryDirectory() as profile:
        proc = subprocess.run(
            [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--hide-scrollbars",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0", f"--screenshot={png}",
             f"--window-size={size[0]},{size[1]}", html.resolve().as_uri()],
            capture_output=True, text=True, timeout=180)
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    if console or not png.is_file():
        sys.exit(f"chromium failed on {html}: {console or proc.stderr[-500:]}")


def downscale(src: Path, dst: Path, *, overwrite: bool) -> Path:
    """Area-downscale a screenshot to :data:`WIDTH` px wide and write it as an 8-bit PNG."""
    import cv2

    from plenodecode.io.images import read_image, write_image

    img = read_image(src)[..., :3]
    h, w = img.shape[:2]
    small = cv2.resize(img, (WIDTH, int(round(h * WIDTH / w))), interpolation=cv2.INTER_AREA)
    return write_image(dst, np.ascontiguousarray(small), bit_depth=8, overwrite=overwrite)


def calibration_report(tmp: Path, *, overwrite: bool) -> Path:
    from plenodecode.calib import calibrate
    from plenodecode.io import read_raw
    from plenodecode.report.calibration import write_calibration_report

    white = read_raw(ROOT / "sample_raws" / "illum-mini" / "MOD_0000.RAW")
    grid = calibrate(white)
    html = write_calibration_report(grid, white, tmp / "calibration_report.html",
                                    title="plenodecode calibration report: sample_raws/illum-mini")
    shot = tmp / "calibration_report.png"
    screenshot(html, shot, size=(1280, 2900))  # down to the residual figures, under the 2 x 3 overlay panels
    return downscale(shot, OUT / "calibration_report.png", overwrite=overwrite)


def batch_index(tmp: Path, *, overwrite: bool) -> Path:
    from plenodecode.batch import BatchOptions, run_batch, write_summary

    raws = tmp / "raws"
    raws.mkdir()
    shutil.copy(ROOT / "sample_raws" / "illum-mini" / "scene.lfr", raws / "illum_scene.lfr")
    shutil.copy(ROOT / "sample_raws" / "f01-mini" / "scene.lfp", raws / "f01_scene.lfp")
    (raws / "corrupt.lfr").write_bytes(b"\x89LFP\r\n\x1a\n" + bytes(64))
    opts = BatchOptions(outputs=("centre", "refocus", "depth"), database=str(ROOT / "calib"), bit_depth=8)
    out = tmp / "batch"
    _, index = write_summary(run_batch([raws], out, opts, jobs=1), out)
    shot = tmp / "batch_index.png"
    screenshot(index, shot, size=(1280, 800))     # down to the failures table under the cards
    return downscale(shot, OUT / "batch_index.png", overwrite=overwrite)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--overwrite", action="store_true", help="replace existing screenshots")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        for make in (calibration_report, batch_index):
            print(make(tmp, overwrite=args.overwrite))


if __name__ == "__main__":
    main()
