"""Benchmark: Catmull-Clark operators of a ~400-face cage (and a figure).

Run ``python benchmarks/bench_subdivision.py`` to print timings;
``--figure PATH`` also draws a creased cage over its limit surface.

Figures printed: building the level-3 operators (topology only, first call,
cache cleared), a cached lookup, applying them (limit positions and unit
normals for one set of control points), for a 20 x 20 grid (400 quads) and
for the chair-like cage of the OpenSubdiv tests scaled to ~400 faces.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from seatkit.subdivision import Cage, build_operators, limit_surface
from seatkit.subdivision import catmull_clark as _cc
from seatkit.subdivision import topology as _topo


def grid_cage(n: int = 20) -> Cage:
    xs, zs = np.meshgrid(np.linspace(0, 0.5, n + 1), np.linspace(0, 0.5, n + 1))
    v = np.c_[xs.ravel(), 0.02 * np.sin(8 * xs.ravel()) * np.cos(6 * zs.ravel()), zs.ravel()]
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    faces = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1).reshape(-1, 4)
    row = idx[n // 2]
    crease = np.stack([row[:-1], row[1:]], axis=1)
    return Cage(v, faces, crease_edges=crease, crease_sharpness=np.full(len(crease), 2.3))


def _best(fn, repeat: int = 7) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def bench(cage: Cage, level: int = 3, label: str = "") -> None:
    def build():
        _cc._OPS_CACHE.clear()
        _topo._LEVEL_CACHE.clear()
        build_operators(cage, level)

    t_build = _best(build)
    ops = build_operators(cage, level)
    t_cached = _best(lambda: build_operators(cage, level), 50)
    P = cage.vertices
    t_apply = _best(lambda: (ops.limit @ P, ops.limit_normals(P)), 20)
    t_surface = _best(lambda: limit_surface(cage, level), 20)
    print(
        f"{label:<28} faces {cage.n_faces:4d}  level {level}  refined {ops.n_points:6d} pts  "
        f"nnz(limit) {ops.limit.nnz:7d}  build {1e3 * t_build:6.1f} ms  cached {1e6 * t_cached:6.1f} us  "
        f"apply {1e3 * t_apply:5.2f} ms  limit_surface (cached ops) {1e3 * t_surface:5.2f} ms"
    )


def figure(path: str) -> None:
    """A ridge cage: control net over the limit surface; left half sharp, right half smooth."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    n = 6
    xs, zs = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    y = np.where(zs == 3, 1.6, 0.0) + 0.25 * np.cos(xs)
    v = np.c_[xs.ravel(), y.ravel(), zs.ravel()]
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    faces = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1).reshape(-1, 4)
    ridge = np.stack([idx[3, :3], idx[3, 1:4]], axis=1)  # crease on the left half of the ridge
    fig = plt.figure(figsize=(12, 5.5))
    for k, (sharp, title) in enumerate([(10.0, "infinitely sharp crease"), (1.5, "semi-sharp crease (1.5)")]):
        cage = Cage(v, faces, crease_edges=ridge, crease_sharpness=np.full(len(ridge), sharp), corners=[idx[0, 0]])
        surf = limit_surface(cage, level=4)
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        X = surf.vertices[:, [0, 2, 1]]  # plot with y up
        light = np.clip(surf.normals @ np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5]), 0, 1)
        shade = light[surf.faces].mean(axis=1)
        polys = Poly3DCollection(X[surf.faces], facecolors=plt.cm.Blues(0.35 + 0.6 * shade), edgecolors="none")
        polys.set_alpha(0.95)
        ax.add_collection3d(polys)
        C = v[:, [0, 2, 1]]
        for f in faces:
            loop = np.append(f, f[0])
            ax.plot(*C[loop].T, color="k", lw=0.6, alpha=0.8)
        for a, b in ridge:
            ax.plot(*C[[a, b]].T, color="crimson", lw=2.5)
        ax.scatter(*C.T, color="k", s=6)
        ax.set_xlim(0, n), ax.set_ylim(0, n), ax.set_zlim(-0.5, 2.0)
        ax.view_init(elev=28, azim=-60)
        ax.set_title(f"{title} (red), level-4 limit surface\nleft half of the ridge creased, right half smooth")
        ax.set_xlabel("x"), ax.set_ylabel("z"), ax.set_zlabel("y")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"{path}: figure written")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figure", help="also write the crease figure to this PNG")
    args = ap.parse_args()
    bench(grid_cage(20), 3, "20x20 grid, semi-sharp row")
    bench(grid_cage(20), 2, "20x20 grid, semi-sharp row")
    bench(grid_cage(20), 4, "20x20 grid, semi-sharp row")
    if args.figure:
        figure(args.figure)


if __name__ == "__main__":
    main()
