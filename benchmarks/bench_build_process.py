"""The default build as a whole process, old and new code alternating, against the numpy+scipy import floor.

    python benchmarks/bench_build_process.py [--old OLD_SEATKIT] [--pairs 8] [--template chair] [-- extra build flags]
    python benchmarks/bench_build_process.py --old seatkit --old-env SEATKIT_HELPERS=on --new-env SEATKIT_HELPERS=off

Each round runs, each in a fresh process as a user runs it:

- the *floor*: ``python -c "import numpy, scipy.spatial"`` with the same
  interpreter (numpy and the part of scipy every build uses: KD-trees,
  which import scipy.sparse and scipy.linalg) — what no build can go under;
- ``NEW_SEATKIT build -q --template chair`` (default: the ``seatkit`` on
  ``PATH``) and, with ``--old``, ``OLD_SEATKIT build ...`` (the ``seatkit``
  command of another install, e.g. a ``git worktree`` of the previous
  revision with its own venv), the order of the two swapped every round so
  that a load that comes and goes falls on both alike.

``--old-env``/``--new-env KEY=VALUE`` (repeatable) set environment
variables for one side only: the same install with and without helper
processes (``SEATKIT_HELPERS``, :func:`seatkit.workers.helpers_pay`).

Wall time is from the start of the command to its end (what a user waits
for). CPU time is user + system of the command *and every process it
started*, helpers included: this script makes itself the child subreaper
(Linux ``prctl``), so a helper process that outlives the command (a fork
server ending after it) is reaped and counted here too. *Main CPU* is the
command's own process alone (its ``/proc/PID/stat`` once it has ended: not
the helpers it forked and reaped itself): with helper processes, the work left on the build's critical path, which on a quiet machine is most
of its wall time, and which other jobs on a shared machine inflate less
than the wall time. Printed: the medians, and per round the ratios new/old
and new/floor (wall, CPU and main CPU), with their medians; the load
average before and after.

Every command runs with Python's bytecode cache on (``PYTHONDONTWRITEBYTECODE``
removed from the environment) and once before the timed rounds, as an
installed seatkit runs (``pip install`` compiles the bytecode).
"""

from __future__ import annotations

import argparse
import ctypes
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

FLOOR = "import numpy, scipy.spatial"
_PR_SET_CHILD_SUBREAPER = 36


def _become_subreaper() -> bool:
    """Orphaned descendants of our commands are re-parented to this process (Linux), so their CPU is counted."""
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _reap() -> None:
    """Wait for every descendant still running (helpers that outlive their command)."""
    while True:
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return


def _own_cpu_at_exit(pid: int) -> float | None:
    """CPU time (user + system, s) of process ``pid`` alone, read once it has ended and before it is reaped.

    Not the rusage that ``wait4`` returns: that includes the children the
    process reaped itself (helper workers forked by the build). Linux
    ``/proc/PID/stat`` of the zombie (``waitid`` with ``WNOWAIT``), fields
    utime and stime; None where that cannot be read.
    """
    try:
        os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT)
        with open(f"/proc/{pid}/stat", "rb") as fh:
            text = fh.read()
    except (OSError, AttributeError):
        return None
    fields = text[text.rindex(b")") + 2 :].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(cmd: list[str], env: dict) -> tuple[float, float, float]:
    """(wall, CPU of the command and all it started, CPU of the command's own process) of one command, s.

    The wall time ends when the command's output pipes close, as for a
    caller that captures its output (a helper process that still holds them
    counts).
    """
    cpu0 = _children_cpu()
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    out: dict[str, bytes] = {}
    readers = [threading.Thread(target=lambda k=k, f=f: out.__setitem__(k, f.read())) for k, f in (("out", proc.stdout), ("err", proc.stderr))]
    for r in readers:
        r.start()
    own = _own_cpu_at_exit(proc.pid)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if own is None:  # no /proc: the rusage of the command, with the children it reaped itself
        own = usage.ru_utime + usage.ru_stime
    for r in readers:
        r.join()
    wall = time.perf_counter() - start
    proc.stdout.close()
    proc.stderr.close()
    _reap()
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)}: failed: {out.get('err', b'').decode(errors='replace').strip()[-2000:]}")
    return wall, _children_cpu() - cpu0, own


def _python_of(seatkit: str) -> str:
    """The interpreter beside a ``seatkit`` script (its venv's python), else this one."""
    exe = Path(seatkit).parent / "python"
    return str(exe) if exe.exists() else sys.executable


def _pairs(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key:
            sys.exit(f"expected KEY=VALUE, got {item!r}")
        out[key] = value
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", help="the seatkit command of the previous code (omit: new and floor only)")
    ap.add_argument("--new", default=shutil.which("seatkit"), help="the seatkit command of the code measured (default: seatkit on PATH)")
    ap.add_argument("--pairs", type=int, default=8, help="rounds (default 8)")
    ap.add_argument("--template", default="chair")
    ap.add_argument("--old-env", action="append", default=[], metavar="KEY=VALUE", help="an environment variable for the old side only")
    ap.add_argument("--new-env", action="append", default=[], metavar="KEY=VALUE", help="an environment variable for the new side only")
    ap.add_argument("extra", nargs="*", help="more flags for seatkit build")
    args = ap.parse_args()
    if not args.new:
        sys.exit("seatkit is not installed (pip install .)")
    counted = _become_subreaper()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    envs = {"floor": env, "new": {**env, **_pairs(args.new_env)}, "old": {**env, **_pairs(args.old_env)}}
    sides = {"new": args.new, **({"old": args.old} if args.old else {})}
    results: dict[str, list[tuple[float, float, float]]] = {k: [] for k in ("floor", *sides)}
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"CPU of helpers {'counted' if counted else 'NOT counted (no prctl)'}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:

        def build(side: str, i: int) -> list[str]:
            out = Path(tmp) / f"{side}{i}"
            return [sides[side], "build", "-q", "--template", args.template, "--out", str(out), "--overwrite", *args.extra]

        floor = [_python_of(args.new), "-c", FLOOR]
        for side in sides:  # bytecode written, disk caches warm
            run(build(side, -1), envs[side])
        run(floor, env)
        for i in range(args.pairs):
            order = [s for s in ("old", "new") if s in sides]
            if i % 2:
                order.reverse()
            results["floor"].append(run(floor, env))
            for side in order:
                results[side].append(run(build(side, i), envs[side]))
            cells = "  ".join(f"{k} {w:.2f} s wall {c:.2f} s CPU {m:.2f} s main" for k, v in results.items() for w, c, m in v[-1:])
            print(f"round {i + 1}: {cells}", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'':8} {'wall median':>12} {'CPU median':>11} {'main CPU median':>16}   ({args.pairs} rounds; floor: python -c {FLOOR!r})")
    for k, v in results.items():
        print(f"{k:8} {statistics.median(x[0] for x in v):10.2f} s {statistics.median(x[1] for x in v):9.2f} s {statistics.median(x[2] for x in v):14.2f} s")

    def ratios(a: str, b: str, j: int) -> list[float]:
        return [x[j] / y[j] for x, y in zip(results[a], results[b])]

    pairs = [("new", "floor")] + ([("old", "floor"), ("new", "old")] if args.old else [])
    for a, b in pairs:
        for j, what in enumerate(("wall", "CPU", "main CPU")):
            r = ratios(a, b, j)
            print(f"{a}/{b} {what:4} per round: median {statistics.median(r):.2f}x  ({', '.join(f'{x:.2f}' for x in r)})")


if __name__ == "__main__":
    main()
