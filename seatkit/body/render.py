"""Preview pictures of a triangle mesh (a body), optionally coloured by a scalar.

Matplotlib only (Agg backend), so it runs headless anywhere. Triangles are
drawn back to front (painter's algorithm) with flat Lambert shading; a
per-vertex scalar (pressure, a region mask, a weight) colours the mesh
through a colour map with a colour bar. Other stages reuse
:func:`render_body` for pressure pictures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

__all__ = ["VIEWS", "render_body", "view_axes"]

#: Camera of each named view: (screen right, screen up, towards the viewer),
#: unit vectors in world axes (+Y up, body facing +Z).
VIEWS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "front": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "back": ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    # seen from the body's right-hand side (-X): the body faces screen right
    "side": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0)),
    "left": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)),
    # from above, the body's front at the bottom of the picture
    "top": ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "bottom": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),
}


def view_axes(view: str | Sequence[float]) -> np.ndarray:
    """Camera axes of a view.

    Parameters
    ----------
    view : str or (azimuth_deg, elevation_deg)
        A name of :data:`VIEWS`, or azimuth about +Y from the front (degrees,
        positive turns towards the body's left) and elevation above the
        horizon (degrees).

    Returns
    -------
    axes : (3, 3) float64
        Rows: screen right, screen up, towards the viewer.
    """
    if isinstance(view, str):
        try:
            return np.array(VIEWS[view], dtype=np.float64)
        except KeyError:
            msg = f"unknown view {view!r}; expected one of {', '.join(VIEWS)} or (azimuth, elevation) in degrees"
            raise ValueError(msg) from None
    az, el = np.radians(np.asarray(view, dtype=np.float64))
    toward = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    right = np.cross([0.0, 1.0, 0.0], toward)
    right /= np.linalg.norm(right)
    up = np.cross(toward, right)
    return np.stack([right, up, toward])


def render_body(
    body,
    path,
    *,
    scalars=None,
    views: Sequence = ("front", "side"),
    cmap: str = "viridis",
    title: str | None = None,
    clim: tuple[float, float] | None = None,
    scalar_label: str = "",
    show_skeleton: bool = False,
    show_ground: bool = True,
    panel_size: float = 4.0,
    dpi: int = 110,
    base_color=(0.82, 0.70, 0.60),
) -> Path:
    """Draw a mesh from one or more views into a PNG.

    Parameters
    ----------
    body : Body, RiggedBody or any object with ``vertices`` (n, 3) and ``faces`` (m, 3)
        If it has ``joints`` and ``tips`` (21, 3) they can be drawn.
    path : str or Path
        Output PNG (written atomically).
    scalars : (n,) array_like, optional
        Per-vertex values; each triangle gets the mean of its corners. NaN
        values are drawn in the base colour.
    views : sequence
        View names (:data:`VIEWS`) or (azimuth, elevation) pairs in degrees.
    cmap : str
        Matplotlib colour map for ``scalars``.
    title : str, optional
    clim : (float, float), optional
        Colour range; default the finite range of ``scalars``.
    scalar_label : str
        Colour bar label (with units).
    show_skeleton : bool
        Draw the bones (joint -> tip) and joints on top.
    show_ground : bool
        Draw the ground line y = 0 in side and front views.
    panel_size : float
        Inches per view panel.
    dpi : int
    base_color : RGB tuple
        Colour of the mesh without scalars.

    Returns
    -------
    Path
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from seatkit.io import atomic_write

    vertices = np.asarray(body.vertices, dtype=np.float64)
    faces = np.asarray(body.faces, dtype=np.int64)
    tri = vertices[faces]  # (m, 3, 3)
    face_normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face_normal /= np.maximum(np.linalg.norm(face_normal, axis=1, keepdims=True), 1e-15)

    face_value = None
    norm = None
    colormap = plt.get_cmap(cmap)
    if scalars is not None:
        values = np.asarray(scalars, dtype=np.float64)
        if values.shape != (len(vertices),):
            msg = f"scalars must be ({len(vertices)},), got {values.shape}"
            raise ValueError(msg)
        face_value = values[faces].mean(axis=1)
        finite = face_value[np.isfinite(face_value)]
        lo, hi = clim if clim is not None else ((finite.min(), finite.max()) if finite.size else (0.0, 1.0))
        if hi <= lo:
            hi = lo + 1.0
        norm = matplotlib.colors.Normalize(vmin=lo, vmax=hi)

    n_views = len(views)
    fig, axes = plt.subplots(1, n_views, figsize=(panel_size * n_views + (0.8 if norm else 0.0), panel_size * 1.25), squeeze=False)
    for ax, view in zip(axes[0], views):
        cam = view_axes(view)
        screen = tri @ cam[:2].T  # (m, 3, 2)
        depth = (tri @ cam[2]).mean(axis=1)
        order = np.argsort(depth)
        # flat shading: a key light from the viewer, up and to the left, plus ambient
        light = cam[2] * 0.8 + cam[1] * 0.45 - cam[0] * 0.3
        light /= np.linalg.norm(light)
        shade = 0.35 + 0.65 * np.abs(face_normal @ light)
        if face_value is not None:
            rgb = colormap(norm(np.nan_to_num(face_value, nan=norm.vmin)))[:, :3]
            rgb[~np.isfinite(face_value)] = base_color
        else:
            rgb = np.broadcast_to(np.asarray(base_color, dtype=np.float64), (len(faces), 3)).copy()
        colors = np.clip(rgb * shade[:, None], 0.0, 1.0)
        ax.add_collection(PolyCollection(screen[order], facecolors=colors[order], edgecolors="none", antialiased=False))
        pts = vertices @ cam[:2].T
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.05 * (hi - lo).max()
        if show_ground and cam[1][1] > 0.999:
            ax.axhline(0.0, color="0.4", lw=0.8, ls="--")
            lo[1] = min(lo[1], 0.0)
        if show_skeleton and hasattr(body, "joints") and hasattr(body, "tips"):
            j = np.asarray(body.joints) @ cam[:2].T
            t = np.asarray(body.tips) @ cam[:2].T
            for a, b in zip(j, t):
                ax.plot([a[0], b[0]], [a[1], b[1]], color="k", lw=1.2, zorder=5)
            ax.scatter(j[:, 0], j[:, 1], s=8, color="r", zorder=6)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_title(view if isinstance(view, str) else f"az {view[0]:g}, el {view[1]:g}", fontsize=9)
        ax.tick_params(labelsize=7)
    if norm is not None:
        sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=colormap)
        fig.colorbar(sm, ax=axes[0].tolist(), shrink=0.8, label=scalar_label)
    if title:
        fig.suptitle(title, fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, "wb") as f:
        fig.savefig(f, format="png", dpi=dpi)
    plt.close(fig)
    return path
