"""``plenodecode warmup``: compile every numba kernel now, so that no later command waits for it."""

from __future__ import annotations

import click


@click.command("warmup")
@click.pass_context
def command(ctx: click.Context) -> None:
    """Compile every numba kernel once (a minute or so) and cache it for all later commands.

    Without it, the first command that needs a group of kernels compiles that group (and says so).
    The cache is $NUMBA_CACHE_DIR, else $XDG_CACHE_HOME/plenodecode/numba (~/.cache/plenodecode/numba).

    \b
    Example:
      plenodecode warmup
    """
    import os

    from .. import _numba
    from ..warmup import WARMUP_GROUPS, warmup

    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    _numba.set_compile_notice(None)             # warmup prints its own line per group
    if not quiet:
        click.echo(f"compiling kernels into {os.environ.get('NUMBA_CACHE_DIR') or _numba.use_user_cache()} "
                   f"({len(WARMUP_GROUPS)} groups)")

    def report(group: str, seconds: float) -> None:
        if not quiet:
            click.echo(f"  {group:12s} {seconds:6.1f} s")

    seconds = warmup(report)
    if not quiet:
        click.echo(f"done in {sum(seconds.values()):.1f} s")
