"""Where the CPU of one default build goes: its imports and its functions.

    python benchmarks/profile_build.py [--top 25] [--prof build.prof] [-- extra seatkit build flags]

Two runs of ``seatkit build -q --template chair``, each a fresh process, in
one process (``SEATKIT_HELPERS=off``: every import and stage counted in the
process profiled), bytecode cache on:

1. ``python -X importtime``: the modules imported, the top-level ones
   sorted by their cumulative import time (self and children);
2. :mod:`cProfile` with CPU time (``time.process_time``) as its clock, so
   that other jobs on a shared machine do not count: the functions of
   seatkit with the most cumulative CPU (the stages, the exporters) and the
   build's total. The profiler's own overhead inflates Python-heavy code
   (about 1.5-2x); compare shares, not seconds, with the stage times of
   ``report.json``. ``--prof`` keeps the profile for ``python -m pstats``
   or snakeviz.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

_PROFILED = """
import cProfile, sys, time
from seatkit.cli import run
sys.argv = ["seatkit", *{argv!r}]
prof = cProfile.Profile(time.process_time)
start = time.process_time()
prof.enable()
run()
prof.disable()
print(f"CPU of the build (imports of seatkit.cli excluded): {{time.process_time() - start:.2f}} s", file=sys.stderr)
prof.dump_stats({prof!r})
"""


def _imports(argv: list[str], env: dict, top: int) -> None:
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "seatkit.cli", *argv], capture_output=True, text=True, env=env)
    if done.returncode != 0:
        sys.exit(f"build failed: {done.stderr[-2000:]}")
    rows = []
    for line in done.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \| (\s*)(\S+)", line)
        if m and not m.group(3):  # top level: imported by the program, not by another module
            rows.append((int(m.group(2)) / 1e6, m.group(4)))
    rows.sort(reverse=True)
    print(f"imports: {sum(s for s, _ in rows):.2f} s in {len(rows)} top-level modules (python -X importtime; wall, inflated by load)")
    for seconds, name in rows[:top]:
        print(f"  {seconds:7.3f} s  {name}")


def _functions(argv: list[str], env: dict, top: int, prof: str) -> None:
    import pstats

    done = subprocess.run([sys.executable, "-c", _PROFILED.format(argv=argv, prof=prof)], capture_output=True, text=True, env=env)
    print(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "(no output)")
    stats = pstats.Stats(prof)
    rows = [(ct, nc, f"{Path(fn).parent.name}/{Path(fn).name}:{ln}({name})") for (fn, ln, name), (_, nc, _, ct, _) in stats.stats.items() if "seatkit" in fn]
    rows.sort(reverse=True)
    print(f"seatkit functions by cumulative CPU (cProfile, process time; {prof}):")
    for ct, nc, label in rows[:top]:
        print(f"  {ct:7.3f} s  {nc:6d} calls  {label}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--prof", help="keep the cProfile file here (default: a temporary file)")
    ap.add_argument("extra", nargs="*", help="more flags for seatkit build")
    args = ap.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["SEATKIT_HELPERS"] = "off"
    with tempfile.TemporaryDirectory() as tmp:
        argv = ["build", "-q", "--template", "chair", "--out", str(Path(tmp) / "out"), "--overwrite", *args.extra]
        subprocess.run([sys.executable, "-m", "seatkit.cli", *argv], capture_output=True, env=env)  # bytecode written
        _imports(argv, env, args.top)
        _functions(argv, env, args.top, args.prof or str(Path(tmp) / "build.prof"))


if __name__ == "__main__":
    main()
