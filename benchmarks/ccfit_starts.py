"""Where the Catmull-Clark surface fit starts: the cage's limit surface in the body, and other starts measured.

The surface fit (:mod:`seatkit.refine.ccfit`) starts from the cage the
``optimize`` stage leaves. Its limit surface is a smoothing of that cage
and, where the cage is concave seen from the body, cuts the corner into
it. This script measures three other starts (docs/performance.md, "Where
the fit starts"), none of them in the code:

``interpolating``
    the moving control points solved so that the limit positions at them
    (the level-0 limit stencils) are the cage's points;
``concave``
    the same, solved only for the moving points whose limit position lies
    on the body side of the point (along the limit normal), the others kept;
``concave-floor``
    ``concave``, then the limit samples under the floor asked back to it
    (the heights in least squares with those rows, up to four rounds).

Fixed and ground points stay. A start replaces the cage the fit is given,
so the fit's fairness then asks for a smooth displacement of the start.

    python benchmarks/ccfit_starts.py where
    python benchmarks/ccfit_starts.py approach
    python benchmarks/ccfit_starts.py run concave --count fits.txt -- benchmarks/compare_ccfit.py run fits.pkl concave.npz
    python benchmarks/ccfit_starts.py run concave --count fits.txt -- benchmarks/bench_generalisation.py --poses 200 ...

``approach`` builds the default chair and runs its surface fit again from
the cage, printing per iteration the deepest probe and the body segments
(of the nearest body vertex) of the probes deeper than 5 mm.
``where`` builds the default chair and prints, for the cage and each
start, how many of the fit's limit samples lie in the body (more than
2 mm), how deep, grouped by the body segment of the nearest body vertex,
and how far the start dips under the floor. ``run`` runs another
benchmark script with every surface fit starting from START (``cage``:
the code) and, with ``--count``, appends one line per fit (template,
iterations) to that file, the worker processes' fits included (they are
forked with the start in place); ``run`` prints the fits' count and
their iterations per template at the end.
"""

from __future__ import annotations

import argparse
import collections
import runpy
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

STARTS = ("cage", "interpolating", "concave", "concave-floor")


def _solve_at(limit, points: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Control points whose limit positions at the control points ``at`` are ``points``' (the others kept)."""
    n = len(points)
    L0 = limit[:n].toarray()  # the refined mesh's first points are the cage's (their limit stencils)
    kept = np.setdiff1d(np.arange(n), at)
    out = points.copy()
    out[at] = np.linalg.solve(L0[np.ix_(at, at)], points[at] - L0[np.ix_(at, kept)] @ points[kept])
    return out


def start_points(mesh, start: str, level: int = 3) -> np.ndarray:
    """The control points a fit of ``mesh`` starts from under ``start``."""
    from seatkit.subdivision import Cage, build_operators

    P = np.array(mesh.vertices, dtype=np.float64)
    if start == "cage":
        return P
    n = len(P)
    ops = build_operators(Cage.from_control_mesh(mesh), level)
    moving = ~(np.asarray(mesh.fixed, bool) | np.asarray(mesh.ground, bool))
    if start == "interpolating":
        return _solve_at(ops.limit, P, np.flatnonzero(moving))
    # the limit position on the body side of its point (the limit normals point to the body)
    concave = np.einsum("kc,kc->k", ops.limit[:n] @ P - P, ops.limit_normals(P)[:n]) > 0.0
    at = np.flatnonzero(moving & concave)
    out = _solve_at(ops.limit, P, at)
    if start == "concave":
        return out
    # the floor: samples under it asked back to y = 0 beside the interpolation, heights in least squares
    L0 = ops.limit[:n].toarray()
    kept = np.setdiff1d(np.arange(n), at)
    A = L0[np.ix_(at, at)]
    rhs = P[at, 1] - L0[np.ix_(at, kept)] @ P[kept, 1]
    rows_at = ops.limit[:, at].toarray()
    rows_kept = ops.limit[:, kept] @ P[kept, 1]
    rows = np.zeros(0, np.int64)
    for _ in range(4):
        below = np.flatnonzero(ops.limit @ out[:, 1] < -1e-4)
        if not below.size:
            break
        rows = np.union1d(rows, below)
        out[at, 1] = np.linalg.lstsq(np.vstack([A, rows_at[rows]]), np.concatenate([rhs, -rows_kept[rows]]), rcond=None)[0]
    return out


def _install(start: str, count: str | None) -> None:
    """Every surface fit from now on starts from ``start``; with ``count``, each fit appends a line to that file."""
    import seatkit.refine.ccfit as ccfit

    fit_cage, fit_once = ccfit.fit_cage, ccfit._fit_once

    def started(mesh, bodies, pressures, params=None):
        return fit_cage(replace(mesh, vertices=start_points(mesh, start)), bodies, pressures, params)

    def counted(mesh, *args, **kwargs):
        out = fit_once(mesh, *args, **kwargs)
        with open(count, "a") as f:
            f.write(f"{mesh.meta.get('template', '?')} {out.meta['catmull-clark-fit']['iterations']}\n")
        return out

    ccfit.fit_cage = started
    if count:
        ccfit._fit_once = counted


def _summary(count: str) -> str:
    fits, iterations = collections.Counter(), collections.Counter()
    for line in Path(count).read_text().splitlines():
        template, it = line.split()
        fits[template] += 1
        iterations[template] += int(it)
    return "; ".join(f"{t}: {fits[t]} fits, {iterations[t]} iterations" for t in sorted(fits))


def _default_chair_fit():
    """The inputs of the default chair's surface fit (our cage's, not the flat patch's): mesh, bodies, pressures, params."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from ccfit_steps import capture

    return capture("chair", "default-male", "upright-sitting")


def _segment_of(body):
    """The body segment of the nearest body vertex, for points."""
    from scipy.spatial import cKDTree

    segment = np.argmax(body.weights, axis=1)
    tree = cKDTree(body.vertices)
    return lambda points: segment[tree.query(points)[1]]


def approach() -> None:
    """The default chair's fit from the cage: per iteration, its deepest probe and the body segments of the probes deeper than 5 mm."""
    import seatkit.refine.ccfit as ccfit
    from seatkit.skeleton import SEGMENTS

    mesh, bodies, pressures, params = _default_chair_fit()
    segment_of = _segment_of(bodies[0])
    step = [0]

    def observe(**state):
        step[0] += 1
        depth, X = state["depth"], state["X"]
        if state["depth_samples"] is None:  # the polish's probes (quad centres too)
            return
        deep = np.flatnonzero(depth > 0.005)
        seg = segment_of(X[deep]) if deep.size else np.zeros(0, np.int64)
        parts = ", ".join(f"{SEGMENTS[s]} {int((seg == s).sum())} (at most {depth[deep][seg == s].max() * 1000:.1f} mm)" for s in np.unique(seg))
        print(f"iteration {step[0]:2d}: deepest probe {max(depth.max(), 0) * 1000:5.1f} mm; deeper than 5 mm: {parts or 'none'}")

    ccfit._observe = observe
    try:
        ccfit.fit_cage(mesh, bodies, pressures, params)
    finally:
        ccfit._observe = None


def where() -> None:
    """The default chair's start, for the cage and each start."""
    from seatkit.geometry.skin import SkinDistance
    from seatkit.skeleton import SEGMENTS
    from seatkit.subdivision import Cage, build_operators

    mesh, bodies, _, _ = _default_chair_fit()
    body = bodies[0]
    skin = SkinDistance.of(body.vertices, body.faces)
    segment_of = _segment_of(body)
    ops = build_operators(Cage.from_control_mesh(mesh), 3)
    P = np.asarray(mesh.vertices, dtype=np.float64)
    n = len(P)
    moving = ~(np.asarray(mesh.fixed, bool) | np.asarray(mesh.ground, bool))
    print(
        f"the cage: {n} control points ({int(moving.sum())} moving), {int((skin.query(P)[0] > 0).sum())} in the body "
        f"(at most {max(skin.query(P)[0].max(), 0) * 1000:.1f} mm); limit positions up to "
        f"{np.linalg.norm(ops.limit[:n] @ P - P, axis=1).max() * 1000:.0f} mm from their points"
    )
    for start in STARTS:
        Q = start_points(mesh, start)
        X = ops.limit @ Q
        depth = skin.query(X)[0]
        inside = depth > 0.0
        deep = depth > 0.002
        seg = segment_of(X[deep])
        moved = np.linalg.norm(Q - P, axis=1)[moving]
        print(
            f"{start}: control points moved median {np.median(moved) * 1000:.0f} mm, at most {moved.max() * 1000:.0f} mm; "
            f"{int(inside.sum())} limit samples in the body ({int(deep.sum())} by more than 2 mm, at most "
            f"{max(depth.max(), 0) * 1000:.1f} mm); the surface down to y = {X[:, 1].min() * 1000:.1f} mm"
        )
        for s in np.unique(seg):
            these = seg == s
            print(f"    {SEGMENTS[s]:12s} {int(these.sum()):4d} samples, at most {depth[deep][these].max() * 1000:5.1f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("where", help="the default chair's start, for the cage and each start")
    sub.add_parser("approach", help="the default chair's fit from the cage: where its probes are deep, per iteration")
    r = sub.add_parser("run", help="run a benchmark script with every surface fit starting from START: run START [--count FILE] -- SCRIPT [ARGS...]")
    r.add_argument("start", choices=STARTS)
    r.add_argument("--count", help="append one line per surface fit (template, iterations) to this file")
    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    args = ap.parse_args(argv[:cut])
    if args.cmd in ("where", "approach"):
        where() if args.cmd == "where" else approach()
        return
    script = argv[cut + 1 :]
    if not script:
        ap.error("run: give the benchmark script to run after --")
    _install(args.start, args.count)
    sys.argv = script
    try:
        runpy.run_path(script[0], run_name="__main__")
    finally:
        if args.count and Path(args.count).exists():
            print(f"{args.start}: {_summary(args.count)}", file=sys.stderr)


if __name__ == "__main__":
    main()
