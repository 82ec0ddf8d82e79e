"""The whole default build, as a user runs it: `seatkit build --template chair`.

Wall time of the command in a fresh process (Python start-up and imports
included), repeated; prints the median and each stage's share from the
report. Target: at most 2 s on 2 cores (docs/performance.md).

    python benchmarks/bench_build.py [--repeat 5] [--template chair] [-- extra seatkit build flags]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--template", default="chair")
    ap.add_argument("extra", nargs="*", help="more flags for seatkit build")
    args = ap.parse_args()
    seatkit = shutil.which("seatkit") or sys.exit("seatkit is not installed (pip install .)")
    walls, stages = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeat):
            out = Path(tmp) / f"run{i}"
            t0 = time.perf_counter()
            done = subprocess.run(
                [seatkit, "build", "--template", args.template, "--out", str(out), "--quiet", *args.extra],
                capture_output=True,
                text=True,
            )
            walls.append(time.perf_counter() - t0)
            if done.returncode != 0:
                sys.exit(f"build failed: {done.stderr}")
            stages.append(json.loads((out / "report.json").read_text())["timings_s"])
    print(f"seatkit build --template {args.template} {' '.join(args.extra)}: {args.repeat} runs")
    print(f"  wall time incl. start-up: median {statistics.median(walls):.2f} s, min {min(walls):.2f} s, max {max(walls):.2f} s")
    keys = list(stages[0])
    for k in keys:
        print(f"  {k:<26} {statistics.median(s[k] for s in stages):.3f} s")
    print(f"  {'sum of stages':<26} {statistics.median(sum(s.values()) for s in stages):.3f} s")


if __name__ == "__main__":
    main()
