"""A drawn pose's first chair cage and its walled version, cut across the seat through the hands.

Poses a draw of ``seatkit.body.generator`` (draw seed 2026, as the
generalisation benchmark), fits the chair and asks ``YamlTemplate.fits``
for its first two cages: the first, and, when it encloses a hand, the same
start's cage with its side walls inside the hands (docs/templates.md,
"Walls inside the hands"). Draws both cut by the plane ``z = --z``:
the cage, its limit surface (level 3), the body within 3 cm of the plane,
the hands outside the furniture and those more than 7 mm inside it
(``seatkit.template.checks.enclosed_parts``).

    python benchmarks/draw_enclosure.py seated 12 --body default-female --z 0.05 --out walls.png
"""

from __future__ import annotations

import argparse

import numpy as np


def plane_cuts(V: np.ndarray, quads: np.ndarray, z: float) -> list:
    """The segments (each (2, 2): x, y) where the plane ``z`` cuts the quads' two triangles each."""
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    out = []
    for t in V[tris]:
        s = t[:, 2] - z
        pts = [(t[i] + s[i] / (s[i] - s[(i + 1) % 3]) * (t[(i + 1) % 3] - t[i]))[:2] for i in range(3) if (s[i] < 0) != (s[(i + 1) % 3] < 0)]
        if len(pts) == 2:
            out.append(np.array(pts))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("index", type=int)
    ap.add_argument("--body", default="default-female")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--z", type=float, default=0.05, help="the cutting plane, m (the body faces +z)")
    ap.add_argument("--out", default="enclosure.png")
    args = ap.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from seatkit.body import load_rig, pose_rig
    from seatkit.body.generator import draw_pose
    from seatkit.pressure.qp import solve_pressure
    from seatkit.resources import template_path
    from seatkit.skeleton import SEGMENT_INDEX
    from seatkit.subdivision import Cage, build_operators
    from seatkit.template import load_template
    from seatkit.template.checks import enclosed_parts

    body = pose_rig(load_rig(args.body), draw_pose(np.random.default_rng([2026, args.index]), args.family).pose)
    chair = load_template(template_path("chair.yaml"))
    cages = chair.fits([body], [solve_pressure(body)], seed=args.seed)
    first = next(cages)
    second = next(cages, None)
    shown = [(first, "first cage")] + ([(second, "walls inside the hands (offered next)")] if second is not None and second.meta["fit_attempts"].get("walls_inside") else [])
    hand = np.isin(np.asarray(body.weights).argmax(1), [SEGMENT_INDEX["RightHand"], SEGMENT_INDEX["LeftHand"]])
    near = np.abs(body.vertices[:, 2] - args.z) < 0.03
    fig, axes = plt.subplots(1, len(shown), figsize=(6 * len(shown), 5.2), sharey=True, squeeze=False)
    top = max(float(np.concatenate(plane_cuts(mesh.vertices, mesh.faces, args.z))[:, 1].max()) for mesh, _ in shown) + 0.3
    for ax, (mesh, title) in zip(axes[0], shown):
        found = enclosed_parts(mesh, [body], 0.007)[0]
        inside = np.zeros(len(body.vertices), bool)
        inside[found["vertices"]] = True
        ops = build_operators(Cage(mesh.vertices, mesh.faces), 3)
        for V, quads, colour, width, label in ((mesh.vertices, mesh.faces, "tab:blue", 1.0, "cage"), (ops.limit_points(mesh.vertices), ops.faces, "tab:green", 2.0, "limit surface")):
            for i, seg in enumerate(plane_cuts(V, quads, args.z)):
                ax.plot(seg[:, 0], seg[:, 1], color=colour, lw=width, label=label if i == 0 else None)
        for sel, size, colour, label in ((near & ~hand, 1, "0.6", "body (z within 3 cm)"), (near & hand & ~inside, 3, "tab:orange", "hands, outside"), (near & hand & inside, 3, "red", "hands, > 7 mm inside the furniture")):
            ax.scatter(body.vertices[sel, 0], body.vertices[sel, 1], s=size, c=colour, label=label)
        ax.set_title(f"{args.family}-{args.index:03d}, {args.body}, seed {args.seed}: {title}\nhands inside: up to {1000 * found['depth_m']:.0f} mm", fontsize=10)
        ax.set_aspect("equal")
        ax.set_ylim(-0.02, top)
        ax.set_xlabel("x (m)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("y (m)")
    axes[0][-1].legend(loc="upper right", fontsize=8)
    plt.tight_layout()
    plt.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
