"""Benchmark: load and pose the default bodies (linear blend skinning).

Run: ``python benchmarks/bench_posing.py``. Prints the median and best wall
time of each step over many repetitions; the target is under 20 ms to pose
the default body and under 50 ms to make a parametric body of given
parameters (``load_rig`` of a default body and the presets go through the
parametric model; ``load_rig_file`` reads the shipped mesh alone).
"""

from __future__ import annotations

import statistics
import time

from seatkit.body import load_pose, load_rig, pose_rig
from seatkit.body.parametric import make_parametric_body
from seatkit.body.presets import make_preset
from seatkit.body.rig import default_body_path, load_rig_file


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
        rows.append((f"load_rig_file({body!r}.npz) (the shipped mesh)", *timeit(lambda: load_rig_file(default_body_path(body)), 20)))
        rows.append((f"load_rig({body!r}) (parametric model, default mass)", *timeit(lambda: load_rig(body), 20)))
    make_preset("p5-female")  # the models are read once per process
    make_preset("p5-male")
    for preset in ("p5-female", "p95-male"):
        rows.append((f"make_preset({preset!r})", *timeit(lambda: make_preset(preset), 20)))
    rows.append(
        (
            "make_parametric_body(female, 1.55 m, 50 kg)",
            *timeit(lambda: make_parametric_body("female", stature=1.55, mass=50.0), 20),
        )
    )
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
