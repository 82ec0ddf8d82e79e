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
The template preview the page asks for while the design runs (the posed
bodies, the template's cage and its limit surface, as JSON) is made once
more after each design, to time it alone.

With --side-thread the side thread runs as `seatkit serve` runs it
(seatkit.side: work that needs no answer yet goes to the second core), and
each move's wall time and the CPU time of the thread the design runs in
(its critical path: what the side thread takes off it does not count) are
printed as well; on a busy machine that CPU time still compares where the
wall time does not.

    python benchmarks/bench_serve_parts.py [--moves 8] [--side-thread]
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
    ap.add_argument("--side-thread", action="store_true", help="run the side thread as seatkit serve does; print each move's wall time and its design thread's CPU time")
    args = ap.parse_args()
    if args.side_thread:
        from seatkit.side import use_side_thread

        use_side_thread(True)
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
        wall, own = time.perf_counter(), time.thread_time()
        try:
            design = d.design(checked, seq, f"bench-{seq}", evaluate=False)
        finally:
            d._check = original
        t_design = cpu()
        wall, own = time.perf_counter() - wall, time.thread_time() - own
        answer = d.report(design)
        answer["view"] = d.view(design)
        t_answer = cpu()
        JSONResponse(answer)
        t_json = cpu()
        JSONResponse(d.preview(f"bench-{seq}"))  # the page's second preview, as it would have asked for it during the design
        t_preview = cpu()
        if not record:
            return
        parts["server: make_pose"].append(t_pose - t)
        parts["server: prepare (recipe checks)"].append(t_prepare - t_pose)
        parts["server: report + view"].append(t_answer - t_design)
        parts["server: JSON"].append(t_json - t_answer)
        parts["server: template preview + JSON"].append(t_preview - t_json)
        parts["design (all stages)"].append(t_design - t_prepare)
        stages = [(s, c) for s, c in marks if s not in ("done",)] + [("end", t_design)]
        for (stage, c0), (_, c1) in zip(stages, stages[1:]):
            parts[f"  stage {stage}"].append(c1 - c0)
        parts["a move in all"].append(t_json - t)
        if args.side_thread:
            parts["design: wall time"].append(wall)
            parts["design: CPU time of its own thread"].append(own)

    move(7, 3.0, record=False)  # warm: the rig, the operators of the chair's cage
    move(7, -1.0, record=False)
    for i in range(args.moves):
        k, deg = MOVES[i % len(MOVES)]
        move(k, deg + 0.25, record=True)  # never back to a pose made before: no design from memory
    side = "with the side thread" if args.side_thread else "without the side thread"
    print(f"load average: {' '.join(f'{x:.1f}' for x in os.getloadavg())} (2 cores); {args.moves} moves {side}; CPU time per move (every thread's unless said), median (min-max):")
    for name, values in parts.items():
        print(f"  {name:<34} {statistics.median(values) * 1000:8.1f} ms  ({min(values) * 1000:.1f}-{max(values) * 1000:.1f})")


if __name__ == "__main__":
    main()
