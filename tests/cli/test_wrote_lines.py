"""What the picture commands print on success: where the output is and its size (width x height in pixels, bits
per sample), measured against the files written, on the real Lytro F01 capture IMG_1.jpg."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from plenodecode.cli.main import cli
from plenodecode.io.images import read_image
from tests.conftest import shared_path


def run(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return next(ln for ln in res.output.splitlines() if ln.startswith("wrote"))


def size_said(line):
    """(width, height, bits or None) as the line says it."""
    m = re.search(r"(\d+) x (\d+) px(?:, (\d+)-bit)?", line)
    assert m, line
    return int(m[1]), int(m[2]), None if m[3] is None else int(m[3])


@pytest.fixture(scope="module")
def real_lf(tmp_path_factory):
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    out = tmp_path_factory.mktemp("lf") / "lf.zarr"
    res = CliRunner().invoke(cli, ["-q", "decode", str(jpeg), "-o", str(out)])
    assert res.exit_code == 0, res.output
    return jpeg, out


def test_the_photograph_line_gives_the_pictures_size_and_bit_depth(real_lf, tmp_path):
    """'plenodecode IMG_1.jpg -o photo.jpg' said 'wrote photo.jpg (focused as captured: ...)': where, not what; a
    Lytro F01 picture is 382 x 383 px, not the 1080 x 1080 of Lytro Desktop, and the line now says so."""
    jpeg, lf = real_lf
    for args, name in (((jpeg,), "photo.jpg"), (("refocus", lf, "--slope", "0.3"), "near.png")):
        line = run(*args, "-o", tmp_path / name)
        image = read_image(tmp_path / name)
        bits = 8 if image.dtype.itemsize == 1 else 16
        assert line.startswith(f"wrote {tmp_path / name} (")
        assert size_said(line) == (image.shape[1], image.shape[0], bits) == (382, 383, bits), line


def test_the_folder_and_animation_lines_give_the_pictures_size(real_lf, tmp_path):
    """'refocus --focal-stack', 'views' and 'parallax' named how many pictures and where, not their size."""
    _, lf = real_lf
    line = run("refocus", lf, "--focal-stack", "-0.5:0.5:3", "-o", tmp_path / "stack")
    image = read_image(tmp_path / "stack" / "slice_000.png")
    assert "wrote 3 slices (" in line and size_said(line) == (image.shape[1], image.shape[0], 16), line
    line = run("views", lf, "-o", tmp_path / "views", "--bit-depth", "8")
    image = read_image(tmp_path / "views" / "view_04_04.png")
    assert "wrote 81 views (9x9, each" in line and size_said(line) == (image.shape[1], image.shape[0], 8), line
    line = run("parallax", lf, "-o", tmp_path / "p.gif", "--frames", "4")
    image = read_image(tmp_path / "p_frames" / "frame_000.png")
    assert "(4 frames of" in line and size_said(line)[:2] == (image.shape[1], image.shape[0]), line
