"""Regenerate the synthetic sample raws in this folder.

    python sample_raws/make_samples.py            # refuses to replace existing files
    python sample_raws/make_samples.py --overwrite

Each sample is ``plenodecode.synthetic.simulate(PRESET, seed=SEED)`` (the default scene,
with noise) written by ``write_simulation(..., name='scene', lightfield=False)``: the scene
raw in the camera's own format, its white image and the ground truth (grid, lens centres,
centre-view disparity; no ground-truth light field, to keep the folder small).  The same
files come from ``plenodecode synth PRESET -o sample_raws/PRESET --seed SEED --no-lightfield``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

#: folder -> (preset, seed)
SAMPLES = {
    "illum-mini": ("illum-mini", 1),
    "f01-mini": ("f01-mini", 2),
    "square": ("square", 3),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--overwrite", action="store_true", help="replace existing sample files")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent, help="output root (default: here)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from plenodecode.synthetic import simulate, write_simulation

    for folder, (preset, seed) in SAMPLES.items():
        sim = simulate(preset, seed=seed)
        paths = write_simulation(sim, args.out / folder, name="scene", overwrite=args.overwrite, lightfield=False)
        for key, path in paths.items():
            print(f"{folder:11s} {key:11s} {path.name:18s} {path.stat().st_size:>10,d} B")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
