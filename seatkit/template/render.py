"""Pictures of a fitted cage with its bodies (front, side, three-quarter).

Orthographic views drawn with matplotlib (Agg) by the painter's algorithm:
the body opaque with flat shading, the cage translucent with its edges, the
faces coloured by role (supporting faces blue, structural ones grey).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from seatkit.export.raster import view_rotation

__all__ = ["render_cage"]

_VIEWS = {"front": (0.0, 0.0), "side": (-90.0, 0.0), "three-quarter": (-40.0, 20.0), "back": (180.0, 10.0), "top": (0.0, 89.0)}


def render_cage(mesh, bodies, path, *, views: Sequence[str] = ("front", "side", "three-quarter"), title: str = "", dpi: int = 90) -> Path:
    """Draw ``bodies`` and the cage ``mesh`` into a PNG, one panel per view.

    Parameters
    ----------
    mesh : ControlMesh
    bodies : sequence of Body
    path : str or Path
    views : sequence of str
        Names among front, side, three-quarter, back, top.
    title : str

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    path = Path(path)
    fig, axs = plt.subplots(1, len(views), figsize=(4.2 * len(views), 4.6))
    axs = np.atleast_1d(axs)
    light = np.array([0.3, 0.8, 0.5])
    light /= np.linalg.norm(light)
    for ax, view in zip(axs, views):
        R = view_rotation(*_VIEWS[view])
        polys, colors, depth, edge = [], [], [], []
        for body in bodies:
            tri = body.vertices[body.faces]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
            facing = n @ R[2] > 0
            shade = 0.35 + 0.65 * np.abs(n @ light)
            p2 = tri[facing] @ R.T
            polys.extend(p2[:, :, :2])
            colors.extend(np.outer(shade[facing], [0.86, 0.72, 0.6]).tolist())
            depth.extend(p2[:, :, 2].mean(1))
            edge.extend([0] * int(facing.sum()))
        quad = mesh.vertices[mesh.faces]
        q2 = quad @ R.T
        for i in range(len(quad)):
            support = mesh.face_segments[i] >= 0
            base = np.array([0.2, 0.45, 0.85]) if support else np.array([0.6, 0.6, 0.6])
            polys.append(q2[i, :, :2])
            colors.append(list(base))
            depth.append(q2[i, :, 2].mean())
            edge.append(1)
        order = np.argsort(depth)
        polys = [polys[i] for i in order]
        colors = np.array([colors[i] for i in order])
        edge = np.array([edge[i] for i in order])
        alpha = np.where(edge == 1, 0.45, 1.0)
        rgba = np.hstack([colors, alpha[:, None]])
        ec = np.where(edge[:, None] == 1, np.array([[0.05, 0.1, 0.3, 0.9]]), rgba)
        ax.add_collection(PolyCollection(polys, facecolors=rgba, edgecolors=ec, linewidths=np.where(edge == 1, 0.8, 0.0)))
        allp = np.vstack([mesh.vertices] + [b.vertices for b in bodies]) @ R.T
        lo, hi = allp[:, :2].min(0), allp[:, :2].max(0)
        pad = 0.05 * (hi - lo).max()
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_title(view)
        ax.axis("off")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
    tmp.replace(path)
    return path
