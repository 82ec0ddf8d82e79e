"""Bench build time against the number of people (the goal: at most linear growth).

1 person is the chair (the bench template needs 2 to 6); 2 to 6 people use
the bench with library poses cycling through supportable sitting poses and
the two default bodies alternating. The full pipeline runs (refiners,
evaluation with the baseline), nothing is written.

    python benchmarks/bench_bench.py [--repeat 3] [--max-people 6]
"""

from __future__ import annotations

import argparse
import statistics
import time

from seatkit.pipeline import build
from seatkit.plugins import get_plugin_manager

POSES = ["upright-sitting", "reclined-sitting"]
BODIES = ["default-male", "default-female"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--max-people", type=int, default=6)
    args = ap.parse_args()
    pm = get_plugin_manager()
    build({"template": "chair"}, pm=pm, write=False)  # warm imports and caches
    rows = []
    for n in range(1, args.max_people + 1):
        people = [{"model": BODIES[i % 2], "pose": POSES[i % len(POSES)]} for i in range(n)]
        recipe = {"template": "chair" if n == 1 else "bench", "bodies": people}
        times, stages = [], None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            result = build(recipe, pm=pm, write=False)
            times.append(time.perf_counter() - t0)
            stages = result.timings
        med = statistics.median(times)
        rows.append((n, med))
        top = sorted(((v, k) for k, v in stages.items() if not k.endswith("(parallel)")), reverse=True)[:3]
        print(f"{n} people: {med:.2f} s  ({med / n:.2f} s per person; largest stages: " + ", ".join(f"{k} {v:.2f}" for v, k in top) + ")")
    base = rows[0][1]
    print("growth relative to 1 person: " + ", ".join(f"{n}: x{t / base:.1f}" for n, t in rows))


if __name__ == "__main__":
    main()
