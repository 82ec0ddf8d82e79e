"""Benchmark of control-mesh generation by the chair template (paper Section 5).

Run:  python benchmarks/bench_template.py [--repeat 7] [--images docs/images/templates] [--template saddle]

Prints, for the default male body in the upright-sitting pose (its pressure
from the QP solver, not timed):

- the first fit in the process and the median and best of ``--repeat``
  further fits (wall time, and the process's CPU time, which a loaded
  machine disturbs far less), each on a fresh copy of the body (the per-body caches of
  edges, k-d tree and normals are rebuilt every time, as in a build),
- the time of each template step (and of the engine's final check) in the
  median run,
- one fit of every other pose of the library (supported ones: time and cage
  size; unsupported ones: the time to refuse),
- whether open3d was imported (it must not be: its import alone is ~1.3 s).

Fits run with BLAS limited to one thread, as ``seatkit.pipeline.build``
does. With ``--images DIR`` it also draws ``DIR/<pose>.png`` (front, side,
three-quarter) for every supported pose.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import sys
import time

from threadpoolctl import threadpool_limits

from seatkit.body import list_poses, load_pose, load_rig, pose_rig
from seatkit.errors import UnsupportedPoseError
from seatkit.pressure.qp import solve_pressure
from seatkit.resources import template_path
from seatkit.template import BUILTIN_STEPS, load_template
from seatkit.template import engine as engine_module


class Timed:
    """A template step that records how long each run takes."""

    def __init__(self, step, log):
        self.name, self.description, self.options = step.name, step.description, step.options
        self.requires, self.stage = step.requires, step.stage
        self._step, self._log = step, log

    def run(self, state, *, options):
        t0 = time.perf_counter()
        self._step.run(state, options=options)
        self._log.append((self.name, time.perf_counter() - t0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--images", default=None, help="folder for <pose>.png pictures of every supported pose")
    parser.add_argument("--template", default="chair", help="a template of templates/ (chair, saddle, ...)")
    args = parser.parse_args()

    print(f"python {platform.python_version()}, {os.cpu_count()} cores, {platform.machine()}")
    rig = load_rig("default-male")
    template = load_template(template_path(f"{args.template}.yaml"))
    body = pose_rig(rig, load_pose("upright-sitting"))
    pressure = solve_pressure(body)
    print(f"body: {len(body.vertices)} vertices, {len(body.faces)} triangles")

    log: list = []
    timed = load_template(template_path(f"{args.template}.yaml"), steps={name: Timed(step, log) for name, step in BUILTIN_STEPS.items()})
    check = engine_module.check_cage

    def timed_check(*a, **k):
        t0 = time.perf_counter()
        check(*a, **k)
        log.append(("final check", time.perf_counter() - t0))

    engine_module.check_cage = timed_check
    with threadpool_limits(limits=1):
        t0 = time.perf_counter()
        mesh = template.fit([dataclasses.replace(body)], [pressure], seed=0)
        first = time.perf_counter() - t0
        runs, cpu = [], []
        for _ in range(args.repeat):
            log.clear()
            fresh = dataclasses.replace(body)
            t0, c0 = time.perf_counter(), time.process_time()
            timed.fit([fresh], [pressure], seed=0)
            runs.append((time.perf_counter() - t0, list(log)))
            cpu.append(time.process_time() - c0)
    engine_module.check_cage = check
    times = sorted(t for t, _ in runs)
    median = statistics.median(times)
    print(f"\nupright-sitting: {len(mesh.vertices)} control points, {len(mesh.faces)} quads")
    print(f"  first fit in the process   {first:.3f} s")
    print(f"  median of {args.repeat} (fresh body) {median:.3f} s   best {times[0]:.3f} s   worst {times[-1]:.3f} s")
    print(f"  CPU time per fit (this process; steady under load) median {statistics.median(cpu):.3f} s   best {min(cpu):.3f} s")
    _, steps = min(runs, key=lambda r: abs(r[0] - median))
    print("  steps of the median run:")
    for name, dt in steps:
        print(f"    {name:<16} {1000 * dt:7.1f} ms")

    print("\nevery pose of the library (one fit each, seed 0):")
    with threadpool_limits(limits=1):
        for info in list_poses():
            b = pose_rig(rig, load_pose(info.name))
            p = solve_pressure(b)
            t0 = time.perf_counter()
            try:
                m = template.fit([b], [p], seed=0)
            except UnsupportedPoseError as e:
                print(f"  {info.name:<22} refused in {time.perf_counter() - t0:.3f} s: {e.parts}")
                continue
            dt = time.perf_counter() - t0
            cases = [c["case"] for c in m.meta["special_cases"] if c["taken"]]
            print(f"  {info.name:<22} {dt:.3f} s  {len(m.faces):4d} quads  special cases: {', '.join(cases) or '-'}")
            if args.images:
                from seatkit.template.render import render_cage

                render_cage(m, [b], os.path.join(args.images, f"{info.name}.png"), title=f"{args.template}: {info.name}", dpi=70)
    print(f"\nopen3d imported: {'open3d' in sys.modules}")


if __name__ == "__main__":
    main()
