"""Where the surface fit's steps go: how far each control point is asked to move, and which rows ask it.

Builds one design (nothing written) and runs our surface fit again on its
inputs, looking at the first ``--iterations`` steps
(:func:`seatkit.refine.ccfit._fit_once` calls ``ccfit._observe`` after each
solve). Per step it prints:

- the solved step's requested move per moving control point (longest, 90th
  percentile, median) against the trust region's reach, and the control
  points that ask most with the cage faces they belong to and how firmly
  the rows hold them against the fairness (the traces of their diagonal
  blocks in the normal equations);
- the motion that step asks of the limit surface, along its normals and
  across them (sliding), at the limit samples;
- the weight of each kind of row in the normal equations (supported
  targets, targets behind the surface, penetration probes) against the
  fairness, and the longest and median move of the step solved without
  each kind of row (the rest unchanged);
- the fit's figures (weighted mean distance, deepest probe, probes inside
  the body) after the step taken at a few shares of its length, the trust
  region's among them.

With ``--png`` it draws the first step: the cage's control points coloured
by their requested move, with the step as arrows at true length, over the
body, the limit samples and the probes deeper than 3 mm, from the side and
from above. docs/performance.md, "Where the surface fit's iterations go",
gives what it measured::

    python benchmarks/ccfit_steps.py --iterations 3 --png steps.png
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def capture(template: str, model: str, pose: str):
    """The inputs of our surface fit in the default build of ``template`` for ``model`` in ``pose``."""
    from seatkit import pipeline
    from seatkit.refine import ccfit

    calls = []
    original = ccfit.fit_cage

    def keep(mesh, bodies, pressures, params=None):
        calls.append((mesh, bodies, pressures, params))
        return original(mesh, bodies, pressures, params)

    ccfit.fit_cage = keep
    try:
        pipeline.build({"template": template, "bodies": [{"model": model, "pose": pose}]}, write=False, processes=False)
    finally:
        ccfit.fit_cage = original
    ours = [c for c in calls if c[0].meta.get("template") == template]
    if not ours:
        sys.exit(f"ccfit_steps: the build of {template} for {model} in {pose} ran no surface fit of its cage")
    return ours[0]


def observe(mesh, bodies, pressures, params, n_steps: int) -> tuple[list, dict]:
    """Run the fit once (no refits), keeping the state of its first ``n_steps`` steps."""
    from threadpoolctl import threadpool_limits

    from seatkit.refine import ccfit

    steps: list = []

    def keep(**state):
        if len(steps) < n_steps:
            steps.append(state)

    ccfit._observe = keep
    try:
        with threadpool_limits(limits=1):
            out = ccfit._fit_once(mesh, bodies, pressures, params or {})
    finally:
        ccfit._observe = None
    return steps, out.meta["catmull-clark-fit"]


def moves(step: np.ndarray) -> np.ndarray:
    return np.linalg.norm(step, axis=1)


def report(i: int, s: dict, labels: dict) -> None:
    cols, P, solved = s["cols"], s["P"], s["solved"]
    L = moves((solved - P)[cols])
    reach = s["reach"]
    print(
        f"\nstep {i + 1}: requested move of the {cols.size} moving control points: longest {L.max() * 100:.1f} cm, "
        f"90th percentile {np.percentile(L, 90) * 100:.1f} cm, median {np.median(L) * 100:.1f} cm; "
        f"reach {reach * 100:.1f} cm (share let through {min(1.0, reach / L.max()):.3f}); "
        f"{int((L > reach).sum())} of {cols.size} ask more than the reach"
    )
    # how firmly the rows hold each control point against the fairness: the traces of
    # their diagonal blocks in the normal equations (targets on their closest samples,
    # along the normal and point to point; probes along their ways out)
    w, w_sum, closest = s["w"], s["w_sum"], s["closest"]
    per_sample = np.bincount(closest[w > 0], weights=w[w > 0] / w_sum, minlength=s["limit"].shape[0])
    lim_sq = s["limit"].multiply(s["limit"]).tocsr()
    held = (1.0 + 3.0 * s["point_to_point"]) * (lim_sq.T @ per_sample)
    idx, wp = s["pen"][0], s["pen"][4]
    held += s["probe"][idx].multiply(s["probe"][idx]).T @ wp
    ratio = held[cols] / np.maximum(s["fairness_diag"], 1e-300)  # per moving point
    top = np.argsort(-L)[:6]
    print(
        "  asking most (rows' hold / fairness's): "
        + ", ".join(f"{cols[j]} ({L[j] * 100:.0f} cm, {ratio[j]:.1f}x, {'/'.join(sorted(labels.get(int(cols[j]), ['?'])))})" for j in top)
        + f"; the median point {np.median(ratio):.0f}x"
    )
    dX = s["limit"] @ (solved - P)
    along = np.abs(np.einsum("ij,ij->i", dX, s["N"]))
    across = np.linalg.norm(dX - np.einsum("ij,ij->i", dX, s["N"])[:, None] * s["N"], axis=1)
    print(
        f"  limit samples' motion: along the normal median {np.median(along) * 1000:.1f} mm, max {along.max() * 100:.1f} cm; "
        f"across it (sliding) median {np.median(across) * 1000:.1f} mm, max {across.max() * 100:.1f} cm"
    )
    w_base, dist = s["w_base"], s["dist"]
    idx, g, foot, gap, wp = s["pen"][:5]
    behind = w > w_base
    retreat = np.einsum("kc,kc->k", g, s["N_probe"][idx]) < -0.99
    inside = s["depth"][idx] > 0
    print(
        f"  row weights (sum, the targets' importance sum is 1): targets {w[~behind].sum() / w_sum:.2f} ({int((w[~behind] > 0).sum())}), "
        f"targets behind the surface {w[behind].sum() / w_sum:.1f} ({int(behind.sum())}), "
        f"probes {wp.sum():.1f} ({idx.size}, {int(inside.sum())} inside); fairness {s['fairness_diag'].sum():.3f} (trace)"
    )
    far = dist > 0.05
    groups = {
        "targets, not behind, within 5 cm": ("w", (w > 0) & ~behind & ~far),
        "targets, not behind, beyond 5 cm": ("w", (w > 0) & ~behind & far),
        "targets behind the surface": ("w", behind),
        "probes leaving backwards (-n)": ("pen", retreat),
        "probes inside, nearest side": ("pen", ~retreat & inside),
        "probes outside, within the clearance": ("pen", ~retreat & ~inside),
    }
    for name, (kind, sel) in groups.items():
        if kind == "w":
            sol = s["solve"](np.where(sel, 0.0, w), s["pen"])
        else:
            sol = s["solve"](w, tuple(a[~sel] for a in s["pen"]))
        Lg = moves(sol.reshape(3, cols.size).T - P[cols])
        print(f"  without {name:38s} ({int(sel.sum()):4d} rows): longest {Lg.max() * 100:5.1f} cm, median {np.median(Lg) * 100:5.1f} cm")
    shares = sorted({0.0, round(min(1.0, reach / L.max()), 3), 0.25, 0.5, 1.0})
    for t in shares:
        _, _, _, _, mean, _, depth = s["measure"](P + t * (solved - P))
        print(
            f"  step taken at {t:5.3f}: mean distance {mean * 1000:5.1f} mm, deepest probe {depth.max() * 1000:5.1f} mm, "
            f"probes inside {int((depth > 0).sum())}"
        )


def picture(path: str, s: dict, mesh, body) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from seatkit.refine.quality import mesh_edges

    P, step = s["P"], s["solved"] - s["P"]
    L = moves(step)
    X, deep = s["X"], s["depth_samples"] > 0.003
    fig, axes = plt.subplots(1, 2, figsize=(16, 8))
    for ax, (a, b, name) in zip(axes, [(2, 1, "from the side (z, y)"), (0, 2, "from above (x, z)")]):
        ax.scatter(body.vertices[::3, a], body.vertices[::3, b], s=0.3, c="0.8")
        ax.scatter(X[:, a], X[:, b], s=0.5, c="tab:blue", alpha=0.3, label="limit samples")
        ax.scatter(X[deep, a], X[deep, b], s=2, c="tab:red", label="probes deeper than 3 mm")
        for e in mesh_edges(mesh.faces):
            ax.plot(P[e, a], P[e, b], c="0.5", lw=0.5)
        sc = ax.scatter(P[:, a], P[:, b], c=L * 100, cmap="viridis", s=30, vmin=0, vmax=L.max() * 100, zorder=5)
        ax.quiver(P[:, a], P[:, b], step[:, a], step[:, b], angles="xy", scale_units="xy", scale=1, width=0.003, zorder=6)
        ends = np.concatenate([P, P + step])
        pad = 0.05
        ax.set_xlim(ends[:, a].min() - pad, ends[:, a].max() + pad)
        ax.set_ylim(ends[:, b].min() - pad, ends[:, b].max() + pad)
        ax.set_aspect("equal")
        ax.set_title(f"{name}: the first solved step, true length (reach {s['reach'] * 100:.1f} cm)")
        ax.legend(loc="lower left", fontsize=8)
    fig.colorbar(sc, ax=axes, label="requested move of the control point, cm")
    fig.savefig(path, dpi=72)
    print(f"\nwrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--template", default="chair")
    ap.add_argument("--body", default="default-male")
    ap.add_argument("--pose", default="upright-sitting")
    ap.add_argument("--iterations", type=int, default=3, help="steps looked at")
    ap.add_argument("--png", help="draw the first step here")
    args = ap.parse_args()

    mesh, bodies, pressures, params = capture(args.template, args.body, args.pose)
    steps, fit = observe(mesh, bodies, pressures, params, args.iterations)
    print(
        f"{args.template} for {args.body} in {args.pose}: {fit['iterations']} iterations; share of the step let through: "
        + ", ".join(f"{x:.2f}" for x in fit["step_scale"][:10])
        + "; deepest probe (mm): "
        + ", ".join(f"{x * 1000:.1f}" for x in fit["depth_history"][:10])
    )
    labels: dict = {}
    for f, face in enumerate(mesh.faces):
        for v in face:
            labels.setdefault(int(v), set()).add(str(mesh.face_labels[f]))
    for i, s in enumerate(steps):
        report(i, s, labels)
    if args.png and steps:
        picture(args.png, steps[0], mesh, bodies[0])


if __name__ == "__main__":
    main()
