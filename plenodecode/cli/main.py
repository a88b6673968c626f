"""The ``plenodecode`` command group.

Commands live in one module each (``plenodecode.cli.<name>``, attribute ``command``) and
are imported only when run, so ``plenodecode --help`` stays fast.  A first argument that
is not a command but a file (``plenodecode raw.lfr --refocus 1.015``) runs ``render``, which --help lists
so that its options (``plenodecode render --help``) and the errors naming it can be found.

Exit codes: 0 success, 1 data error (one line on stderr; traceback with ``-v``), 2 usage error.
"""

from __future__ import annotations

import difflib
import importlib
import logging
import sys
from pathlib import Path

import click

from .. import __version__, _numba
from ..io.atomic import os_error_text
from ..errors import (DarkFrameMismatchError, GeometryMismatchError, LevelOptionError,
                      MissingConstantsError, PlenodecodeError, configure_logging)

#: command name -> (module, one-line description shown by --help)
COMMANDS: dict[str, tuple[str, str]] = {
    "info": ("plenodecode.cli.info", "Describe a raw or container: camera, serial, kind, sizes, sections."),
    "synth": ("plenodecode.cli.synth", "Generate a synthetic plenoptic raw with exact ground truth."),
    "calibrate": ("plenodecode.cli.calibrate", "Fit the lenslet grid from white images; build a calibration database."),
    "calibrate-geometry": ("plenodecode.cli.calibrate_geometry",
                           "Fit the camera's ray geometry (H, distortion) from checkerboard captures."),
    "decode": ("plenodecode.cli.decode", "Decode a raw into a 4D light field and write it."),
    "export": ("plenodecode.cli.export", "Convert a saved light field to another format."),
    "extract": ("plenodecode.cli.extract", "Write the JPEGs, depth maps and H.264 streams embedded in a Lytro file."),
    "refocus": ("plenodecode.cli.refocus", "Refocus a raw or light field (slope or alpha), or write a focal stack."),
    "render": ("plenodecode.cli.render", "Decode a raw and write its photograph in one call; 'plenodecode RAW ...' is "
                                          "short for 'plenodecode render RAW ...'."),
    "views": ("plenodecode.cli.views", "Write sub-aperture or perspective views."),
    "parallax": ("plenodecode.cli.parallax", "Write a parallax animation (circle of viewpoints)."),
    "depth": ("plenodecode.cli.depth", "Estimate disparity / metric depth and write PFM, EXR, PNG, PLY."),
    "batch": ("plenodecode.cli.batch", "Decode and render many raws, locally or on a Dask cluster."),
    "warmup": ("plenodecode.cli.warmup", "Compile every numba kernel now (first run after installing)."),
}


_PLAIN_DISPARITY = ("plain disparity (without --metric and --ply), or for a light-field microscope give its optics "
                    "(--magnification, --na, --medium-index, --lens-pitch-um, --pixel-um, or --optics FILE.json)")
#: A keyword of :class:`~plenodecode.errors.MissingConstantsError` -> (the click parameter that set it, what to
#: type instead).
CONSTANTS_OPTIONS = {"alpha": ("alpha", "--slope S (px per view step)"),
                     "units": ("stack_units", "--stack-units slope (START and STOP as slopes)"),
                     "focus_distance": ("focus_distance", "--slope S (px per view step)"),
                     "metric": ("metric", _PLAIN_DISPARITY),
                     "points": ("ply", _PLAIN_DISPARITY)}


def use_instead(keyword: str) -> str:
    """What a command says to type instead of the option behind a MissingConstantsError's ``keyword``
    (:data:`CONSTANTS_OPTIONS`): 'use --slope S (px per view step) instead'."""
    return f"use {CONSTANTS_OPTIONS[keyword][1]} instead"


def constants_usage_error(command: click.Command | None, exc: MissingConstantsError) -> click.BadParameter:
    """The usage error (exit 2, one line) of a product asked of an input without the camera constants it needs
    (alpha, a focus distance, metric depth): it names the command's option (``--refocus`` / ``--alpha``,
    ``--stack-units``, ``--focus-distance``, ``--metric``, ``--ply``), the missing constants and what to type
    instead (``--focus-distance``, batch's ``--depth-focus-distance``, where only the camera's focus distance is
    missing for metric depth)."""
    param_name = CONSTANTS_OPTIONS[exc.keyword][0]
    instead = use_instead(exc.keyword)
    param = next((p for p in getattr(command, "params", ()) if p.name == param_name), None)
    hint = " / ".join(param.opts) if param is not None else f"--{param_name.replace('_', '-')}"
    if not exc.missing:         # the message says why; the request that serves instead (a microscope's slope) by option
        text = str(exc) if exc.instead is None else f"{exc.source}: {exc.reason}; {instead}"
        return click.BadParameter(text, param_hint=hint)
    if exc.keyword in ("metric", "points") and exc.missing == ("focus_distance_m",):
        own = next((p for p in getattr(command, "params", ()) if p.name == "depth_focus_distance"), None)
        instead = f"use {own.opts[0] if own is not None else '--focus-distance'} METRES (the distance in focus) instead"
    return click.BadParameter(f"{exc.source} has no {', '.join(exc.missing)} in its metadata, which {exc.need} "
                              f"needs; {instead}", param_hint=hint)


#: The group's own flags, also taken where they follow the command (:meth:`LazyGroup.parse_args`): 'plenodecode
#: decode --version' prints the version as 'plenodecode --version' does.
GROUP_FLAGS = ("-q", "--quiet", "-v", "-vv", "-vvv", "--verbose", "--version")


class LazyGroup(click.Group):
    """A click group whose commands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        module = importlib.import_module(COMMANDS[name][0])
        return module.command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, COMMANDS[name][1]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        # -q / -v / --version typed after the command ('plenodecode RAW -o x.png -q') mean what they mean before it: no
        # command has options of those names, and a path or value never is one of these exact tokens
        if "--" not in args:
            hoisted = [a for a in args if a in GROUP_FLAGS]
            args = hoisted + [a for a in args if a not in GROUP_FLAGS]
        return super().parse_args(ctx, args)

    def resolve_command(self, ctx: click.Context, args: list[str]):
        if args and args[0] in ("version", "help") and not Path(args[0]).exists():
            # what a user types for 'plenodecode --version' / '--help' (no file of that name: not the one-liner)
            click.echo(f"plenodecode, version {__version__}" if args[0] == "version" else ctx.get_help())
            ctx.exit(0)
        if args and args[0] not in COMMANDS and not args[0].startswith("-"):
            # 'plenodecode RAW ...' is the one-liner; a mistyped command is no file either: say which it meant
            close = difflib.get_close_matches(args[0], self.list_commands(ctx), n=1, cutoff=0.75)
            if close and not Path(args[0]).exists():
                ctx.fail(f"no command or file {args[0]!r}: did you mean 'plenodecode {close[0]}'?")
            args = ["render", *args]
        return super().resolve_command(ctx, args)

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except GeometryMismatchError as exc:      # checked before any decoding: a usage error like a bad file
            raise click.BadParameter(str(exc), param_hint="--geometry") from None
        except DarkFrameMismatchError as exc:     # checked as soon as the raw is read, before the calibration
            raise click.BadParameter(str(exc), param_hint="--dark") from None
        except LevelOptionError as exc:           # a typed level the file's samples cannot have: found on reading it
            raise click.BadParameter(str(exc), param_hint=exc.option) from None
        except MissingConstantsError as exc:      # checked once the input is read, before calibration and decoding
            name = ctx.invoked_subcommand
            raise constants_usage_error(self.get_command(ctx, name) if name else None, exc) from None
        except PlenodecodeError as exc:
            if ctx.obj and ctx.obj.get("verbose", 0) > 0:
                raise
            click.echo(f"error: {exc}", err=True)
            ctx.exit(1)
        except OSError as exc:     # a write failing mid-run (full or read-only disk, a folder gone): one line
            if ctx.obj and ctx.obj.get("verbose", 0) > 0:
                raise
            click.echo(f"error: {os_error_text(exc)}", err=True)
            ctx.exit(1)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="plenodecode")
@click.option("-v", "--verbose", count=True, help="More log output; -v also shows tracebacks.")
@click.option("-q", "--quiet", is_flag=True, help="Only errors.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool) -> None:
    """plenodecode: decode plenoptic camera raws into 4D light fields.

    \b
    Example:
      plenodecode raw.lfr --refocus 1.015 -o photo.png    # the render command; its options: render --help
    """
    ctx.ensure_object(dict)
    ctx.obj["verbose"] = verbose
    ctx.obj["quiet"] = quiet
    level = logging.ERROR if quiet else (logging.DEBUG if verbose > 1 else logging.INFO if verbose else logging.WARNING)
    configure_logging(level, stream=sys.stderr)
    # a command that meets kernels missing from the cache says so on stderr, one line per group
    _numba.set_compile_notice(None if quiet else lambda message: click.echo(message, err=True))


def main() -> None:  # pragma: no cover - console entry
    cli(obj={})


if __name__ == "__main__":  # pragma: no cover
    main()
