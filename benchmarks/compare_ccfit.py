"""The Catmull-Clark surface fit on fixed inputs: time per fit, and how far two versions' results lie apart.

Three steps, so that two versions of seatkit (say a commit and the working
tree, each in its own venv) fit exactly the same cages to exactly the same
bodies:

    python benchmarks/compare_ccfit.py record fits.pkl     # every supported library pose x both default bodies
    python benchmarks/compare_ccfit.py record drawn.pkl --library 0 --drawn 8   # 8 drawn poses (seatkit.body.generator)
    python benchmarks/compare_ccfit.py record cases.pkl --library 0 --case pose.yaml:default-male   # given poses, one body each
    python benchmarks/compare_ccfit.py record cases.pkl --library 0 --draw-seed 2026 --case seated-048:default-male   # a drawn pose
    python benchmarks/compare_ccfit.py run fits.pkl new.npz [--repeat 3] [--only NAME] [--cold]
    python benchmarks/compare_ccfit.py compare old.npz new.npz

``record`` builds each design (nothing written) and keeps the inputs of every
``catmull-clark-fit`` call: our cage after ``optimize`` and the flat-patch
baseline's. ``run`` fits each of them ``--repeat`` times and keeps the best
time, the fitted control points and the final depths (the 5 mm guarantee);
``--only`` fits only those whose name holds that text (say
``default-male/upright-sitting/chair``, the default build's), and
``--cold`` empties the library's memo caches before every fit (the
subdivision operators and the skins' distance structures), so that each
fit pays for them as the one fit of a build does.
``compare`` prints, per fit, the largest control-point and limit-surface
distance between the two results and both versions' times and depths, then
the CPU-time ratio per fit and how many fits are the same to the bit; it
exits 1 when a limit-surface vertex moved more than ``--tolerance`` (m) or a
depth exceeds the 5 mm limit.
"""

from __future__ import annotations

import argparse
import pickle
import sys
import tempfile
import time
from pathlib import Path
from typing import Sequence

import numpy as np

BODIES = ("default-female", "default-male")


def record(path: str, *, library: bool = True, drawn: int = 0, draw_seed: int = 0, cases: Sequence[str] = ()) -> None:
    from seatkit import pipeline
    from seatkit.errors import SeatkitError
    import seatkit.refine.ccfit as ccfit

    calls = []
    original = ccfit.fit_cage

    def keep(mesh, bodies, pressures, params=None):
        calls.append({"mesh": mesh, "bodies": bodies, "pressures": pressures, "params": params})
        return original(mesh, bodies, pressures, params)

    ccfit.fit_cage = keep
    fits = []
    from seatkit.body.generator import draw_pose, draw_poses, pose_yaml

    folder = Path(tempfile.mkdtemp(prefix="compare-ccfit-"))
    poses = _poses() if library else []
    for d in draw_poses(drawn, seed=draw_seed):  # the families in turn; their YAML read back bit for bit
        poses.append(str(folder / f"{d.name}.yaml"))
        Path(poses[-1]).write_text(pose_yaml(d))
    runs = [(pose, model) for pose in poses for model in BODIES]
    for case in cases:  # a pose file, or a drawn pose FAMILY-INDEX, and the one body it is built for
        pose, model = case.rsplit(":", 1)
        if not Path(pose).is_file():
            family, index = pose.rsplit("-", 1)
            one = draw_pose(np.random.default_rng([draw_seed, int(index)]), family, pose)
            pose = str(folder / f"{pose}.yaml")
            Path(pose).write_text(pose_yaml(one))
        runs.append((pose, model))
    for pose, model in runs:
        calls.clear()
        recipe = {"template": "chair", "bodies": [{"model": model, "pose": pose}]}
        try:
            pipeline.build(recipe, write=False, processes=False)
        except SeatkitError as e:
            print(f"{model} {pose}: {str(e).splitlines()[0][:100]}", file=sys.stderr)
        for call in calls:  # ours and the baseline's (on a thread: in either order), the design search's candidates
            name = f"{model}/{Path(pose).stem}/{call['mesh'].meta.get('template', '?')}"
            seen = sum(fit["name"].split("#")[0] == name for fit in fits)
            fits.append({"name": f"{name}#{seen}" if seen else name, **call})
        print(f"{model} {Path(pose).stem}: {len(calls)} fit(s)", file=sys.stderr)
    with open(path, "wb") as f:
        pickle.dump(fits, f)


def _poses() -> list[str]:
    from seatkit.body.poses import list_poses

    return [info.name for info in list_poses() if info.supported]


def _empty_caches() -> None:
    """Empty the memo caches a fit fills (those a version has): its next fit builds everything again."""
    import seatkit.geometry.skin as skin
    import seatkit.subdivision.catmull_clark as catmull_clark

    for cache in (getattr(catmull_clark, "_OPS_CACHE", None), getattr(catmull_clark, "_LEVEL_CACHE", None), getattr(skin, "_CACHE", None)):
        if cache is not None:
            cache.clear()


def run(path: str, out: str, repeat: int, only: str | None = None, cold: bool = False) -> None:
    from seatkit.errors import SolverError
    from seatkit.refine.ccfit import fit_cage
    from seatkit.subdivision import limit_surface

    with open(path, "rb") as f:
        fits = pickle.load(f)
    if only:
        fits = [fit for fit in fits if only in fit["name"]]
    result = {}
    for fit in fits:
        best, cpu = np.inf, np.inf
        for _ in range(repeat):
            if cold:
                _empty_caches()
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                mesh = fit_cage(fit["mesh"], fit["bodies"], fit["pressures"], fit["params"])
                error = ""
            except SolverError as e:
                mesh, error = None, str(e)
            best = min(best, time.perf_counter() - t0)
            cpu = min(cpu, time.process_time() - c0)
        name = fit["name"]
        result[f"{name}|seconds"] = best
        result[f"{name}|cpu"] = cpu
        if mesh is None:
            result[f"{name}|error"] = np.array(error)
            print(f"{name:50s} {best:6.2f} s  refused: {error[:80]}")
            continue
        report = mesh.meta["catmull-clark-fit"]
        depth = report["final_depth"] or {}
        result[f"{name}|cage"] = mesh.vertices
        result[f"{name}|surface"] = limit_surface(mesh, level=3).vertices
        result[f"{name}|depth"] = np.array([depth.get("surface_in_body", np.nan), depth.get("body_in_surface", np.nan)])
        result[f"{name}|iterations"] = report["iterations"]
        result[f"{name}|mean"] = report["after"]["mean_distance"]
        print(
            f"{name:50s} {best:6.2f} s (cpu {cpu:5.2f})  {report['iterations']:3d} it  "
            f"mean {report['after']['mean_distance'] * 1000:6.2f} mm  depth {1000 * max(depth.values(), default=0):4.1f} mm"
        )
    np.savez(out, **result)


def compare(a_path: str, b_path: str, tolerance: float, limit: float) -> int:
    a, b = np.load(a_path), np.load(b_path)
    names = sorted({k.split("|")[0] for k in a.files} | {k.split("|")[0] for k in b.files})
    bad, ta, tb, ca, cb = 0, 0.0, 0.0, 0.0, 0.0
    ratios = []  # CPU time a / b per fit
    same = 0  # fits whose every kept result is the same to the bit
    print(f"{'fit':50s} {'cage':>8s} {'surface':>8s}  {'time a':>7s} {'time b':>7s}  {'depth a':>7s} {'depth b':>7s}  it a/b")
    for name in names:
        ta += float(a[f"{name}|seconds"])
        tb += float(b[f"{name}|seconds"])
        ca += float(a[f"{name}|cpu"])
        cb += float(b[f"{name}|cpu"])
        ratios.append(float(a[f"{name}|cpu"]) / max(float(b[f"{name}|cpu"]), 1e-9))
        ea, eb = f"{name}|error" in a.files, f"{name}|error" in b.files
        if ea or eb:
            same = ea and eb
            bad += not same
            print(f"{name:50s} refused in {'both' if same else ('a' if ea else 'b')}")
            continue
        same += all(np.array_equal(a[f"{name}|{k}"], b[f"{name}|{k}"], equal_nan=True) for k in ("cage", "surface", "depth", "iterations", "mean"))
        dc = np.linalg.norm(a[f"{name}|cage"] - b[f"{name}|cage"], axis=1).max()
        ds = np.linalg.norm(a[f"{name}|surface"] - b[f"{name}|surface"], axis=1).max()
        da, db = a[f"{name}|depth"].max(), b[f"{name}|depth"].max()
        flag = ds > tolerance or db > limit
        bad += flag
        print(
            f"{name:50s} {dc * 1000:6.3f}mm {ds * 1000:6.3f}mm  {float(a[name + '|seconds']):6.2f}s {float(b[name + '|seconds']):6.2f}s  "
            f"{da * 1000:5.2f}mm {db * 1000:5.2f}mm  {int(a[name + '|iterations'])}/{int(b[name + '|iterations'])}{'  <--' if flag else ''}"
        )
    print(f"total fit time: a {ta:.2f} s, b {tb:.2f} s ({ta / max(tb, 1e-9):.2f}x); CPU time a {ca:.2f} s, b {cb:.2f} s ({ca / max(cb, 1e-9):.2f}x); {bad} fit(s) off")
    if ratios:
        q = np.percentile(ratios, [0, 50, 100])
        print(f"CPU time a / b per fit: median {q[1]:.2f}x (from {q[0]:.2f}x to {q[2]:.2f}x)")
    print(f"{same} of {len(ratios)} fitted fits the same to the bit (cage, limit surface, depths, iterations, mean distance)")
    return 1 if bad else 0


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="record FITS [--library 0|1] [--drawn N] [--draw-seed S] [--case POSE:MODEL ...]; run FITS OUT [--repeat N] [--only NAME] [--cold]; "
        "compare A B [--tolerance M] [--limit M] (each command's --help says more)",
    )
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("fits")
    r.add_argument("--library", type=int, default=1, help="1: every supported library pose (default), 0: none")
    r.add_argument("--drawn", type=int, default=0, help="also this many drawn poses (seatkit.body.generator.draw_poses)")
    r.add_argument("--draw-seed", type=int, default=0)
    r.add_argument("--case", action="append", default=[], metavar="POSE:MODEL", help="also this pose built on this body (repeatable): a pose file, or FAMILY-INDEX drawn with --draw-seed as draw_pose(default_rng([seed, index]), family) draws it")
    u = sub.add_parser("run")
    u.add_argument("fits")
    u.add_argument("out")
    u.add_argument("--repeat", type=int, default=1)
    u.add_argument("--only", help="fit only those whose name holds this text")
    u.add_argument("--cold", action="store_true", help="empty the memo caches before every fit")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--tolerance", type=float, default=1e-4, help="m, largest limit-surface vertex move allowed")
    c.add_argument("--limit", type=float, default=0.005, help="m, the surface_limit every fit must hold")
    args = ap.parse_args()
    if args.cmd == "record":
        record(args.fits, library=bool(args.library), drawn=args.drawn, draw_seed=args.draw_seed, cases=args.case)
    elif args.cmd == "run":
        run(args.fits, args.out, args.repeat, args.only, args.cold)
    else:
        sys.exit(compare(args.a, args.b, args.tolerance, args.limit))


if __name__ == "__main__":
    main()
