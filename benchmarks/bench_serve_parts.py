"""Where a slider move's CPU time goes in `seatkit serve`: the design's stages and the server's own work, in one process.

Makes the designer of `seatkit serve` (no HTTP), warms it with two moves,
then makes N slider moves as the page does (each a pose never seen before:
`Designer.make_pose`, `Designer.prepare`, `Designer.design(evaluate=False)`,
the answer `Designer.report` + `Designer.view` and its JSON) and reads the
process's CPU time (every thread's: the side thread's work counts) at the
start of each stage of the design (the pipeline's progress callback). Prints
the median CPU time per move of each stage and of the server's own parts.
The design is the same as over HTTP; what is left out is the HTTP server
itself (a few milliseconds, benchmarks/bench_serve.py measures it all).

    python benchmarks/bench_serve_parts.py [--moves 8]
"""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import tempfile
import time
from collections import defaultdict
from pathlib import Path

#: Joint moves (segment index, degrees added to its X angle), as bench_serve.py makes them.
MOVES = [(5, -10.0), (5, 10.0), (2, -10.0), (2, 10.0), (1, 8.0), (4, 8.0), (1, -8.0), (4, -8.0), (0, -8.0), (0, 8.0), (14, -15.0), (14, 15.0)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=8)
    args = ap.parse_args()
    from starlette.responses import JSONResponse

    from seatkit.serve.designer import Designer

    d = Designer(Path(tempfile.mkdtemp(prefix="bench-serve-parts-")))
    recipe = {"template": "chair", "bodies": [{"model": "default-female", "pose": "reclined-sitting"}]}
    start = d.pose_angles("reclined-sitting")
    angles = [list(r) for r in start["angles"]]
    parts: dict[str, list[float]] = defaultdict(list)

    def move(k: int, degrees: float, record: bool) -> None:
        angles[k][0] += degrees
        cpu = time.process_time
        t = cpu()
        pose = d.make_pose(angles, start["translation"])["pose"]
        t_pose = cpu()
        r = copy.deepcopy(recipe)
        r["bodies"][0]["pose"] = pose
        checked = d.prepare(r)
        t_prepare = cpu()
        marks: list[tuple[str, float]] = []
        seq = d.new_request()
        original = d._check

        def check(s, stage, **kw):
            marks.append((stage, cpu()))
            return original(s, stage, **kw)

        d._check = check
        try:
            design = d.design(checked, seq, evaluate=False)
        finally:
            d._check = original
        t_design = cpu()
        answer = d.report(design)
        answer["view"] = d.view(design)
        t_answer = cpu()
        JSONResponse(answer)
        t_json = cpu()
        if not record:
            return
        parts["server: make_pose"].append(t_pose - t)
        parts["server: prepare (recipe checks)"].append(t_prepare - t_pose)
        parts["server: report + view"].append(t_answer - t_design)
        parts["server: JSON"].append(t_json - t_answer)
        parts["design (all stages)"].append(t_design - t_prepare)
        stages = [(s, c) for s, c in marks if s not in ("done",)] + [("end", t_design)]
        for (stage, c0), (_, c1) in zip(stages, stages[1:]):
            parts[f"  stage {stage}"].append(c1 - c0)
        parts["a move in all"].append(t_json - t)

    move(7, 3.0, record=False)  # warm: the rig, the operators of the chair's cage
    move(7, -1.0, record=False)
    for i in range(args.moves):
        k, deg = MOVES[i % len(MOVES)]
        move(k, deg + 0.25, record=True)  # never back to a pose made before: no design from memory
    print(f"load average: {' '.join(f'{x:.1f}' for x in os.getloadavg())} (2 cores); {args.moves} moves; CPU time per move, median (min-max):")
    for name, values in parts.items():
        print(f"  {name:<34} {statistics.median(values) * 1000:8.1f} ms  ({min(values) * 1000:.1f}-{max(values) * 1000:.1f})")


if __name__ == "__main__":
    main()
