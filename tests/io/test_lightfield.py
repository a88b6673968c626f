import json
from pathlib import Path

import numpy as np
import pytest

from plenodecode.errors import FormatError
from plenodecode.io.lightfield import (ESLF_DEFAULT_VIEWS, LIGHTFIELD_FORMATS, detect_format, eslf_from_lightfield,
                                       lightfield_from_eslf, load_lightfield, save_lightfield, stores_display_encoded)
from plenodecode.io.images import srgb_encode
from plenodecode.types import LightField


def make_lf(V=3, U=5, Y=6, X=7, C=3, weight=True, seed=0):
    rng = np.random.default_rng(seed)
    data = rng.random((V, U, Y, X, C)).astype(np.float32)
    w = rng.random((V, U, Y, X)).astype(np.float32) if weight else None
    meta = {"source": "synthetic", "spatial_step_px": 8.6, "camera": {"model": "F01", "serial": "A1",
                                                                      "zoom_step": 981.0}}
    return LightField(data, w, "linear-srgb", meta)


# maximum |error| of a round trip at each stored depth
TOL = {8: 0.5 / 255 + 1e-6, 16: 0.5 / 65535 + 1e-6, 32: 0.0}

CASES = [("zarr", "lf.zarr", 16, 32), ("views", "views", 8, 8), ("views", "views16", 16, 16),
         ("views", "views32", 32, 32), ("mat", "lf.mat", 16, 16), ("npy", "lf.npy", 16, 32),
         ("eslf", "lf.png", 16, 16), ("eslf", "lf8.png", 8, 8)]


@pytest.mark.parametrize("fmt,name,bits,stored", CASES)
@pytest.mark.parametrize("channels", [3, 1])
def test_round_trip(tmp_path, fmt, name, bits, stored, channels):
    lf = make_lf(C=channels)
    calls = []
    out = save_lightfield(lf, tmp_path / name, bit_depth=bits, progress=lambda d, t: calls.append((d, t)))
    assert detect_format(out) == fmt
    back = load_lightfield(out)
    # 8-bit views and ESLF are stored sRGB-encoded by default, as the CLI writes them
    encoded = stores_display_encoded(fmt, lf.colour, bits)
    assert encoded == (bits == 8 and fmt in ("views", "eslf"))
    expected = srgb_encode(lf.data) if encoded else lf.data
    assert isinstance(back, LightField) and back.shape == lf.shape and back.data.dtype == np.float32
    assert np.abs(back.data - expected).max() <= TOL[stored]
    assert back.weight is not None and np.abs(back.weight - lf.weight).max() <= TOL[stored]
    assert back.colour == ("srgb" if encoded else "linear-srgb")
    assert back.metadata["camera"]["serial"] == "A1" and back.metadata["spatial_step_px"] == 8.6
    assert calls and calls[-1][0] == calls[-1][1]
    # one view, and nothing left behind but the outputs
    v = load_lightfield(out, view=(2, 3))
    assert v.shape == lf.shape[2:] and np.abs(v - expected[2, 3]).max() <= TOL[stored]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("fmt,name", [("zarr", "a.zarr"), ("views", "a"), ("mat", "a.mat"), ("npy", "a.npy"),
                                      ("eslf", "a.png")])
def test_no_weight_stays_none_and_overwrite_rules(tmp_path, fmt, name):
    lf = make_lf(weight=False)
    out = save_lightfield(lf, tmp_path / name, format=fmt)
    assert load_lightfield(out).weight is None
    with pytest.raises(FileExistsError):
        save_lightfield(lf, out, format=fmt)
    lf2 = make_lf(seed=5)
    save_lightfield(lf2, out, format=fmt, overwrite=True)
    back = load_lightfield(out)
    assert np.abs(back.data - lf2.data).max() <= 1e-4 and back.weight is not None
    save_lightfield(lf, out, format=fmt, overwrite=True)         # weight removed again
    assert load_lightfield(out).weight is None
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_zarr_layout_and_single_chunk_read(tmp_path, monkeypatch):
    import zarr
    from zarr.storage import LocalStore

    lf = make_lf(V=3, U=4)
    out = save_lightfield(lf, tmp_path / "lf.zarr")
    group = zarr.open_group(str(out), mode="r")
    assert group["data"].chunks == (1, 1, 6, 7, 3) and group["weight"].chunks == (1, 1, 6, 7)
    assert group.attrs["format"] == "plenodecode.LightField" and group.attrs["colour"] == "linear-srgb"
    chunk_files = sorted(p.relative_to(out).as_posix() for p in (out / "data" / "c").rglob("*") if p.is_file())
    assert len(chunk_files) == 12

    seen = []
    original = LocalStore.get

    async def spy(self, key, *args, **kwargs):
        seen.append(key)
        return await original(self, key, *args, **kwargs)

    monkeypatch.setattr(LocalStore, "get", spy)
    view = load_lightfield(out, view=(1, 2))
    np.testing.assert_array_equal(view, lf.data[1, 2])
    chunks_read = [k for k in seen if "/c/" in k]
    assert chunks_read == ["data/c/1/2/0/0/0"], seen


def test_views_use_hci_names_and_read_one_file(tmp_path, monkeypatch):
    lf = make_lf(V=3, U=5)
    out = save_lightfield(lf, tmp_path / "views")
    names = sorted(p.name for p in out.iterdir())
    assert names[:3] == ["input_Cam000.png", "input_Cam001.png", "input_Cam002.png"]
    assert "input_Cam014.png" in names and "lightfield.json" in names and "weight.npy" in names
    doc = json.loads((out / "lightfield.json").read_text())
    assert doc["shape"] == [3, 5, 6, 7, 3] and doc["bit_depth"] == 16
    from plenodecode.io import lightfield as mod
    opened = []
    real = mod.read_image
    monkeypatch.setattr(mod, "read_image", lambda p: opened.append(p.name) or real(p))
    view = load_lightfield(out, view=(2, 1))        # index 2 * 5 + 1 = 11
    assert opened == ["input_Cam011.png"]
    assert np.abs(view - lf.data[2, 1]).max() <= TOL[16]


def test_views_folder_without_json_is_square_and_srgb(tmp_path):
    from plenodecode.io.images import write_image

    rng = np.random.default_rng(2)
    imgs = rng.integers(0, 256, (9, 4, 5, 3)).astype(np.uint8)
    for k in range(9):
        write_image(tmp_path / f"input_Cam{k:03d}.png", imgs[k], bit_depth=8)
    lf = load_lightfield(tmp_path)
    assert lf.shape == (3, 3, 4, 5, 3) and lf.colour == "srgb" and lf.weight is None
    np.testing.assert_allclose(lf.data[1, 2], imgs[5] / 255.0, atol=1e-6)


def test_mat_is_lftoolbox_layout(tmp_path):
    import scipy.io

    lf = make_lf(V=3, U=5)
    out = save_lightfield(lf, tmp_path / "lf.mat")
    mat = scipy.io.loadmat(str(out))
    LF = mat["LF"]
    assert LF.dtype == np.uint16 and LF.shape == (3, 5, 6, 7, 4)     # (j, i, l, k, RGB + weight)
    np.testing.assert_array_equal(LF[1, 4, 2, 3, :3], np.rint(lf.data[1, 4, 2, 3] * 65535).astype(np.uint16))
    np.testing.assert_array_equal(LF[1, 4, 2, 3, 3], np.uint16(np.rint(lf.weight[1, 4, 2, 3] * 65535)))
    assert str(mat["LFMetadata"]["CamSerial"][0, 0][0]) == "A1"
    # a bare LFToolbox-style file (no plenodecode metadata) reads with the 4th channel as weight
    scipy.io.savemat(str(tmp_path / "toolbox.mat"), {"LF": LF})
    bare = load_lightfield(tmp_path / "toolbox.mat")
    assert bare.colour == "camera" and bare.weight is not None
    assert np.abs(bare.data - lf.data).max() <= TOL[16]
    with pytest.raises(ValueError, match="bit_depth"):
        save_lightfield(lf, tmp_path / "b.mat", bit_depth=8)


def test_eslf_mapping_and_default_views(tmp_path):
    lf = make_lf(V=2, U=3, Y=4, X=5, weight=False)
    e = eslf_from_lightfield(lf.data)
    assert e.shape == (4 * 2, 5 * 3, 3)
    rng = np.random.default_rng(0)
    for _ in range(20):
        v, u, y, x = (int(rng.integers(n)) for n in (2, 3, 4, 5))
        np.testing.assert_array_equal(e[y * 2 + v, x * 3 + u], lf.data[v, u, y, x])
    np.testing.assert_array_equal(lightfield_from_eslf(e, (2, 3)), lf.data)
    # an archive-style ESLF without sidecar: 14 x 14 views, 8-bit sRGB
    big = make_lf(V=14, U=14, Y=3, X=2, weight=False)
    from plenodecode.io.images import write_image
    write_image(tmp_path / "archive.png", eslf_from_lightfield(big.data), bit_depth=8)
    back = load_lightfield(tmp_path / "archive.png")
    assert ESLF_DEFAULT_VIEWS == (14, 14) and back.shape == (14, 14, 3, 2, 3) and back.colour == "srgb"
    assert np.abs(back.data - big.data).max() <= TOL[8]
    with pytest.raises(FormatError, match="14x14"):
        write_image(tmp_path / "odd.png", np.zeros((15, 28, 3), np.uint8), bit_depth=8)
        load_lightfield(tmp_path / "odd.png")


def test_encode_srgb_on_export(tmp_path):
    lf = make_lf(weight=False)
    out = save_lightfield(lf, tmp_path / "v", bit_depth=16, encode_srgb=True)
    back = load_lightfield(out)
    assert back.colour == "srgb"
    expected = np.where(lf.data <= 0.0031308, 12.92 * lf.data, 1.055 * lf.data ** (1 / 2.4) - 0.055)
    assert np.abs(back.data - expected).max() <= TOL[16] + 1e-6
    with pytest.raises(ValueError, match="encode_srgb"):
        save_lightfield(back, tmp_path / "w", encode_srgb=True)


def test_bad_arguments_and_inputs(tmp_path):
    lf = make_lf()
    with pytest.raises(ValueError, match="format"):
        save_lightfield(lf, tmp_path / "x.zarr", format="hdf5")
    with pytest.raises(ValueError, match="format"):
        save_lightfield(lf, tmp_path / "x.h5")
    with pytest.raises(ValueError, match="bit_depth"):
        save_lightfield(lf, tmp_path / "x.zarr", bit_depth=12)
    out = save_lightfield(lf, tmp_path / "x.npy")
    with pytest.raises(ValueError, match="view"):
        load_lightfield(out, view=(3, 0))
    with pytest.raises(FormatError):
        load_lightfield(tmp_path / "missing.zarr")
    (tmp_path / "junk.npy").write_bytes(b"nope")
    with pytest.raises(FormatError):
        load_lightfield(tmp_path / "junk.npy")
    assert sorted(LIGHTFIELD_FORMATS) == ["eslf", "mat", "npy", "views", "zarr"]


def test_cli_export(tmp_path):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    lf = make_lf(V=3, U=3)
    src = save_lightfield(lf, tmp_path / "in.zarr")
    runner = CliRunner()
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "out.mat")], obj={})
    assert res.exit_code == 0, res.output
    assert "out.mat" in res.output and "mat" in res.output
    back = load_lightfield(tmp_path / "out.mat")
    assert np.abs(back.data - lf.data).max() <= TOL[16] and np.abs(back.weight - lf.weight).max() <= TOL[16]

    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "v"), "--format", "views", "--bit-depth", "8",
                              "--srgb"], obj={})
    assert res.exit_code == 0, res.output
    v = load_lightfield(tmp_path / "v")
    assert v.colour == "srgb" and (tmp_path / "v" / "input_Cam008.png").is_file()
    expected = np.where(lf.data <= 0.0031308, 12.92 * lf.data, 1.055 * lf.data ** (1 / 2.4) - 0.055)
    assert np.abs(v.data - expected).max() <= TOL[8] + 1e-6

    # refuses to overwrite (usage error, exit 2), replaces with --overwrite
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "out.mat")], obj={})
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "out.mat"), "--overwrite"], obj={})
    assert res.exit_code == 0
    # a bad input is a data error: one line, exit 1
    (tmp_path / "bad.npy").write_bytes(b"junk")
    res = runner.invoke(cli, ["export", str(tmp_path / "bad.npy"), "-o", str(tmp_path / "o.zarr")], obj={})
    assert res.exit_code == 1 and "error:" in res.output
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "o.h5")], obj={})
    assert res.exit_code == 2 and "--format" in res.output
    res = runner.invoke(cli, ["export", "--help"], obj={})
    assert res.exit_code == 0 and "Example" in res.output


# ---------------------------------------------------------------------------------------------------------------
# the typed geometry in saved light fields; files of format version 1 (free metadata dict)
# ---------------------------------------------------------------------------------------------------------------
V1_DATA = Path(__file__).parent / "data" / "lightfield_v1"
V1_FILES = ["lf.zarr", "views", "lf.npy", "lf.mat", "mosaic.png"]


def _geometry_lf(colour="linear-srgb"):
    from plenodecode.types import CameraMetadata, HCIParameters, LightFieldGeometry

    cam = CameraMetadata(model="ILLUM", serial="B5", focal_length_m=0.0301, f_number=2.0, lens_pitch_m=2.0e-5,
                         pixel_pitch_m=1.4e-6, wb_gains={"r": 1.9, "g": 1.0, "b": 1.4},
                         ccm=((1.5, -0.3, -0.2), (-0.2, 1.4, -0.2), (0.0, -0.5, 1.5)), extra={"a": [1, 2]})
    geometry = LightFieldGeometry(spatial_step_px=12.4, view_step_px=1.0, focal_length_m=0.0301, f_number=2.0,
                                  lens_pitch_m=2.0e-5, pixel_pitch_m=1.4e-6, mla_sensor_gap_m=3.7e-5,
                                  infinity_lambda=12.5, focus_distance_m=1.2, disparity_range=(-0.75, 1.25),
                                  source="a.lfr", calibration={"pitch": 14.3, "row_spacing": 12.4}, camera=cam,
                                  hci=HCIParameters(baseline_mm=100.0, resolution_px=(7, 6)))
    lf = make_lf()
    return LightField(lf.data, lf.weight, colour, {"demosaic": "malvar", "hot_pixels_repaired": 2}, geometry)


@pytest.mark.parametrize("fmt,name,bits,stored", CASES)
def test_geometry_round_trips_through_every_format(tmp_path, fmt, name, bits, stored):
    lf = _geometry_lf()
    back = load_lightfield(save_lightfield(lf, tmp_path / name, bit_depth=bits, encode_srgb=False))
    assert back.geometry == lf.geometry and back.provenance == lf.provenance
    doc = json.loads(json.dumps(lf.geometry.to_dict()))
    assert doc["format"] == "plenodecode.LightFieldGeometry" and doc["version"] >= 1


@pytest.mark.parametrize("name", V1_FILES)
def test_files_of_format_version_1_load_with_the_same_geometry(name):
    """Written by the code before the typed geometry (tests/io/data/lightfield_v1/README.md); the numbers are
    what that code computed from them."""
    from plenodecode.depth.pipeline import metadata_disparity_range
    from plenodecode.depth.metric import depth_constants, focal_length_px
    from plenodecode.render.alpha import slope_per_alpha_unit

    lf = load_lightfield(V1_DATA / name)
    g = lf.geometry
    assert lf.colour == g.colour == "linear-srgb" and g.source == "scene.lfr"
    assert (g.focal_length_m, g.f_number, g.lens_pitch_m, g.pixel_pitch_m) == (0.0301, 2.0, 2.0e-5, 1.4e-6)
    assert (g.spatial_step_px, g.view_step_px, g.focus_distance_m) == (12.384, 1.0, 1.2)
    assert g.mla_sensor_gap_m == 3.7e-5 and g.infinity_lambda == 12.5 and g.disparity_range == (-0.75, 1.25)
    assert g.calibration["pitch"] == 14.3 and g.camera.serial == "B5151500000"
    assert lf.provenance["demosaic"] == "malvar" and lf.provenance["hot_pixels_repaired"] == 3
    assert slope_per_alpha_unit(lf) == pytest.approx(60.76388888888888, rel=1e-14)
    g_px_m, zf, model = depth_constants(lf)
    assert (g_px_m, zf, model) == (pytest.approx(1.8760506596005355, rel=1e-14), 1.2, "plenoptic")
    g_px_m, zf, _ = depth_constants(lf, focus_distance_m=None)     # from infinityLambda and the MLA gap
    assert (g_px_m, zf) == pytest.approx((1.8570963541666663, 1.9890405405405356), rel=1e-14)
    assert focal_length_px(lf) == pytest.approx(1782.5597629427016, rel=1e-14)
    assert metadata_disparity_range(lf.metadata) == (-0.75, 1.25)
    assert lf.shape == (3, 3, 4, 5, 3) and lf.weight is not None


def test_version_1_file_saved_again_keeps_the_geometry(tmp_path):
    from plenodecode.io.lightfield import FORMAT_VERSION

    old = load_lightfield(V1_DATA / "lf.npy")
    out = save_lightfield(old, tmp_path / "new.npy")
    doc = json.loads(out.with_suffix(".json").read_text())
    assert doc["version"] == FORMAT_VERSION == 2 and "geometry" in doc and "camera" not in doc["metadata"]
    assert load_lightfield(out).geometry == old.geometry


def test_newer_geometry_schema_is_refused(tmp_path):
    out = save_lightfield(_geometry_lf(), tmp_path / "a.npy")
    side = out.with_suffix(".json")
    doc = json.loads(side.read_text())
    doc["geometry"]["version"] = 99
    side.write_text(json.dumps(doc))
    with pytest.raises(FormatError, match="newer"):
        load_lightfield(out)


def write_hci_folder(root, seed=0, views=3, size=(8, 10)):
    """A small HCI benchmark scene folder: input_CamNNN.png views and the antinous parameters.cfg."""
    import cv2

    root.mkdir()
    rng = np.random.default_rng(seed)
    for k in range(views * views):
        cv2.imwrite(str(root / f"input_Cam{k:03d}.png"), rng.integers(0, 256, (*size, 3), dtype=np.uint8))
    (root / "parameters.cfg").write_text(
        "[intrinsics]\nfocal_length_mm = 100\nimage_resolution_x_px = 512\nimage_resolution_y_px = 512\n"
        "sensor_size_mm = 35\nfstop = 100\n\n[extrinsics]\nfocus_distance_m = 7\nbaseline_mm = 100\n"
        f"num_cams_x = {views}\nnum_cams_y = {views}\noffset = 20.89795918367347\n\n"
        "[meta]\ndisp_min = -3.3\ndisp_max = 2.8\n")
    return root


@pytest.mark.parametrize("source", ["generated", "hci-antinous"])
def test_load_lightfield_of_an_hci_folder_keeps_parameters_cfg(tmp_path, source):
    from tests.conftest import shared_path
    from plenodecode.depth.pipeline import disparity_range
    from plenodecode.depth.metric import depth_constants, focal_length_px
    from plenodecode.io.hci import read_hci

    folder = write_hci_folder(tmp_path / "scene") if source == "generated" else shared_path(source)
    loaded, read = load_lightfield(folder), read_hci(folder).lightfield
    assert loaded.colour == read.colour == "srgb" and loaded.geometry == read.geometry
    assert loaded.geometry.hci.disparity_range == (-3.3, 2.8)

    def no_estimate():
        raise AssertionError("the range must come from parameters.cfg")

    assert disparity_range(loaded, no_estimate) == disparity_range(read, no_estimate) == ((-3.3, 2.8), "metadata")
    assert depth_constants(loaded) == depth_constants(read)
    assert depth_constants(read)[:2] == pytest.approx((0.1 * 100 / 35 * 512, 7.0)) and depth_constants(read)[2] == "hci"
    assert focal_length_px(loaded) == focal_length_px(read)
    np.testing.assert_allclose(loaded.data, read.data, atol=1e-6)


@pytest.mark.parametrize("fmt,name", [("views", "views"), ("eslf", "lf.png")])
def test_camera_rgb_encoded_round_trip_keeps_camera_rgb(tmp_path, fmt, name):
    """An 8-bit views folder or ESLF of a camera-RGB light field (no white balance or colour matrix: the F01 JPEGs)
    was labelled 'srgb', so reading it back claimed sRGB colours.  It is 'camera-srgb-curve' now, and linearise()
    takes it back to 'camera' through the inverse sRGB curve: exact values on a small array whose encodings are
    whole 8-bit steps."""
    from plenodecode.io.images import srgb_decode
    from plenodecode.io.lightfield import linearise

    # 8-bit codes 0, 10 (linear segment of the curve), 128, 255 -> their linear values, in the three channels
    codes = np.array([[0, 10, 128], [255, 128, 10]], np.float64)
    linear = srgb_decode(codes / 255.0)
    expected_linear = np.array([[0.0, 10 / 255 / 12.92, ((128 / 255 + 0.055) / 1.055) ** 2.4],
                                [1.0, ((128 / 255 + 0.055) / 1.055) ** 2.4, 10 / 255 / 12.92]])
    np.testing.assert_allclose(linear, expected_linear, rtol=1e-12)
    assert abs(expected_linear[0, 2] - 0.2158605) < 1e-7          # the sRGB value of 128/255
    data = np.broadcast_to(linear.astype(np.float32)[None, None, :, None, :], (3, 3, 2, 4, 3)).copy()
    lf = LightField(data, None, "camera", {"source": "synthetic", "spatial_step_px": 8.6})
    out = save_lightfield(lf, tmp_path / name, bit_depth=8)
    back = load_lightfield(out)
    assert back.colour == back.geometry.colour == "camera-srgb-curve" and back.geometry.display_encoded
    codes5 = np.broadcast_to(codes[None, None, :, None, :], data.shape)
    np.testing.assert_array_equal(np.rint(back.data * 255.0), codes5)        # stored as the sRGB-encoded codes
    lin = linearise(back)
    assert lin.colour == lin.geometry.colour == "camera" and not lin.geometry.display_encoded
    assert lin.data.dtype == np.float32 and lin.shape == lf.shape and lin.geometry.spatial_step_px == 8.6
    np.testing.assert_allclose(lin.data, np.broadcast_to(expected_linear[None, None, :, None, :], data.shape),
                               rtol=2e-6, atol=1e-9)
    # a linear light field is linearise()'s identity; a second encoding is refused, naming the state
    assert linearise(lin) is lin
    with pytest.raises(ValueError, match="already sRGB-encoded .colour 'camera-srgb-curve'"):
        save_lightfield(back, tmp_path / "again", bit_depth=8, encode_srgb=True)


def test_linear_srgb_still_encodes_to_srgb_and_linearises_to_linear_srgb(tmp_path):
    """The sRGB path is unchanged: linear sRGB saved as 8-bit views loads as 'srgb' and linearises to 'linear-srgb'."""
    from plenodecode.io.images import srgb_decode
    from plenodecode.io.lightfield import linearise

    lf = make_lf()
    back = load_lightfield(save_lightfield(lf, tmp_path / "v", bit_depth=8))
    assert back.colour == "srgb"
    lin = linearise(back)
    assert lin.colour == "linear-srgb"
    np.testing.assert_allclose(lin.data, srgb_decode(back.data), rtol=1e-6)
    # within the 8-bit step of the curve's steepest linear slope (2.4 / 1.055 per unit at full scale)
    assert np.abs(lin.data - lf.data).max() <= 0.5 / 255 * 2.4 / 1.055 * 1.01


def test_a_colour_state_of_a_newer_version_says_upgrade(tmp_path):
    """A light field whose colour state this version does not know (one a later version added, as
    'camera-srgb-curve' was) is refused saying to upgrade, not 'unreadable geometry; rewrite the light field'."""
    from plenodecode.io.lightfield import load_lightfield, save_lightfield

    out = save_lightfield(make_lf(), tmp_path / "views", format="views", bit_depth=16)
    doc_path = Path(out) / "lightfield.json"
    doc = json.loads(doc_path.read_text())
    doc["colour"] = "camera-log"
    if isinstance(doc.get("geometry"), dict):
        doc["geometry"]["colour"] = "camera-log"
    doc_path.write_text(json.dumps(doc))
    with pytest.raises(FormatError, match="'camera-log' is unknown to this plenodecode .*upgrade plenodecode$"):
        load_lightfield(out)


@pytest.mark.parametrize("name, fmt", [("lf.mat", "mat"), ("lf.NPY", "npy"), ("lf.zarr", "zarr"), ("lf.tif", "eslf")])
def test_detect_format_looks_the_extension_up_once(tmp_path, monkeypatch, name, fmt):
    """detect_format asked format_of_extension twice for every path with a format's extension (once to test, once
    to return)."""
    import plenodecode.io.lightfield as lightfield

    asked = []
    real = lightfield.format_of_extension
    monkeypatch.setattr(lightfield, "format_of_extension", lambda p: asked.append(Path(p).name) or real(p))
    assert detect_format(tmp_path / name) == fmt
    assert asked == [name]
