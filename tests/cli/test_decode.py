"""``plenodecode decode`` on files written to a temporary folder."""

from __future__ import annotations

import os

import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode import synthetic
from plenodecode.cli.main import cli


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from plenodecode.io.generic import write_mosaic

    d = tmp_path_factory.mktemp("decode_cli")
    sim = synthetic.simulate("f01", shape=(240, 260), seed=1)
    raw = write_mosaic(d / "scene.png", sim.raw)
    white = write_mosaic(d / "white.png", sim.white)
    grid = d / "grid.json"
    grid.write_text(sim.grid.to_json(), encoding="utf-8")
    return sim, raw, white, grid


def run(args, cwd=None):
    runner = CliRunner()
    if cwd is None:
        return runner.invoke(cli, args, catch_exceptions=False)
    old = os.getcwd()
    os.chdir(cwd)
    try:
        return runner.invoke(cli, args, catch_exceptions=False)
    finally:
        os.chdir(old)


def test_decode_with_grid_and_white_writes_what_decode_returns(files, tmp_path):
    from plenodecode.decoding import decode
    from plenodecode.io.lightfield import load_lightfield

    sim, raw, white, grid = files
    out = tmp_path / "lf.npy"
    res = run(["-q", "decode", str(raw), "-g", str(grid), "-w", str(white), "-o", str(out)])
    assert res.exit_code == 0, res.output
    lf = load_lightfield(out)
    ref = decode(sim.raw, sim.grid, white=sim.white)
    assert lf.shape == ref.shape == (9, 9, *ref.shape[2:])
    np.testing.assert_allclose(lf.data, ref.data, atol=1e-6)
    assert lf.colour == "linear-srgb"


def test_decode_options_views_demosaic_format(files, tmp_path):
    from plenodecode.io.lightfield import load_lightfield

    sim, raw, white, grid = files
    out = tmp_path / "lf.zarr"
    res = run(["-q", "decode", str(raw), "-g", str(grid), "-w", str(white), "-o", str(out), "--views", "5",
               "--demosaic", "bilinear", "--colour", "camera"])
    assert res.exit_code == 0, res.output
    lf = load_lightfield(out)
    assert lf.shape[:2] == (5, 5) and lf.colour == "camera"
    assert lf.metadata["demosaic"] == "bilinear"
    bad = run(["decode", str(raw), "-g", str(grid), "-o", str(tmp_path / "x.npy"), "--demosaic", "menon"])
    assert bad.exit_code == 2 and "malvar" in bad.output
    even = run(["decode", str(raw), "-g", str(grid), "-o", str(tmp_path / "x.npy"), "--views", "4"])
    assert even.exit_code == 2


def test_white_alone_calibrates_on_the_fly(files, tmp_path):
    sim, raw, white, grid = files
    out = tmp_path / "lf.npy"
    res = run(["-q", "decode", str(raw), "-w", str(white), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.is_file()


def test_existing_output_is_not_overwritten(files, tmp_path):
    sim, raw, white, grid = files
    out = tmp_path / "lf.npy"
    out.write_bytes(b"keep me")
    res = run(["decode", str(raw), "-g", str(grid), "-o", str(out)])
    assert res.exit_code == 2 and "--overwrite" in res.output
    assert out.read_bytes() == b"keep me"
    res = run(["-q", "decode", str(raw), "-g", str(grid), "-w", str(white), "-o", str(out), "--overwrite"])
    assert res.exit_code == 0, res.output
    assert out.read_bytes() != b"keep me"


def test_raw_without_calibration_exits_1_saying_what_to_pass(files, tmp_path):
    sim, raw, white, grid = files
    res = CliRunner().invoke(cli, ["decode", str(raw), "-o", str(tmp_path / "lf.npy")])
    if (os.path.isdir("calib")):                       # run from a checkout with a database: use an empty cwd
        res = run(["decode", str(raw), "-o", str(tmp_path / "lf.npy")], cwd=tmp_path)
    assert res.exit_code == 1
    assert "--calibration" in res.output and "--white" in res.output
    assert not (tmp_path / "lf.npy").exists()


def test_wrong_sensor_grid_exits_1_without_output(files, tmp_path):
    sim, raw, white, grid = files
    other = tmp_path / "other.json"
    other.write_text(sim.grid.replace(sensor_shape=(100, 100)).to_json(), encoding="utf-8")
    out = tmp_path / "lf.npy"
    res = run(["decode", str(raw), "-g", str(other), "-o", str(out)])
    assert res.exit_code == 1 and "100x100" in res.output
    assert not out.exists()


def test_white_dir_database_picks_the_white_by_serial(files, tmp_path):
    from plenodecode.calib import store
    from plenodecode.io.lightfield import load_lightfield
    from plenodecode.io.lytro import write_lfp, write_raw_pair

    sim, *_ = files
    (tmp_path / "whites").mkdir()
    write_raw_pair(tmp_path / "whites" / "MOD_0000.RAW", sim.white)
    scene = write_lfp(tmp_path / "scene.lfp", sim.raw)
    store.build_database(tmp_path / "whites", tmp_path / "db")
    out = tmp_path / "out.npy"
    res = run(["decode", str(scene), "--white-dir", str(tmp_path / "db"), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "9x9 views" in res.output
    lf = load_lightfield(out)
    assert lf.metadata["devignetted"] is True
    assert lf.metadata["camera"]["serial"] == sim.raw.metadata.serial
    mixed = run(["decode", str(scene), "--white-dir", str(tmp_path / "db"), "-g", str(files[3]), "-o", str(out)])
    assert "cannot be combined" in mixed.output
    assert mixed.exit_code == 2


def test_decode_resample_hex_is_the_2d_kernel_and_closer_to_the_truth(files, tmp_path):
    """``--resample hex`` decodes with the 2-D hex-lattice kernel (recorded in the metadata); on the generated F01
    raw its centre view is closer to the ground truth than the row kernel's (noise-free the gain is ~1 dB)."""
    from plenodecode.io.lightfield import load_lightfield

    sim, raw, white, grid = files
    truth = sim.ground_truth_lightfield().centre_view()
    psnr = {}
    for method in ("cubic", "hex"):
        out = tmp_path / f"{method}.npy"
        res = run(["-q", "decode", str(raw), "-g", str(grid), "-w", str(white), "-o", str(out),
                   "--resample", method])
        assert res.exit_code == 0, res.output
        lf = load_lightfield(out)
        assert lf.metadata["resample"] == method
        err = (lf.centre_view() - truth)[4:-4, 4:-4]
        psnr[method] = 10 * np.log10(1.0 / np.mean(err ** 2))
    print(psnr)
    assert psnr["hex"] > psnr["cubic"] + 0.05
    bad = run(["decode", str(raw), "-g", str(grid), "-o", str(tmp_path / "x.npy"), "--resample", "lanczos"])
    assert bad.exit_code == 2 and "--resample" in bad.output


def test_more_views_than_a_micro_image_holds_is_refused_before_decoding(files, tmp_path, monkeypatch):
    """'decode --views 101' on a 14.3 px Illum grid decoded 101 x 101 views (22 s, 8 GB of views of nothing but the
    neighbouring lenses' disks or zeros); more views than 2 ceil(pitch / 2) + 1 is now a usage error naming --views
    before the decoder runs; that many still decodes, with data in its middle ring."""
    from plenodecode import pipeline
    from plenodecode.io.lightfield import load_lightfield

    sim, raw, white, grid = files
    most = sim.grid.max_views()
    assert most == 2 * int(np.ceil(sim.grid.pitch / 2)) + 1 == 11           # F01: 9.93 px
    decoded = []
    real = pipeline.decode_raw
    monkeypatch.setattr(pipeline, "decode_raw", lambda *a, **k: decoded.append(1) or real(*a, **k))
    res = CliRunner().invoke(cli, ["decode", str(raw), "-g", str(grid), "-w", str(white), "-o",
                                   str(tmp_path / "lf.zarr"), "--views", str(most + 2)])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1, res.output
    assert f"Invalid value for --views: {most + 2} is more than the {most} views per axis" in errors[0]
    assert decoded == [] and not (tmp_path / "lf.zarr").exists()
    with pytest.raises(ValueError, match="n_views 13 is more than the 11"):
        from plenodecode import decode
        decode(sim.raw, sim.grid, n_views=13)
    res = run(["decode", str(raw), "-g", str(grid), "-w", str(white), "-o", str(tmp_path / "lf.zarr"),
               "--views", str(most)])
    assert res.exit_code == 0, res.output
    lf = load_lightfield(tmp_path / "lf.zarr")
    assert lf.shape[:2] == (most, most) and lf.weight[most // 2, most // 2].mean() > 0.5


def test_a_light_field_or_a_folder_given_to_decode_says_which_command_takes_it(files, tmp_path):
    """'decode lf.mat' said 'not a raw LibRaw can read', 'decode lf.zarr' or an HCI scene folder 'File ... is a
    directory'; a decoded input now gets one usage error naming RAW and the commands that take it (and they do),
    a folder of raws the batch command, before anything is written."""
    sim, raw, white, grid = files
    assert run(["-q", "decode", str(raw), "-g", str(grid), "-o", str(tmp_path / "lf.mat")]).exit_code == 0
    assert run(["-q", "decode", str(raw), "-g", str(grid), "-o", str(tmp_path / "lf.zarr")]).exit_code == 0
    for given, words in ((tmp_path / "lf.mat", "lf.mat is a saved light field, decoded already: 'plenodecode "
                          f"export {tmp_path / 'lf.mat'} -o lf.zarr' converts it"),
                         (tmp_path / "lf.zarr", "lf.zarr is a saved light field"),
                         (raw.parent, f"{raw.parent.name} is a folder; decode reads one raw file ('plenodecode "
                                      f"batch {raw.parent} -o OUT/'")):
        res = CliRunner().invoke(cli, ["decode", str(given), "-o", str(tmp_path / "out.zarr")])
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, res.output
        assert "Invalid value for RAW:" in errors[0] and words in errors[0], errors
    assert not (tmp_path / "out.zarr").exists()
    res = run([str(tmp_path / "lf.mat"), "-o", str(tmp_path / "photo.png")])    # what the message says works
    assert res.exit_code == 0 and (tmp_path / "photo.png").is_file(), res.output


def test_database_option_on_a_folder_of_white_images_says_how_to_index_it(tmp_path):
    """'decode scene.lfr --database sample_raws/illum-mini' (white images, no index) said 'no calibration database
    in sample_raws/illum-mini; pass --database DIR, ...': the option the user had just passed.  It now says the
    index is missing and the command that makes one of that folder."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini"
    res = CliRunner().invoke(cli, ["decode", str(folder / "scene.lfr"), "--database", str(folder),
                                   "-o", str(tmp_path / "lf.zarr")])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 1 and len(lines) == 1, res.output
    assert f"no calibration database in {folder} (no index.json); white images beside it (MOD_0000.RAW): " \
           f"'plenodecode calibrate --database {folder} {folder}' builds" in lines[0]
    assert not (tmp_path / "lf.zarr").exists()


def test_one_liner_without_a_database_names_the_white_image_beside_the_raw(tmp_path, monkeypatch):
    """'plenodecode scene.lfr -o photo.png' in a folder without ./calib, the white image MOD_0000.RAW beside the
    raw, said only 'calibrate --database calib FOLDER ... or --white WHITE_IMAGE'.  It now names the white image
    and the two commands that use it; the --white one writes the photo.  A raw with no white image beside it keeps
    the FOLDER form."""
    import shutil
    from pathlib import Path

    import cv2

    src = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini"
    raws = tmp_path / "raws"
    raws.mkdir()
    for name in ("scene.lfr", "MOD_0000.RAW", "MOD_0000.TXT"):
        shutil.copy(src / name, raws / name)
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(cli, [str(raws / "scene.lfr"), "-o", "photo.png"])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 1 and len(lines) == 1, res.output
    assert "white images beside it (MOD_0000.RAW): 'plenodecode calibrate --database calib " \
           f"{raws}' builds the database of them, or pass --white {raws / 'MOD_0000.RAW'}" in lines[0]
    assert not (tmp_path / "photo.png").exists()
    res = CliRunner().invoke(cli, [str(raws / "scene.lfr"), "--white", str(raws / "MOD_0000.RAW"), "-o", "photo.png"])
    photo = cv2.imread(str(tmp_path / "photo.png"), cv2.IMREAD_UNCHANGED)
    assert res.exit_code == 0 and photo is not None and photo.std() > 0.02 * np.iinfo(photo.dtype).max, res.output
    (raws / "MOD_0000.RAW").unlink()
    res = CliRunner().invoke(cli, [str(raws / "scene.lfr"), "-o", "photo2.png"])
    assert res.exit_code == 1 and "'plenodecode calibrate --database calib FOLDER' makes one" in res.output


def test_an_output_over_the_raw_or_its_sidecar_is_refused(files, tmp_path):
    """'decode scene.png -w white.png -o scene.png --overwrite' wrote an ESLF mosaic over the raw and its JSON over
    the raw's sidecar (both inputs lost); '-o scene.tif' replaced only the sidecar.  An output whose files would
    replace an input or its sidecar is refused naming -o, before any work, and the inputs are unchanged."""
    import shutil

    sim, raw, white, grid = files
    for p in (raw, raw.with_suffix(".json"), white, white.with_suffix(".json")):
        shutil.copy(p, tmp_path / p.name)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    for out, words in (("scene.png", "would replace the input scene.png"),
                       ("scene.tif", "would replace the input scene.json, the sidecar of scene.png"),
                       ("white.npy", "would replace the input white.json, the sidecar of white.png")):
        res = CliRunner().invoke(cli, ["decode", str(tmp_path / "scene.png"), "-w", str(tmp_path / "white.png"),
                                       "-o", str(tmp_path / out), "--overwrite"])
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1 and "Invalid value for -o / --output:" in errors[0], res.output
        assert words in errors[0], errors
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    res = CliRunner().invoke(cli, ["decode", str(tmp_path / "scene.png"), "-w", str(tmp_path / "white.png"),
                                   "-o", str(tmp_path / "lf.png")])
    assert res.exit_code == 0 and (tmp_path / "lf.json").is_file(), res.output


def test_the_one_liner_and_the_other_writers_refuse_to_write_over_their_inputs(files, tmp_path):
    """'plenodecode scene.png -w white.png -o scene.png --overwrite' decoded the mosaic and wrote the photograph over
    it (the raw lost); refocus, views, parallax, export and depth (its colour map scene.png beside scene.pfm) did the
    same with their outputs.  Every writer now refuses, naming -o, before any work, and leaves the inputs byte for
    byte as they were."""
    import shutil

    sim, raw, white, grid = files
    for p in (raw, raw.with_suffix(".json"), white, white.with_suffix(".json")):
        shutil.copy(p, tmp_path / p.name)
    scene, wpng, frame = tmp_path / "scene.png", tmp_path / "white.png", tmp_path / "frame_001.png"
    shutil.copy(scene, frame)                               # a raw named like a parallax frame
    (tmp_path / "lf.npy").write_bytes(b"not read")          # export's input: refused before it is read
    (tmp_path / "lf.json").write_text("{}")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    cases = [([scene, "-w", wpng, "-o", scene], "would replace the input scene.png"),
             ([scene, "-w", wpng, "--refocus", "1.01", "-o", wpng], "would replace the input white.png"),
             (["refocus", scene, "-w", wpng, "-o", scene], "would replace the input scene.png"),
             (["views", scene, "-w", wpng, "--view", "1", "1", "-o", wpng], "would replace the input white.png"),
             (["parallax", frame, "-w", wpng, "-o", tmp_path / "w.gif", "--frames-dir", tmp_path, "--frames", "2"],
              "would replace the input frame_001.png"),
             (["export", tmp_path / "lf.npy", "-o", tmp_path / "lf.png", "--format", "eslf"],
              "would replace the input lf.json, the sidecar of lf.npy"),
             (["depth", scene, "-w", wpng, "-o", tmp_path / "scene.pfm"], "would replace the input scene.png")]
    for args, words in cases:
        res = CliRunner().invoke(cli, [str(a) for a in args] + ["--overwrite"])
        errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
        assert res.exit_code == 2 and len(errors) == 1, (args, res.output)
        assert "Invalid value for -o / --output:" in errors[0] and words in errors[0], (args, errors)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    res = CliRunner().invoke(cli, [str(scene), "-w", str(wpng), "-o", str(tmp_path / "photo.png")])
    assert res.exit_code == 0 and (tmp_path / "photo.png").is_file(), res.output


def test_8_bit_views_are_written_for_viewing_and_16_bit_ones_stay_linear(files, tmp_path):
    """'decode RAW -o views/ --format views --bit-depth 8' wrote linear light in 8 bits: views about a third as bright
    as the 'views' command's (the real F01 JPEG's centre view: median 42 of 255 against 113) and 1/255 steps in the
    shadows.  8-bit views and ESLF mosaics are now sRGB-encoded, recorded as colour 'srgb' (they load back as what
    they are) and said so; 16 bits keep linear light; export does the same without --srgb."""
    from plenodecode.io.images import srgb_encode
    from plenodecode.io.lightfield import load_lightfield

    sim, raw, white, grid = files
    base = ["decode", str(raw), "-g", str(grid), "-w", str(white), "--format", "views"]
    res8 = run([*base, "-o", str(tmp_path / "v8"), "--bit-depth", "8"])
    assert res8.exit_code == 0 and "8-bit views are sRGB-encoded for viewing" in res8.output, res8.output
    assert "views of" in res8.output and "sRGB)" in res8.output
    res16 = run([*base, "-o", str(tmp_path / "v16")])
    assert res16.exit_code == 0 and "sRGB-encoded" not in res16.output, res16.output
    v8, v16 = load_lightfield(tmp_path / "v8"), load_lightfield(tmp_path / "v16")
    assert v8.colour == "srgb" and v16.colour == "linear-srgb"
    centre = v16.centre_view()
    assert np.abs(v8.centre_view() - srgb_encode(centre)).max() <= 0.5 / 255 + 1e-3
    assert np.median(v8.centre_view()) > 1.5 * np.median(centre) > 0
    res = run(["export", str(tmp_path / "v16"), "-o", str(tmp_path / "e.png"), "--format", "eslf", "--bit-depth", "8"])
    assert res.exit_code == 0 and "an 8-bit ESLF mosaic is sRGB-encoded" in res.output, res.output
    e = load_lightfield(tmp_path / "e.png")
    assert e.colour == "srgb" and np.abs(e.centre_view() - srgb_encode(centre)).max() <= 0.5 / 255 + 1e-3


def test_python_save_lightfield_writes_the_8_bit_views_the_cli_writes(tmp_path):
    """'decode scene.lfr --format views --bit-depth 8' wrote sRGB-encoded views, while pd.save_lightfield(lf, path,
    bit_depth=8) of the same light field wrote linear ones (median about a third as bright): the encoding was
    chosen in the CLI.  It is save_lightfield's default now, so both write the same bytes; encode_srgb=False still
    keeps linear light."""
    from pathlib import Path

    import plenodecode as pd
    from plenodecode.io.lightfield import load_lightfield

    folder = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini"
    raw, white = folder / "scene.lfr", folder / "MOD_0000.RAW"
    res = run(["decode", str(raw), "--white", str(white), "--format", "views", "--bit-depth", "8",
               "-o", str(tmp_path / "cli_views")])
    assert res.exit_code == 0, res.output
    lf = pd.open_source(raw, white=white).lightfield
    pd.save_lightfield(lf, tmp_path / "py_views", bit_depth=8)
    cli_files = {p.name: p.read_bytes() for p in (tmp_path / "cli_views").iterdir()}
    py_files = {p.name: p.read_bytes() for p in (tmp_path / "py_views").iterdir()}
    assert len(cli_files) > 1 and cli_files == py_files
    pd.save_lightfield(lf, tmp_path / "linear_views", bit_depth=8, encode_srgb=False)
    encoded, linear = load_lightfield(tmp_path / "py_views"), load_lightfield(tmp_path / "linear_views")
    assert encoded.colour == "srgb" and linear.colour == lf.colour
    assert np.median(encoded.centre_view()) > 1.5 * np.median(linear.centre_view()) > 0


def test_views_folder_of_decode_is_a_loadable_light_field_and_views_writes_named_pictures(files, tmp_path):
    """'decode --format views' names its files input_CamNNN.png and 'views' view_VV_UU.png: two things (a light field
    that loads back, HCI-named; pictures named by position).  Each command's help now says which it writes."""
    sim, raw, white, grid = files
    lf_dir, pics = tmp_path / "lf_views", tmp_path / "pictures"
    res = run(["decode", str(raw), "-g", str(grid), "-w", str(white), "--format", "views", "-o", str(lf_dir)])
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in lf_dir.iterdir())
    assert "lightfield.json" in names and "input_Cam000.png" in names
    assert run(["views", str(lf_dir), "-o", str(pics)]).exit_code == 0       # the folder loads back
    pictures = sorted(p.name for p in pics.iterdir())
    assert pictures[0] == "view_00_00.png" and len(pictures) == len([n for n in names if n.startswith("input_Cam")])
    res = run(["views", str(pics), "-o", str(tmp_path / "again")])            # pictures are not a light field
    assert res.exit_code != 0 and not (tmp_path / "again").exists()
    decode_help = " ".join(run(["decode", "--help"]).output.split())
    views_help = " ".join(run(["views", "--help"]).output.split())
    assert "input_Cam000.png" in decode_help and "view_VV_UU.png" in decode_help
    assert "view_VV_UU.png" in views_help and "input_Cam000.png" in views_help and "do not load back" in views_help
