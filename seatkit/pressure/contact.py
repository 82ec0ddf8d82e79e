"""Contact sets: which body vertices touch a support surface."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from seatkit.model import Body, PressureField

__all__ = ["contact_from_surface", "sample_triangles", "supported_vertices", "SUPPORTED_FRACTION"]

#: A vertex is "supported" when its importance-map pressure is at least this
#: fraction of the maximum.
SUPPORTED_FRACTION = 0.01


def sample_triangles(vertices: np.ndarray, faces: np.ndarray, spacing: float) -> np.ndarray:
    """Points covering every triangle at most ``spacing`` apart.

    Each triangle gets a barycentric grid with ``s`` subdivisions per side,
    ``s = ceil(longest edge / spacing)``; triangles are grouped by ``s`` so
    the work is vectorised.

    Parameters
    ----------
    vertices : (p, 3) float64
    faces : (q, 3) int64 (or (q, 4) quads, split into two triangles)
    spacing : float
        Largest distance between neighbouring samples, m.

    Returns
    -------
    points : (s, 3) float64
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if faces.shape[1] == 4:
        faces = np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
    tri = vertices[faces]
    edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    subdiv = np.maximum(1, np.ceil(edges / spacing).astype(np.int64))
    out = [vertices]
    for s in np.unique(subdiv):
        i, j = np.meshgrid(np.arange(s + 1), np.arange(s + 1), indexing="ij")
        keep = (i + j) <= s
        bary = np.stack([i[keep], j[keep], s - i[keep] - j[keep]], axis=1) / s  # (b, 3)
        group = tri[subdiv == s]  # (g, 3, 3)
        out.append(np.einsum("bc,gcd->gbd", bary, group).reshape(-1, 3))
    return np.concatenate(out)


def contact_from_surface(body, surface, distance: float) -> np.ndarray:
    """Body vertices within ``distance`` of a support surface.

    Parameters
    ----------
    body : Body
    surface : (p, 3) float64 points, or (vertices, faces), or an object with
        ``vertices`` and ``faces`` (trimesh, :class:`seatkit.model.Surface`)
        A mesh is sampled densely (spacing ``distance / 4``), so vertices
        within ``distance`` are always found and vertices up to
        ``1.25 distance`` away may be included.
    distance : float
        Contact distance, m.

    Returns
    -------
    contact : (n,) bool
    """
    if hasattr(surface, "vertices") and hasattr(surface, "faces"):
        points = sample_triangles(surface.vertices, surface.faces, distance / 4.0)
        slack = distance / 4.0
    elif isinstance(surface, tuple) and len(surface) == 2:
        points = sample_triangles(surface[0], surface[1], distance / 4.0)
        slack = distance / 4.0
    else:
        points = np.asarray(surface, dtype=np.float64).reshape(-1, 3)
        slack = 0.0
    tree = cKDTree(points, balanced_tree=False, compact_nodes=False)  # much faster queries here
    nearest, _ = tree.query(body.vertices, k=1, distance_upper_bound=distance + slack)
    return np.isfinite(nearest)


def supported_vertices(pressure: PressureField, body: Body | None = None, segments=None) -> np.ndarray:
    """(n,) bool: vertices that carry load in the importance map.

    With ``segments`` (segment indices) and ``body``, only vertices whose
    dominant skinning segment is one of them: the body parts the design
    means to support (the paper compares designs on the same parts).
    """
    peak = float(pressure.pressure.max()) if pressure.pressure.size else 0.0
    if peak <= 0:
        return np.zeros(pressure.pressure.shape, dtype=bool)
    mask = pressure.pressure >= SUPPORTED_FRACTION * peak
    if segments is not None and body is not None:
        owner = np.argmax(body.weights, axis=1)
        mask &= np.isin(owner, np.asarray(list(segments), dtype=np.int64))
    return mask
