"""``python -m bench [name ...]``: run the benchmark modules and print one table."""

from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path

from . import machine, print_table


def main(argv: list[str]) -> None:
    here = Path(__file__).parent
    names = sorted(m.name for m in pkgutil.iter_modules([str(here)]) if m.name.startswith("bench_"))
    if argv:
        names = [n for n in names if any(a in n for a in argv)]
    figures = []
    for name in names:
        print(f"# {name}", file=sys.stderr, flush=True)
        figures.extend(importlib.import_module(f"bench.{name}").run())
    print(machine())
    print_table(figures)


if __name__ == "__main__":
    main(sys.argv[1:])
