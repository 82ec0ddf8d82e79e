"""Pictures of a fitted cage with its bodies (front, side, three-quarter).

Drawn with :mod:`seatkit.picture`, as the report's ``cage.png``: the bodies
opaque and Gouraud-shaded, the cage's faces translucent and flat, coloured by
role (supporting faces blue, structural ones grey), its edges and control
points on top with the lines its own faces hide left out (those behind a
body only drawn light). All views at one scale.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from seatkit import picture as pic
from seatkit.picture import draw as pic_draw
from seatkit.geometry.normals import vertex_normals

__all__ = ["VIEWS", "render_cage"]

#: Camera (azimuth, elevation) of each view, degrees (:func:`seatkit.picture.view_rotation`).
VIEWS = {"front": (0.0, 0.0), "side": (-90.0, 0.0), "three-quarter": (-40.0, 20.0), "back": (180.0, 10.0), "top": (0.0, 89.0)}
#: Colours: the bodies, supporting and structural cage faces (RGB in [0, 1]); edges (RGB bytes).
BODY_RGB = np.array([0.86, 0.72, 0.60])
SUPPORT_RGB, STRUCTURE_RGB = np.array([0.20, 0.45, 0.85]), np.array([0.60, 0.60, 0.60])
EDGE_RGB, EDGE_HIDDEN_RGB = (13, 26, 77), (140, 150, 190)
#: Opacity of the cage's faces.
CAGE_ALPHA = 0.4


def _flat_quads(vertices: np.ndarray, quads: np.ndarray, colours: np.ndarray):
    """Per-face copies of the quads' corners: (4f, 3) vertices, (2f, 3) triangles, flat normals and colours."""
    corners = vertices[quads]  # (f, 4, 3)
    normal = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-15)
    local = np.arange(len(quads))[:, None] * 4
    tris = np.concatenate([local + [0, 1, 2], local + [0, 2, 3]])
    return corners.reshape(-1, 3), tris, np.repeat(normal, 4, axis=0), np.repeat(colours, 4, axis=0)


def render_cage(mesh, bodies, path, *, views: Sequence[str] = ("front", "side", "three-quarter"), title: str = "", dpi: int = 90) -> Path:
    """Draw ``bodies`` and the cage ``mesh`` into a PNG, one panel per view.

    Parameters
    ----------
    mesh : ControlMesh
    bodies : sequence of Body
    path : str or Path
        Output PNG (written atomically).
    views : sequence of str
        Names among front, side, three-quarter, back, top.
    title : str
    dpi : int
        Panels are ``4.2 * dpi`` by ``4.4 * dpi`` pixels.

    Returns
    -------
    Path
    """
    from seatkit.io import write_bytes_atomic

    unknown = [v for v in views if v not in VIEWS]
    if unknown:
        msg = f"unknown view {unknown[0]!r}; expected one of {', '.join(VIEWS)}"
        raise ValueError(msg)
    cage_v = np.asarray(mesh.vertices, dtype=np.float64)
    quads = np.asarray(mesh.faces, dtype=np.int64)
    support = np.asarray(mesh.face_segments) >= 0
    fv, ft, fn, fc = _flat_quads(cage_v, quads, np.where(support[:, None], SUPPORT_RGB, STRUCTURE_RGB))
    sizes = [len(b.vertices) for b in bodies]
    offsets = np.cumsum([0, *sizes[:-1]])
    body_v = np.concatenate([np.asarray(b.vertices, dtype=np.float64) for b in bodies])
    body_f = np.concatenate([np.asarray(b.faces, dtype=np.int64) + o for b, o in zip(bodies, offsets)])
    body_n = vertex_normals(body_v, body_f)
    body_c = np.broadcast_to(BODY_RGB, body_v.shape)
    width, height = round(4.2 * dpi), round(4.4 * dpi)
    frames = pic.fit_frames([cage_v, body_v], [pic.view_rotation(*VIEWS[v]) for v in views], width, height)
    panels = []
    for view, frame in zip(views, frames):
        body_r = pic.rasterize(frame, body_v, body_f)
        cage_r = pic.rasterize(frame, fv, ft)
        layers = [
            (body_r, body_r.shade(pic.light_vertices(body_c, body_n, frame.rotation)), 1.0),
            (cage_r, cage_r.shade(pic.light_vertices(fc, fn, frame.rotation)), CAGE_ALPHA),
        ]
        image = pic.to_pil(pic.composite(pic.BACKGROUND, layers))
        pic_draw.draw_wire(image, frame, cage_v, quads, cage_r.depth, body_r.depth, colour=EDGE_RGB, hidden_colour=EDGE_HIDDEN_RGB)
        panels.append((image, view))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_bytes_atomic(path, pic.png_bytes(pic.sheet(title, panels)))
