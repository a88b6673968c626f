"""What a person reads in the report 'plenodecode calibrate --report' writes on the real captures: the grid drawn
on the image at the scale of its micro-images, clear of its legend."""

from __future__ import annotations

import base64
import html as html_module
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from tests.conftest import ROOT, shared_path

BLUE = (0x2B, 0x8C, 0xFF)       # the grid's markers


def _calibrate(tmp_path: Path, *args: str) -> tuple[str, str]:
    """Run 'plenodecode calibrate ARGS -o grid.json --report grid.html'; return (output, the report's HTML)."""
    res = CliRunner().invoke(cli, ["calibrate", *map(str, args), "-o", str(tmp_path / "grid.json"),
                                   "--report", str(tmp_path / "grid.html")], obj={})
    assert res.exit_code == 0, res.output
    return res.output, (tmp_path / "grid.html").read_text()


def _text(html: str) -> str:
    """The page's visible text: no style, no figures, no markup, single spaces."""
    html = re.sub(r"<style>.*?</style>|src=\"[^\"]+\"", "", html, flags=re.S)
    return html_module.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html)))


def _overlay(html: str, tmp_path: Path) -> tuple[dict[str, float], np.ndarray]:
    """The overlay figure's recorded drawing facts (``data-*`` px) and its PNG as (H, W, 3) uint8."""
    from plenodecode.io.images import read_image

    sec = html[html.index("Lattice on the image"):]
    tag = re.search(r"<figure([^>]*)>", sec).group(1)
    facts = {k: float(v) for k, v in re.findall(r'data-([a-z-]+)="([^"]+)"', tag)}
    png = base64.b64decode(re.search(r'data:image/png;base64,([^"]+)', sec).group(1))
    path = tmp_path / "overlay.png"
    path.write_bytes(png)
    return facts, read_image(path)[..., :3]


# (capture, arguments): hex Raytrix micro-images of 35 px, the square microscope grid of 27.5 px, hex Lytro grids
# of 14.3 px (Illum white) and 9.9 px (F01 JPEG, self-calibrated)
CASES = {
    "raytrix-r42": lambda: [shared_path("raytrix-r42", "sc2_klein.png")],
    "antleg-white": lambda: [shared_path("lf-microscopy-antleg", "radiometry_frame.png")],
    "illum-white": lambda: [ROOT / "sample_raws" / "illum-mini" / "MOD_0000.RAW"],
    "f01-jpeg-scene": lambda: ["--scene", shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")],
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_overlay_markers_scale_with_the_pitch_and_the_legend_stays_off_the_image(case, tmp_path):
    """The overlay drew every grid centre as a 60 pt^2 ring (about 12 px on the page) whatever the pitch: on the
    R42's 35 px micro-images a speck in each; five panels in a row made 245 px of image 300 px wide, and the legend
    sat on the top-left panel's lenses.  Now the grid's lenses are circles of the disk radius (0.47 pitch) with a
    centre dot, detections '+' of 0.2 pitch arms, all in image px; 2 x 3 panels, the legend in the free slot.
    Measured: marker blue was 1.5-2.0 % of the overlay's pixels, now 5.2-6.5 %; the figure 1690 px wide (shrunk to
    the page), now 1190 px."""
    _, html = _calibrate(tmp_path, *CASES[case]())
    facts, png = _overlay(html, tmp_path)
    pitch = facts["pitch-px"]
    assert 0.40 < facts["circle-radius-px"] / pitch < 0.5, facts      # the circle outlines the micro-image
    assert facts["cross-arm-px"] / pitch == pytest.approx(0.2, abs=0.001)
    assert facts["dot-radius-px"] / pitch == pytest.approx(0.06, abs=0.001)
    assert facts["legend-overlap"] == 0.0                               # display px^2 of legend over the panels
    assert png.shape[1] <= 1200                                          # the page's width: shown at full size
    blue = np.all(np.abs(png.astype(np.int64) - BLUE) <= 40, axis=-1).mean()
    assert blue > 0.04, blue
    assert "drawn at the disk radius the decoder uses" in _text(html)


def test_the_antleg_white_report_heads_with_the_lens_centre_accuracy_and_labels_the_lattice_rms(tmp_path):
    """The ant leg's report said 'RMS 0.569 px (0.071 px about a smooth distortion ...)' in its header and drew
    'RMS 0.089 px' on its histogram, reconciled by a caption ('... so the RMS line is theirs, not the fit's').  Its
    header now gives the one figure decoding depends on, the lens-centre accuracy: the RMS distance of the lens
    centres the decoder uses from the white image's disks, measured here again; the lattice fit's figure follows,
    named 'lattice RMS' as the CLI's line names it.  Measured: accuracy 0.089 px over 6899 disks, lattice 0.569 px."""
    from plenodecode.io import read_raw
    from plenodecode.report.calibration import _white_measure
    from plenodecode.types import LensletGrid

    white = shared_path("lf-microscopy-antleg", "radiometry_frame.png")
    out, html = _calibrate(tmp_path, white)
    text = _text(html)
    head = re.search(r"verdict: good; lens-centre accuracy (\d\.\d{3}) px RMS \(the lens centres the decoder uses, "
                     r"measured against (\d+) disks of the white image\)", text)
    assert head, text[:2000]
    accuracy, n = float(head.group(1)), int(head.group(2))
    grid = LensletGrid.from_json((tmp_path / "grid.json").read_text())
    m = _white_measure(grid, [read_raw(white)])
    mag = np.hypot(*m["residuals"][m["assigned"]].T)
    assert n == len(mag) and accuracy == pytest.approx(np.sqrt(np.mean(mag ** 2)), abs=0.0005)
    assert 0.05 < accuracy < 0.1                                       # 0.089: 'good' (<= 0.1 px)
    lattice = re.search(r"Fit to a regular lattice: lattice RMS (\d\.\d{3}) px \((\d\.\d{3}) px about a smooth "
                        r"distortion of up to (\d\.\d+) px\)", text)
    assert lattice and float(lattice.group(1)) > 0.4 and float(lattice.group(2)) < 0.1, text[:2000]
    assert f"lattice RMS {lattice.group(1)} px" in out                  # the CLI's line, the same figure, same name
    info = CliRunner().invoke(cli, ["info", str(tmp_path / "grid.json")], obj={})
    assert info.exit_code == 0 and f"lattice RMS {lattice.group(1)} px" in info.output, info.output
    assert "not the fit's" not in text


@pytest.mark.parametrize("case", ["f01-jpeg-scene", "antleg-white"])
def test_the_parameters_read_as_words_with_units(case, tmp_path):
    """The F01 scene's report listed 'rim radius px 3.994' (a grid.info key with its unit in the name, the number
    bare), 'method rim', 'method dog' and 'source kind white-image' / 'self-calibration' as stored in the JSON, while
    every other row reads 'disk radius 4.569 px'.  They now read as the rest of the table."""
    from plenodecode.types import LensletGrid

    _, html = _calibrate(tmp_path, *CASES[case]())
    text = _text(html)
    info = LensletGrid.from_json((tmp_path / "grid.json").read_text()).info
    for raw_words in ("rim radius px", "radius px ", "source kind", "method rim", "method dog", "refined lenses",
                      "_px", "white-image"):
        assert raw_words not in text, raw_words
    if case == "f01-jpeg-scene":
        assert f"disk rim radius (fitted) {info['rim_radius_px']:.3f} px" in text
        assert "how the centres were measured circles fitted to the disks' rims (rim)" in text
        assert "source self-calibration from a scene (no white image)" in text
    else:
        assert "how the centres were measured peaks of the disks' brightness, difference-of-Gaussians fit (dog)" in text
        assert "binning of the fit's detection 2 (2 x 2 pixels summed)" in text
        assert "source fitted to white image(s)" in text
    assert re.search(r" disk radius \d+\.\d{3} px ", text)
