"""What a photographer types as the output: the image type of -o (or --ext) decides what --bit-depth may be,
and both are checked before any decoding, naming the option."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode import pipeline
from plenodecode.cli.main import cli
from plenodecode.io.images import read_image

ROOT = Path(__file__).resolve().parents[2]
ILLUM = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture
def no_work(monkeypatch):
    """Records every input opened: a refused command must open none."""
    opened = []
    real = pipeline.open_source
    monkeypatch.setattr(pipeline, "open_source", lambda *a, **k: opened.append(a) or real(*a, **k))
    return opened


def test_photo_as_jpeg_is_written_in_8_bits(tmp_path):
    """'plenodecode RAW -o photo.jpg' decoded the raw and then failed ('bit_depth 16 cannot be stored in .jpg
    files'): --bit-depth's default 16 now gives way to what the type holds, and the JPEG is the 8-bit PNG's
    picture."""
    res = run(ILLUM, "--database", ROOT / "calib", "-o", tmp_path / "photo.jpg")
    assert res.exit_code == 0, res.output
    jpeg = read_image(tmp_path / "photo.jpg")
    assert run(ILLUM, "--database", ROOT / "calib", "--bit-depth", 8, "-o", tmp_path / "photo.png").exit_code == 0
    png = read_image(tmp_path / "photo.png")
    assert jpeg.dtype == png.dtype == np.uint8 and jpeg.shape == png.shape == (87, 125, 3)
    assert np.mean(np.abs(jpeg.astype(float) - png)) < 3.0        # JPEG's loss only
    assert 60 < png.mean() < 200                                    # a photograph, not a black or white field


@pytest.mark.parametrize("args, option, words", [
    (["-o", "p.jpg", "--bit-depth", "16"], "--bit-depth", ".jpg files hold 8 bits per sample, not 16"),
    (["-o", "p.xyz"], "-o / --output", "an image file ends in .exr, .jpeg, .jpg, .pfm, .png, .tif, .tiff"),
    (["-o", "photo"], "-o / --output", "got 'no extension'"),
    (["refocus", "-o", "p.exr", "--bit-depth", "8"], "--bit-depth", ".exr files hold 16 or 32 bits"),
    (["refocus", "--focal-stack", "-1:1:3", "--ext", "exr", "--bit-depth", "8", "-o", "stack"], "--bit-depth",
     ".exr files hold 16 or 32 bits"),
    (["views", "--ext", "exr", "--bit-depth", "8", "-o", "views"], "--bit-depth", ".exr files hold 16 or 32"),
    (["views", "--view", "2", "2", "-o", "v.bmp"], "-o / --output", "got '.bmp'"),
], ids=["jpeg-16", "unknown-type", "no-type", "refocus-exr-8", "stack-exr-8", "views-exr-8", "view-bmp"])
def test_an_image_type_or_bit_depth_that_cannot_be_written_is_refused_before_decoding(tmp_path, no_work, args,
                                                                                       option, words):
    """These failed after decoding with the library's words ('bit_depth', 'path must end in ...')."""
    command = [args[0]] if args[0] in ("refocus", "views") else []
    rest = args[len(command):]
    rest = [str(tmp_path / a) if prev == "-o" else a for prev, a in zip([None, *rest], rest)]
    res = run(*command, ILLUM, "--database", ROOT / "calib", *rest)
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and f"Invalid value for {option}:" in errors[0] and words in errors[0], res.output
    assert no_work == [] and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, words", [
    (["refocus", "--focal-stack", "-1:1:3", "-o", "stack.png"], "a focal stack goes into a folder"),
    (["views", "-o", "views.png"], "every view (without --view) goes into a folder"),
    (["extract", "-o", "items.jpg"], "every item goes into a folder"),
], ids=["focal-stack", "views", "extract"])
def test_a_folder_output_named_like_an_image_is_refused(tmp_path, args, words):
    """'refocus --focal-stack ... -o stack.png' wrote a folder called stack.png holding slice_000.png ...; an
    output that is a folder of files but is named like an image is now refused, naming -o, with nothing made."""
    out = tmp_path / args[-1]
    res = run(args[0], ILLUM, "--database", ROOT / "calib", *args[1:-1], out) if args[0] != "extract" else \
        run("extract", ILLUM, "-o", out)
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1, res.output
    assert "Invalid value for -o / --output:" in errors[0] and words in errors[0], res.output
    assert f"give a folder, e.g. {out.with_suffix('')}/" in errors[0]
    assert not out.exists()


def test_export_of_a_raw_says_to_decode_it_first(tmp_path):
    """'plenodecode export scene.lfr -o page.html' said \"cannot tell the light-field format; pass format= one of
    [...]\" (a Python keyword; export has no input format option) and the real R42 PNG 'is not a whole number of
    14x14 view tiles'; a raw given to export is now a usage error naming LF_IN that says to decode it first."""
    from tests.conftest import shared_path

    for raw in (ILLUM, shared_path("raytrix-r42", "sc2_klein.png")):
        res = run("export", raw, "-o", tmp_path / "page.html")
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert f"Invalid value for LF_IN: {raw.name} is not a saved light field" in errors[0]
        assert f"'plenodecode decode {raw} -o lf.zarr'" in errors[0] and "format=" not in errors[0]
    assert list(tmp_path.iterdir()) == []
    assert run("decode", ILLUM, "--database", ROOT / "calib", "-o", tmp_path / "lf.zarr").exit_code == 0
    res = run("export", tmp_path / "lf.zarr", "-o", tmp_path / "page.html")
    assert res.exit_code == 0 and (tmp_path / "page.html").stat().st_size > 10000, res.output


def test_decode_to_an_unknown_extension_names_the_format_option(tmp_path, no_work):
    """'plenodecode decode RAW -o x.xyz' said 'pass format= one of [...] (use --format)', naming the Python keyword;
    it now names --format and the extensions that choose a format, in one line, before the raw is opened."""
    for command in (["decode", ILLUM, "--database", ROOT / "calib"], ["export", ILLUM]):
        res = run(*command, "-o", tmp_path / "x.xyz")
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert "pass --format one of ['eslf', 'mat', 'npy', 'views', 'zarr']" in errors[0], errors
        assert ".zarr" in errors[0] and "format=" not in res.output, res.output
    assert no_work == [] and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command, args, option, words", [
    ("decode", ["-o", "lf.jpg", "--format", "eslf"], "-o / --output", "an ESLF mosaic is written as .png, .tif or "
                                                                      ".tiff"),
    ("decode", ["-o", "lf.mat", "--bit-depth", "8"], "--bit-depth", "the LFToolbox .mat format stores 16-bit"),
    ("decode", ["-o", "lf.zarr", "--bit-depth", "8"], "--bit-depth", "zarr stores float32 samples (lossless), not 8"),
    ("decode", ["-o", "lf.npy", "--bit-depth", "16"], "--bit-depth", "npy stores float32 samples"),
    ("export", ["-o", "lf.exr", "--format", "eslf"], "-o / --output", "not .exr"),
    ("export", ["-o", "v", "--format", "views", "--image-type", "exr", "--bit-depth", "8"], "--bit-depth",
     ".exr files hold 16 or 32 bits per sample, not 8"),
    ("export", ["-o", "v", "--format", "views", "--image-type", "png", "--bit-depth", "32"], "--bit-depth",
     ".png files hold 8 or 16 bits per sample, not 32"),
    # an extension that says another format (a .mat file named .png loads back as nothing); an image type of a
    # format without images: both written (or ignored) in silence before
    ("export", ["-o", "lf.png", "--format", "mat"], "--format", "name it lf.mat, or leave --format out"),
    ("decode", ["-o", "lf.png", "--format", "zarr"], "--format", "name it lf.zarr, or leave --format out"),
    ("export", ["-o", "lf.mat", "--format", "npy"], "--format", "-o lf.mat says mat by its extension"),
    ("export", ["-o", "lf.mat", "--image-type", "exr"], "--image-type", "is the image type of a views folder"),
], ids=["decode-eslf-jpg", "decode-mat-8", "decode-zarr-8", "decode-npy-16", "export-eslf-exr", "export-exr-8",
        "export-png-32", "export-png-as-mat", "decode-png-as-zarr", "export-mat-as-npy", "export-mat-image-type"])
def test_a_lightfield_format_its_bit_depth_cannot_hold_is_refused_before_any_work(tmp_path, monkeypatch, command,
                                                                                  args, option, words):
    """'decode RAW -o lf.mat --bit-depth 8' and '-o lf.jpg --format eslf' decoded the raw (export: loaded the light
    field) and then failed naming the keyword 'bit_depth' (or wrote an ESLF .exr that does not load back); '--bit-depth
    8' with zarr was ignored in silence.  Now one line naming the option, before the raw or light field is read."""
    from plenodecode.io import lightfield
    from plenodecode.types import LightField

    opened = []
    monkeypatch.setattr(pipeline, "open_raw", lambda *a, **k: opened.append(a))
    monkeypatch.setattr(lightfield, "load_lightfield", lambda *a, **k: opened.append(a))
    src = ILLUM
    if command == "export":
        src = tmp_path / "in" / "lf.zarr"
        lightfield.save_lightfield(LightField(np.zeros((3, 3, 4, 5, 3), np.float32)), src)
    out = tmp_path / "out"
    rest = [str(out / a) if prev == "-o" else a for prev, a in zip([None, *args], args)]
    res = run(command, src, *(["--database", ROOT / "calib"] if command == "decode" else []), *rest)
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1, res.output
    assert f"Invalid value for {option}:" in errors[0] and words in errors[0] and "bit_depth" not in errors[0], errors
    assert opened == [] and not out.exists()


def test_lightfield_bit_depths_that_fit_are_written(tmp_path):
    """The depths the formats hold still write: zarr with --bit-depth 32, an ESLF .tif of floats that loads back as
    the light field, views as 32-bit TIFFs."""
    from plenodecode.io.lightfield import load_lightfield, save_lightfield

    assert run("decode", ILLUM, "--database", ROOT / "calib", "-o", tmp_path / "lf.zarr",
               "--bit-depth", 32).exit_code == 0
    lf = load_lightfield(tmp_path / "lf.zarr")
    res = run("export", tmp_path / "lf.zarr", "-o", tmp_path / "lf.tif", "--bit-depth", 32)
    assert res.exit_code == 0, res.output
    assert np.abs(load_lightfield(tmp_path / "lf.tif").data - lf.data).max() < 1e-6
    res = run("export", tmp_path / "lf.zarr", "-o", tmp_path / "v", "--format", "views", "--image-type", "tif",
              "--bit-depth", 32)
    assert res.exit_code == 0 and read_image(tmp_path / "v" / "input_Cam112.tif").dtype == np.float32, res.output
    with pytest.raises(ValueError, match="an ESLF mosaic is written as"):
        save_lightfield(lf, tmp_path / "lf.exr", format="eslf")
    assert not (tmp_path / "lf.exr").exists()


def test_a_light_field_never_replaces_a_folder_of_other_files(tmp_path):
    """'decode RAW -o important --overwrite', with 'important' a folder of the user's files, replaced the folder by
    the views and deleted them (and without --overwrite the advice was 'pass --overwrite to replace it').  A folder
    that holds files but no light field is now refused naming -o, with or without --overwrite, by decode, export
    and save_lightfield; a light-field folder is still replaced with --overwrite."""
    from plenodecode.io.lightfield import load_lightfield, save_lightfield

    mine = tmp_path / "important"
    mine.mkdir()
    (mine / "notes.txt").write_text("precious")
    assert run("decode", ILLUM, "--database", ROOT / "calib", "-o", tmp_path / "lf.zarr").exit_code == 0
    for args in (["decode", ILLUM, "--database", ROOT / "calib", "-o", mine],
                 ["decode", ILLUM, "--database", ROOT / "calib", "-o", mine, "--overwrite"],
                 ["export", tmp_path / "lf.zarr", "-o", mine, "--format", "zarr", "--overwrite"]):
        res = run(*args)
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert "Invalid value for -o / --output:" in errors[0] and "folder of other files (notes.txt)" in errors[0]
        assert "--overwrite" not in errors[0]
    lf = load_lightfield(tmp_path / "lf.zarr")
    with pytest.raises(ValueError, match="would replace the folder and delete them"):
        save_lightfield(lf, mine, format="views", overwrite=True)
    assert sorted(p.name for p in mine.iterdir()) == ["notes.txt"] and (mine / "notes.txt").read_text() == "precious"
    res = run("export", tmp_path / "lf.zarr", "-o", tmp_path / "v", "--format", "views")
    assert res.exit_code == 0 and run("export", tmp_path / "lf.zarr", "-o", tmp_path / "v", "--format", "views",
                                      "--bit-depth", 8, "--overwrite").exit_code == 0
    assert read_image(tmp_path / "v" / "input_Cam112.png").dtype == np.uint8


def test_views_of_a_light_field_name_the_corner_views_without_data(tmp_path):
    """'decode RAW -o views/ --format views' wrote the Illum sample's corner views as black PNGs without a word
    ('plenodecode views' names them); decode and export now say how many hold no data and where the weight is."""
    from plenodecode.imaging import view_data_share
    from plenodecode.io.lightfield import load_lightfield

    res = run("decode", ILLUM, "--database", ROOT / "calib", "-o", tmp_path / "v", "--format", "views")
    assert res.exit_code == 0, res.output
    lf = load_lightfield(tmp_path / "v")
    empty = view_data_share(lf.weight) == 0
    assert f"; {int(empty.sum())} corner views past the round micro-images hold no data" in res.output
    assert empty.sum() == (lf.weight.max(axis=(2, 3)) < 0.01).sum() == 24          # the 15 x 15 Illum's corners
    U = empty.shape[1]
    black = [read_image(tmp_path / "v" / f"input_Cam{v * U + u:03d}.png").max() == 0
             for v, u in zip(*np.nonzero(empty))]
    assert sum(black) == 16                                       # the other 8: samples of weight < 0.01 (stripes)
    res = run("export", tmp_path / "v", "-o", tmp_path / "e.png")
    assert res.exit_code == 0 and "hold no data (weight under 0.01: black, or the rims' stripes; the image's last " \
        "channel holds" in res.output
    res = run("export", tmp_path / "v", "-o", tmp_path / "z.zarr")
    assert res.exit_code == 0 and "hold no data" not in res.output


def test_srgb_of_an_srgb_light_field_names_the_option(tmp_path):
    """'export antinous -o v --format views --srgb' said 'encode_srgb: the light field is already sRGB-encoded'
    (the Python keyword); it names --srgb and writes nothing."""
    from tests.conftest import shared_path

    res = run("export", shared_path("hci-antinous"), "-o", tmp_path / "v", "--format", "views", "--srgb")
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1, res.output
    assert "Invalid value for --srgb: hci-antinous is sRGB-encoded already" in errors[0] and "encode_srgb" not in \
        res.output
    assert not (tmp_path / "v").exists()


@pytest.mark.parametrize("command, name", [((), "photo.png"), (("refocus",), "photo.png"),
                                           (("views", "--view", 1, 1), "view.png"), (("parallax",), "wobble.gif"),
                                           (("depth",), "d.png"), (("decode",), "lf.npy")])
def test_an_output_file_never_replaces_a_folder_of_its_name(tmp_path, no_work, command, name):
    """'-o photo.png --overwrite' where photo.png was a folder deleted the folder and everything in it, and wrote
    the photograph in its place ('depth -o d.pfm --overwrite' with a folder d.png wrote d.pfm and d.exr, then
    failed: half-written); '-o folder/' without --overwrite said 'pass --overwrite to replace it'.  Now each is a
    usage error naming the folder, before any work, and the folder and its file are left as they were."""
    from plenodecode.io.lightfield import save_lightfield
    from tests.cli.test_render import small_lf

    src = save_lightfield(small_lf(), tmp_path / "in" / "lf.npy")
    if command and command[0] == "decode":
        src = ILLUM
    out = tmp_path / "out"
    folder = out / name
    folder.mkdir(parents=True)
    (folder / "keep.txt").write_text("mine")
    target = out / "d.pfm" if command == ("depth",) else folder
    for extra in (["--overwrite"], []):
        res = run(*command[:1], src, *command[1:], "-o", target, *extra)
        errors = [ln for ln in res.output.splitlines() if ln.startswith("Error")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert f"{folder} is a folder; an output file never replaces a folder" in errors[0], errors
    assert (folder / "keep.txt").read_text() == "mine"
    assert sorted(p.name for p in out.iterdir()) == [name] and no_work == []
