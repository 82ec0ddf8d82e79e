"""The slowest builds of a drawn-pose benchmark run against its median, each timed again, best of several.

    python benchmarks/retime_builds.py gen.jsonl [--slowest 6] [--middle 6] [--rounds 3] [--against PYTHON]

One build's CPU time in ``bench_generalisation.py`` varies by up to 40 %
from run to run on a shared 2-core machine, and the slowest of 398 builds
is the one most likely to have been slowed by its neighbour: the ratio of
the slowest build to the median moves by 0.2-0.4 between two runs of the
same code and the same designs. This script reads the results
(``--results`` of ``bench_generalisation.py``, drawn poses), takes the
``--slowest`` builds and the ``--middle`` builds nearest the median CPU,
and builds each again ``--rounds`` times, every build in a fresh process
(after one untimed build of another pose on the same body, so the shared
operators are made as in the benchmark's workers), the cases in turn,
one at a time. Both groups are timed the same way, so their ratio is the
slowest build against a typical one without the neighbour's noise: the
best (smallest) CPU time of each build's rounds, then the slowest of the
slow group against the median of the middle group.

It prints one line per build (the CPU time of each round, and the best)
and the ratio. ``--against`` names the Python of another version of
seatkit (say a venv of the code before a change): every build is then run
by both, one after the other in each round, and the ratio and each build's
best CPU are given for both (the same builds, so their ratio per build is
the change's).

    python benchmarks/retime_builds.py --case reclined-169:default-male --case default [--draw-seed 2026] --against PYTHON

times the builds named instead (a drawn pose as FAMILY-INDEX:BODY, drawn
with ``--draw-seed`` and built with seed 0; ``default``: the default
chair), the same way, and prints each one's best CPU time per version and
their ratio.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

#: The untimed build each fresh process runs first (the benchmark's workers have built other poses before).
WARM_UP = ("seated", 0)


def _cases(path: str) -> list[dict]:
    """Every accepted, built drawn-pose case of a results file: pose, family, index, draw seed, body, CPU."""
    cases = []
    for line in Path(path).read_text().splitlines():
        row = json.loads(line)
        if row.get("kind") != "case":
            continue
        result, build = row["result"], row["result"].get("build")
        if not build or not build.get("ok") or not build.get("cpu_seconds"):
            continue
        index, family, draw_seed = row["key"].split(":")[:3]
        cases.append({"pose": result["pose"], "family": family, "index": int(index), "draw_seed": int(draw_seed), "body": result["body"], "cpu": float(build["cpu_seconds"]), "seed": int(build["seed"])})
    return cases


def _build_one(family: str, index: int, draw_seed: int, body: str, seed: int) -> float:
    """Build one drawn pose as the benchmark does (no files, one process); its CPU seconds."""
    import tempfile

    import numpy as np
    from threadpoolctl import threadpool_limits

    from seatkit.body.generator import draw_pose, pose_yaml
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager

    threadpool_limits(limits=1)
    pm = get_plugin_manager()
    folder = Path(tempfile.mkdtemp(prefix="retime-"))

    def once(fam, idx):
        if fam == "default":  # the default chair
            recipe = {"template": "chair", "seed": seed}
        else:
            drawn = draw_pose(np.random.default_rng([draw_seed, idx]), fam, f"{fam}-{idx:03d}")
            path = folder / f"{drawn.name}.yaml"
            path.write_text(pose_yaml(drawn))
            recipe = {"template": "chair", "seed": seed, "bodies": [{"model": body, "pose": str(path)}]}
        c0 = time.process_time()
        build(recipe, pm=pm, write=False, processes=False)
        return time.process_time() - c0

    once(*WARM_UP)
    return once(family, index)


def _times(chosen: list[dict], sides: dict[str, str], rounds: int, order: list[int]) -> dict:
    """CPU seconds of each chosen build, per side and round: every build in a fresh process, the versions in turn (the first one alternating by round)."""
    times = {side: {i: [] for i in range(len(chosen))} for side in sides}
    for r in range(rounds):
        for i in order:
            c = chosen[i]
            for side in list(sides)[:: 1 if r % 2 == 0 else -1]:
                cmd = [sides[side], __file__, "--one", c["family"], str(c["index"]), str(c["draw_seed"]), c["body"], str(c["seed"])]
                out = subprocess.run(cmd, capture_output=True, text=True, check=True)
                times[side][i].append(float(out.stdout.strip().splitlines()[-1]))
        print(f"round {r + 1} of {rounds} done", file=sys.stderr)
    return times


def _retime_cases(args) -> None:
    """The builds named by ``--case``, each version's best CPU time and their ratio."""
    chosen = []
    for case in args.case:
        name, _, body = case.partition(":")
        family, _, index = name.rpartition("-") if name != "default" else ("default", "", "0")
        chosen.append({"pose": name, "family": family, "index": int(index), "draw_seed": args.draw_seed, "body": body or "default-male", "seed": 0})
    sides = {"this": sys.executable, **({"other": args.against} if args.against else {})}
    times = _times(chosen, sides, args.rounds, list(range(len(chosen))))
    print(f"{'case':34} " + "  ".join(f"{side + ' best':>10}" for side in sides) + ("  this/other" if args.against else "") + "  rounds")
    for i, c in enumerate(chosen):
        best = {side: min(times[side][i]) for side in sides}
        rounds = "; ".join(side + " " + ", ".join(f"{t:.2f}" for t in times[side][i]) for side in sides)
        ratio = f"  {best['this'] / best['other']:10.2f}" if args.against else ""
        print(f"{c['pose'] + ' ' + (c['body'] if c['family'] != 'default' else ''):34} " + "  ".join(f"{best[side]:9.2f}s" for side in sides) + ratio + f"  ({rounds})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="?", help="a bench_generalisation.py --results file (drawn poses)")
    ap.add_argument("--slowest", type=int, default=6, help="the slowest builds timed again (default 6)")
    ap.add_argument("--middle", type=int, default=6, help="the builds nearest the median timed again (default 6)")
    ap.add_argument("--rounds", type=int, default=3, help="builds of each case (default 3)")
    ap.add_argument("--against", metavar="PYTHON", help="the Python of another version of seatkit, run beside this one")
    ap.add_argument("--case", action="append", default=[], metavar="FAMILY-INDEX:BODY", help="time this build instead (repeatable; 'default': the default chair)")
    ap.add_argument("--draw-seed", type=int, default=2026, help="the draw seed of the --case poses (default 2026)")
    ap.add_argument("--one", nargs=5, metavar=("FAMILY", "INDEX", "DRAW_SEED", "BODY", "SEED"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        family, index, draw_seed, body, seed = args.one
        print(json.dumps(_build_one(family, int(index), int(draw_seed), body, int(seed))))
        return
    if args.case:
        _retime_cases(args)
        return
    if not args.results:
        ap.error("a results file or --case is needed")
    cases = _cases(args.results)
    if len(cases) < args.slowest + args.middle:
        sys.exit(f"{args.results}: {len(cases)} built cases, fewer than --slowest + --middle")
    median = statistics.median(c["cpu"] for c in cases)
    by_cpu = sorted(cases, key=lambda c: -c["cpu"])
    slow = by_cpu[: args.slowest]
    middle = sorted(by_cpu[args.slowest :], key=lambda c: abs(c["cpu"] - median))[: args.middle]
    chosen = [("slow", c) for c in slow] + [("middle", c) for c in middle]
    sides = {"this": sys.executable, **({"other": args.against} if args.against else {})}
    # the groups interleaved, so that a slower stretch of the machine falls on both
    order = [i for pair in zip(range(len(slow)), range(len(slow), len(chosen))) for i in pair]
    order += [i for i in range(len(chosen)) if i not in order]
    times = _times([c for _, c in chosen], sides, args.rounds, order)
    print(f"{len(cases)} built cases in {args.results}; median CPU {median:.2f} s (one run each)")
    print(f"one run each: slowest {by_cpu[0]['cpu']:.2f} s / median {median:.2f} s = {by_cpu[0]['cpu'] / median:.2f}x")
    best = {side: {i: min(t) for i, t in times[side].items()} for side in sides}
    for side in sides:
        print(f"\n{side} ({sides[side]})")
        print(f"{'group':7} {'case':34} {'in the run':>10}  {'best':>6}  rounds")
        for i, (group, c) in enumerate(chosen):
            rounds = ", ".join(f"{t:.2f}" for t in times[side][i])
            print(f"{group:7} {c['pose'] + ' ' + c['body']:34} {c['cpu']:9.2f}s  {best[side][i]:5.2f}s  ({rounds})")
        slowest = max(range(len(slow)), key=lambda i: best[side][i])
        typical = statistics.median(best[side][i] for i in range(len(slow), len(chosen)))
        print(f"best of {args.rounds}: slowest {best[side][slowest]:.2f} s ({chosen[slowest][1]['pose']} {chosen[slowest][1]['body']}) / median of the middle group {typical:.2f} s = {best[side][slowest] / typical:.2f}x")
    if args.against:
        ratios = [best["this"][i] / best["other"][i] for i in range(len(chosen))]
        print("\nthis / other, best against best, per build: " + ", ".join(f"{x:.2f}" for x in ratios) + f"; median {statistics.median(ratios):.2f}x")

if __name__ == "__main__":
    main()
