"""``python -m plenodecode ...``: the same command line as the ``plenodecode`` console script."""

from .cli.main import cli

if __name__ == "__main__":
    cli(prog_name="plenodecode")
