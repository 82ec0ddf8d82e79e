"""Benchmark: load and pose the default bodies (linear blend skinning).

Run: ``python benchmarks/bench_posing.py``. Prints the median and best wall
time of each step over many repetitions; the target is under 20 ms to pose
the default body.
"""

from __future__ import annotations

import statistics
import time

from seatkit.body import load_pose, load_rig, pose_rig


def timeit(fn, repeat: int) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times)


def main() -> None:
    rows = []
    for body in ("default-male", "default-female"):
        rows.append((f"load_rig({body!r})", *timeit(lambda: load_rig(body), 20)))
    rig = load_rig("default-male")
    rows.append(("load_pose('crossed-legs-knees') (base chain)", *timeit(lambda: load_pose("crossed-legs-knees"), 50)))
    for name in ("upright-sitting", "lounger"):
        pose = load_pose(name)
        rows.append((f"pose_rig(default-male, {name}) [{len(rig.vertices)} vertices]", *timeit(lambda: pose_rig(rig, pose), 200)))
    width = max(len(r[0]) for r in rows)
    print(f"{'step':<{width}}  median ms  best ms")
    for name, median, best in rows:
        print(f"{name:<{width}}  {median * 1e3:9.2f}  {best * 1e3:7.2f}")


if __name__ == "__main__":
    main()
