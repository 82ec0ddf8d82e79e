"""The structural analysis of the default chair (issue 19): time, memory and convergence.

Builds the default chair once (nothing written), then times
:func:`seatkit.structure.analyse` on it: the first call (scikit-fem's import
and first use included) and the median of repeated calls, with the peak
memory the analysis allocates (tracemalloc: numpy's arrays are counted).
Target: at most 2 s at the default resolution. Wall and CPU time are both
printed: on a shared machine the CPU time (this process's) is the steadier
figure.

``--convergence`` also analyses the chair at finer meshes (level 2, two
layers) and prints how the figures move: the table in docs/structure.md.

    python benchmarks/bench_structure.py [--repeat 5] [--material petg --thickness 0.003] [--level 1] [--convergence]
"""

from __future__ import annotations

import argparse
import statistics
import time
import tracemalloc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--material", default="birch-plywood")
    ap.add_argument("--thickness", type=float, default=0.02)
    ap.add_argument("--template", default="chair")
    ap.add_argument("--level", type=int, default=None, help="mesh level (default: the analysis' default, 2)")
    ap.add_argument("--convergence", action="store_true")
    args = ap.parse_args()

    from threadpoolctl import threadpool_limits

    from seatkit.pipeline import build
    from seatkit.recipe import apply_overrides, load_recipe

    recipe = apply_overrides(load_recipe(None)[0], template=args.template, baseline="")
    result = build(recipe, write=False)
    people = result.extra["contact_pressures"]

    from seatkit.structure import analyse  # scikit-fem is imported here, on first use

    def run(**kw):
        if args.level is not None:
            kw.setdefault("level", args.level)
        return analyse(result.control_mesh, result.bodies, people, material=args.material, thickness=args.thickness, **kw)

    with threadpool_limits(limits=1):
        t0, c0 = time.perf_counter(), time.process_time()
        first = run()
        cold, cold_cpu = time.perf_counter() - t0, time.process_time() - c0
        warm, cpu = [], []
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            run()
            warm.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        tracemalloc.start()
        run()
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    s = first.summary
    m = s["mesh"]
    print(f"{args.template}, {args.material} {args.thickness * 1000:g} mm: level {m['level']}, {m['layers']} layer(s), "
          f"{m['elements']} elements, {m['nodes']} nodes, {m['dofs']} dofs")
    print(f"  first call (imports included) {cold:.2f} s wall, {cold_cpu:.2f} s CPU; then median {statistics.median(warm):.2f} s wall "
          f"(min {min(warm):.2f}, max {max(warm):.2f}, {args.repeat} runs), {statistics.median(cpu):.2f} s CPU")
    print(f"  peak memory allocated by one analysis: {peak / 2**20:.0f} MiB")
    print(f"  max von Mises {s['max_von_mises_pa'] / 1e6:.3f} MPa, safety factor {s['safety_factor']:.1f}, "
          f"max deflection {s['max_deflection_m'] * 1000:.3f} mm")
    if args.convergence:
        print("  level layers  elements    dofs   max deflection   max von Mises   away from floor   seconds")
        with threadpool_limits(limits=1):
            for level, layers in ((1, 1), (1, 2), (2, 1), (2, 2)):
                t0 = time.perf_counter()
                r = run(level=level, layers=layers).summary
                print(f"  {level:5d} {layers:6d} {r['mesh']['elements']:9d} {r['mesh']['dofs']:7d} "
                      f"{r['max_deflection_m'] * 1000:13.4f} mm {r['max_von_mises_pa'] / 1e6:11.4f} MPa "
                      f"{r['max_von_mises_away_from_floor_pa'] / 1e6:11.4f} MPa {time.perf_counter() - t0:9.2f}")


if __name__ == "__main__":
    main()
