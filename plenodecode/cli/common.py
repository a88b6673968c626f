"""Options and helpers shared by every command, so they behave the same everywhere."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Callable

import click

output_option = click.option("-o", "--output", "output", type=click.Path(path_type=Path), required=True,
                             help="Output file or folder.")
overwrite_option = click.option("--overwrite", is_flag=True, help="Replace existing outputs.")
bit_depth_option = click.option("--bit-depth", type=click.Choice(["8", "16", "32"]), default="16", show_default=True,
                                help="Bits per sample of image outputs (32 = float).")
jobs_option = click.option("--jobs", "-j", type=int, default=None,
                           help="Worker processes (default: all cores).")


def check_output(path: Path, overwrite: bool) -> None:
    """Refuse to replace an existing output unless ``--overwrite`` was given (usage error, exit 2)."""
    if path.exists() and not overwrite:
        raise click.UsageError(f"{path} exists; pass --overwrite to replace it")


def lightfield_output_format(output: Path, fmt: str | None, overwrite: bool) -> str:
    """The light-field format to write ``output`` in: ``fmt``, else detected from its name (usage errors for an
    existing output without ``--overwrite`` and for a name that says no format)."""
    from ..io.lightfield import detect_format

    check_output(output, overwrite)
    try:
        return fmt or detect_format(output)
    except ValueError as exc:
        raise click.UsageError(f"{exc} (use --format)") from exc


def progress_bar(label: str, ctx: click.Context | None = None) -> Callable[[int, int], None]:
    """A ``callback(done, total)`` that draws a click progress bar on stderr (silent with -q)."""
    ctx = ctx or click.get_current_context(silent=True)
    quiet = bool(ctx and ctx.obj and ctx.obj.get("quiet"))
    state: dict = {}

    def callback(done: int, total: int) -> None:
        if quiet:
            return
        bar = state.get("bar")
        if bar is None:
            bar = click.progressbar(length=total, label=label, show_pos=True, show_eta=True, file=sys.stderr)
            bar.__enter__()
            state["bar"] = bar
            state["done"] = 0
        bar.update(done - state["done"])
        state["done"] = done
        if done >= total:
            bar.__exit__(None, None, None)
            state.pop("bar")

    return callback


def default_jobs() -> int:
    """All cores."""
    return os.cpu_count() or 1
