"""The geometry kernels of the surface fit and the evaluation, in CPU time, optionally side by side with another checkout's.

    python benchmarks/bench_geometry.py [--pose upright-sitting] [--repeat 9] [--against /path/to/other/checkout]

On the default male body in a library pose and the chair's cage for it
(the template's, not fitted: its limit surface lies near the body, as the
fit's does), each kernel's CPU time (``time.process_time``: other jobs on
a shared machine count little), the median of ``--repeat`` calls:

- the skin's set-up (:class:`seatkit.geometry.skin.SkinDistance` with its
  open-space grid), its signed-distance query on 1,000 points the fit asks
  (level-3 limit points the open-space grid cannot rule out) and on the
  points of the 5 mm check (level-4 limit points and quad centres outside
  the open space);
- the body's vertex normals (:func:`seatkit.geometry.normals.vertex_normals`);
- a :class:`seatkit.geometry.surface.SurfaceQuery` of the level-4 surface,
  set up and asked for every body vertex's closest point, and for 25 of
  them (the fit's final check asks about the few body vertices inside the
  furniture);
- :func:`seatkit.geometry.surface.inside_furniture` of every body vertex.

With ``--against``, the same kernels of another checkout (its
``seatkit/geometry/skin.py``, ``surface.py`` and ``normals.py``, loaded
from their files beside the installed seatkit) run interleaved with the
installed ones, call for call, in this one process, and the median of the
per-call ratios (other / installed) is printed: a load that comes and goes
falls on both alike.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pose", default="upright-sitting")
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("--against", help="a checkout of another version of seatkit (its seatkit/geometry files are loaded)")
    args = ap.parse_args()

    from seatkit.body import load_pose, load_rig, pose_rig
    from seatkit.geometry import normals, skin, surface
    from seatkit.plugins import get_plugin_manager
    from seatkit.pressure import solve_pressure
    from seatkit.subdivision import limit_surface

    body = pose_rig(load_rig("default-male", mass=75.0), load_pose(args.pose), ground=True)
    cage = get_plugin_manager(autoload=False).registry.get("template", "chair").fit([body], [solve_pressure(body)])
    level3, level4 = limit_surface(cage, 3), limit_surface(cage, 4)
    v, f = body.vertices, body.faces

    versions = [(skin, surface, normals)]
    if args.against:
        geometry = Path(args.against) / "seatkit" / "geometry"
        versions.insert(0, tuple(_load(f"other_{m}", geometry / f"{m}.py") for m in ("skin", "surface", "normals")))
    ready = [sk.SkinDistance(v, f).prepare() for sk, _, _ in versions]
    near = np.flatnonzero(ready[-1].clear_of(level3.vertices) < 0.006)  # what the fit asks
    batch = level3.vertices[np.resize(near, 1000)] if near.size else level3.vertices[:1000]
    check = np.concatenate([level4.vertices, level4.vertices[level4.faces].mean(axis=1)])
    check = check[~ready[-1]._in_open_space(check)]

    def kernels(k):
        sk, su, no = versions[k]
        return [
            ("skin set-up (with its open-space grid)", lambda: sk.SkinDistance(v, f).prepare()),
            ("skin query, 1,000 points the fit asks", lambda: ready[k].query(batch)),
            (f"skin query, {len(check):,} points of the 5 mm check", lambda: ready[k].query(check)),
            (f"vertex normals of the body ({len(v):,} vertices)", lambda: no.vertex_normals(v, f)),
            ("SurfaceQuery of level 4: set-up and every body vertex", lambda: su.SurfaceQuery(level4).closest_normals(v)),
            ("SurfaceQuery of level 4: set-up and 25 body vertices (as the final check's inside the furniture)", lambda: su.SurfaceQuery(level4).closest_normals(v[::534])),
            ("inside_furniture, level 4, every body vertex", lambda: su.inside_furniture(level4, v)),
        ]

    table = [kernels(k) for k in range(len(versions))]
    print(f"default-male, {args.pose}: {len(v):,} skin vertices; chair cage of {len(cage.vertices)} control points")
    head = "| kernel | " + ("other | installed | other / installed |" if args.against else "installed |")
    print(head)
    print("|---|" + "---:|" * (3 if args.against else 1))
    for row in zip(*table):
        times = [[] for _ in row]
        for _ in range(args.repeat):
            for k, (_, fn) in enumerate(row):
                start = time.process_time()
                fn()
                times[k].append(time.process_time() - start)
        cells = [f"{np.median(t) * 1000:.1f} ms" for t in times]
        if args.against:
            cells.append(f"{np.median(np.array(times[0]) / np.array(times[1])):.2f}x")
        print(f"| {row[0][0]} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
