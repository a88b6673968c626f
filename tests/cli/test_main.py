"""The command line as a whole: every command listed, documented with an example, consistent exit codes."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from plenodecode import __version__
from plenodecode.cli.main import COMMANDS, cli

def test_help_lists_every_command_with_a_description():
    res = CliRunner().invoke(cli, ["--help"])
    assert res.exit_code == 0
    listed = [line.split()[0] for line in res.output.split("Commands:", 1)[1].splitlines() if line.startswith("  ")
              and not line.startswith("   ")]
    assert listed == list(COMMANDS), listed
    assert "--version" in res.output


def test_help_lists_the_render_command_the_errors_and_readme_name():
    """'render' was hidden from --help while the one-liner's options live under 'plenodecode render --help' and a
    focused raw's errors (and the README) say 'plenodecode render RAW --total-focus': --help lists it, as the
    one-liner's long form, and the group's example says where its options are."""
    from plenodecode.cli.common import FOCUSED_PHOTO

    help_text = CliRunner().invoke(cli, ["--help"]).output
    row = next(line for line in help_text.splitlines() if line.startswith("  render "))
    assert "plenodecode RAW" in " ".join(help_text.split()) and "short for 'plenodecode render RAW" in \
        " ".join(help_text.split()), row
    assert "render --help" in help_text
    assert FOCUSED_PHOTO.split("'plenodecode ", 1)[1].split()[0] == "render"
    listed = {line.split()[0] for line in help_text.split("Commands:", 1)[1].splitlines() if line.startswith("  ")
              and not line.startswith("   ")}
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    named = set(re.findall(r"plenodecode ([a-z][a-z-]+) ", readme)) & set(COMMANDS)
    assert "render" in named and named <= listed, named - listed


@pytest.mark.parametrize("name", list(COMMANDS))
def test_each_command_help_shows_an_example(name):
    res = CliRunner().invoke(cli, [name, "--help"])
    assert res.exit_code == 0, res.output
    assert "Example" in res.output and "plenodecode" in res.output.split("Example", 1)[1]


def test_version():
    res = CliRunner().invoke(cli, ["--version"])
    assert res.exit_code == 0 and __version__ in res.output


def test_usage_error_exits_2():
    res = CliRunner().invoke(cli, ["decode"])
    assert res.exit_code == 2


def test_data_error_exits_1_with_one_line(tmp_path):
    bad = tmp_path / "bad.lfr"
    bad.write_bytes(b"\x89LFP\r\n\x1a\n" + b"\x00" * 7)
    res = CliRunner().invoke(cli, ["info", str(bad)])
    assert res.exit_code == 1
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "bad.lfr" in err[0]
    assert "Traceback" not in res.output


def test_database_option_has_one_spelling_in_the_help():
    """``--database`` everywhere; ``--white-dir`` still parses but is not shown; the default is calib.store's."""
    from plenodecode.calib.store import DEFAULT_DB

    for command in ("decode", "refocus", "views", "parallax", "depth", "render", "batch"):
        out = CliRunner().invoke(cli, [command, "--help"]).output
        assert "--database" in out and "--white-dir" not in out, command
        assert f"[default: ./{DEFAULT_DB}, else {DEFAULT_DB}/ beside the raw or in a folder above it]" in \
            " ".join(out.split()), command


def test_errors_name_the_database_option_not_its_old_spelling(tmp_path):
    """'--database nowhere' (or the old '--white-dir nowhere') said "Invalid value for '--database' / '--white-dir'",
    naming the spelling the help hides; the error names '--database' alone, whichever was typed."""
    for command in ("decode", "refocus", "views", "parallax", "depth", "render", "batch", "calibrate-geometry"):
        for spelling in ("--database", "--white-dir"):
            res = CliRunner().invoke(cli, [command, str(tmp_path), spelling, str(tmp_path / "nowhere"),
                                           "-o", str(tmp_path / "out.png")])
            errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
            assert res.exit_code == 2 and errors == [
                f"Error: Invalid value for '--database': Directory '{tmp_path / 'nowhere'}' does not exist."], \
                (command, spelling, res.output)


def test_version_and_help_typed_as_commands_do_what_the_flags_do(tmp_path, monkeypatch):
    """'plenodecode version' said "Invalid value for 'RAW_OR_LF': Path 'version' does not exist" (the one-liner took
    it for a raw); it prints what '--version' prints, and 'plenodecode help' the group's help, exit 0.  A file
    named 'version' is still the one-liner's input."""
    runner = CliRunner()
    flag = runner.invoke(cli, ["--version"])
    typed = runner.invoke(cli, ["version"])
    assert typed.exit_code == 0 and typed.output == flag.output and flag.output.startswith("plenodecode, version ")
    helped = runner.invoke(cli, ["help"])
    assert helped.exit_code == 0 and helped.output == runner.invoke(cli, ["--help"]).output
    monkeypatch.chdir(tmp_path)
    Path("version").write_bytes(b"not a raw")
    res = runner.invoke(cli, ["version", "-o", "photo.png"])
    assert res.exit_code != 0 and "plenodecode, version" not in res.output, res.output


@pytest.mark.parametrize("name", list(COMMANDS))
def test_command_help_imports_neither_numba_nor_opencv(name):
    """Help is read often and must come fast: building it imports no compiled-kernel or OpenCV module
    (registries are read through light modules; a fresh interpreter, so nothing is imported already)."""
    code = ("import sys\n"
            "from click.testing import CliRunner\n"
            "from plenodecode.cli.main import cli\n"
            f"res = CliRunner().invoke(cli, [{name!r}, '--help'])\n"
            "assert res.exit_code == 0, res.output\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'cv2'}))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", f"plenodecode {name} --help imports {out.strip()}"


def test_python_dash_m_runs_the_same_command_line():
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "plenodecode", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("plenodecode") and out.stdout.strip().split()[-1][0].isdigit()


def test_a_mistyped_command_is_named_with_the_command_it_meant(tmp_path, monkeypatch):
    """'plenodecode refocs lf.zarr ...' answered \"Path 'refocs' does not exist\" (the one-liner took the typo for
    its input); a first word close to a command that is no file now gets the command it meant, and a file of
    that name is still the one-liner's input."""
    res = CliRunner().invoke(cli, ["refocs", "lf.zarr", "--slope", "0.5", "-o", str(tmp_path / "x.png")])
    assert res.exit_code == 2
    assert "Error: no command or file 'refocs': did you mean 'plenodecode refocus'?" in res.output
    assert not (tmp_path / "x.png").exists()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "dept").write_bytes(b"not a raw")
    res = CliRunner().invoke(cli, ["dept", "-o", "x.png"])
    assert res.exit_code == 1 and "did you mean" not in res.output and "dept" in res.output, res.output


def test_quiet_and_verbose_after_the_command_mean_the_same(tmp_path):
    """'plenodecode RAW -o x.png -q' was refused ("No such option '-q'"): the group's flags had to come first.
    After the command they now do what they do before it: -q silences the one-liner's summary line."""
    from pathlib import Path

    raw = Path(__file__).resolve().parents[2] / "sample_raws" / "illum-mini" / "scene.lfr"
    loud = CliRunner().invoke(cli, [str(raw), "-o", str(tmp_path / "a.png")], obj={})
    quiet = CliRunner().invoke(cli, [str(raw), "-o", str(tmp_path / "b.png"), "-q"], obj={})
    assert loud.exit_code == 0 and "wrote" in loud.output, loud.output
    assert quiet.exit_code == 0 and quiet.output == "", quiet.output
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
    r = CliRunner().invoke(cli, ["info", str(raw), "--quiet"], obj={})
    assert r.exit_code == 0 and "ILLUM" in r.output


def test_help_says_what_extract_writes_and_how_many_views_decode_takes():
    """'extract --help' called -o an 'Output file or folder' (it is always a folder); 'decode --help' gave no
    bound or unit for --views."""
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    text = CliRunner().invoke(cli, ["extract", "--help"]).output
    assert "Folder the items are written into (created if missing)." in " ".join(text.split())
    text = " ".join(CliRunner().invoke(cli, ["decode", "--help"]).output.split())
    assert "at most 2*ceil(pitch/2)+1 [default: 2*floor(pitch/2)+1, pitch in px]" in text


@pytest.mark.parametrize("command", ["decode", "info", "calibrate", "synth", "extract", "export", "warmup",
                                     "calibrate-geometry"])
def test_version_after_a_command_prints_the_version(command):
    """'plenodecode decode --version' said "No such option '--version'. Did you mean '--overwrite'?"; after any
    command it now prints what 'plenodecode --version' prints, and does nothing else."""
    res = CliRunner().invoke(cli, [command, "--version"])
    assert res.exit_code == 0 and res.output.strip() == f"plenodecode, version {__version__}", res.output


def test_several_files_to_a_one_input_command_give_the_batch_that_takes_them(tmp_path):
    """'plenodecode IMG_1.jpg IMG_2.jpg -o photo.png' (a shell glob over the real F01 JPEGs) said only 'Got
    unexpected extra argument (IMG_2.jpg)'.  Every one-input command now says it reads one input and, where batch
    writes the same product, gives the batch command; that command, run as printed, writes both photos.  Extras
    that are no files keep click's wording."""
    import shlex

    import cv2
    import numpy as np

    from tests.conftest import shared_path

    folder = shared_path("lytro-f01-lenslet-jpg")
    jpgs = [str(folder / "IMG_1.jpg"), str(folder / "IMG_2.jpg")]
    res = CliRunner().invoke(cli, [*jpgs, "-o", str(tmp_path / "photo.png")])
    errors = [line for line in res.output.splitlines() if line.startswith("Error:")]
    assert res.exit_code == 2 and len(errors) == 1, res.output
    assert f"'plenodecode render' reads one input, got 2 ({' '.join(jpgs)})" in errors[0]
    command = re.search(r"'(plenodecode batch [^']*)'", errors[0]).group(1)
    assert command == f"plenodecode batch {' '.join(jpgs)} -o OUT/ --outputs photo"
    assert not (tmp_path / "photo.png").exists()
    args = shlex.split(command.replace("OUT/", str(tmp_path / "out")))[1:]
    res = CliRunner().invoke(cli, [*args, "--jobs", "1", "-q"])
    assert res.exit_code == 0, res.output
    for stem in ("IMG_1", "IMG_2"):
        photo = cv2.imread(str(tmp_path / "out" / stem / "refocus_s+0.00.png"), cv2.IMREAD_UNCHANGED)   # batch's photo
        assert photo is not None and photo.shape[:2] == (383, 382) and photo.std() > 0.05 * np.iinfo(photo.dtype).max
    for argv, words in ((["depth", *jpgs, "-o", "d.pfm"], "--outputs depth' writes one folder per raw"),
                        (["export", *jpgs, "-o", "x.mat"], "'plenodecode export' reads one input, got 2"),
                        (["refocus", jpgs[0], "--slope", "0.5", "bogus", "-o", "r.png"],
                         "Got unexpected extra argument (bogus)")):
        res = CliRunner().invoke(cli, argv)
        assert res.exit_code == 2 and words in res.output, (argv, res.output)


def test_warnings_read_as_the_commands_own_lines(tmp_path):
    """A warning read 'WARNING plenodecode.io.generic: IMG_1.jpg: ...' beside the command's 'note: ...' and
    'error: ...' lines; it is now 'warning: IMG_1.jpg: ...', the module named only with -v (for whoever debugs)."""
    from tests.conftest import shared_path

    jpg = shared_path("lytro-f01-lenslet-jpg", "IMG_1.jpg")
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root)}
    for flags, start in (([], "warning: IMG_1.jpg: no JSON sidecar"),
                         (["-v"], "warning plenodecode.io.generic: IMG_1.jpg: no JSON sidecar")):
        res = subprocess.run([sys.executable, "-m", "plenodecode", *flags, "info", str(jpg)], capture_output=True,
                             text=True, env=env, cwd=tmp_path, timeout=120)
        assert res.returncode == 0 and res.stderr.splitlines()[0].startswith(start), res.stderr
