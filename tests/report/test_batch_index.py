"""The batch index page as a user sees it, made through the CLI: failure messages, depth captions, names of linked
raws, and the cards' layout in a real browser (the Raytrix R42 capture of ../shared/data, skipped when absent)."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from tests.conftest import browser_screenshot, shared_path

from plenodecode.batch import output_names
from plenodecode.cli.main import cli
from plenodecode.report.batch import display_names

ROOT = Path(__file__).resolve().parents[2]
CORRUPT = b"\x89LFP\r\n\x1a\n" + bytes(64)      # the LFP signature, then nothing a container holds


def _link(link: Path, target: Path) -> None:
    try:
        link.symlink_to(target)
    except OSError as exc:                  # a file system without links
        pytest.skip(f"cannot make a symbolic link here: {exc}")


@pytest.fixture(scope="module")
def raytrix_run(tmp_path_factory):
    """``batch --outputs centre,depth`` over a folder holding a corrupt LFR, the bundled F01 sample and the real
    Raytrix R42 crop linked in as r42.png (its XML as r42.xml), which leaves out 'centre': (output folder, CLI
    output)."""
    tmp = tmp_path_factory.mktemp("raytrix_index")
    raws = tmp / "raws"
    raws.mkdir()
    _link(raws / "r42.png", shared_path("raytrix-r42", "sc2_klein.png"))
    _link(raws / "r42.xml", shared_path("raytrix-r42", "sc2_klein.xml"))
    (raws / "corrupt.lfr").write_bytes(CORRUPT)
    shutil.copy(ROOT / "sample_raws" / "f01-mini" / "scene.lfp", raws / "f01.lfp")
    out = tmp / "out"
    res = CliRunner().invoke(cli, ["batch", str(raws), "-o", str(out), "--outputs", "centre,depth",
                                   "--jobs", "1", "--database", str(ROOT / "calib")])
    assert res.exit_code == 1, res.output          # the corrupt raw fails
    return out, res.output


def test_a_linked_raw_keeps_the_name_the_user_gave(raytrix_run, tmp_path):
    """A link r42.png -> sc2_klein.png was shown as sc2_klein.png in the table and on the page and decoded into
    sc2_klein/: the names followed the link.  Now the link's own name, everywhere."""
    out, said = raytrix_run
    assert (out / "r42").is_dir() and not (out / "sc2_klein").exists()
    page = (out / "index.html").read_text()
    assert re.findall(r'class="name" title="[^"]+">([^<]+)<', page) == ["corrupt.lfr", "f01.lfp", "r42.png"]
    assert "sc2_klein" not in page and "sc2_klein" not in said
    # two links to one file in one folder: two names, not one name made unique by a suffix
    _link(tmp_path / "a.jpg", tmp_path / "IMG_1.jpg")
    _link(tmp_path / "b.jpg", tmp_path / "IMG_1.jpg")
    assert output_names([tmp_path / "a.jpg", tmp_path / "b.jpg"]) == ["a", "b"]
    assert display_names([tmp_path / "a.jpg", tmp_path / "b.jpg"]) == ["a.jpg", "b.jpg"]


def test_a_failed_raws_message_leaves_out_the_path_its_card_names(raytrix_run):
    """The card titled corrupt.lfr said '/tmp/.../raws/corrupt.lfr: expected exactly one LFM ...', and so did the
    Failures table and the terminal's row beside the name: now the message alone; summary.json keeps the whole line
    for scripts."""
    out, said = raytrix_run
    doc = json.loads((out / "summary.json").read_text())
    (failed,) = [r for r in doc["results"] if r["status"] == "failed"]
    src = failed["source"]
    assert failed["error"].startswith(f"{src}: expected exactly one LFM")
    page = (out / "index.html").read_text()
    assert src not in page.replace(f'title="{src}"', "")     # only in the card name's tooltip
    shown = re.findall(r"class=.err.>([^<]+)<", page)
    assert len(shown) == 2 and all(s.startswith("expected exactly one LFM") for s in shown), shown
    # the terminal's row likewise
    (row,) = [line for line in said.splitlines() if line.startswith("corrupt.lfr ")]
    assert row.split()[1:4] == ["failed", "0.0", "expected"], row


def test_the_depth_picture_is_captioned_with_the_file_it_shows_and_opens(raytrix_run):
    """The colour-mapped virtual depth picture (virtual_depth.png) was captioned virtual_depth.pfm while 'also:' listed
    virtual_depth.png; now the caption names the PNG it shows and opens, and 'also:' lists the PFM."""
    out, _ = raytrix_run
    page = (out / "index.html").read_text()
    figures = re.findall(r'<figure><a href="([^"]+)"><img class="legend"[^>]*></a><figcaption>([^<]+)<', page)
    assert figures == [("f01/disparity.png", "disparity.png"), ("r42/virtual_depth.png", "virtual_depth.png")]
    also = [re.findall(r">([^<]+)</a>", a) for a in re.findall(r'class="files">also: (.*?)</div>', page)]
    assert also == [[f"{stem}.pfm", f"{stem}_confidence.png", f"{stem}_confidence.exr", f"{stem}.exr"]
                    for stem in ("disparity", "virtual_depth")]


def _card_boxes(rgb: np.ndarray, border: tuple[int, int, int]) -> list[tuple[int, int]]:
    """(width, height) in px of each card whose 6 px left border has colour ``border``, top to bottom and left to
    right: its height the border's, its width the white (#fff) run right of the border just under its top edge (the
    card's padding)."""
    from scipy import ndimage

    labels, n = ndimage.label(np.all(np.abs(rgb.astype(int) - border) <= 8, axis=-1))
    boxes = []
    for ys, xs in ndimage.find_objects(labels):
        row = np.all(rgb[ys.start + 3, xs.stop:] == 255, axis=-1)
        boxes.append((ys.start, xs.start, int(np.argmin(row) if not row.all() else row.size), ys.stop - ys.start))
    return [(w, h) for _, _, w, h in sorted(boxes)]


def test_cards_are_as_wide_as_their_pictures_and_as_tall_as_their_content(raytrix_run, tmp_path):
    """Headless Chromium: the Raytrix card (one 240 px depth picture, four file links and a long 'left out' line)
    was 540 px wide with its right half empty, and the failed card beside the F01 card was stretched to its height.
    Measured (1280 px window, inside the borders): failed card 322 x 109 px beside the F01 card's 425 x 299, Raytrix
    card 322 x 329; before 535 x 299, 555 x 299 and 555 x 281."""
    from plenodecode.io.images import read_image

    out, _ = raytrix_run
    png = tmp_path / "index.png"
    assert browser_screenshot(out / "index.html", png, size=(1280, 1000)) == []
    rgb = read_image(png)[..., :3]
    (failed,) = _card_boxes(rgb, (0xcc, 0x22, 0x22))
    f01, r42 = _card_boxes(rgb, (0x22, 0xaa, 0x22))
    assert 320 <= failed[0] <= 360 and 320 <= r42[0] <= 360, (failed, r42)
    assert failed[1] < 150 and f01[1] > 2 * failed[1], (failed, f01)


def test_raws_sharing_a_stem_are_named_by_their_folders(tmp_path):
    """The bundled samples f01-mini/scene.lfp, illum-mini/scene.lfr and square/scene.png went to the output folders
    f01-mini__scene, illum-mini__scene and square__scene, but their cards and rows were titled scene.lfp, scene.lfr
    and scene.png: three 'scene' a user could not tell apart.  Now as many folders as tell them apart."""
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["batch", str(ROOT / "sample_raws"), "-o", str(out), "--outputs", "centre",
                                   "--jobs", "1", "--database", str(ROOT / "calib")])
    assert res.exit_code == 0, res.output
    page = (out / "index.html").read_text()
    names = re.findall(r'class="name" title="[^"]+">([^<]+)<', page)
    assert names == ["f01-mini/scene.lfp", "illum-mini/scene.lfr", "square/scene.png"], names
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["f01-mini__scene", "illum-mini__scene",
                                                                   "square__scene"]
    rows = [line.split()[0] for line in res.output.splitlines() if "scene." in line and " done " in line]
    assert rows == names, res.output
    # one folder: the suffix tells them apart, no folder is added
    assert display_names([tmp_path / "IMG_1.lfr", tmp_path / "IMG_1.jpg"]) == ["IMG_1.lfr", "IMG_1.jpg"]
