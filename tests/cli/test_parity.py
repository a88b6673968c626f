"""House rule: every feature is reachable from the CLI, from ``plenodecode batch`` and from Python, through the one
workflow layer (:mod:`plenodecode.pipeline`), with the same names.

:data:`TABLE` is the map of that rule: every option of the commands that render a raw (:data:`COMMANDS`) -> the
``batch`` option and the Python keyword that reach the same feature.  A new option fails
:func:`test_every_option_is_in_the_table` until it is entered; a batch option or keyword that does not exist, or a
name that differs (beyond ``-`` / ``_``) or is missing without a stated reason, fails the others.
"""

from __future__ import annotations

import dataclasses
import json
import importlib
import inspect
from collections.abc import Mapping

import click
import numpy as np
import pytest
from click.testing import CliRunner

from plenodecode import pipeline
from plenodecode.batch import BatchOptions
from plenodecode.cli.main import cli
from tests.conftest import ROOT

#: The commands that read a raw and render it through the workflow (the others read white images, checkerboards,
#: saved light fields or containers, and have no batch product: info, synth, calibrate, calibrate-geometry, export,
#: extract, warmup).
COMMANDS = ("decode", "refocus", "render", "views", "parallax", "depth")

#: Output options of one file or folder; a batch writes one folder per raw (``batch -o``) and the Python caller
#: passes its own path to the writer (``pipeline.write_product(output=)`` ...).
PER_FILE = "batch: one folder per raw under -o, the file names fixed"

#: Option (its long name; ``command:--option`` where one command means something else by it) ->
#: (batch option or None, Python ``module.object:keyword`` of the workflow layer or None, why a name differs or a
#: front end lacks it: empty when the names agree).
TABLE: dict[str, tuple[str | None, str | None, str]] = {
    # ---- where the input and its calibration come from (pipeline.open_source, every command)
    "--output": ("--output", "pipeline.write_product:output", PER_FILE),
    "--calibration": ("--calibration", "pipeline.open_source:grid",
                      "Python 'grid' as pipeline.choose_calibration and BatchOptions.grid: a LensletGrid or its JSON"),
    "--white": ("--white", "pipeline.open_source:white", ""),
    "--database": ("--database", "pipeline.open_source:database", ""),
    "--self-calibrate": ("--self-calibrate", "pipeline.open_source:self_calibrate", ""),
    "--raytrix-xml": (None, "pipeline.open_source:raytrix_xml",
                      "batch: each Raytrix raw finds its own XML (same stem, or the only one in its folder)"),
    "--cfa": ("--cfa", "io.mosaic_levels.MosaicOptions:cfa", ""),
    "--black-level": ("--black-level", "io.mosaic_levels.MosaicOptions:black_level", ""),
    "--white-level": ("--white-level", "io.mosaic_levels.MosaicOptions:white_level", ""),
    "--input-encoding": ("--input-encoding", "io.mosaic_levels.MosaicOptions:input_encoding", ""),
    "--dark": ("--dark", "pipeline.open_source:dark", ""),
    "--optics": ("--optics", "pipeline.open_source:optics", "Python: a MicroscopeOptics, not its JSON file"),
    # the optics values: MicroscopeOptics fields in SI units, named by optics.OPTICS_OPTIONS (checked below)
    "--lens-pitch-um": ("--lens-pitch-um", "optics.MicroscopeOptics:lens_pitch_m", "SI units in Python"),
    "--pixel-um": ("--pixel-um", "optics.MicroscopeOptics:pixel_pitch_m", "SI units in Python"),
    "--magnification": ("--magnification", "optics.MicroscopeOptics:magnification", ""),
    "--na": ("--na", "optics.MicroscopeOptics:numerical_aperture", "spelt out in Python"),
    "--tube-lens-mm": ("--tube-lens-mm", "optics.MicroscopeOptics:tube_lens_focal_length_m", "SI units in Python"),
    "--medium-index": ("--medium-index", "optics.MicroscopeOptics:medium_index", ""),
    "--microlens-focal-um": ("--microlens-focal-um", "optics.MicroscopeOptics:microlens_focal_length_m",
                             "SI units in Python"),
    "--wavelength-nm": ("--wavelength-nm", "optics.MicroscopeOptics:wavelength_m", "SI units in Python"),
    "--geometry": ("--geometry", "pipeline.open_source:geometry", ""),
    "--views-anyway": ("--views-anyway", "batch.BatchOptions:views_anyway",
                       "Python: the workflow renders what it is asked; the refusal is the front ends' guard"),
    "--overwrite": ("--overwrite", "pipeline.write_product:overwrite", ""),
    # ---- decoding (pipeline.decode_raw -> plenodecode.decode)
    "decode:--format": ("--format", "pipeline.write_lightfield:format", ""),
    "--demosaic": ("--demosaic", "decoding.decode:demosaic", ""),
    "--resample": ("--resample", "decoding.decode:resample", ""),
    "--views": ("--views", "decoding.decode:n_views",
                "Python 'n_views': the keyword of plenodecode.decode, decode_options and ~100 library call sites"),
    "--colour": ("--colour", "decoding.decode:colour", ""),
    "--no-hot-pixels": ("--no-hot-pixels", "decoding.decode:hot_pixels", "Python: hot_pixels=False"),
    # ---- writing images (pipeline.write_product)
    "--bit-depth": ("--bit-depth", "pipeline.write_product:bit_depth", ""),
    "--exposure": ("--exposure", "pipeline.write_product:exposure", ""),
    "--ext": (None, "pipeline.write_product:ext", "batch: the extension follows --bit-depth (PNG, 32: EXR)"),
    # ---- refocus (pipeline.render_refocus / render_focal_stack / render_focused_refocus)
    "--slope": ("--slope", "pipeline.products.render_refocus:slope", ""),
    "--alpha": ("--alpha", "pipeline.products.render_refocus:alpha", ""),
    "--refocus": ("--refocus", "pipeline.products.render_refocus:alpha", "the one-liner's spelling of --alpha"),
    "--focus-distance": ("--focus-distance", "pipeline.products.render_refocus:focus_distance", ""),
    "--focus-at": (None, "pipeline.products.render_refocus:focus_at",
                   "batch: one X,Y for many pictures is rarely meant"),
    "--no-depth": (None, "pipeline.products.render_refocus:focus_at_method",
                   "with --focus-at only; Python focus_at_method='sharpness' (a choice of method, not a flag)"),
    "--virtual-depth": (None, "pipeline.products.render_focused_refocus:virtual_depth",
                        "batch: a Raytrix raw's 'photo' is its total focus"),
    "--focal-stack": ("--focal-stack", "pipeline.products.render_focal_stack:start",
                      "Python start, stop, n for START:STOP:N (BatchOptions.focal_stack: the tuple); batch without "
                      "it: 9 slopes over each raw's refocusable range"),
    "--stack-units": ("--stack-units", "pipeline.products.render_focal_stack:units",
                      "Python 'units' of render_focal_stack, BatchOptions.stack_units"),
    "--method": (None, "pipeline.products.render_refocus:method",
                 "batch: its --method would be ambiguous with the depth method; refocuses by shift-sum"),
    "--aperture": ("--aperture", "pipeline.products.render_refocus:aperture", ""),
    "--upsample": (None, "pipeline.products.render_refocus:upsample", "batch: pictures at the light field's size"),
    "--total-focus": (None, "pipeline.products.render_total_focus:patch",
                      "batch: the 'total-focus' output (--outputs); Python: the product 'total-focus'"),
    "--patch": (None, "pipeline.products.render_total_focus:patch", "batch: the total focus with its default patch"),
    # ---- views and parallax (pipeline.render_views / render_parallax / write_parallax)
    "--view": (None, "pipeline.products.render_views:view", "batch: the 'views' output writes every view"),
    "views:--interp": (None, "pipeline.products.render_views:interp", "with --view only"),
    "parallax:--interp": ("--interp", "pipeline.products.render_parallax:interp", ""),
    "--frames": ("--frames", "pipeline.products.render_parallax:frames", ""),
    "--radius": ("--radius", "pipeline.products.render_parallax:radius", ""),
    "--fps": ("--fps", "pipeline.write_parallax:fps", ""),
    "--frames-dir": (None, "pipeline.write_parallax:frames_dir",
                     PER_FILE + " (parallax_frames/ beside parallax.gif)"),
    "--no-frames": ("--no-frames", "pipeline.write_parallax:frames_dir",
                    "Python: frames_dir=None; BatchOptions.parallax_frames=False"),
    # ---- depth (pipeline.render_depth / write_depth)
    "depth:--method": ("--depth-method", "pipeline.products.render_depth:method",
                       "batch: --depth-method, as a batch also refocuses"),
    "depth:--focus-distance": ("--depth-focus-distance", "pipeline.products.render_depth:focus_distance",
                               "batch: --depth-focus-distance, as its --focus-distance refocuses "
                               "(BatchOptions.depth_focus_distance)"),
    "--metric": ("--metric", "pipeline.products.render_depth:metric", ""),
    "--ply": ("--ply", "pipeline.write_depth:ply",
              "batch: a flag, <stem>.ply beside the PFM; Python render_depth(points=True), BatchOptions.ply"),
    "--disparity-range": ("--disparity-range", "pipeline.products.render_depth:disparity_range", ""),
    "--min-confidence": ("--min-confidence", "pipeline.write_depth:min_confidence", ""),
}

#: Options only a batch has, and their Python keyword (:func:`plenodecode.batch.run_batch`, :class:`BatchOptions`).
BATCH_ONLY: dict[str, tuple[str, str]] = {
    "--jobs": ("batch.run_batch:jobs", ""),
    "--scheduler": ("batch.run_batch:scheduler", ""),
    "--outputs": ("batch.BatchOptions:outputs", ""),
    "--format": ("batch.BatchOptions:format", ""),
    "--depth-method": ("batch.BatchOptions:depth_method", "see depth:--method"),
}

#: The keyword of :class:`plenodecode.batch.BatchOptions` (or :func:`run_batch`) each batch option sets, where it is
#: not the option's own name: a Python batch user's names.
BATCH_KEYWORDS = {"--output": "run_batch:output", "--calibration": "grid",
                  "--no-hot-pixels": "hot_pixels", "--no-frames": "parallax_frames", "--views": "n_views",
                  "--refocus": "alpha", "--jobs": "run_batch:jobs",
                  "--scheduler": "run_batch:scheduler", "--overwrite": "run_batch:overwrite",
                  "--optics": "optics", "--lens-pitch-um": "optics", "--pixel-um": "optics",
                  "--magnification": "optics", "--na": "optics", "--tube-lens-mm": "optics",
                  "--medium-index": "optics", "--microlens-focal-um": "optics", "--wavelength-nm": "optics"}


def _options(name: str) -> dict[str, click.Option]:
    command = cli.get_command(click.Context(cli), name)
    return {next((o for o in p.opts if o.startswith("--")), p.opts[0]): p
            for p in command.params if isinstance(p, click.Option)}


def _batch_has(option: str) -> bool:
    return any(option in p.opts for p in _options("batch").values())


def _entry(command: str, option: str) -> tuple[str | None, str | None, str] | None:
    return TABLE.get(f"{command}:{option}", TABLE.get(option))


def _keyword_exists(spec: str) -> bool:
    """'pipeline.render_refocus:slope' -> is ``slope`` a keyword of plenodecode.pipeline.render_refocus (or a key of
    a mapping, a field of a dataclass)?"""
    target, keyword = spec.split(":")
    module, _, attribute = target.rpartition(".")
    obj = getattr(importlib.import_module(f"plenodecode.{module}"), attribute)
    if isinstance(obj, Mapping):
        return keyword in obj
    if dataclasses.is_dataclass(obj):
        return keyword in {f.name for f in dataclasses.fields(obj)}
    return keyword in inspect.signature(obj).parameters


def _same(option: str, keyword: str) -> bool:
    return option.lstrip("-").replace("-", "_") == keyword


@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_is_in_the_table(command):
    """A new option of a command that renders raws needs its batch option and Python keyword, or a stated reason."""
    missing = [o for o in _options(command) if _entry(command, o) is None]
    assert not missing, f"enter {command} {missing} in tests/cli/test_parity.py TABLE (batch option, Python keyword)"


def test_every_batch_option_is_accounted_for():
    used = {e[0] for e in TABLE.values() if e[0]}
    missing = [o for o in _options("batch") if o not in used and o not in BATCH_ONLY]
    assert not missing, f"enter batch {missing} in TABLE or BATCH_ONLY"


@pytest.mark.parametrize("option", sorted(BATCH_ONLY))
def test_batch_only_options_name_real_keywords_and_say_why_they_differ(option):
    keyword, why = BATCH_ONLY[option]
    assert _keyword_exists(keyword), f"batch {option}: {keyword} is no workflow keyword"
    assert _same(option, keyword.split(":")[1]) or why, f"batch {option}: the keyword differs; say why in BATCH_ONLY"


@pytest.mark.parametrize("key", sorted(TABLE))
def test_table_names_real_options_and_keywords_and_says_why_they_differ(key):
    batch_option, keyword, why = TABLE[key]
    option = key.split(":")[-1]
    assert any(option in _options(c) for c in COMMANDS), f"{key}: no command has {option}"
    if batch_option is not None:
        assert _batch_has(batch_option), f"{key}: batch has no {batch_option}"
    assert keyword is not None and _keyword_exists(keyword), f"{key}: {keyword} is no workflow keyword"
    differs = batch_option != option or not _same(option, keyword.split(":")[1])
    assert not differs or why, f"{key}: the batch option or Python keyword differs; say why in TABLE"


@pytest.mark.parametrize("option", sorted(set(_options("batch"))))
def test_every_batch_option_sets_a_batch_keyword(option):
    """``plenodecode batch --x`` is ``run_batch(..., BatchOptions(x=...))`` in Python: the same name, or one of
    :data:`BATCH_KEYWORDS`."""
    from plenodecode.batch import run_batch

    spec = BATCH_KEYWORDS.get(option, option.lstrip("-").replace("-", "_"))
    target, _, keyword = spec.rpartition(":")
    params = (inspect.signature(run_batch).parameters if target == "run_batch"
              else {f.name for f in dataclasses.fields(BatchOptions)})
    assert keyword in params, f"batch {option}: no BatchOptions / run_batch keyword {keyword!r}"


def test_optics_fields_are_named_by_their_options():
    from plenodecode.optics import OPTICS_OPTIONS

    for key, (batch_option, keyword, _) in TABLE.items():
        if keyword.startswith("optics.MicroscopeOptics:"):
            assert OPTICS_OPTIONS[keyword.split(":")[1]][0] == key


# ----------------------------------------------------------- the same feature through the three front ends
RAW = ROOT / "sample_raws" / "illum-mini" / "scene.lfr"
WHITE = ROOT / "sample_raws" / "illum-mini" / "MOD_0000.RAW"


def _invoke(args) -> None:
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, (res.output, res.exception)


@pytest.fixture(scope="module")
def grid_json(tmp_path_factory):
    """The illum-mini lenslet grid fitted from its white image, as 'plenodecode calibrate' writes it."""
    out = tmp_path_factory.mktemp("grid") / "grid.json"
    _invoke(["calibrate", WHITE, "-o", out])
    return out


def test_decoding_options_and_grid_reach_the_same_light_field_from_decode_batch_and_python(tmp_path, grid_json,
                                                                                          monkeypatch):
    """--demosaic bilinear --colour camera --no-hot-pixels --views 9 with -g GRID.json: 'decode', 'batch' (which had
    none of these options) and pipeline.open_source(grid=, decode_options=) give the same light field, bit for bit,
    and not the default one."""
    opts = ["--demosaic", "bilinear", "--colour", "camera", "--no-hot-pixels", "--views", "9"]
    _invoke(["decode", RAW, "-g", grid_json, "-o", tmp_path / "cli.npy", *opts])
    monkeypatch.chdir(tmp_path)         # no ./calib: the batch must take the grid, not the database
    _invoke(["batch", RAW, "-o", tmp_path / "batch", "-g", grid_json, "--outputs", "lightfield", "--format", "npy",
             "-j", "1", *opts])
    src = pipeline.open_source(RAW, grid=grid_json, decode_options={
        "demosaic": "bilinear", "colour": "camera", "hot_pixels": False, "n_views": 9})
    py = src.lightfield
    cli_lf = np.load(tmp_path / "cli.npy")
    batch_lf = np.load(tmp_path / "batch" / "scene" / "lightfield.npy")
    assert cli_lf.shape == batch_lf.shape == py.data.shape == (9, 9) + py.data.shape[2:]
    assert py.colour == "camera"
    np.testing.assert_array_equal(batch_lf, cli_lf)
    np.testing.assert_array_equal(py.data, cli_lf)
    default = pipeline.open_source(RAW, grid=grid_json, decode_options={"n_views": 9}).lightfield.data
    assert np.abs(default - cli_lf).max() > 0.05        # the options changed the light field


def test_batch_grid_is_used_without_a_database(tmp_path, grid_json, monkeypatch):
    """'batch -g GRID.json' decodes with that grid where no database is (it refused '--database' missing before)."""
    monkeypatch.chdir(tmp_path)
    _invoke(["batch", RAW, "-o", tmp_path / "out", "-g", grid_json, "--outputs", "centre", "-j", "1"])
    assert (tmp_path / "out" / "scene" / "centre.png").is_file()
    res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", str(tmp_path / "o2"), "-g", str(grid_json),
                                   "--database", str(ROOT / "calib")])
    assert res.exit_code == 2 and "--database cannot be combined with --calibration" in res.output


def _database() -> list[str]:
    return ["--database", str(ROOT / "calib")]


def test_aperture_reaches_the_same_photograph_from_refocus_batch_and_python(tmp_path):
    """--slope 0.5 --aperture 0.5 (batch had no --aperture): 'refocus', 'batch --outputs refocus,photo' and
    pipeline.render_product(src, 'refocus', aperture=0.5) give the same linear 32-bit picture; it differs from the
    full aperture's."""
    from plenodecode.io.images import read_image

    _invoke(["refocus", RAW, "-o", tmp_path / "cli.exr", "--slope", "0.5", "--aperture", "0.5", "--bit-depth", "32",
             *_database()])
    _invoke(["batch", RAW, "-o", tmp_path / "batch", "--outputs", "refocus,photo", "--slope", "0.5", "--aperture",
             "0.5", "--bit-depth", "32", "-j", "1", *_database()])
    src = pipeline.open_source(RAW, database=ROOT / "calib")
    (_, py), = pipeline.render_product(src, "refocus", slope=0.5, aperture=0.5).images
    (_, full), = pipeline.render_product(src, "refocus", slope=0.5).images
    cli_img = read_image(tmp_path / "cli.exr")
    batch_img = read_image(tmp_path / "batch" / "scene" / "refocus_s+0.50.exr")
    py = np.asarray(py, np.float32).reshape(cli_img.shape)
    np.testing.assert_allclose(batch_img, cli_img, atol=1e-6)
    np.testing.assert_allclose(py, cli_img, atol=1e-6)
    assert np.abs(np.asarray(full).reshape(cli_img.shape) - cli_img).mean() > 1e-3   # the aperture mattered
    marker = json.loads((tmp_path / "batch" / "scene" / ".done.json").read_text())
    assert marker["options"]["aperture"] == 0.5      # a run with another aperture is not taken as done


def test_disparity_range_reaches_the_same_depth_from_depth_batch_and_python(tmp_path):
    """--method fast --disparity-range -0.4:0.4 (batch had no --disparity-range): 'depth', 'batch --outputs depth'
    and pipeline.render_product(src, 'depth', disparity_range=) give the same disparities, not the default search's."""
    from plenodecode.io.pfm import read_pfm

    _invoke(["depth", RAW, "-o", tmp_path / "cli.pfm", "--method", "fast", "--disparity-range", "-0.4:0.4",
             *_database()])
    _invoke(["batch", RAW, "-o", tmp_path / "batch", "--outputs", "depth", "--depth-method", "fast",
             "--disparity-range", "-0.4:0.4", "-j", "1", *_database()])
    src = pipeline.open_source(RAW, database=ROOT / "calib")
    py = pipeline.render_product(src, "depth", method="fast", disparity_range=(-0.4, 0.4)).data["values"]
    default = pipeline.render_product(src, "depth", method="fast").data["values"]
    cli_d = read_pfm(tmp_path / "cli.pfm")
    batch_d = read_pfm(tmp_path / "batch" / "scene" / "disparity.pfm")
    np.testing.assert_allclose(batch_d, cli_d, atol=1e-6)
    np.testing.assert_allclose(py, cli_d, atol=1e-6)
    # the range bounds the labels; sub-label refinement may leave it, so only some pixels change (0.3 % here)
    assert np.abs(default - cli_d).max() > 0.5


def test_batch_refuses_a_disparity_range_past_the_picture_naming_the_option(tmp_path):
    res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", str(tmp_path / "b"), "--outputs", "depth",
                                   "--disparity-range", "-500:500", "-j", "1", *_database()])
    assert res.exit_code == 1
    assert "--disparity-range -500:500 does not suit scene.lfr" in res.output
    assert not (tmp_path / "b" / "scene").exists()


# ------------------------------------------------ a bad value: Python names the keyword, the CLI the option
def _source():
    return pipeline.open_source(RAW, database=ROOT / "calib")       # not decoded: the checks come first


BAD_VALUES = [   # (Python call, the keyword its error starts with; command line, the option its error names)
    (lambda: BatchOptions(aperture=2), "aperture",
     ["batch", RAW, "-o", "OUT", "--aperture", "2"], "--aperture"),
    (lambda: BatchOptions(n_views=4), "n_views",
     ["batch", RAW, "-o", "OUT", "--views", "4"], "--views"),
    (lambda: BatchOptions(disparity_range=(1, 0)), "disparity_range",
     ["batch", RAW, "-o", "OUT", "--disparity-range", "1:0"], "--disparity-range"),
    (lambda: pipeline.render_product(_source(), "parallax", frames=0), "frames",
     ["parallax", RAW, "-o", "OUT.gif", "--frames", "0"], "--frames"),
    (lambda: pipeline.render_product(_source(), "focal-stack", start=0, stop=1, n=1), "n",
     ["refocus", RAW, "-o", "OUT", "--focal-stack", "0:1:1"], "--focal-stack"),
    (lambda: BatchOptions(demosaic="ahd"), "demosaic",
     ["batch", RAW, "-o", "OUT", "--demosaic", "ahd"], "--demosaic"),
]


@pytest.mark.parametrize("call, keyword, args, option", BAD_VALUES, ids=[c[3] for c in BAD_VALUES])
def test_a_bad_value_names_the_keyword_in_python_and_the_option_on_the_command_line(tmp_path, call, keyword, args,
                                                                                    option):
    """'render_product(src, "parallax", frames=0)' said 'n_frames must be ...' (render.render_parallax's name), and
    only after decoding; a focal stack of n=1 said 'a focal stack has 2 to 512 slices'."""
    with pytest.raises(ValueError) as err:
        call()
    assert str(err.value).split()[0] == keyword, str(err.value)
    out = str(tmp_path / "out")
    res = CliRunner().invoke(cli, [out + str(a)[3:] if str(a).startswith("OUT") else str(a) for a in args])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1 and option in errors[0], res.output
    assert not list(tmp_path.iterdir())


def test_batch_refuses_more_views_than_the_lenses_give_naming_the_option(tmp_path):
    """'decode --views 31' is a usage error on illum-mini (at most 17 views per axis see a micro-image); a batch fails
    that raw in one line naming --views, before decoding it."""
    res = CliRunner().invoke(cli, ["batch", str(RAW), "-o", str(tmp_path / "b"), "--outputs", "centre", "--views",
                                   "31", "-j", "1", *_database()])
    assert res.exit_code == 1
    error, = [r["error"] for r in json.loads((tmp_path / "b" / "summary.json").read_text())["results"]]
    assert error.startswith("--views 31 does not suit scene.lfr: more than the 17 views per axis"), error
    assert not (tmp_path / "b" / "scene").exists()
