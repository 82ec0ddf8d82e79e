"""The ``optimize`` refiner in CPU time, optionally side by side with another checkout's, call for call.

    python benchmarks/bench_optimize.py [--repeat 5] [--cases cases.pkl] [--against /path/to/other/checkout]

Runs :func:`seatkit.refine.optimize.optimize_cage` on the chair's cage
(the template's fit with seed 0, the input of ``optimize``) for every
supported library pose on both default bodies, or on the cages of
``--cases`` (a file of ``benchmarks/compare_template.py record``: library
and drawn poses), ``--repeat`` times each, and keeps the least CPU time
(``time.process_time``) per cage. Prints, per cage, the CPU time, the
L-BFGS-B iterations and function evaluations (every penalty round's), and
at the end their medians and totals.

With ``--against``, another checkout's ``seatkit/refine/optimize.py``
(loaded from its file beside the installed seatkit) runs interleaved with
the installed one, call for call, in this one process, so that a load that
comes and goes falls on both alike; printed as well: the median of the
per-cage ratios (other / installed) and how many cages both versions
optimise to the same control points, energy and iterations, bit for bit.
"""

from __future__ import annotations

import argparse
import pickle
import statistics
import sys
import time
from pathlib import Path

import numpy as np

BODIES = ("default-female", "default-male")


def _library_cages() -> list[tuple[str, object]]:
    from seatkit.body import list_poses, load_pose, load_rig, pose_rig
    from seatkit.errors import UnsupportedPoseError
    from seatkit.pressure.qp import solve_pressure
    from seatkit.resources import template_path
    from seatkit.template import load_template

    template = load_template(template_path("chair.yaml"))
    cages = []
    for model in BODIES:
        rig = load_rig(model)
        for info in list_poses():
            if not info.supported:
                continue
            body = pose_rig(rig, load_pose(info.name))
            try:
                cages.append((f"{model}/{info.name}", template.fit([body], [solve_pressure(body)], seed=0)))
            except UnsupportedPoseError:
                continue
    return cages


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cases", help="cages recorded by compare_template.py record (default: the library's, made here)")
    ap.add_argument("--against", help="a checkout of another version of seatkit (its seatkit/refine/optimize.py is loaded)")
    args = ap.parse_args()

    import scipy.optimize

    from seatkit.refine import optimize

    if args.cases:
        with open(args.cases, "rb") as f:
            cages = [(case["name"], case["cage"]) for case in pickle.load(f) if case["cage"] is not None]
    else:
        cages = _library_cages()
    versions = [("this", optimize)]
    if args.against:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bench_geometry import _load  # another checkout's module, loaded from its file

        versions.insert(0, ("other", _load("other_optimize", Path(args.against) / "seatkit" / "refine" / "optimize.py")))

    evaluations = [0]
    minimize = scipy.optimize.minimize

    def counted(*a, **kw):
        result = minimize(*a, **kw)
        evaluations[0] += int(result.nfev)
        return result

    scipy.optimize.minimize = counted  # both versions call scipy.optimize.minimize
    rows = []
    for name, cage in cages:
        best = {label: np.inf for label, _ in versions}
        out = {}
        for r in range(args.repeat):
            order = versions if r % 2 == 0 else versions[::-1]
            for label, module in order:
                evaluations[0] = 0
                start = time.process_time()
                mesh = module.optimize_cage(cage)
                best[label] = min(best[label], time.process_time() - start)
                report = mesh.meta["optimize"]
                out[label] = (mesh.vertices, report["energy_after"], report["iterations"], evaluations[0])
        vertices, energy, iterations, nfev = out["this"]
        row = {"name": name, "cpu": best["this"], "iterations": iterations, "evaluations": nfev}
        line = f"{name:45s} {best['this'] * 1000:7.1f} ms  {iterations:4d} it  {nfev:4d} evaluations"
        if args.against:
            o_vertices, o_energy, o_iterations, _ = out["other"]
            row["ratio"] = best["other"] / best["this"]
            row["same"] = bool(np.array_equal(o_vertices, vertices) and o_energy == energy and o_iterations == iterations)
            moved = float(np.linalg.norm(o_vertices - vertices, axis=1).max())
            line += f"  | other {best['other'] * 1000:7.1f} ms, other/this {row['ratio']:.2f}x, moved {moved * 1000:.4f} mm"
        rows.append(row)
        print(line, flush=True)

    cpu = [r["cpu"] for r in rows]
    print(
        f"{len(rows)} cages: median {statistics.median(cpu) * 1000:.1f} ms, total {sum(cpu):.2f} s of CPU; "
        f"median {statistics.median(r['iterations'] for r in rows):.0f} iterations, "
        f"{statistics.median(r['evaluations'] for r in rows):.0f} evaluations"
    )
    if args.against:
        ratios = [r["ratio"] for r in rows]
        q = np.percentile(ratios, [0, 50, 100])
        print(f"other / this, per cage: median {q[1]:.2f}x (from {q[0]:.2f}x to {q[2]:.2f}x)")
        print(f"{sum(r['same'] for r in rows)} of {len(rows)} cages the same to the bit (control points, energy, iterations)")


if __name__ == "__main__":
    main()
