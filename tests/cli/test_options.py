"""Every numeric option refuses a meaningless value (nan, inf, negative or zero where it means nothing) while the
command line is parsed: exit 2, one ``Error:`` line naming the option, nothing written, no input opened."""

import pytest
from click.testing import CliRunner

from plenodecode import pipeline
from plenodecode.cli.main import cli
from tests.conftest import ROOT

RAW = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"
WHITE = ROOT / "sample_raws" / "illum-mini" / "MOD_0000.RAW"

#: (command line before the bad option, with OUT for the output; the bad option and its value(s); its name)
CASES = [
    *[(["refocus", RAW, "-o", "OUT"], ["--slope", v], "--slope") for v in ("nan", "inf", "-inf")],
    *[(["refocus", RAW, "-o", "OUT"], ["--alpha", v], "--alpha") for v in ("0", "-1", "nan", "inf")],
    (["refocus", RAW, "-o", "OUT"], ["--refocus", "0"], "--alpha"),
    *[(["refocus", RAW, "-o", "OUT", "--slope", "0"], ["--aperture", v], "--aperture") for v in ("nan", "0", "2")],
    (["refocus", RAW, "-o", "OUT", "--slope", "0"], ["--upsample", "0"], "--upsample"),
    (["refocus", RAW, "-o", "OUT", "--stack-units", "alpha"], ["--focal-stack", "0:2:5"], "--focal-stack"),
    (["refocus", RAW, "-o", "OUT"], ["--focal-stack", "-1:1:100000"], "--focal-stack"),
    (["refocus", RAW, "-o", "OUT"], ["--focal-stack", "nan:1:3"], "--focal-stack"),
    (["refocus", RAW, "-o", "OUT"], ["--focal-stack", "-inf:1:3"], "--focal-stack"),
    *[(["refocus", RAW, "-o", "OUT"], ["--focus-at", v], "--focus-at") for v in ("-1,2", "nan,1", "3", "a,b")],
    *[(["refocus", RAW, "-o", "OUT"], ["--focus-distance", v], "--focus-distance") for v in ("0", "-2", "nan", "inf")],
    *[([RAW, "-o", "OUT"], ["--refocus", v], "--refocus") for v in ("0", "-1", "nan", "inf")],
    *[([RAW, "-o", "OUT"], ["--slope", v], "--slope") for v in ("inf", "nan")],
    *[([RAW, "-o", "OUT", "--total-focus"], ["--patch", v], "--patch") for v in ("nan", "0", "inf")],
    ([RAW, "-o", "OUT", "--slope", "0"], ["--aperture", "nan"], "--aperture"),
    ([RAW, "-o", "OUT"], ["--focus-distance", "inf"], "--focus-distance"),
    ([RAW, "-o", "OUT"], ["--focus-at", "1,inf"], "--focus-at"),
    *[(["views", RAW, "-o", "OUT"], ["--view", *v], "--view") for v in (("nan", "1"), ("-1", "0"), ("1", "inf"))],
    *[(["parallax", RAW, "-o", "OUT.gif"], ["--fps", v], "--fps") for v in ("0", "nan", "inf")],
    *[(["parallax", RAW, "-o", "OUT.gif"], ["--radius", v], "--radius") for v in ("-1", "nan", "inf")],
    (["parallax", RAW, "-o", "OUT.gif"], ["--frames", "0"], "--frames"),
    *[(["depth", RAW, "-o", "OUT.pfm"], ["--focus-distance", v], "--focus-distance") for v in ("0", "nan", "inf")],
    *[(["depth", RAW, "-o", "OUT.pfm"], ["--disparity-range", v], "--disparity-range")
      for v in ("nan:1", "-inf:1", "1:0")],
    *[(["decode", RAW, "-o", "OUT.zarr"], ["--views", v], "--views") for v in ("0", "4", "-3")],
    *[(["decode", RAW, "-o", "OUT.zarr"], ["--black-level", v], "--black-level") for v in ("nan", "-1", "inf")],
    *[(["decode", RAW, "-o", "OUT.zarr"], ["--white-level", v], "--white-level") for v in ("nan", "0", "inf")],
    *[(["depth", RAW, "-o", "OUT.pfm"], ["--magnification", v], "--magnification") for v in ("nan", "0", "inf")],
    (["batch", RAW, "-o", "OUT"], ["--na", "nan"], "--na"),
    *[(["synth", "illum-mini", "-o", "OUT"], ["--pitch", v], "--pitch") for v in ("0", "-3", "nan", "inf")],
    (["synth", "illum-mini", "-o", "OUT"], ["--rotation", "inf"], "--rotation"),
    (["synth", "illum-mini", "-o", "OUT"], ["--offset", "nan", "0"], "--offset"),
    (["synth", "illum-mini", "-o", "OUT"], ["--shape", "0", "10"], "--shape"),
    (["synth", "illum-mini", "-o", "OUT"], ["--seed", "-1"], "--seed"),
    *[(["calibrate", WHITE, "-o", "OUT.json"], ["--pitch", v], "--pitch") for v in ("nan", "-3", "0", "0.5", "2")],
    *[(["batch", RAW, "-o", "OUT"], ["--scheduler", v], "--scheduler")
      for v in ("bogus", "tcp://host", "tcp://host:99999", "http://host:8786", "tcp://my host:8786")],
    (["batch", RAW, "-o", "OUT"], ["--slope", "nan"], "--slope"),
    *[(["batch", RAW, "-o", "OUT"], ["--jobs", v], "--jobs") for v in ("0", "-2")],
]


@pytest.mark.parametrize("before, bad, option", CASES,
                         ids=[f"{c[0][0] if c[0][0] != RAW else 'render'} {' '.join(c[1])}" for c in CASES])
def test_bad_numeric_value_is_a_one_line_usage_error(tmp_path, monkeypatch, before, bad, option):
    def no_work(*args, **kwargs):
        raise AssertionError("an input was opened before the options were checked")

    monkeypatch.setattr(pipeline, "open_input", no_work)
    monkeypatch.setattr(pipeline.source, "open_input", no_work)
    monkeypatch.setattr("plenodecode.io.read_raw", no_work)
    out = tmp_path / "out"
    args = [str(out) + str(a)[3:] if str(a).startswith("OUT") else str(a) for a in before] + bad
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2, (res.output, res.exception)
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and option in errors[0], res.output
    assert "Traceback" not in res.output
    assert not list(tmp_path.iterdir()), "something was written"


@pytest.mark.parametrize("command", ["refocus", "render", "views", "parallax", "depth", "synth"])
def test_help_describes_only_real_bounds(command):
    """An unbounded finite option (--slope) shows no range in the help; a bounded one (--aperture) shows its
    bounds (click printed '[x<=None]' for the first)."""
    r = CliRunner().invoke(cli, [command, "--help"])
    assert r.exit_code == 0, r.output
    assert "None]" not in r.output and "x<=None" not in r.output
    if command == "refocus":
        assert "0<x<=1]" in r.output                    # --aperture
