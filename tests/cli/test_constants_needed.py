"""Alpha, a focus distance or metric depth asked of a raw whose metadata lacks the camera constants: refused as
soon as the raw is read, before the calibration (the F01 JPEG self-calibrates for about 7 s) and before any
decoding; a usage error (exit 2) naming the option typed, the missing constants and what to use instead, and no
output written.

The raws: a generated Illum-like LFR whose metadata has no focal length, one with every constant but the focus
distance (both run everywhere), and the real F01 JPEG mosaic of ../shared/data (skipped when absent).
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from click.testing import CliRunner

from plenodecode import pipeline
from plenodecode.cli.main import cli
from plenodecode.errors import MissingConstantsError

from ..conftest import shared_path


@pytest.fixture(scope="module")
def no_focal(tmp_path_factory):
    """A generated Illum-like raw (.lfr) whose camera metadata has f_number and the pitches, but no focal length."""
    from plenodecode.io import lytro
    from plenodecode.synthetic import PRESETS, simulate

    sim = simulate(replace(PRESETS["illum-mini"], focal_length_m=None), seed=1, shape=(200, 280))
    return lytro.write_lfr(tmp_path_factory.mktemp("nofocal") / "nofocal.lfr", sim.raw)


@pytest.fixture(scope="module")
def no_focus(tmp_path_factory):
    """A generated Illum-like raw (.lfr) with every camera constant but the distance it was focused at."""
    from plenodecode.io import lytro
    from plenodecode.synthetic import PRESETS, simulate

    sim = simulate(PRESETS["illum-mini"], seed=1, shape=(200, 280))
    return lytro.write_lfr(tmp_path_factory.mktemp("nofocus") / "nofocus.lfr", sim.raw)


@pytest.fixture
def no_work(monkeypatch):
    """Records every calibration and decoding the workflow starts (none is expected)."""
    calls = []

    def refuse(step):
        def fn(*args, **kw):
            calls.append(step)
            raise AssertionError(f"{step} ran")
        return fn

    monkeypatch.setattr("plenodecode.pipeline.source.choose_calibration", refuse("calibration"))
    monkeypatch.setattr("plenodecode.pipeline.source.decode_raw", refuse("decode"))
    return calls


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def check_refused(res, option, missing, instead, calls, tmp_path):
    """Exit 2, one error line naming ``option``, the ``missing`` constants and ``instead``; no work, no file."""
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1, res.output
    assert option in errors[0] and instead in errors[0], errors[0]
    assert f"has no {missing} in its metadata" in errors[0], errors[0]
    assert calls == []
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, option, instead", [
    ([], "--refocus", "--slope"),                                      # the card's one-liner (render)
    (["render"], "--refocus", "--slope"),
    (["refocus"], "--alpha", "--slope"),
], ids=["one-liner", "render", "refocus"])
def test_alpha_on_a_raw_without_focal_length_is_a_usage_error(no_focal, no_work, tmp_path, args, option, instead):
    alias = "--refocus" if option == "--alpha" else "--alpha"       # either spelling of the option
    for spelling in (option, alias):
        res = invoke(*args, no_focal, spelling, "1.0", "-o", tmp_path / "photo.png")
        check_refused(res, option, "focal_length_m", instead, no_work, tmp_path)


def test_focal_stack_in_alpha_units_on_a_raw_without_focal_length(no_focal, no_work, tmp_path):
    res = invoke("refocus", no_focal, "--focal-stack", "0.99:1.01:3", "--stack-units", "alpha", "-o",
                 tmp_path / "stack")
    check_refused(res, "--stack-units", "focal_length_m", "--stack-units slope", no_work, tmp_path)


def test_slope_on_the_same_raw_goes_on_to_the_calibration(no_focal, no_work, tmp_path):
    """The control: the check refuses alpha only; a slope reaches the calibration (recorded, then stopped)."""
    res = invoke(no_focal, "--slope", "0.3", "-o", tmp_path / "photo.png")
    assert no_work == ["calibration"], res.output


def test_real_f01_jpeg_refocus_alpha_is_refused_before_self_calibration(no_work, tmp_path, monkeypatch):
    """What the user typed, from the project root: ``plenodecode ../shared/data/.../IMG_1.jpg --refocus 1.0``."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir(out)
    res = invoke(jpeg, "--refocus", "1.0", "-o", "IMG_1_refocus.png")
    check_refused(res, "--refocus", "focal_length_m, f_number, lens_pitch_m", "--slope", no_work, out)
    assert "IMG_1.jpg has no" in res.output


def test_python_workflow_refuses_alpha_before_calibrating(no_focal, no_work):
    with pytest.raises(MissingConstantsError, match="focal_length_m") as info:
        pipeline.open_source(no_focal, check={"refocus": {"alpha": 1.0}})
    assert info.value.keyword == "alpha" and info.value.missing == ("focal_length_m",)
    assert info.value.source == "nofocal.lfr" and no_work == []
    # a Source made by hand: render_product checks before it decodes
    raw = pipeline.open_raw(no_focal)
    src = pipeline.Source(raw=raw, calibration=pipeline.Calibration(grid=None, white=None, source="test"))
    for name, options in (("refocus", {"alpha": 1.02}), ("focal-stack", {"start": 0.99, "stop": 1.01, "n": 3,
                                                                         "units": "alpha"})):
        with pytest.raises(MissingConstantsError, match="focal_length_m"):
            pipeline.render_product(src, name, **options)
    assert no_work == []


@pytest.mark.parametrize("args, option", [
    (["--focus-distance", "0.5", "-o", "photo.png"], "--focus-distance"),
    (["refocus", "--focus-distance", "0.5", "-o", "photo.png"], "--focus-distance"),
    (["depth", "--metric", "-o", "depth.pfm"], "--metric"),
    (["depth", "--ply", "points.ply", "-o", "depth.pfm"], "--ply"),
], ids=["one-liner", "refocus", "depth-metric", "depth-ply"])
def test_real_f01_jpeg_distance_and_metric_depth_refused_before_self_calibration(no_work, tmp_path, monkeypatch,
                                                                                  args, option):
    """The JPEG mosaic carries no camera constants: a focus distance or metric depth stops in about 0.5 s
    instead of failing after 15 s of self-calibration and decoding."""
    jpeg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir(out)
    command = args[:1] if args[0] in ("refocus", "depth") else []
    res = invoke(*command, jpeg, *args[len(command):])
    instead = "--slope" if option == "--focus-distance" else "without --metric"
    check_refused(res, option, "focal_length_m, f_number, lens_pitch_m", instead, no_work, out)


def test_metric_depth_without_the_focus_distance_asks_for_it(no_focus, no_work, tmp_path):
    """Every constant but the focus distance: --metric names it and the option that supplies it; given, the
    command goes on to the calibration (recorded, then stopped)."""
    res = invoke("depth", no_focus, "--metric", "-o", tmp_path / "depth.pfm")
    check_refused(res, "--metric", "focus_distance_m", "--focus-distance METRES", no_work, tmp_path)
    res = invoke("depth", no_focus, "--metric", "--focus-distance", "0.5", "-o", tmp_path / "depth.pfm")
    assert no_work == ["calibration"], res.output


def test_refocus_at_a_distance_needs_the_camera_focus_distance(no_focal, no_focus, no_work, tmp_path):
    """Metres -> slope needs the camera constants and the distance the camera was focused at."""
    res = invoke(no_focal, "--focus-distance", "0.5", "-o", tmp_path / "photo.png")
    check_refused(res, "--focus-distance", "focal_length_m", "--slope", no_work, tmp_path)
    res = invoke("refocus", no_focus, "--focus-distance", "0.5", "-o", tmp_path / "photo.png")
    check_refused(res, "--focus-distance", "focus_distance_m", "--slope", no_work, tmp_path)
