"""Closest points on triangle meshes: the geometry the surface and skin queries share.

:func:`closest_barycentric` is Ericson's closest-point-on-triangle by
regions (Real-Time Collision Detection 5.1.5), from two dot products per
point and triangle (the other four follow from per-triangle constants, which
:class:`seatkit.geometry.skin.SkinDistance` keeps); :func:`closest_point_on_triangles`
is the same for explicit corners. :func:`vertex_triangle_rings` lists the
triangles around each vertex, the candidates both queries search.
"""

from __future__ import annotations

import numpy as np

__all__ = ["safe_ratio", "row_norms", "closest_barycentric", "closest_point_on_triangles", "vertex_triangle_rings"]


def safe_ratio(num, den) -> np.ndarray:
    """``num / den``, 0 where ``den`` is 0 (a degenerate triangle's edge or area)."""
    out = np.zeros(np.broadcast(num, den).shape)
    np.divide(num, den, out=out, where=den != 0)
    return out


def row_norms(a: np.ndarray) -> np.ndarray:
    """Euclidean lengths of 3-vectors along the last axis: ``np.linalg.norm(a, axis=-1)``, to the bit, about 5x faster.

    (The same sum in the same order, x*x + y*y + z*z, over the three
    components as columns: numpy's reduction along a short axis is slow.)
    """
    x, y, z = a[..., 0], a[..., 1], a[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def closest_barycentric(d1, d2, d00, d01, d11) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Barycentric coordinates (u, v, w) of the closest point of triangles to points.

    Ericson's regions from the two dot products ``d1 = ab . ap`` and
    ``d2 = ac . ap`` and the triangle's own ``ab . ab``, ``ab . ac``,
    ``ac . ac``. Coordinates on an edge or at a corner are exact zeros: a
    caller can tell the features apart by them.
    """
    shape = np.broadcast_shapes(np.shape(d1), np.shape(d2), np.shape(d00), np.shape(d01), np.shape(d11))
    if not shape:  # one point and triangle: as arrays of one (written in place below, by flat index)
        u, v, w = closest_barycentric(*(np.reshape(x, 1) for x in (d1, d2, d00, d01, d11)))
        return u.reshape(()), v.reshape(()), w.reshape(())
    d1, d2 = np.broadcast_to(d1, shape), np.broadcast_to(d2, shape)  # (read by flat index below)
    d3, d4, d5, d6 = d1 - d00, d2 - d01, d1 - d01, d2 - d11
    # (in place where a product or sum is only an intermediate: the same
    # operations in the same order, fewer temporaries)
    va = d3 * d6
    va -= d5 * d4
    vb = d5 * d2
    vb -= d1 * d6
    vc = d1 * d4
    vc -= d3 * d2
    denom = va + vb
    denom += vc
    v = safe_ratio(vb, denom)
    w = safe_ratio(vc, denom)
    u = 1.0 - v
    u -= w
    # edge regions, then corners (later ones take precedence, as in Ericson's
    # order reversed). The denominators are squared edge lengths: a triangle
    # with two coincident corners has a zero one, and its edge is a point.
    # A region's parameter is computed only where the region holds
    # (elementwise: the same values) and written there
    d43, d56 = d4 - d3, d5 - d6
    region = va <= 0
    region &= d43 >= 0
    region &= d56 >= 0
    k, t = _edge_parameter(region, d43, d56, 1.0)  # edge bc: d43 / (d43 + d56)
    np.put(u, k, 0.0), np.put(v, k, 1.0 - t), np.put(w, k, t)
    np.less_equal(vb, 0, out=region)
    region &= d2 >= 0
    region &= d6 <= 0
    k, t = _edge_parameter(region, d2, d6, -1.0)  # edge ac: d2 / (d2 - d6)
    np.put(u, k, 1.0 - t), np.put(v, k, 0.0), np.put(w, k, t)
    np.less_equal(vc, 0, out=region)
    region &= d1 >= 0
    region &= d3 <= 0
    k, t = _edge_parameter(region, d1, d3, -1.0)  # edge ab: d1 / (d1 - d3)
    np.put(u, k, 1.0 - t), np.put(v, k, t), np.put(w, k, 0.0)
    for corner, mask in ((2, (d6 >= 0) & (d5 <= d6)), (1, (d3 >= 0) & (d4 <= d3)), (0, (d1 <= 0) & (d2 <= 0))):
        k = np.flatnonzero(mask)
        np.put(u, k, 1.0 if corner == 0 else 0.0)
        np.put(v, k, 1.0 if corner == 1 else 0.0)
        np.put(w, k, 1.0 if corner == 2 else 0.0)
    return u, v, w


def _edge_parameter(region: np.ndarray, num: np.ndarray, other: np.ndarray, sign: float) -> tuple[np.ndarray, np.ndarray]:
    """Where ``region`` holds (flat indices), and there ``num / (num + sign * other)`` (0 where that is 0/0 or x/0).

    ``sign`` is 1 or -1: ``num + -1 * other`` is ``num - other`` to the bit.
    """
    k = np.flatnonzero(region)
    a = np.take(num, k)
    return k, safe_ratio(a, a + sign * np.take(other, k))


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest point of each triangle (a, b, c) to each point p.

    Parameters
    ----------
    p, a, b, c : (..., 3) float64
        Broadcast together.

    Returns
    -------
    point : (..., 3) float64
    bary : (..., 3) float64
        Barycentric coordinates of ``point`` in (a, b, c).
    """
    ab, ac, ap = b - a, c - a, p - a
    u, v, w = closest_barycentric(
        np.einsum("...i,...i", ab, ap),
        np.einsum("...i,...i", ac, ap),
        np.einsum("...i,...i", ab, ab),
        np.einsum("...i,...i", ab, ac),
        np.einsum("...i,...i", ac, ac),
    )
    point = a + v[..., None] * ab + w[..., None] * ac
    return point, np.stack([u, v, w], axis=-1)


def vertex_triangle_rings(triangles: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_vertices, width) int64: the triangles around each vertex, padded with -1.

    Each ring lists its triangles by index. A corner given as -1 is left
    out: with the corners renumbered to some vertices and the rest -1, the
    rings of those vertices alone (the same as in the whole surface's rings,
    padded to their own width).
    """
    corner = np.asarray(triangles, dtype=np.int64).ravel()
    owner = np.repeat(np.arange(len(corner) // 3), 3)
    if len(corner) and corner.min() < 0:
        keep = corner >= 0
        corner, owner = corner[keep], owner[keep]
    order = np.argsort(corner, kind="stable")
    counts = np.bincount(corner, minlength=n_vertices)
    width = int(counts.max()) if len(counts) else 0
    slot = np.arange(len(corner)) - np.repeat(np.cumsum(counts) - counts, counts)
    rings = np.full((n_vertices, width), -1, dtype=np.int64)
    rings[corner[order], slot] = owner[order]
    return rings
