"""``python -m bench.depth`` (``make bench-depth``): accuracy and runtime of every depth method.

Scenes:

* ``hci-antinous``: the HCI 4D benchmark scene in ../shared/data (skipped when absent), 9 x 9 x 512 x 512;
* ``illum-mini GT``: the synthetic generator's ideal light field of its default scene (15 x 15 views);
* ``illum-mini decoded``: the same scene's raw decoded by the pipeline (demosaicing, resampling, noise,
  dark border views), against the generator's disparity.

Metrics as the benchmark toolkit: BadPix0.07 and BadPix0.03 (% of pixels off by more than t), MSE x 100,
a 15 px border excluded (5 px on the 87 x 125 px synthetic scenes).  Runtime is one wall-clock run on this
machine (the load average is printed: other processes slow it down) and the process CPU time (both cores
count, so on an idle 2-core machine wall time is about CPU time / 1.5 .. 2).

``python -m bench.depth --quick`` runs every method on the illum-mini ground-truth light field only (seconds).
What each step of the pipeline bought when it was introduced is tabled in the README's depth section.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path


from . import Figure

ROOT = Path(__file__).resolve().parents[1]
ANTINOUS = ROOT.parent / "shared" / "data" / "hci-antinous"

#: Targets of issue 6 on hci-antinous: method -> (BadPix0.07 %, MSE x100, seconds)
TARGETS = {"costvolume": (5.0, 1.0, 60.0), "fast": (15.0, None, 5.0)}


def _scenes(quick: bool = False):
    """(name, lightfield, ground truth, border) for every available scene; ``quick``: the small generated
    scene's ideal light field only."""
    from plenodecode.decoding import decode
    from plenodecode.synthetic import simulate

    sim = simulate("illum-mini", seed=1)
    ideal = ("illum-mini GT", sim.ground_truth_lightfield(), sim.disparity, 5)
    if quick:
        return [ideal]
    out = []
    if ANTINOUS.exists():
        from plenodecode.io.hci import read_hci

        s = read_hci(ANTINOUS)
        out.append(("hci-antinous", s.lightfield, s.disparity, 15))
    else:
        print(f"# {ANTINOUS} not found: HCI rows skipped", file=sys.stderr)
    out.append(ideal)
    lf = decode(sim.raw, sim.grid, white=sim.white)
    lf = lf.replace(metadata={**lf.metadata, "disparity_range": list(sim.disparity_range)})
    out.append(("illum-mini decoded", lf, sim.disparity, 5))
    return out


def measure_all(quick: bool = False) -> list[dict]:
    """Run every method on every scene (``quick``: on the small generated scene only); a list of result rows."""
    from plenodecode.depth import DEPTH_METHODS, estimate_depth
    from plenodecode.depth.scores import badpix, mse100

    rows = []
    for name, lf, gt, border in _scenes(quick):
        for method in DEPTH_METHODS:
            estimate_depth(lf, method=method) if name != "hci-antinous" else None   # warm caches / numba
            t0, c0 = time.perf_counter(), time.process_time()
            dm = estimate_depth(lf, method=method)
            sec, cpu = time.perf_counter() - t0, time.process_time() - c0
            rows.append({
                "scene": name, "method": method, "seconds": sec, "cpu": cpu,
                "bp07": badpix(dm, gt, 0.07, border), "bp03": badpix(dm, gt, 0.03, border),
                "mse100": mse100(dm, gt, border), "views": dm.params.get("views_used"),
                "labels": dm.params.get("n_labels"),
            })
            print(f"# {name:20s} {method:11s} {sec:6.1f} s", file=sys.stderr, flush=True)
    return rows


def print_rows(rows: list[dict]) -> None:
    """The table: metrics, runtime and the issue's targets beside them."""
    head = (f"{'scene':20s} {'method':11s} {'BadPix.07':>9s} {'target':>7s} {'BadPix.03':>9s} {'MSEx100':>8s} "
            f"{'target':>7s} {'seconds':>8s} {'target':>7s} {'cpu s':>6s} {'views':>5s}  status")
    print(head)
    print("-" * len(head))
    for r in rows:
        tb = tm = ts = None
        if r["scene"] == "hci-antinous":
            tb, tm, ts = TARGETS.get(r["method"], (None, None, None))
        fails = []
        if tb is not None and r["bp07"] > tb:
            fails.append("BadPix")
        if tm is not None and r["mse100"] > tm:
            fails.append("MSE")
        if ts is not None and r["seconds"] > ts:
            fails.append("time")
        status = "" if tb is None else ("ok" if not fails else "MISSED " + ",".join(fails))
        fmt = lambda v, f: "" if v is None else format(v, f)  # noqa: E731
        print(f"{r['scene']:20s} {r['method']:11s} {r['bp07']:9.2f} {fmt(tb, '7.1f'):>7s} {r['bp03']:9.2f} "
              f"{r['mse100']:8.3f} {fmt(tm, '7.1f'):>7s} {r['seconds']:8.2f} {fmt(ts, '7.0f'):>7s} "
              f"{r['cpu']:6.1f} {r['views'] or '':>5}  {status}")


def run() -> list[Figure]:
    """Runtime figures for the common ``make bench`` table."""
    figs = []
    for r in measure_all():
        target = TARGETS.get(r["method"], (None, None, None))[2] if r["scene"] == "hci-antinous" else None
        figs.append(Figure(name=f"depth {r['method']} {r['scene']}", seconds=r["seconds"], target_s=target,
                           note=f"BadPix0.07 {r['bp07']:.1f}% MSEx100 {r['mse100']:.2f}"))
    return figs


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    if set(args) - {"--quick"}:
        raise SystemExit(f"usage: python -m bench.depth [--quick]; got {' '.join(args)}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"# depth benchmark on {os.cpu_count()} cores, load average {load:.1f} at start", file=sys.stderr)
    rows = measure_all(quick="--quick" in args)
    print_rows(rows)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"(load average {load:.1f} at the end; runtimes grow with other processes on the machine)")


if __name__ == "__main__":
    main()
