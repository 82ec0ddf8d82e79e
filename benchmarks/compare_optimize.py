"""The ``optimize`` refiner on fixed cages: CPU time per run, and how far two versions' results lie apart.

Three steps, so that two versions of seatkit (say a commit and the working
tree, each in its own venv) optimise exactly the same cages:

    python benchmarks/compare_optimize.py record cages.pkl               # every supported library pose x both default bodies
    python benchmarks/compare_optimize.py record drawn.pkl --library 0 --drawn 8   # 8 drawn poses (seatkit.body.generator)
    python benchmarks/compare_optimize.py run cages.pkl new.npz [--repeat 5]
    python benchmarks/compare_optimize.py compare old.npz new.npz

``record`` builds each default chair design (nothing written) and keeps the
cage every ``optimize`` call received. ``run`` optimises each of them
``--repeat`` times and keeps the least CPU time, the control points, the
energy and the L-BFGS-B iterations. ``compare`` prints, per cage, the
largest control-point distance and the energy difference between the two
results, both CPU times and their ratio, then the median ratio and how many
cages give the same result to the bit; it exits 1 when a control point moved
more than ``--tolerance`` (m).
"""

from __future__ import annotations

import argparse
import pickle
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BODIES = ("default-female", "default-male")


def record(path: str, *, library: bool = True, drawn: int = 0, draw_seed: int = 0) -> None:
    from seatkit import pipeline
    from seatkit.body.generator import draw_poses, pose_yaml
    from seatkit.body.poses import list_poses
    from seatkit.errors import SeatkitError
    import seatkit.refine.optimize as optimize

    calls = []
    original = optimize.optimize_cage

    def keep(mesh, params=None):
        calls.append({"mesh": mesh, "params": params})
        return original(mesh, params)

    optimize.optimize_cage = keep
    folder = Path(tempfile.mkdtemp(prefix="compare-optimize-"))
    poses = [info.name for info in list_poses() if info.supported] if library else []
    for d in draw_poses(drawn, seed=draw_seed):
        poses.append(str(folder / f"{d.name}.yaml"))
        Path(poses[-1]).write_text(pose_yaml(d))
    cages = []
    for pose in poses:
        for model in BODIES:
            calls.clear()
            recipe = {"template": "chair", "bodies": [{"model": model, "pose": pose}]}
            try:
                pipeline.build(recipe, write=False, processes=False)
            except SeatkitError as e:
                print(f"{model} {Path(pose).stem}: {str(e).splitlines()[0][:100]}", file=sys.stderr)
            for k, call in enumerate(calls):
                cages.append({"name": f"{model}/{Path(pose).stem}/{k}", **call})
            print(f"{model} {Path(pose).stem}: {len(calls)} cage(s)", file=sys.stderr)
    with open(path, "wb") as f:
        pickle.dump(cages, f)


def run(path: str, out: str, repeat: int) -> None:
    from seatkit.errors import SolverError
    from seatkit.refine.optimize import optimize_cage

    with open(path, "rb") as f:
        cages = pickle.load(f)
    result = {}
    for cage in cages:
        cpu = np.inf
        for _ in range(repeat):
            c0 = time.process_time()
            try:
                mesh, error = optimize_cage(cage["mesh"], cage["params"]), ""
            except SolverError as e:
                mesh, error = None, str(e)
            cpu = min(cpu, time.process_time() - c0)
        name = cage["name"]
        result[f"{name}|cpu"] = cpu
        if mesh is None:
            result[f"{name}|error"] = np.array(error)
            print(f"{name:45s} cpu {cpu * 1000:6.1f} ms  refused: {error[:80]}")
            continue
        report = mesh.meta["optimize"]
        result[f"{name}|cage"] = mesh.vertices
        result[f"{name}|energy"] = report["energy_after"]
        result[f"{name}|iterations"] = report["iterations"]
        print(
            f"{name:45s} cpu {cpu * 1000:6.1f} ms  {report['iterations']:4d} it  "
            f"{report['penalty_rounds']} rounds  energy {report['energy_after']:.10g}"
        )
    np.savez(out, **result)


def compare(a_path: str, b_path: str, tolerance: float) -> int:
    a, b = np.load(a_path), np.load(b_path)
    names = sorted({k.split("|")[0] for k in a.files} | {k.split("|")[0] for k in b.files})
    bad, same, ca, cb, ratios, worst_move, worst_energy = 0, 0, 0.0, 0.0, [], 0.0, 0.0
    print(f"{'cage':45s} {'moved':>9s} {'energy a':>14s} {'b - a':>9s}  {'cpu a':>8s} {'cpu b':>8s}  a/b   it a/b")
    for name in names:
        cpu_a, cpu_b = float(a[f"{name}|cpu"]), float(b[f"{name}|cpu"])
        ca, cb = ca + cpu_a, cb + cpu_b
        ratios.append(cpu_a / max(cpu_b, 1e-9))
        ea, eb = f"{name}|error" in a.files, f"{name}|error" in b.files
        if ea or eb:
            both = ea and eb
            same += both and str(a[f"{name}|error"]) == str(b[f"{name}|error"])
            bad += not both
            print(f"{name:45s} refused in {'both' if both else ('a' if ea else 'b')}")
            continue
        same += all(np.array_equal(a[f"{name}|{k}"], b[f"{name}|{k}"]) for k in ("cage", "energy", "iterations"))
        moved = float(np.linalg.norm(a[f"{name}|cage"] - b[f"{name}|cage"], axis=1).max())
        energy_a, d_energy = float(a[f"{name}|energy"]), float(b[f"{name}|energy"] - a[f"{name}|energy"])
        worst_move, worst_energy = max(worst_move, moved), max(worst_energy, abs(d_energy) / abs(energy_a))
        flag = moved > tolerance
        bad += flag
        print(
            f"{name:45s} {moved * 1000:7.4f}mm {energy_a:14.8g} {d_energy:+9.2e}  {cpu_a * 1000:6.1f}ms {cpu_b * 1000:6.1f}ms  "
            f"{ratios[-1]:4.2f}  {int(a[name + '|iterations'])}/{int(b[name + '|iterations'])}{'  <--' if flag else ''}"
        )
    print(f"total CPU time: a {ca:.3f} s, b {cb:.3f} s ({ca / max(cb, 1e-9):.2f}x); {bad} cage(s) off")
    if ratios:
        q = np.percentile(ratios, [0, 50, 100])
        print(f"CPU time a / b per cage: median {q[1]:.2f}x (from {q[0]:.2f}x to {q[2]:.2f}x)")
    print(f"largest control-point move {worst_move * 1000:.4g} mm, largest relative energy change {worst_energy:.3g}")
    print(f"{same} of {len(names)} cages the same to the bit (control points, energy, iterations)")
    return 1 if bad else 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("cages")
    r.add_argument("--library", type=int, default=1, help="1: every supported library pose (default), 0: none")
    r.add_argument("--drawn", type=int, default=0, help="also this many drawn poses (seatkit.body.generator.draw_poses)")
    r.add_argument("--draw-seed", type=int, default=0)
    u = sub.add_parser("run")
    u.add_argument("cages")
    u.add_argument("out")
    u.add_argument("--repeat", type=int, default=5)
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--tolerance", type=float, default=1e-4, help="m, largest control-point move allowed")
    args = ap.parse_args()
    if args.cmd == "record":
        record(args.cages, library=bool(args.library), drawn=args.drawn, draw_seed=args.draw_seed)
    elif args.cmd == "run":
        run(args.cages, args.out, args.repeat)
    else:
        sys.exit(compare(args.a, args.b, args.tolerance))


if __name__ == "__main__":
    main()
