"""Command-line interface: ``plenodecode.cli.main:cli`` and one thin module per command."""
