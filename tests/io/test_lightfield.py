import json

import numpy as np
import pytest

from plenodecode.errors import FormatError
from plenodecode.io.lightfield import (ESLF_DEFAULT_VIEWS, LIGHTFIELD_FORMATS, detect_format, eslf_from_lightfield,
                                       lightfield_from_eslf, load_lightfield, save_lightfield)
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
    assert isinstance(back, LightField) and back.shape == lf.shape and back.data.dtype == np.float32
    assert np.abs(back.data - lf.data).max() <= TOL[stored]
    assert back.weight is not None and np.abs(back.weight - lf.weight).max() <= TOL[stored]
    assert back.colour == "linear-srgb"
    assert back.metadata["camera"]["serial"] == "A1" and back.metadata["spatial_step_px"] == 8.6
    assert calls and calls[-1][0] == calls[-1][1]
    # one view, and nothing left behind but the outputs
    v = load_lightfield(out, view=(2, 3))
    assert v.shape == lf.shape[2:] and np.abs(v - lf.data[2, 3]).max() <= TOL[stored]
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
