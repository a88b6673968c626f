"""Light-field microscopes end to end through the command line (issue 18, items 3 and 7).

Optics files in the napari-LF / LFAnalyze dialects, a generated square (microscope-like) raw with known optics
and plane depths, and the real LFAnalyze ant-leg capture (radiometry + dark frame; skipped without
``../shared/data``).
"""

from __future__ import annotations

import html
import math
from pathlib import Path
import re

import numpy as np
import pytest
from click.testing import CliRunner

from tests.conftest import shared_path
from plenodecode.cli.main import cli
from plenodecode.errors import MetadataError
from plenodecode.io.microscope import format_metadata_txt, format_optics_json, parse_optics
from plenodecode.io.pfm import read_pfm
from plenodecode.synthetic import PRESETS

ANTLEG = ("lf-microscopy-antleg",)
#: A napari-LF metadata.txt as the plugin writes it (JSON; um, mm and nm as documented by lfcalibrate).
NAPARI_METADATA = """{
    "main": {"comments": "ant leg"},
    "calibrate": {"radiometry_frame_file": "radiometry_frame.png", "dark_frame_file": "dark_frame.tif",
                  "ulens_pitch": 125.0, "pixel_size": 4.55, "ulens_focal_length": 2500.0,
                  "ulens_focal_distance": 2433.0, "objective_magnification": 20, "objective_na": 0.5,
                  "tubelens_focal_length": 180.0, "center_wavelength": 510.0, "medium_index": 1.33,
                  "ulens_profile": "rect", "num_slices": 10},
    "rectify": {"input_file": "light_field.png"},
    "hw": {"gpu_id": "none"}
}"""


def test_optics_dialects_agree():
    optics = PRESETS["square"].microscope
    napari = parse_optics(NAPARI_METADATA)
    assert napari == optics                                   # focal distance wins over focal length
    lfanalyze = parse_optics("pixel-size 4.55 um\npitch 125 um\nfocal-length 2433 um\nmagnification 20 x\n"
                             "na 0.5\ntubelens-focal-length 180.0\nwavelength 510\nmedium-index 1.33\n")
    assert lfanalyze == optics
    assert parse_optics(format_optics_json(optics)) == optics
    assert parse_optics(format_metadata_txt(optics)) == optics
    with pytest.raises(MetadataError, match="no microscope optics"):
        parse_optics('{"main": {}, "calibrate": {}}')
    with pytest.raises(MetadataError, match="numerical_aperture 1.5 must be below medium_index"):   # Python's names
        parse_optics('{"calibrate": {"objective_na": 1.5, "medium_index": 1.33}}')


def _plane_disparity(z_m: float) -> float:
    """Disparity of a plane ``z_m`` from the native object plane for the 'square' preset's optics, from the
    ray geometry: the next view's pixel (4.55 um off the micro-image centre, 2433 um behind the lenslet) sees
    n sin(theta) = 20 * 4.55 / 2433 in the specimen; the ray crosses the native plane z tan(theta) away, in
    lenslets of 125 um / 20 (the decoded spatial step is the lattice row spacing of 27.5 px = one pitch)."""
    theta = math.asin(20 * 4.55 / 2433 / 1.33)
    return -z_m * math.tan(theta) / (27.5 * 4.55e-6 / 20)


@pytest.fixture(scope="module")
def square_capture(tmp_path_factory):
    """A generated microscope raw + white: a plane 50 um towards the objective (left) and one 40 um away (right)."""
    from plenodecode.synthetic import simulate, write_simulation
    from plenodecode.synthetic.scene import Plane

    folder = tmp_path_factory.mktemp("lfm")
    near, far = -50e-6, 40e-6
    planes = [Plane(d0=_plane_disparity(near), support=("rect", -5, -5, 100, 19), depth_order=0, texture_seed=1),
              Plane(d0=_plane_disparity(far), depth_order=1, texture_seed=2)]
    sim = simulate("square", seed=3, scene=planes, shape=(660, 880))
    paths = write_simulation(sim, folder, name="lfm")
    (folder / "metadata.txt").write_text(format_metadata_txt(PRESETS["square"].microscope), encoding="utf-8")
    return paths, near, far


def test_generated_microscope_metric_depth(square_capture, tmp_path):
    paths, near, far = square_capture
    out = tmp_path / "z.pfm"
    r = CliRunner().invoke(cli, ["depth", str(paths["raw"]), "-w", str(paths["white"]), "--metric", "-o", str(out)],
                           obj={})
    assert r.exit_code == 0, r.output
    assert " um (2nd..98th percentile)" in r.output
    z = read_pfm(out)                                           # micrometres (metadata.txt beside the raw)
    X = z.shape[1]
    left, right = np.nanmedian(z[3:-3, 3:14]), np.nanmedian(z[3:-3, 24:X - 3])
    # tolerance: 0.03 px per view step of disparity error is 6.7 um here (222 um per px/view)
    assert left == pytest.approx(near * 1e6, abs=7.0)
    assert right == pytest.approx(far * 1e6, abs=7.0)


def test_missing_optics_name_the_cli_options(square_capture, tmp_path):
    """Metric depth of a microscope raw without (all) its optics: a usage error naming the options, before any
    work."""
    paths, _, _ = square_capture
    bare = tmp_path / "bare"
    bare.mkdir()
    for key in ("raw", "raw_json", "white", "white_json"):
        (bare / paths[key].name).write_bytes(paths[key].read_bytes())
    base = ["depth", str(bare / paths["raw"].name), "-w", str(bare / paths["white"].name), "--metric",
            "--method", "fast"]
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "a.pfm")], obj={})
    assert r.exit_code == 2 and "--magnification" in r.output and "=..." not in r.output
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "b.pfm"), "--magnification", "20", "--na", "0.5"],
                           obj={})
    assert r.exit_code == 2 and "--medium-index" in r.output and "=..." not in r.output
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "c.pfm"), "--na", "1.4", "--medium-index", "1.33"],
                           obj={})
    assert r.exit_code == 2 and "--na 1.4 must be below --medium-index 1.33" in r.output
    # the library names MicroscopeOptics fields (numerical_aperture, ...); the command line says its options
    for out in (r.output, CliRunner().invoke(cli, base + ["-o", str(tmp_path / "d.pfm"), "--magnification", "20"],
                                             obj={}).output):
        assert not any(f in out for f in ("numerical_aperture", "medium_index", "MicroscopeOptics", "open_source"))
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "d.pfm"), "--magnification", "20"], obj={})
    assert r.exit_code == 2 and "needs --medium-index, which its optics do not give; pass --medium-index (or " \
        "--optics FILE.json" in " ".join(r.output.split()), r.output
    assert not list(tmp_path.glob("?.pfm"))                  # refused before any output


def test_optics_file_errors_name_the_cli_options(square_capture, tmp_path):
    """A bad optics file seen through the CLI: the error names --optics and the value's option (--na), while
    parse_optics from Python names the MicroscopeOptics field (test_optics_dialects_agree)."""
    paths, _, _ = square_capture
    bad = tmp_path / "optics.json"
    bad.write_text('{"calibrate": {"objective_na": 1.5, "medium_index": 1.33}}')
    r = CliRunner().invoke(cli, ["depth", str(paths["raw"]), "-w", str(paths["white"]), "--optics", str(bad),
                                 "-o", str(tmp_path / "a.pfm")], obj={})
    text = " ".join(r.output.split())
    assert r.exit_code == 2 and "--optics" in text and "--na 1.5 must be below --medium-index 1.33" in text, text
    assert "numerical_aperture" not in text and not (tmp_path / "a.pfm").exists()


def test_optics_beside_a_raw_come_from_metadata_txt_else_a_readme_that_lists_them(tmp_path):
    """An LFAnalyze sample's README (``pitch 125 um`` lines) beside the raw gives its optics when there is no
    metadata.txt; a README that lacks one of pitch, pixel size, magnification and NA, or only mentions them in
    prose, gives none (a camera is not made a microscope by its README); metadata.txt wins over a README."""
    from plenodecode.io.microscope import optics_beside

    raw = tmp_path / "light_field.png"
    full = "SUMMARY\n\npixel-size 4.55 um\npitch 125 um\nmagnification 20 x\nna 0.5\nmedium-index 1.33\n"
    (tmp_path / "README").write_text(full)
    optics = optics_beside(raw)
    assert optics.lens_pitch_m == pytest.approx(125e-6) and optics.pixel_pitch_m == pytest.approx(4.55e-6)
    assert (optics.magnification, optics.numerical_aperture, optics.medium_index) == (20, 0.5, 1.33)
    (tmp_path / "README").write_text(full.replace("na 0.5\n", ""))
    assert optics_beside(raw) is None
    (tmp_path / "README").write_text("This camera has a pitch of 125 um and an NA of 0.5.\n")
    assert optics_beside(raw) is None
    (tmp_path / "README").write_text(full)
    (tmp_path / "metadata.txt").write_text(format_metadata_txt(PRESETS["square"].microscope))
    assert optics_beside(raw) == PRESETS["square"].microscope


# ------------------------------------------------------------------------------------- the real ant-leg capture
@pytest.fixture(scope="module")
def antleg(tmp_path_factory):
    """The ant leg decoded through the CLI with its radiometry and dark frames, saved as Zarr; its optics come from
    the LFAnalyze parameter list of the README beside it, with no option (``--optics README`` was needed)."""
    folder = shared_path(*ANTLEG)
    out = tmp_path_factory.mktemp("antleg") / "lf.zarr"
    r = CliRunner().invoke(cli, ["decode", str(folder / "light_field.png"), "-w", str(folder / "radiometry_frame.png"),
                                 "--dark", str(folder / "dark_frame.tif"), "-o", str(out)], obj={})
    assert r.exit_code == 0, r.output
    from plenodecode.io.lightfield import load_lightfield

    return folder, out, load_lightfield(out)


def test_antleg_every_lens_found(antleg):
    _, _, lf = antleg
    grid = lf.geometry.calibration
    optics = lf.geometry.microscope
    assert optics.magnification == 20 and optics.medium_index == 1.33    # carried by the saved light field
    assert lf.provenance.get("dark_subtracted") is True
    # 125 um lenses on 4.55 um pixels over the 2160 x 2592 sensor: 78.6 x 94.4 -> 79 x 95 (partial at the edges)
    rows, cols = (math.ceil(n * 4.55 / 125) for n in (2160, 2592))
    assert tuple(grid["shape"]) == (rows, cols) and grid["info"]["n_lenses"] == rows * cols
    assert grid["pitch"] == pytest.approx(125 / 4.55, rel=0.01)
    from plenodecode.types import LensletGrid

    g = LensletGrid.from_dict(grid)
    lat = g.lattice_centres()
    r = g.radius
    inside = (lat[..., 0] > r) & (lat[..., 0] < 2159 - r) & (lat[..., 1] > r) & (lat[..., 1] < 2591 - r)
    measured = np.isfinite(g.refined[..., 0])
    # every lens is placed by the lattice; >= 95 % of those with their whole disk on the sensor are also measured
    # (the rest sit in the dark corners of the radiometry frame)
    assert (measured & inside).sum() / inside.sum() >= 0.95
    assert lf.shape[:2] == (27, 27)


def _textured_window(centre: np.ndarray, h: int = 24, w: int = 32) -> tuple[slice, slice]:
    """The h x w window of the centre view with the most gradient energy (the structure, not the background)."""
    import cv2

    gy, gx = np.gradient(cv2.GaussianBlur(centre, (0, 0), 1.0))
    energy = cv2.boxFilter(gx ** 2 + gy ** 2, -1, (w, h), normalize=False, anchor=(0, 0))
    valid = energy[:centre.shape[0] - h + 1, :centre.shape[1] - w + 1]
    y0, x0 = np.unravel_index(np.argmax(valid), valid.shape)
    return slice(y0, y0 + h), slice(x0, x0 + w)


def test_antleg_parallax_and_metric_depth(antleg, tmp_path):
    import cv2

    from plenodecode.depth.metric import disparity_to_depth

    _, zarr, lf = antleg
    V, U = lf.shape[:2]
    vc, uc = V // 2, U // 2
    centre = np.nan_to_num(lf.data[vc, uc, :, :, 0]).astype(np.float64)
    ys, xs = _textured_window(centre)
    # parallax between opposite views: (vc, uc - k) and (vc, uc + k) with k = 8, well inside the 0.5 NA disk
    # (its rim, 13.4 px off the micro-image centre, holds the dim, vignetted views 0 and U - 1)
    k = 8
    a = np.nan_to_num(lf.data[vc, uc - k, ys, xs, 0]).astype(np.float64)
    b = np.nan_to_num(lf.data[vc, uc + k, ys, xs, 0]).astype(np.float64)
    (shift_x, _), response = cv2.phaseCorrelate(a, b, cv2.createHanningWindow(a.shape[::-1], cv2.CV_64F))
    assert response > 0.5
    # HCI convention: view u is the centre shifted by -d (u - uc), so b(x) = a(x + 2 k d) and shift_x = -2 k d
    d = -shift_x / (2 * k)
    z_parallax = float(disparity_to_depth(np.array([[d]]), lf)[0, 0]) * 1e6
    # the bright cuticle band is 5..60 um nearer the objective than the native object plane
    assert -60.0 < z_parallax < -5.0
    out = tmp_path / "z.pfm"
    r = CliRunner().invoke(cli, ["depth", str(zarr), "--metric", "-o", str(out)], obj={})
    assert r.exit_code == 0, r.output
    z = read_pfm(out)
    # the depth estimate agrees with the parallax where the structure is (sign and size)
    assert np.nanmedian(z[ys, xs]) == pytest.approx(z_parallax, abs=15.0)
    lo, hi = np.nanpercentile(z, [2, 98])
    # an ant leg: a few hundred um of relief at most, tens at least
    assert -200.0 < lo < 0.0 < hi < 400.0 and 30.0 < hi - lo < 500.0
    # the range the command prints is the one of the pixels its PNG colours (confidence >= 0.1: the leg), not of
    # the 64 % greyed-out background, whose noise made it 'depth -65.06 .. 243.7 um' against -71 .. 141 um shown
    from plenodecode.io.depthio import DEFAULT_MIN_CONFIDENCE
    from plenodecode.io.images import read_image

    conf = np.asarray(read_image(tmp_path / "z_confidence.exr"), np.float64)
    conf = conf[..., 0] if conf.ndim == 3 else conf
    shown = z[(conf >= DEFAULT_MIN_CONFIDENCE) & np.isfinite(z)]
    assert 0.2 < shown.size / z.size < 0.6                                 # measured 36 %
    found = re.search(r"^depth (\S+) \.\. (\S+) um \(2nd\.\.98th percentile\) where confidence >= 0\.1 "
                      r"\(all pixels: (\S+) \.\. (\S+)\)$", r.output, flags=re.MULTILINE)
    assert found, r.output
    printed = [float(x) for x in found.groups()]
    np.testing.assert_allclose(printed[:2], np.percentile(shown, [2, 98]), rtol=1e-3, atol=0.01)
    np.testing.assert_allclose(printed[2:], [lo, hi], rtol=1e-3, atol=0.01)
    assert printed[1] < 0.7 * hi                                          # measured 141 against 244 um


def test_antleg_refocus_by_slope_and_no_focus_distance(antleg, tmp_path):
    """A microscope's light field refocuses by slope (its refocusable range has no distance in metres: depth is an
    axial offset from the native object plane), and --focus-distance is refused before any work, naming the
    option."""
    from plenodecode.io.images import read_image
    from plenodecode.render import refocus_range_units

    _, saved, lf = antleg
    span = refocus_range_units(lf)
    assert span.distance_m is None and -3.0 < span.slope[0] < 0.0 < span.slope[1] < 3.0
    photos = {}
    for slope in ("-0.5", "0.5"):
        out = tmp_path / f"photo_{slope}.png"
        r = CliRunner().invoke(cli, ["refocus", str(saved), "--slope", slope, "-o", str(out)], obj={})
        assert r.exit_code == 0, r.output
        photos[slope] = np.asarray(read_image(out), np.float64)
    ys, xs = _textured_window(lf.centre_view().mean(axis=-1))
    assert np.abs(photos["-0.5"] - photos["0.5"])[ys, xs].mean() > 1.0      # 8-bit levels: the focus moved
    r = CliRunner().invoke(cli, ["refocus", str(saved), "--focus-distance", "0.5", "-o", str(tmp_path / "d.png")],
                           obj={})
    assert r.exit_code == 2 and "--focus-distance" in r.output and "microscope" in r.output, r.output
    assert not (tmp_path / "d.png").exists()


def test_antleg_dark_photo_is_named_and_auto_exposure_brightens_it(antleg, tmp_path):
    """The ant leg is a dim specimen over a bright radiometry frame: the one-liner's photograph, radiometrically
    right, has its brightest 0.5 % at 14 % of full scale (linear) and looked black.  The command now says so and
    names --exposure; --exposure auto puts that percentile at full scale, --exposure 1 doubles the linear light,
    and a bad value is refused before any work."""
    from plenodecode.io.images import read_image, srgb_decode, to_unit_float

    folder, _, _ = antleg
    base = [str(folder / "light_field.png"), "-w", str(folder / "radiometry_frame.png"), "--dark",
            str(folder / "dark_frame.tif"), "--bit-depth", "32"]
    levels = {}
    for exposure in (None, "1", "auto"):
        out = tmp_path / f"photo_{exposure}.exr"
        r = CliRunner().invoke(cli, base + ["-o", str(out)] + ([] if exposure is None else ["--exposure", exposure]),
                               obj={})
        assert r.exit_code == 0, r.output
        assert ("picture is dark" in r.output and "--exposure auto" in r.output) == (exposure is None), r.output
        levels[exposure] = np.asarray(read_image(out), np.float64)
    brightest = {k: float(np.percentile(v.max(axis=-1) if v.ndim == 3 else v, 99.5)) for k, v in levels.items()}
    assert 0.05 < brightest[None] < 0.25                                  # measured 0.14
    assert brightest["auto"] == pytest.approx(1.0, rel=0.02)
    np.testing.assert_allclose(levels["1"], 2.0 * levels[None], rtol=1e-5, atol=1e-6)
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "bad.png"), "--exposure", "bright"], obj={})
    assert r.exit_code == 2 and "--exposure" in r.output and not (tmp_path / "bad.png").exists()
    # a 16-bit PNG at auto exposure: display-encoded, the brightest 0.5 % near white
    out = tmp_path / "auto.png"
    r = CliRunner().invoke(cli, base[:-2] + ["-o", str(out), "--exposure", "auto"], obj={})
    assert r.exit_code == 0, r.output
    png = srgb_decode(to_unit_float(read_image(out)))
    assert float(np.percentile(png.max(axis=-1) if png.ndim == 3 else png, 99.5)) > 0.97
    # the parallax animation and its frames take the same option (one gain for all frames)
    anim = tmp_path / "wobble.gif"
    r = CliRunner().invoke(cli, ["parallax"] + base[:-2] + ["-o", str(anim), "--frames", "4", "--exposure", "auto"],
                           obj={})
    assert r.exit_code == 0, r.output
    for written in (anim, tmp_path / "wobble_frames" / "frame_000.png"):
        img = to_unit_float(read_image(written))
        img = img[..., :3] if img.ndim == 3 else img                         # the GIF has alpha; the PNG is grey
        assert float(np.percentile(img, 99.5)) > 0.95, written              # 0.47 at the default exposure


def test_antleg_dark_views_and_parallax_are_named(antleg, tmp_path):
    """'plenodecode views' and 'parallax' of the ant leg wrote pictures as dark as the one-liner's photograph (its
    centre view's brightest 0.5 % at 17 % of full scale) without the note the photograph gets; they now say so on
    stderr and name --exposure, measured on the view they wrote, and say nothing at --exposure auto."""
    from plenodecode.io.images import read_image, srgb_decode, to_unit_float

    _, saved, lf = antleg
    vc, uc = (n // 2 for n in lf.shape[:2])
    r = CliRunner().invoke(cli, ["views", str(saved), "-o", str(tmp_path / "views")], obj={})
    assert r.exit_code == 0, r.output
    found = re.search(r"note: the centre view is dark \(its brightest 0\.5 % reach (\d+) % of full scale, in linear "
                      r"light\); --exposure auto", r.output)
    assert found, r.output
    centre = srgb_decode(to_unit_float(read_image(tmp_path / "views" / f"view_{vc:02d}_{uc:02d}.png")))
    level = float(np.percentile(centre, 99.5))
    assert 0.05 < level < 0.25 and int(found.group(1)) == pytest.approx(100 * level, abs=1.0)     # measured 17 %
    r = CliRunner().invoke(cli, ["views", str(saved), "-o", str(tmp_path / "bright"), "--exposure", "auto"], obj={})
    assert r.exit_code == 0 and "is dark" not in r.output, r.output
    r = CliRunner().invoke(cli, ["parallax", str(saved), "-o", str(tmp_path / "p.gif"), "--frames", "4"], obj={})
    assert r.exit_code == 0 and "note: the middle frame is dark" in r.output and "--exposure auto" in r.output, \
        r.output


def test_antleg_batch_names_its_dark_picture_once(tmp_path):
    """'plenodecode batch' over the ant leg wrote pictures and thumbnails as dark as the single commands' (the
    photograph's brightest 0.5 % at 14 % of full scale) without the note those commands print.  It now prints
    that note, in the same words, once per raw (naming the raw and its first picture), and none at --exposure
    auto; the thumbnails stay what the files are (dim at the default exposure: mean 36 of 255 for the photo's),
    and --exposure auto brightens both."""
    from plenodecode.io.images import read_image, srgb_decode, to_unit_float

    folder = shared_path(*ANTLEG)
    base = ["batch", str(folder / "light_field.png"), "-w", str(folder / "radiometry_frame.png"), "--dark",
            str(folder / "dark_frame.tif"), "--outputs", "photo,views", "--jobs", "1"]

    def brightest(path: Path) -> float:
        return float(np.percentile(srgb_decode(to_unit_float(read_image(path))), 99.5))

    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "out")], obj={})
    assert r.exit_code == 0, r.output
    notes = [line for line in r.output.splitlines() if "is dark" in line]
    assert len(notes) == 1, r.output
    found = re.fullmatch(r"note: refocus_s\+0\.00\.png of light_field\.png is dark \(its brightest 0\.5 % reach "
                         r"(\d+) % of full scale, in linear light\); --exposure auto brightens it to full scale, "
                         r"--exposure 2 by two stops", notes[0])
    assert found, notes
    folder_out = tmp_path / "out" / "light_field"
    level = brightest(folder_out / "refocus_s+0.00.png")
    assert 0.05 < level < 0.25 and int(found.group(1)) == pytest.approx(100 * level, abs=1.0)    # measured 14 %
    assert brightest(folder_out / "thumbs" / "refocus_s+0.00.png") == pytest.approx(level, abs=0.03)
    # the index page's card said nothing of it (its dim thumbnails alone); it says the same note, naming the picture
    # as its caption does (it said 'the photo' under a picture captioned refocus_s+0.00.png)
    card = f"note: {notes[0].removeprefix('note: ').replace(' of light_field.png', '')}"
    assert card.startswith("note: refocus_s+0.00.png is dark (its brightest 0.5 % reach ")
    page = (tmp_path / "out" / "index.html").read_text()
    assert page.count(f'<div class="note">{html.escape(card)}</div>') == 1
    assert page.count("<figcaption>refocus_s+0.00.png</figcaption>") == 1
    # run again, the raw skipped as done: its pictures are as dark, and the terminal and the rewritten page say so
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "out")], obj={})
    assert r.exit_code == 0 and "0 done, 1 skipped" in r.output and notes[0] in r.output.splitlines(), r.output
    assert html.escape(card) in (tmp_path / "out" / "index.html").read_text()
    r = CliRunner().invoke(cli, base + ["-o", str(tmp_path / "auto"), "--exposure", "auto"], obj={})
    assert r.exit_code == 0 and "is dark" not in r.output, r.output
    assert 'class="note"' not in (tmp_path / "auto" / "index.html").read_text()
    for name in ("refocus_s+0.00.png", "thumbs/refocus_s+0.00.png"):
        assert brightest(tmp_path / "auto" / "light_field" / name) > 0.95, name


def test_antleg_focal_stack_all_in_focus_has_no_bright_edge_column(antleg, tmp_path):
    """The focal stack's all-in-focus image of the ant leg had a bright line down its second column (rows 28-43 at
    2.7 x the background beside it, in linear light), in none of the slices: the ant leg's first column holds a few
    samples of almost no weight (0.04) whose values, divided by a nearly black white, are 27 x the background, and
    the per-pixel refocus interpolated the data and the weights apart, so those samples counted in full where
    they were interpolated.  With the data premultiplied by the weight, column 1 is the background (at most 1.2 x)."""
    from plenodecode.io.images import read_image, srgb_decode, to_unit_float

    _, saved, _ = antleg
    r = CliRunner().invoke(cli, ["refocus", str(saved), "--focal-stack", "-1:1:9", "-o", str(tmp_path / "stack")],
                           obj={})
    assert r.exit_code == 0, r.output

    def linear(name: str) -> np.ndarray:
        img = srgb_decode(to_unit_float(read_image(tmp_path / "stack" / name)))
        return img[..., 0] if img.ndim == 3 else img

    for name in ("all_in_focus.png", "slice_004.png"):
        img = linear(name)
        beside = np.median(img[5:-5, 2:6], axis=1)
        assert float(np.max(img[5:-5, 1] / beside)) < 1.5, name      # 2.74 before, 1.2 now; the slices 1.1


def test_antleg_page_greys_the_unconfident_background_and_says_monochrome(antleg, tmp_path):
    """'export --format html' of the ant leg coloured its whole disparity panel, the featureless background's noise
    (64 % of the pixels, which 'depth' greys out) included, with a legend and a focal stack spanning that noise
    (-1.108 .. 0.330 px/view), and called the monochrome light field '1 channel(s), colour camera'.  The panel now
    greys the pixels below the depth PNGs' confidence, its colours and slopes span the others, and it says
    'monochrome'."""
    import base64
    import json

    import cv2

    from plenodecode.io.depthio import MASK_GREY

    _, saved, _ = antleg
    out = tmp_path / "page.html"
    r = CliRunner().invoke(cli, ["export", str(saved), "-o", str(out), "--format", "html"], obj={})
    assert r.exit_code == 0, r.output
    html = out.read_text(encoding="utf-8")
    assert "monochrome" in html and "colour camera" not in html and "channel(s)" not in html
    data = json.loads(re.search(r'<script type="application/json" id="lf-data">(.*?)</script>', html,
                                flags=re.DOTALL).group(1))
    depth = data["depth"]
    png = base64.b64decode(depth["src"].split(",", 1)[1])
    rgb = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[..., ::-1].astype(int)
    grey = np.all(np.abs(rgb - np.rint(255 * np.array(MASK_GREY))) <= 1, axis=-1)
    assert 0.4 < grey.mean() < 0.85, grey.mean()                               # measured 64 %
    values = np.frombuffer(base64.b64decode(depth["values"]), "<f4").reshape(depth["height"], depth["width"])
    np.testing.assert_allclose([depth["vmin"], depth["vmax"]], np.percentile(values[~grey], [1, 99]), atol=0.02)
    noise_low = np.percentile(values, 1)                                      # -1.108, of the background's noise
    assert depth["vmin"] > noise_low + 0.25 and data["slopes"][0] > noise_low + 0.15    # -0.646 and -0.795 now


def test_antleg_alpha_is_refused_as_not_applying_to_a_microscope(antleg, tmp_path):
    """'--refocus 1.02' on the ant leg with its optics said it 'has no focal_length_m, f_number, lens_pitch_m in its
    metadata', as if giving them (its lens pitch is known: 125 um) would do, where '--focus-distance' says a
    microscope has none; alpha now says so too, naming the option to use, before any decoding."""
    folder, saved, _ = antleg
    raw = [str(folder / "light_field.png"), "-w", str(folder / "radiometry_frame.png"), "--optics",
           str(folder / "README")]
    for args, option, instead in (
            (["refocus", str(saved), "--alpha", "1.02"], "--alpha / --refocus", "use --slope S (px per view step)"),
            (raw + ["--refocus", "1.02"], "--refocus / --alpha", "use --slope S (px per view step)"),
            (["refocus", str(saved), "--focal-stack", "0.98:1.02:5", "--stack-units", "alpha"], "--stack-units",
             "use --stack-units slope")):
        out = tmp_path / "out.png" if "--focal-stack" not in args else tmp_path / "stack"
        r = CliRunner().invoke(cli, args + ["-o", str(out)], obj={})
        errors = [line for line in r.output.splitlines() if line.startswith("Error:")]
        assert r.exit_code == 2 and len(errors) == 1, r.output
        assert errors[0].startswith(f"Error: Invalid value for {option}: light_field.png: alpha (Ng's film depth -> "
                                    "slope) does not apply to a light-field microscope"), errors
        assert instead in errors[0] and "focal_length_m" not in errors[0] and not out.exists(), errors


def test_microscope_alpha_refusal_carries_what_to_use_instead():
    """The command line's 'use --slope S ... instead' for a microscope's alpha was added by matching the end of the
    error's message against MICROSCOPE_NO_ALPHA (a reworded message would have lost it, and the library's message
    said no alternative at all).  The error now carries it (``instead``, ``reason``), the library's message ends
    with it, and the command line says its option from those fields (real ant-leg raw with its optics; no decoding).
    """
    from plenodecode.cli.main import constants_usage_error
    from plenodecode.errors import MissingConstantsError
    from plenodecode.io.microscope import read_optics
    from plenodecode.pipeline import check_product, open_raw

    folder = shared_path(*ANTLEG)
    raw = open_raw(folder / "light_field.png", optics=read_optics(folder / "README"))
    for product, options, instead in (("refocus", {"alpha": 1.02}, "refocus by slope instead"),
                                      ("focal-stack", {"units": "alpha"},
                                       "give START and STOP as slopes (units='slope')")):
        with pytest.raises(MissingConstantsError) as caught:
            check_product(raw, product, **options)
        exc = caught.value
        assert exc.instead == instead and exc.missing == (), str(exc)
        assert exc.reason.startswith("alpha (Ng's film depth -> slope) does not apply to a light-field microscope")
        assert str(exc) == f"light_field.png: {exc.reason}; {instead}"
    # the command line's words come from the fields: another reason still gets the option to use
    other = MissingConstantsError("x.png: another reason; refocus by slope instead", keyword="alpha", missing=(),
                                  source="x.png", need="alpha", reason="another reason",
                                  instead="refocus by slope instead")
    assert constants_usage_error(None, other).format_message() == (
        "Invalid value for --alpha: x.png: another reason; use --slope S (px per view step) instead")
    without = MissingConstantsError("x.png: why, and what to do", keyword="alpha", missing=(), source="x.png",
                                    need="alpha")
    assert constants_usage_error(None, without).format_message() == ("Invalid value for --alpha: x.png: why, and "
                                                                     "what to do")


def test_info_of_the_dark_frame_says_it_has_no_micro_images():
    """'plenodecode info dark_frame.tif' (the ant leg's real dark frame) said 'black 95 ... (black estimated from the
    gaps between micro-images', alarming nonsense for a dark frame; it now says the image is nearly uniform and
    dark with no micro-images, with its values, as the light field itself still gets its estimate."""
    import os
    import subprocess
    import sys

    folder = shared_path(*ANTLEG)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}

    def info(name: str) -> subprocess.CompletedProcess:
        proc = subprocess.run([sys.executable, "-m", "plenodecode", "info", str(folder / name)], capture_output=True,
                              text=True, env=env, timeout=120)
        assert proc.returncode == 0, proc.stderr
        return proc

    dark = info("dark_frame.tif")
    assert "gaps" not in dark.stderr and "black 0, white 65535" in dark.stdout, dark.stderr
    # measured: 98 % of its values within 95..107 of 65535 (min 42, max 199)
    assert re.search(r"no micro-images to estimate the black level from: nearly uniform and dark, 98 % of the "
                     r"values within 9\d\.\.1[01]\d, as in a dark frame", dark.stderr), dark.stderr
    raw = info("light_field.png")
    assert "black estimated from the gaps between micro-images" in raw.stderr and "black 92" in raw.stdout


def test_dark_frame_of_another_size_is_refused_before_any_work(tmp_path, monkeypatch):
    """'--dark' with a frame of another camera was reported as 'dark image must have the raw's size ...' (no
    option named) after the white image had been calibrated (~1.4 s); it is now a usage error naming --dark,
    before the calibration (decode, views and batch on the real ant-leg capture with the F01 JPEG as dark)."""
    from plenodecode import pipeline
    from plenodecode.pipeline import source as source_module

    folder = shared_path(*ANTLEG)
    wrong = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    calibrated = []
    for module in (pipeline, source_module):
        monkeypatch.setattr(module, "choose_calibration",
                            lambda *a, _real=module.choose_calibration, **k: calibrated.append(a) or _real(*a, **k))
    common = [str(folder / "light_field.png"), "-w", str(folder / "radiometry_frame.png"), "--dark", str(wrong)]
    for command, out in (("decode", tmp_path / "lf.zarr"), ("views", tmp_path / "views")):
        res = CliRunner().invoke(cli, [command, *common, "-o", str(out)])
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert errors[0] == ("Error: Invalid value for --dark: IMG_1.jpg is 3280 x 3280 px but the raw "
                             "light_field.png is 2592 x 2160; pass the dark frame of this camera"), errors
        assert not out.exists()
    assert calibrated == []
    # batch failed the raw on its row (exit 1, a summary of that); a dark frame that suits no raw of the batch is now
    # refused as the single commands refuse it
    res = CliRunner().invoke(cli, ["batch", *common, "-o", str(tmp_path / "batch")])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1] == errors[0] and not (tmp_path / "batch").exists()
    assert "Traceback" not in res.output


def test_a_bright_frame_given_as_the_dark_is_refused_before_any_work(tmp_path, monkeypatch):
    """'--dark radiometry_frame.png' (the white and dark swapped) or '--dark light_field.png' decoded the ant leg
    into an all-black light field (every sample 0.0) without a word; a frame that would leave the raw black is now a
    usage error naming --dark before the calibration, while the real dark frame still decodes a picture."""
    from plenodecode import pipeline
    from plenodecode.io.lightfield import load_lightfield

    folder = shared_path(*ANTLEG)
    calibrated = []
    monkeypatch.setattr(pipeline, "choose_calibration",
                        lambda *a, _real=pipeline.choose_calibration, **k: calibrated.append(a) or _real(*a, **k))
    for bright in ("radiometry_frame.png", "light_field.png"):
        res = CliRunner().invoke(cli, ["decode", str(folder / "light_field.png"), "-w",
                                       str(folder / "radiometry_frame.png"), "--dark", str(folder / bright),
                                       "-o", str(tmp_path / "lf.zarr")])
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert f"Invalid value for --dark: {bright} is no dark frame for light_field.png" in errors[0], errors
        assert "keep 0.0% of the range" in errors[0] and not (tmp_path / "lf.zarr").exists()
    assert calibrated == []
    res = CliRunner().invoke(cli, ["decode", str(folder / "light_field.png"), "-w",
                                   str(folder / "radiometry_frame.png"), "--dark", str(folder / "dark_frame.tif"),
                                   "-o", str(tmp_path / "lf.zarr")])
    assert res.exit_code == 0, res.output
    centre = load_lightfield(tmp_path / "lf.zarr").centre_view()
    assert float(np.percentile(centre, 99.5)) > 0.1 and calibrated        # the specimen, not black


def test_antleg_reader_lines_name_the_dark_frame_not_an_unused_black(tmp_path):
    """With --dark the decoder subtracts the dark frame pixel by pixel, yet every microscope command printed four
    warnings, two of them 'black 92 ... estimated from the gaps between micro-images' for the raw and the white:
    a level the decoding does not use.  Each mosaic without a sidecar now gets one line, which names the dark
    frame when one is given (the one-liner and a batch alike) and the estimated black otherwise."""
    import os
    import subprocess
    import sys

    folder = shared_path(*ANTLEG)
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root)}

    def reader_lines(args: list[str]) -> list[str]:
        proc = subprocess.run([sys.executable, "-m", "plenodecode", *args], capture_output=True, text=True, env=env,
                              cwd=tmp_path, timeout=600)
        assert proc.returncode == 0, proc.stderr
        return [line for line in proc.stderr.splitlines() if "no JSON sidecar" in line]     # the reader's lines

    white = ["-w", str(folder / "radiometry_frame.png")]
    dark = ["--dark", str(folder / "dark_frame.tif")]
    lines = reader_lines([str(folder / "light_field.png"), *white, *dark, "-o", str(tmp_path / "a.png")])
    assert len(lines) == 2 and all("no JSON sidecar" in x and "black from the dark frame dark_frame.tif" in x
                                   and "estimated" not in x for x in lines), lines
    assert sorted(x.split(": ")[1] for x in lines) == ["light_field.png", "radiometry_frame.png"]
    lines = reader_lines([str(folder / "light_field.png"), *white, "-o", str(tmp_path / "b.png")])
    # without a dark frame: the estimated black, in the same one line per file
    assert lines and all(re.search(r"black 9\d, white 65535 of 65535 \(black estimated from the gaps", x)
                         for x in lines), lines
    lines = reader_lines(["batch", str(folder / "light_field.png"), *white, *dark, "--outputs", "photo", "-o",
                          str(tmp_path / "out")])
    assert lines and all("black from the dark frame dark_frame.tif" in x and "estimated" not in x
                         for x in lines), lines
    assert len(list((tmp_path / "out" / "light_field").glob("*.png"))) == 1       # the photograph


def test_option_names_replace_bare_optics_fields_only():
    """Messages raised inside a command with microscope options name the options: a bare field becomes its option,
    but an option already named stayed no option ('--magnification' became '----magnification'), and a camera's
    missing constants (a Lytro's lens_pitch_m, for alpha or metric depth) were renamed microscope options."""
    from plenodecode.cli.common import in_option_names, optics_in_option_names
    from plenodecode.errors import MissingConstantsError

    assert in_option_names("needs numerical_aperture; give --magnification or magnification") == \
        "needs --na; give --magnification or --magnification"
    camera = "IMG_1.jpg has no focal_length_m, f_number, lens_pitch_m in its metadata"
    with pytest.raises(MissingConstantsError) as info:
        with optics_in_option_names():
            raise MissingConstantsError(camera, keyword="metric", missing=("focal_length_m", "f_number",
                                                                           "lens_pitch_m"),
                                        source="IMG_1.jpg", need="metric depth")
    assert str(info.value) == camera
    with pytest.raises(ValueError, match="^needs --medium-index$"):
        with optics_in_option_names():
            raise ValueError("needs medium_index")
