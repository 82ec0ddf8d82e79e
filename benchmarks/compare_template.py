"""The template fit and ``optimize`` on fixed inputs: CPU time per fit, and whether two versions' cages are the same.

Three steps, so that two versions of seatkit (say a commit and the working
tree, each in its own venv) fit exactly the same bodies and pressures:

    python benchmarks/compare_template.py record cases.pkl   # library poses x 2 bodies x seeds 0-2, 30 drawn poses x 2 bodies
    python benchmarks/compare_template.py record cases.pkl --builds crossed-legs-050@default-female seated-000@default-male
    python benchmarks/compare_template.py run cases.pkl new.npz [--repeat 1] [--only template|optimize]
    python benchmarks/compare_template.py compare old.npz new.npz [--tolerance 1e-9]

``record`` poses every supported library pose and ``--drawn`` (30) poses of
:func:`seatkit.body.generator.draw_poses` (draw seed ``--draw-seed``, 2026)
on both default bodies, solves their pressure (QP), and keeps the bodies, the
pressures and, for every case, the chair the recording version fits with
seed 0 (the input of ``optimize``, so that both versions optimise the very
same cage). With ``--builds FAMILY-INDEX@BODY ...`` it records only those
drawn cases (draw seed 2026, as the generalisation benchmark draws them),
with the bodies and pressures the default build (seed 0) hands the
template: posed, in the canonical frame, placed. ``run`` fits the chair to every case with every seed of the case
(seeds 0-2 on the library poses, ``--drawn-seeds`` on the drawn ones) and
runs ``optimize`` on every recorded cage, ``--repeat`` times each, keeping
the least CPU time (``time.process_time``, BLAS on one thread as in a build),
every array of the resulting ``ControlMesh`` and, for a refusal, its message.
``compare`` prints the largest vertex distance per case, both versions' CPU
times, and exits 1 when an array differs by more than ``--tolerance`` (m for
positions; 0 means bit for bit), a refusal differs, or one version refuses
what the other builds.
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time

import numpy as np

BODIES = ("default-female", "default-male")
#: ControlMesh arrays compared (positions with the tolerance, the rest exactly).
POSITIONS = ("vertices", "plane_points", "plane_normals", "vertex_weights")
EXACT = ("faces", "face_segments", "face_person", "fixed", "ground", "crease_edges", "corners")


def record_builds(path: str, names: list[str]) -> None:
    """Record the drawn cases ``names`` with the bodies and pressures the default build hands the chair template."""
    import tempfile
    from pathlib import Path

    from seatkit.body.generator import draw_case, pose_yaml
    from seatkit.errors import SeatkitError
    from seatkit.pipeline import build
    from seatkit.template import engine

    seen: list = []
    fits = engine.YamlTemplate.fits

    def recorded(self, bodies, pressures, **kw):
        if not seen:
            seen.append((list(bodies), list(pressures)))
        return fits(self, bodies, pressures, **kw)

    engine.YamlTemplate.fits = recorded
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            drawn, model = draw_case(name)
            pose = Path(tmp) / f"{drawn.name}.yaml"
            pose.write_text(pose_yaml(drawn))
            seen.clear()
            try:
                r = build({"template": "chair", "seed": 0, "bodies": [{"model": model, "pose": str(pose)}]}, write=False, processes=False)
                cage, note = r.initial_mesh, f"{len(r.initial_mesh.vertices)} control points"
            except SeatkitError as e:
                cage, note = None, f"refused: {str(e)[:90]}"
            if not seen:
                print(f"{name}: the build never fitted the template ({note})", file=sys.stderr)
                continue
            (body,), (pressure,) = seen[0]
            cases.append({"name": f"{model}/{drawn.name}", "body": body, "pressure": pressure, "seeds": [0], "cage": cage})
            print(f"{name}: {note}", file=sys.stderr)
    engine.YamlTemplate.fits = fits
    with open(path, "wb") as f:
        pickle.dump(cases, f)


def record(path: str, drawn: int, draw_seed: int, drawn_seeds: list[int]) -> None:
    from threadpoolctl import threadpool_limits

    from seatkit.body import list_poses, load_pose, load_rig, pose_rig
    from seatkit.body.generator import draw_poses
    from seatkit.errors import UnsupportedPoseError
    from seatkit.pressure.qp import solve_pressure
    from seatkit.resources import template_path
    from seatkit.template import load_template

    template = load_template(template_path("chair.yaml"))
    poses = [(info.name, load_pose(info.name), [0, 1, 2]) for info in list_poses() if info.supported]
    poses += [(d.name, d.pose, list(drawn_seeds)) for d in draw_poses(drawn, seed=draw_seed)]
    cases = []
    with threadpool_limits(limits=1):
        for model in BODIES:
            rig = load_rig(model)
            for name, pose, seeds in poses:
                body = pose_rig(rig, pose)
                pressure = solve_pressure(body)
                try:
                    cage = template.fit([body], [pressure], seed=0)
                    note = f"{len(cage.vertices)} control points"
                except UnsupportedPoseError as e:
                    cage, note = None, f"refused: {str(e)[:90]}"
                cases.append({"name": f"{model}/{name}", "body": body, "pressure": pressure, "seeds": seeds, "cage": cage})
                print(f"{model}/{name}: {note}", file=sys.stderr)
    with open(path, "wb") as f:
        pickle.dump(cases, f)


def _arrays(mesh, prefix: str, out: dict) -> None:
    for key in POSITIONS + EXACT:
        value = getattr(mesh, key)
        if value is not None:
            out[f"{prefix}|{key}"] = np.asarray(value)
    out[f"{prefix}|labels"] = np.array(mesh.face_labels)


def run(path: str, out: str, repeat: int, only: str | None, match: str = "") -> None:
    from threadpoolctl import threadpool_limits

    from seatkit.errors import SeatkitError, UnsupportedPoseError
    from seatkit.refine.optimize import optimize_cage
    from seatkit.resources import template_path
    from seatkit.template import load_template

    with open(path, "rb") as f:
        cases = pickle.load(f)
    template = load_template(template_path("chair.yaml"))
    result: dict = {}
    totals = {"template": 0.0, "optimize": 0.0}
    with threadpool_limits(limits=1):
        for case in cases:
            if match not in case["name"]:
                continue
            if only in (None, "template"):
                for seed in case["seeds"]:
                    key = f"template/{case['name']}/seed{seed}"
                    # a fresh Body each time: no per-body cache survives from the last fit
                    fit = lambda seed=seed: template.fit([_fresh(case["body"])], [case["pressure"]], seed=seed)  # noqa: E731
                    mesh = _keep(key, fit, UnsupportedPoseError, repeat, result, totals, "template")
                    if mesh is not None:
                        result[f"{key}|attempt"] = mesh.meta["fit_attempts"]["attempt"]
                    print(f"{key:60s} cpu {result[key + '|cpu']:6.3f} s  {'refused' if mesh is None else 'attempt %d' % mesh.meta['fit_attempts']['attempt']}", flush=True)
            if only in (None, "optimize") and case["cage"] is not None:
                key = f"optimize/{case['name']}"
                mesh = _keep(key, lambda: optimize_cage(case["cage"]), SeatkitError, repeat, result, totals, "optimize")
                if mesh is not None:
                    result[f"{key}|iterations"] = mesh.meta["optimize"]["iterations"]
                print(f"{key:60s} cpu {result[key + '|cpu']:6.3f} s", flush=True)
    print(f"total CPU: template {totals['template']:.2f} s, optimize {totals['optimize']:.2f} s")
    np.savez(out, **result)


def _keep(key, call, refusal, repeat, result, totals, kind):
    """Run ``call()`` ``repeat`` times; keep the least CPU time and the mesh's arrays (or the refusal's message) under ``key``."""
    cpu, mesh, error = np.inf, None, ""
    for _ in range(repeat):
        c0 = time.process_time()
        try:
            mesh, error = call(), ""
        except refusal as e:
            mesh, error = None, str(e)
        cpu = min(cpu, time.process_time() - c0)
    result[f"{key}|cpu"] = cpu
    totals[kind] += cpu
    if mesh is None:
        result[f"{key}|error"] = np.array(error)
    else:
        _arrays(mesh, key, result)
    return mesh


def _fresh(body):
    """A new Body object with the same arrays (per-body caches are keyed by the object)."""
    import dataclasses

    return dataclasses.replace(body)


def compare(a_path: str, b_path: str, tolerance: float) -> int:
    a, b = np.load(a_path), np.load(b_path)
    names = sorted({k.split("|")[0] for k in a.files} | {k.split("|")[0] for k in b.files})
    bad = 0
    sums = {"template": [0.0, 0.0], "optimize": [0.0, 0.0]}
    print(f"{'case':62s} {'max |dv| m':>11s}  {'cpu a':>7s} {'cpu b':>7s}")
    for name in names:
        kind = name.split("/")[0]
        if f"{name}|cpu" not in a.files or f"{name}|cpu" not in b.files:
            bad += 1
            print(f"{name:62s} run by {'b' if f'{name}|cpu' in b.files else 'a'} only")
            continue
        ca, cb = float(a[f"{name}|cpu"]), float(b[f"{name}|cpu"])
        sums[kind][0] += ca
        sums[kind][1] += cb
        ea, eb = f"{name}|error" in a.files, f"{name}|error" in b.files
        if ea or eb:
            same = ea and eb and str(a[f"{name}|error"]) == str(b[f"{name}|error"])
            bad += not same
            print(f"{name:62s} {'refused' if same else 'DIFFERENT refusal':>11s}  {ca:7.3f} {cb:7.3f}")
            if not same:
                for tag, f, e in (("a", a, ea), ("b", b, eb)):
                    print(f"    {tag}: {str(f[f'{name}|error'])[:150] if e else 'built'}")
            continue
        worst, problems = 0.0, []
        for key in POSITIONS + EXACT + ("labels",):
            ka, kb = f"{name}|{key}", f"{name}|{key}"
            if (ka in a.files) != (kb in b.files):
                problems.append(f"{key} missing on one side")
                continue
            if ka not in a.files:
                continue
            va, vb = a[ka], b[kb]
            if va.shape != vb.shape:
                problems.append(f"{key} shape {va.shape} vs {vb.shape}")
                continue
            if key in POSITIONS:
                diff = float(np.nanmax(np.abs(va - vb), initial=0.0)) if va.size else 0.0
                if not np.array_equal(np.isnan(va), np.isnan(vb)):
                    problems.append(f"{key} NaN pattern differs")
                if key == "vertices":
                    worst = diff
                if diff > tolerance:
                    problems.append(f"{key} differs by {diff:.3g}")
            elif not np.array_equal(va, vb):
                problems.append(f"{key} differs")
        for extra in ("attempt", "iterations"):
            k = f"{name}|{extra}"
            if k in a.files and k in b.files and int(a[k]) != int(b[k]):
                problems.append(f"{extra} {int(a[k])} vs {int(b[k])}")
        bad += bool(problems)
        print(f"{name:62s} {worst:11.3g}  {ca:7.3f} {cb:7.3f}  {'; '.join(problems)}")
    for kind, (ta, tb) in sums.items():
        if ta or tb:
            print(f"{kind}: CPU a {ta:.2f} s, b {tb:.2f} s, b/a {tb / ta if ta else float('nan'):.3f}")
    print(f"{len(names)} cases, {bad} differ (tolerance {tolerance:g})")
    return 1 if bad else 0


def main() -> None:
    usage = "\n".join(line for line in __doc__.splitlines() if line.strip().startswith("python benchmarks/compare_template.py"))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], epilog=usage, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("record")
    r.add_argument("cases")
    r.add_argument("--drawn", type=int, default=30)
    r.add_argument("--draw-seed", type=int, default=2026)
    r.add_argument("--drawn-seeds", type=int, nargs="+", default=[0])
    r.add_argument("--builds", nargs="+", metavar="FAMILY-INDEX@BODY", help="only these drawn cases, as the default build fits them")
    u = sub.add_parser("run")
    u.add_argument("cases")
    u.add_argument("out")
    u.add_argument("--repeat", type=int, default=1)
    u.add_argument("--only", choices=("template", "optimize"))
    u.add_argument("--match", default="", help="only the cases whose name contains this")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--tolerance", type=float, default=0.0)
    args = parser.parse_args()
    if args.command == "record" and args.builds:
        record_builds(args.cases, args.builds)
    elif args.command == "record":
        record(args.cases, args.drawn, args.draw_seed, args.drawn_seeds)
    elif args.command == "run":
        run(args.cases, args.out, args.repeat, args.only, args.match)
    else:
        sys.exit(compare(args.a, args.b, args.tolerance))


if __name__ == "__main__":
    main()
