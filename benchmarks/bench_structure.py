"""The structural analysis of the default chair: time, memory and convergence.

Builds the default chair once (nothing written), then times
:func:`seatkit.structure.analyse` on it: the first call (scikit-fem's import
and first use included) and the median of repeated calls, with the peak
memory the analysis allocates (tracemalloc: numpy's arrays are counted).
Target: at most 2 s at the default resolution. Wall and CPU time are both
printed: on a shared machine the CPU time (this process's) is the steadier
figure.

``--convergence`` also analyses the chair at levels 1-3 (and two layers at
levels 1 and 2) and prints how the figures move, with the CPU time and the
process' peak resident memory so far: the table in docs/structure.md.

``--against REV`` times the FEM module (seatkit/structure/fem.py) of a git
revision side by side with the working tree's, alternating the two in each
round (on a shared machine the load drifts: alternating keeps the
comparison fair), and prints how far their figures differ. A side whose
solve is refused (seatkit.errors.StructureError) is timed all the same, and
said so.

``--solver`` picks the factorisation (seatkit.structure.solvers.SOLVER):
``auto`` (CHOLMOD through cvxopt where installed, else SuperLU),
``cholmod`` or ``superlu``.

    python benchmarks/bench_structure.py [--repeat 5] [--material petg --thickness 0.003] [--level 1] [--solver auto]
        [--template chair] [--pose P ...] [--convergence] [--against REV]
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
    ap.add_argument("--pose", action="append", help="library pose (repeat for several people; default: the template's)")
    ap.add_argument("--level", type=int, default=None, help="mesh level (default: the analysis' default, 2)")
    ap.add_argument("--convergence", action="store_true")
    ap.add_argument("--against", metavar="REV", help="also time seatkit/structure/fem.py of this git revision, alternating")
    ap.add_argument("--solver", choices=("auto", "cholmod", "superlu"), default="auto")
    args = ap.parse_args()

    from seatkit.structure import solvers

    solvers.SOLVER = args.solver

    from threadpoolctl import threadpool_limits

    from seatkit.pipeline import build
    from seatkit.recipe import apply_overrides, load_recipe

    recipe = apply_overrides(load_recipe(None)[0], template=args.template, poses=args.pose, baseline="")
    result = build(recipe, write=False)
    people = result.contact_pressures

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
          f"{m['elements']} elements, {m['nodes']} nodes, {m['dofs']} dofs; factorisation {solvers.factorise_name()}")
    print(f"  first call (imports included) {cold:.2f} s wall, {cold_cpu:.2f} s CPU; then median {statistics.median(warm):.2f} s wall "
          f"(min {min(warm):.2f}, max {max(warm):.2f}, {args.repeat} runs), {statistics.median(cpu):.2f} s CPU")
    print(f"  peak memory allocated by one analysis: {peak / 2**20:.0f} MiB")
    print(f"  max von Mises {s['max_von_mises_pa'] / 1e6:.3f} MPa, safety factor {s['safety_factor']:.1f}, "
          f"max deflection {s['max_deflection_m'] * 1000:.3f} mm")
    if args.against:
        _against(args.against, run, args.repeat)
    if args.convergence:
        import resource

        print("  level layers  elements    dofs   max deflection   max von Mises   away from floor   CPU s  wall s  peak RSS so far")
        with threadpool_limits(limits=1):
            for level, layers in ((1, 1), (1, 2), (2, 1), (2, 2), (3, 1)):
                t0, c0 = time.perf_counter(), time.process_time()
                r = run(level=level, layers=layers).summary
                rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB -> GiB
                print(f"  {level:5d} {layers:6d} {r['mesh']['elements']:9d} {r['mesh']['dofs']:7d} "
                      f"{r['max_deflection_m'] * 1000:13.4f} mm {r['max_von_mises_pa'] / 1e6:11.4f} MPa "
                      f"{r['max_von_mises_away_from_floor_pa'] / 1e6:11.4f} MPa {time.process_time() - c0:7.1f} "
                      f"{time.perf_counter() - t0:7.1f} {rss:6.2f} GiB  ({r['distorted_elements']} distorted)", flush=True)


def _against(rev: str, run, repeat: int) -> None:
    """Old (``rev``'s fem.py) and new analyses alternating: CPU and wall medians, largest figure difference."""
    import importlib.util
    import os
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    import numpy as np
    from threadpoolctl import threadpool_limits

    import seatkit.structure.analysis as analysis
    from seatkit.structure import fem

    root = Path(__file__).resolve().parent.parent
    source = subprocess.run(["git", "show", f"{rev}:seatkit/structure/fem.py"], cwd=root, capture_output=True, text=True, check=True).stdout
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fem_reference.py"
        path.write_text(source)
        spec = importlib.util.spec_from_file_location("fem_reference", path)
        old = importlib.util.module_from_spec(spec)
        sys.modules["fem_reference"] = old
        spec.loader.exec_module(old)
    if not hasattr(old.Elasticity, "det"):  # before 052f275 the analysis read the Jacobian from scikit-fem's basis
        old.Elasticity.det = property(lambda self: self.basis.mapping.detDF(self.basis.X))
    if "solver" not in old.Solution.__dataclass_fields__:  # before the factorisation was named in structure.json
        old.Solution.solver = "SuperLU (scipy)"
    models = {rev: old.Elasticity, "working tree": fem.Elasticity}
    times = {k: [] for k in models}
    out, loads = {}, []
    from seatkit.errors import StructureError

    try:
        with threadpool_limits(limits=1):
            for r in range(repeat + 1):  # round 0 warms both up
                for name in models if r % 2 == 0 else list(models)[::-1]:
                    analysis.Elasticity = models[name]
                    t0, c0 = time.perf_counter(), time.process_time()
                    try:
                        out[name] = run()
                    except StructureError as e:
                        out[name] = e
                    if r:
                        times[name].append((time.process_time() - c0, time.perf_counter() - t0))
                loads.append(os.getloadavg()[0])
    finally:
        analysis.Elasticity = fem.Elasticity
    print(f"  against {rev}, {repeat} alternating rounds, 1-minute load average {min(loads):.1f}-{max(loads):.1f}:")
    for name, v in times.items():
        cpu, wall = np.array(v).T
        print(f"    {name:>14}: median {np.median(cpu):.2f} s CPU (min {cpu.min():.2f}, max {cpu.max():.2f}), "
              f"{np.median(wall):.2f} s wall (min {wall.min():.2f}, max {wall.max():.2f})")
    for name, result in out.items():
        if isinstance(result, Exception):
            print(f"    {name} refused the solve: {result}")
    a, b = out[rev], out["working tree"]
    if isinstance(a, Exception) or isinstance(b, Exception):
        return
    keys = ("max_von_mises_pa", "safety_factor", "max_deflection_m", "applied_load_n", "floor_reaction_n", "mass_kg")
    figures = max(abs(a.summary[k] - b.summary[k]) / abs(a.summary[k]) for k in keys)
    field = np.abs(a.solution.displacement - b.solution.displacement).max() / np.abs(a.solution.displacement).max()
    print(f"    largest relative difference: figures {figures:.1e}, displacement field {field:.1e}")


if __name__ == "__main__":
    main()
