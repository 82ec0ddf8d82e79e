"""The default build's wall time for two seatkit checkouts, runs interleaved.

    python benchmarks/compare_build_times.py OLD_SEATKIT NEW_SEATKIT [--pairs 6] [-- extra seatkit build flags]

``OLD_SEATKIT`` and ``NEW_SEATKIT`` are the ``seatkit`` commands of the two
installs (e.g. ``/tmp/base/.venv/bin/seatkit``). Each pair runs the old
build, then the new one (the order swapped every other pair), each in a
fresh process as a user runs it (``seatkit build --template chair``,
start-up included), so that a load that comes and goes on a shared machine
falls on both alike. Prints the median wall time of each, the median of the
per-pair differences and the median of each stage (from report.json).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(seatkit: str, out: Path, extra: list[str]) -> tuple[float, dict]:
    start = time.perf_counter()
    done = subprocess.run([seatkit, "build", "--template", "chair", "--out", str(out), "--quiet", *extra], capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"{seatkit}: build failed: {done.stderr}")
    return wall, json.loads((out / "report.json").read_text())["timings_s"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--pairs", type=int, default=6)
    ap.add_argument("extra", nargs="*", help="more flags for seatkit build")
    args = ap.parse_args()
    walls: dict[str, list[float]] = {"old": [], "new": []}
    stages: dict[str, list[dict]] = {"old": [], "new": []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.pairs):
            order = ("old", "new") if i % 2 == 0 else ("new", "old")
            for side in order:
                wall, timings = _run(getattr(args, side), Path(tmp) / f"{side}{i}", args.extra)
                walls[side].append(wall)
                stages[side].append(timings)
                print(f"pair {i + 1} {side}: {wall:.2f} s", flush=True)
    diffs = [n - o for o, n in zip(walls["old"], walls["new"])]
    for side in ("old", "new"):
        w = walls[side]
        print(f"{side}: median {statistics.median(w):.2f} s (min {min(w):.2f}, max {max(w):.2f}) over {len(w)} runs")
    print(f"new - old, per pair: median {statistics.median(diffs):+.2f} s (each: {', '.join(f'{d:+.2f}' for d in diffs)})")
    keys = list(dict.fromkeys(k for side in stages.values() for t in side for k in t))
    print(f"  {'stage':<26} {'old':>8} {'new':>8}")
    for k in keys:
        cells = []
        for side in ("old", "new"):
            values = [t[k] for t in stages[side] if k in t]
            cells.append(f"{statistics.median(values):8.3f}" if values else f"{'-':>8}")
        print(f"  {k:<26} {cells[0]} {cells[1]}")


if __name__ == "__main__":
    main()
