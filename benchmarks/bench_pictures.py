"""Time the pictures of a body and of a cage: ``render_body`` and ``render_cage``.

Run:  python benchmarks/bench_pictures.py [--repeat 5] [--out DIR]

The default male body in upright-sitting (13,348 vertices, 26,692
triangles), drawn front and side with its skeleton as ``seatkit body --png``
draws it, and the default chair's cage over it (front, side,
three-quarter) as ``benchmarks/bench_template.py --images`` draws it.
Prints the median and the fastest wall time of each over ``--repeat`` runs.
It uses the public functions only, so the same file times an older
checkout (docs/performance.md, "The stages alone").
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None, help="folder for body.png and cage.png (default a temporary one)")
    args = ap.parse_args()

    from seatkit.body import load_pose, load_rig, pose_rig
    from seatkit.body.render import render_body
    from seatkit.pressure.qp import solve_pressure
    from seatkit.resources import template_path
    from seatkit.template import load_template
    from seatkit.template.render import render_cage

    body = pose_rig(load_rig("default-male"), load_pose("upright-sitting"))
    mesh = load_template(template_path("chair.yaml")).fit([body], [solve_pressure(body)], seed=0)
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-pictures-"))
    out.mkdir(parents=True, exist_ok=True)
    jobs = {
        "render_body (front, side, skeleton)": lambda: render_body(body, out / "body.png", views=("front", "side"), title=body.name, show_skeleton=True),
        "render_cage (front, side, three-quarter)": lambda: render_cage(mesh, [body], out / "cage.png", title="chair: upright-sitting"),
    }
    for name, job in jobs.items():
        job()  # warm: imports, caches
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            job()
            times.append(time.perf_counter() - t0)
        print(f"{name}: median {statistics.median(times):.3f} s, fastest {min(times):.3f} s over {args.repeat} runs")
    print(f"pictures in {out}")


if __name__ == "__main__":
    main()
