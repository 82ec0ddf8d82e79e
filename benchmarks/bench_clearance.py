"""The clearance step's lift on its real inputs: record every call a build makes, replay them against a previous version.

``--record`` runs the full default build (seed 0, one process) of each drawn
case (``FAMILY-INDEX@BODY``, draw seed 2026, as ``bench_starts.py`` draws
them) with :func:`seatkit.template.clearance.lift_off_bodies` wrapped, and
keeps every call's inputs and result. Without it, this version's lift runs
on every recorded input, in turns with the lift of ``--previous`` (another
version's ``seatkit/template/clearance.py``) call by call when given, and
prints both versions' CPU time per pass (``time.process_time``, BLAS on one
thread) and how many results differ from the recorded ones in any bit
(vertices, moves, rows, rounds, feasibility, deepest sink); it exits 1 when
one does. docs/performance.md, "The chair's cage", gives what it measured:

    python benchmarks/bench_clearance.py calls.pkl --record crossed-legs-050@default-female
    python benchmarks/bench_clearance.py calls.pkl --previous /path/to/previous/seatkit/template/clearance.py
"""

from __future__ import annotations

import argparse
import copy
import importlib.util
import pickle
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def record(path: Path, cases: list[str]) -> None:
    from seatkit.body.generator import draw_case, pose_yaml
    from seatkit.errors import SeatkitError
    from seatkit.pipeline import build
    from seatkit.template import clearance, steps

    calls: list = []
    lift = clearance.lift_off_bodies

    def logged(vertices, quads, bodies, movable, **kw):
        inputs = copy.deepcopy((vertices, quads, list(bodies), movable, kw))
        out = lift(vertices, quads, bodies, movable, **kw)
        calls.append((inputs, copy.deepcopy(out)))  # the caller moves the cage's vertices in place afterwards
        return out

    clearance.lift_off_bodies = steps.lift_off_bodies = logged
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            drawn, body = draw_case(case)
            pose = Path(tmp) / f"{drawn.name}.yaml"
            pose.write_text(pose_yaml(drawn))
            before = len(calls)
            try:
                build({"template": "chair", "seed": 0, "bodies": [{"model": body, "pose": str(pose)}]}, write=False, processes=False)
                note = "built"
            except SeatkitError as e:
                note = f"refused: {str(e)[:80]}"
            print(f"{case}: {note}; {len(calls) - before} lifts", flush=True)
    with open(path, "wb") as f:
        pickle.dump(calls, f)


def _same(a, b) -> bool:
    return (
        np.array_equal(a.vertices, b.vertices)
        and np.array_equal(a.moves, b.moves)
        and (a.rows, a.rounds, a.feasible) == (b.rows, b.rounds, b.feasible)
        and np.float64(a.worst).tobytes() == np.float64(b.worst).tobytes()
    )


def run(path: Path, previous: Path | None, passes: int) -> int:
    from threadpoolctl import threadpool_limits

    from seatkit.template.clearance import lift_off_bodies

    versions = [("this", lift_off_bodies)]
    if previous is not None:
        spec = importlib.util.spec_from_file_location("previous_clearance", previous)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
        versions.append(("previous", module.lift_off_bodies))
    with open(path, "rb") as f:
        calls = pickle.load(f)
    cpu = dict.fromkeys((name for name, _ in versions), 0.0)
    differ = dict.fromkeys(cpu, 0)
    with threadpool_limits(limits=1):
        for (V, Q, bodies, movable, kw), _ in calls:  # the bodies' k-d trees and normals, made once per body
            lift_off_bodies(V, Q, bodies, movable, **kw)
        for p in range(passes):
            for (V, Q, bodies, movable, kw), recorded in calls:
                for name, lift in versions if p % 2 == 0 else versions[::-1]:
                    start = time.process_time()
                    out = lift(V, Q, bodies, movable, **kw)
                    cpu[name] += time.process_time() - start
                    differ[name] += p == 0 and not _same(out, recorded)
    line = ", ".join(f"{name} {cpu[name] / passes:.3f} s CPU a pass, {differ[name]} differ" for name in cpu)
    ratio = f"; this/previous {cpu['this'] / cpu['previous']:.3f}" if previous is not None else ""
    print(f"{len(calls)} recorded lifts, {passes} passes: {line}{ratio}")
    return int(any(differ.values()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("calls", type=Path, help="the recorded lifts (written with --record, else read)")
    ap.add_argument("--record", nargs="+", metavar="CASE", help="build these cases (FAMILY-INDEX@BODY) and keep every lift's inputs and result")
    ap.add_argument("--previous", type=Path, help="another version's seatkit/template/clearance.py, run in turns with this one")
    ap.add_argument("--passes", type=int, default=4, help="passes over the recorded lifts (default 4)")
    args = ap.parse_args()
    if args.record:
        record(args.calls, args.record)
    else:
        sys.exit(run(args.calls, args.previous, args.passes))

if __name__ == "__main__":
    main()
