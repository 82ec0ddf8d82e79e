"""Benchmark the refiners on the default seated body, and draw them.

Run: ``python benchmarks/bench_refine.py [--pose upright-sitting] [--repeat 5]
[--png docs/images/refine-upright-sitting.png]``

Prints wall times of ``optimize`` and ``catmull-clark-fit`` on the chair cage
(when the chair template fits the pose) and of ``catmull-clark-fit`` on the
flat-patch baseline, with the quality and distance figures, and writes a PNG
of cage, limit surface and body before and after.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def _timed(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return out, statistics.median(times), min(times)


def _draw(path, body, targets, panels):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from seatkit.subdivision import limit_surface

    fig = plt.figure(figsize=(5 * len(panels), 10))
    for k, (title, mesh) in enumerate(panels):
        surface = limit_surface(mesh, level=3)
        for row, view in enumerate([(12, -90), (15, -35)]):
            ax = fig.add_subplot(2, len(panels), row * len(panels) + k + 1, projection="3d")
            v = body.vertices[::5]
            ax.scatter(v[:, 0], v[:, 2], v[:, 1], s=0.2, c="0.75")
            ax.scatter(targets[:, 0], targets[:, 2], targets[:, 1], s=0.4, c="crimson")
            quads = surface.vertices[surface.faces][:, :, [0, 2, 1]]
            ax.add_collection3d(Poly3DCollection(quads, facecolor="steelblue", edgecolor="none", alpha=0.35))
            cv = mesh.vertices
            for f in mesh.faces:
                loop = cv[np.r_[f, f[0]]]
                ax.plot(loop[:, 0], loop[:, 2], loop[:, 1], "k-", lw=0.5)
            ax.set_xlim(-0.5, 0.5)
            ax.set_ylim(-0.4, 0.8)
            ax.set_zlim(0.0, 1.3)
            ax.set_box_aspect((1.0, 1.2, 1.3))
            ax.view_init(*view)
            ax.set_title(title, fontsize=9)
            ax.set_xlabel("x")
            ax.set_ylabel("z")
            ax.set_zlabel("y")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pose", default="upright-sitting")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--png", default="")
    args = parser.parse_args()

    from seatkit.body import load_pose, load_rig, pose_rig
    from seatkit.errors import SeatkitError
    from seatkit.plugins import get_plugin_manager
    from seatkit.pressure import solve_pressure
    from seatkit.refine import CatmullClarkFitRefiner, OptimizeRefiner, fit_report
    from seatkit.template.flat_patch import FlatPatchTemplate
    from seatkit.refine.ccfit import supported_targets

    body = pose_rig(load_rig("default-male", mass=75.0), load_pose(args.pose), ground=True)
    pressure = solve_pressure(body)
    print(f"body: default-male, pose {args.pose}, {len(body.vertices)} vertices")
    fit = CatmullClarkFitRefiner()
    panels = []

    registry = get_plugin_manager(autoload=False).registry
    chair = None
    try:
        chair = registry.get("template", "chair").fit([body], [pressure])
    except SeatkitError as exc:
        print(f"chair template: not available for this pose ({exc})")
    segments = None
    if chair is not None:
        opt, med, best = _timed(lambda: OptimizeRefiner().refine(chair, [body], [pressure]), args.repeat)
        q = opt.meta["optimize"]
        print(
            f"optimize: {len(chair.vertices)} control points, {len(chair.faces)} faces: "
            f"median {med:.3f} s, best {best:.3f} s, {q['iterations']} L-BFGS-B iterations"
        )
        for key in ("planarity_mean", "planarity_max", "min_angle_deg", "regularity_deg"):
            print(f"  {key}: {q['before'][key]:.4g} -> {q['after'][key]:.4g}")
        fitted, med, best = _timed(lambda: fit.refine(opt, [body], [pressure]), args.repeat)
        r = fitted.meta["catmull-clark-fit"]
        ours = fit_report(fitted, [body], [pressure])
        print(
            f"catmull-clark-fit on the chair: median {med:.3f} s, best {best:.3f} s, "
            f"{r['iterations']} iterations, {r['supported_vertices']} supported vertices"
        )
        print(
            f"  mean distance {fit_report(opt, [body], [pressure])['mean_distance'] * 1000:.1f} mm -> "
            f"{ours['mean_distance'] * 1000:.1f} mm, max penetration {ours['max_penetration'] * 1000:.1f} mm"
        )
        segments = r["supported_segments"][0]
        panels += [("chair template", chair), ("+ optimize", opt), ("+ catmull-clark-fit", fitted)]

    flat = FlatPatchTemplate().fit([body], [pressure], params={"segments": segments} if segments else None)
    flat_fit, med, best = _timed(lambda: fit.refine(flat, [body], [pressure]), args.repeat)
    r = flat_fit.meta["catmull-clark-fit"]
    base = fit_report(flat_fit, [body], [pressure])
    print(
        f"catmull-clark-fit on the flat patch: median {med:.3f} s, best {best:.3f} s, "
        f"{r['iterations']} iterations; mean distance {fit_report(flat, [body], [pressure])['mean_distance'] * 1000:.1f} mm -> "
        f"{base['mean_distance'] * 1000:.1f} mm, max penetration {base['max_penetration'] * 1000:.1f} mm"
    )
    panels += [("flat patch", flat), ("flat patch + catmull-clark-fit", flat_fit)]
    if args.png:
        targets = supported_targets(flat_fit, [body], [pressure], threshold=0.02).points
        _draw(args.png, body, targets, panels)
        print(f"figure: {args.png}")


if __name__ == "__main__":
    main()
