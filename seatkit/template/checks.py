"""Checks of a fitted cage: topology, self-intersection, body crossing, sides, supportability.

A cage is one oriented surface: each face's normal (its corners in order,
``(c - a) x (d - b)``) points to the side the body is on. A face that
supports a body segment with the segment behind it (a seat on the lap, its
normals pointing down) is refused (:func:`wrong_side_faces`). A refiner's
cage is held to the template's constraints (:func:`check_refined`).

Non-planar quads are checked as four triangles around their centre (a close
stand-in for the bilinear patch). Triangle-triangle intersection is tested
edge against triangle (two triangles intersect iff an edge of one crosses the
other, coplanar overlaps aside), vectorised in numpy over candidate pairs
found with scipy's k-d tree, for the cage against itself and against the
body (no open3d: its import alone costs about 1.3 s).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from seatkit.cache import IdentityCache, content_key
from seatkit.errors import PluginError, UnsupportedPoseError
from seatkit.geometry.normals import kept_vertex_normals
from seatkit.geometry.surface import SurfaceQuery, inside_furniture
from seatkit.model import Body, ControlMesh, Surface
from seatkit.skeleton import PARENTS, SEGMENT_INDEX, SEGMENTS
from seatkit.template.grid import NOT_HELD
from seatkit.template.planes import cross, unit

__all__ = [
    "quad_triangles",
    "topology_problems",
    "self_intersecting_faces",
    "crossing_faces",
    "prepare_body",
    "faces_cross_body",
    "check_cage",
    "check_refined",
    "refined_problems",
    "wrong_side_faces",
    "check_supportability",
    "cast_parallel",
    "segments_cross_triangles",
    "body_vertex_normals",
    "held_segments",
    "enclosed_vertices",
    "enclosed_parts",
    "free_segments",
]



def person_label(index: int, body) -> str:
    """``person 2 (default-female:reclined-sitting)``: 1-based seat number and body name, for messages."""
    name = getattr(body, "name", "")
    return f"person {index + 1}" + (f" ({name})" if name else "")

def quad_triangles(vertices: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split each quad into four triangles around its centre.

    Returns
    -------
    points : (v + f, 3) float64
        The vertices, then one centre per quad.
    triangles : (4 f, 3) int64
    owner : (4 f,) int64
        Quad of each triangle.
    """
    nv, nf = len(vertices), len(quads)
    centres = vertices[quads].mean(1)
    points = np.vstack([vertices, centres])
    c = nv + np.arange(nf)
    tris = np.concatenate([np.stack([quads[:, i], quads[:, (i + 1) % 4], c], 1) for i in range(4)])
    owner = np.tile(np.arange(nf), 4)
    return points, tris.astype(np.int64), owner


def topology_problems(quads: np.ndarray, n_vertices: int) -> list:
    """What keeps ``quads`` from being a connected, consistently oriented manifold.

    Returns
    -------
    list of str
        Empty for a good cage.
    """
    problems = []
    q = np.asarray(quads)
    if (np.sort(q, 1)[:, 1:] == np.sort(q, 1)[:, :-1]).any():
        problems.append("a face repeats a vertex")
    directed = np.stack([q, np.roll(q, -1, axis=1)], -1).reshape(-1, 2)
    d_unique, d_count = np.unique(directed, axis=0, return_counts=True)
    if (d_count > 1).any():
        problems.append(f"{int((d_count > 1).sum())} edges have inconsistent orientation or are shared by more than two faces")
    undirected = np.sort(directed, 1)
    _, u_count = np.unique(undirected, axis=0, return_counts=True)
    if (u_count > 2).any():
        problems.append(f"{int((u_count > 2).sum())} edges are shared by more than two faces (non-manifold)")
    used = np.unique(q)
    if len(used) != n_vertices:
        problems.append(f"{n_vertices - len(used)} vertices belong to no face")
    g = coo_matrix((np.ones(len(directed)), (directed[:, 0], directed[:, 1])), shape=(n_vertices, n_vertices))
    n_comp, labels = connected_components(g, directed=False)
    if len(np.unique(labels[used])) > 1:
        problems.append(f"the cage has {len(np.unique(labels[used]))} connected parts")
    # vertex manifoldness: the faces around each vertex form one fan
    return problems


def segments_cross_triangles(p0: np.ndarray, p1: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, *, eps: float = 1e-9) -> np.ndarray:
    """(k,) bool: segment ``p0 -> p1`` crosses triangle ``(a, b, c)`` strictly inside, pairwise.

    Möller-Trumbore on k (segment, triangle) pairs, every argument (k, 3).
    Touching (an end point on the triangle, a hit on its border) does not count.
    """
    e1, e2 = b - a, c - a
    d = p1 - p0
    pvec = cross(d, e2)
    det = np.einsum("ij,ij->i", pvec, e1)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tvec = p0 - a
    u = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = cross(tvec, e1)
    v = np.einsum("ij,ij->i", d, qvec) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    return ok & (u > eps) & (v > eps) & (u + v < 1 - eps) & (t > eps) & (t < 1 - eps)


def _triangle_spheres(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (t, 3) and bounding radius (t,) of each triangle."""
    P = points[tris]
    c = P.mean(1)
    return c, np.linalg.norm(P - c[:, None], axis=2).max(1)


def _set_tree(points: np.ndarray) -> cKDTree:
    """A k-d tree for questions whose answer does not depend on the tree's shape: a distance, or a set of pairs read in sorted order.

    Split at the sliding midpoint, nodes not shrunk to their points: about
    half the build time of scipy's default (median splits, compact nodes)
    and faster pair searches. Which of two equally near points a k-nearest
    query names, and the order ``sparse_distance_matrix`` lists its pairs
    in, depend on the tree's shape: a query that reads those keeps the
    default tree.
    """
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def _close_pairs(queries: np.ndarray, reach: float, targets, radii: np.ndarray | None = None, *, make_tree=cKDTree) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) pairs with ``|queries[i] - targets[j]| <= reach + radii[j]`` (a superset).

    Targets are split by radius (the smallest 60 %, up to 95 %, the rest),
    so that one large target does not widen every query (scipy k-d trees,
    ``sparse_distance_matrix``). ``targets`` may also be the bins
    :func:`_target_bins` made of them once (a body's edges, kept per body).
    ``make_tree`` makes the k-d trees (:func:`_set_tree` when the caller
    reads the pairs as a set: their order is the trees').
    """
    bins = _target_bins(targets, radii, make_tree=make_tree) if radii is not None else targets
    if len(queries) == 0 or not bins:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    qtree = make_tree(queries)
    out_i, out_j = [], []
    for sel, tree, rmax in bins:
        res = qtree.sparse_distance_matrix(tree, reach + rmax, output_type="ndarray")
        out_i.append(res["i"].astype(np.int64))
        out_j.append(sel[res["j"]])
    return np.concatenate(out_i), np.concatenate(out_j)


def _target_bins(targets: np.ndarray, radii: np.ndarray, *, make_tree=cKDTree) -> list:
    """[(indices, k-d tree of those targets, their largest radius)] by radius: the smallest 60 %, up to 95 %, the rest."""
    if len(targets) == 0:
        return []
    cuts = np.quantile(radii, [0.6, 0.95])
    bins = []
    for sel in (np.flatnonzero(radii <= cuts[0]), np.flatnonzero((radii > cuts[0]) & (radii <= cuts[1])), np.flatnonzero(radii > cuts[1])):
        if len(sel):
            bins.append((sel, make_tree(targets[sel]), float(radii[sel].max())))
    return bins


def _sample_triangles(points: np.ndarray, tris: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points covering each triangle at about ``spacing`` (vertices, edges, inside), and their triangle."""
    P = points[tris]
    longest = np.linalg.norm(P - np.roll(P, 1, axis=1), axis=2).max(1)
    n = np.maximum(np.ceil(longest / spacing).astype(np.int64), 1)
    samples, owner = [], []
    for k in np.unique(n):
        sel = np.flatnonzero(n == k)
        bary = _barycentric_grid(int(k))
        samples.append(np.einsum("mk,tkd->tmd", bary, P[sel]).reshape(-1, 3))
        owner.append(np.repeat(sel, len(bary)))
    return np.concatenate(samples), np.concatenate(owner)


@functools.lru_cache(maxsize=64)
def _barycentric_grid(k: int) -> np.ndarray:
    """(m, 3) float64 barycentric weights of the points ``i / k, j / k`` (``i + j <= k``) of a triangle, in :func:`_sample_triangles`' order (read-only)."""
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    keep = i + j <= k
    bary = np.stack([k - i[keep] - j[keep], i[keep], j[keep]], 1) / k
    bary.flags.writeable = False
    return bary


def _cover_triangles(points: np.ndarray, tris: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points within ``spacing`` of every point of each triangle, and their triangle (a cover, for candidate pairs).

    Rows parallel to the longest edge AB, at most ``spacing / sqrt 2`` apart
    from AB to the opposite corner C, each sampled end to end at most
    ``sqrt 2 * spacing`` apart. A point of the triangle lies within
    ``spacing / sqrt 2`` of the row on its AB side (the foot of the
    perpendicular stays on that row: the angles at A and B are acute, AB
    being the longest edge) and that foot within ``spacing / sqrt 2`` of a
    sample. About area / spacing^2 samples per triangle, where
    :func:`_sample_triangles` takes (longest edge / spacing)^2 / 2: a long
    thin wall triangle gets a few rows instead of a full grid.
    """
    P = points[tris]
    if len(P) == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    step = spacing / np.sqrt(2.0) * (1.0 - 1e-6)  # a hair under, for round-off
    side = np.linalg.norm(P[:, [1, 2, 0]] - P, axis=2)  # |AB|, |BC|, |CA| of the given order
    first = np.argmax(side, axis=1)  # the longest edge runs from corner ``first`` to the next
    t = np.arange(len(P))
    A, B, C = P[t, first], P[t, (first + 1) % 3], P[t, (first + 2) % 3]
    L = side[t, first]
    area2 = np.linalg.norm(cross(B - A, C - A), axis=1)
    h = area2 / np.maximum(L, 1e-300)
    m = np.maximum(np.ceil(h / step).astype(np.int64), 1)  # row gaps per triangle
    row_tri = np.repeat(t, m + 1)
    row_start = np.repeat(np.cumsum(m + 1) - (m + 1), m + 1)
    frac = (np.arange(len(row_tri)) - row_start) / m[row_tri]  # 0 at AB, 1 at C
    start = A[row_tri] + frac[:, None] * (C - A)[row_tri]
    end = B[row_tri] + frac[:, None] * (C - B)[row_tri]
    n = np.maximum(np.ceil(L[row_tri] * (1.0 - frac) / (2.0 * step)).astype(np.int64), 1)  # gaps per row
    samples, row = _sample_segments(start, end, 0.0, gaps=n)
    return samples, row_tri[row]


def _sample_segments(p0: np.ndarray, p1: np.ndarray, spacing: float, *, gaps: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``spacing`` or less along each segment (end points included), and their segment.

    ``gaps`` (one count per segment) gives the number of equal intervals instead.
    """
    if gaps is None:
        length = np.linalg.norm(p1 - p0, axis=1)
        n = np.maximum(np.ceil(length / spacing).astype(np.int64), 1)
    else:
        n = gaps
    seg = np.repeat(np.arange(len(p0)), n + 1)
    start = np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)
    frac = (np.arange(len(seg)) - start) / n[seg]
    return p0[seg] + frac[:, None] * (p1 - p0)[seg], seg


def _unique_pairs(a: np.ndarray, b: np.ndarray, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct pairs ``(a[i], b[i])`` (``0 <= b < nb``), in ascending order of ``a * nb + b``.

    ``np.unique``'s values, by a sort and a comparison with the neighbour:
    numpy's hashed ``unique`` of integers takes about twice as long on the
    few hundred thousand keys of a check.
    """
    key = np.sort(a * nb + b)
    first = np.ones(len(key), bool)
    np.not_equal(key[1:], key[:-1], out=first[1:])
    key = key[first]
    return key // nb, key % nb


def self_intersecting_faces(vertices: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(k, 2) int64 pairs of quads that intersect (quads sharing a vertex are not compared)."""
    if len(quads) < 2:
        return np.zeros((0, 2), np.int64)
    points, tris, owner = quad_triangles(vertices, quads)
    centres, radius = _triangle_spheres(points, tris)
    # triangle pairs whose bounding spheres overlap
    # (every pair within twice the largest radius, each once, ordered by quad)
    i, j = _set_tree(centres).query_pairs(2.0 * float(radius.max()), output_type="ndarray").T.astype(np.int64)
    oi, oj = owner[i], owner[j]
    apart = np.flatnonzero(oi != oj)  # triangles of one quad are not compared
    i, j, first = i[apart], j[apart], oi[apart] < oj[apart]
    i, j = np.where(first, i, j), np.where(first, j, i)
    keep = np.linalg.norm(centres[i] - centres[j], axis=1) <= radius[i] + radius[j]
    i, j = i[keep], j[keep]
    # quads sharing a vertex are neighbours, not intersections
    shared = (quads[owner[i]][:, :, None] == quads[owner[j]][:, None, :]).any((1, 2))
    i, j = i[~shared], j[~shared]
    hit = np.zeros(len(i), bool)
    for a_, b_ in ((i, j), (j, i)):
        E = tris[a_]
        T = points[tris[b_]]
        for e0, e1 in ((0, 1), (1, 2), (2, 0)):
            hit |= segments_cross_triangles(points[E[:, e0]], points[E[:, e1]], T[:, 0], T[:, 1], T[:, 2])
    pairs = np.unique(np.sort(np.stack([owner[i[hit]], owner[j[hit]]], 1), 1), axis=0)
    return pairs.reshape(-1, 2).astype(np.int64)


#: What the checks derive from a body (edges, k-d tree, normals, ...), by body object
_BODY_CACHE = IdentityCache()


def _cached(body: Body, name: str, make):
    """``make(body)``, computed once per body object (bodies are immutable)."""
    return _BODY_CACHE.get((body,), lambda: make(body), tag=name)


def body_edges(body: Body) -> np.ndarray:
    """(e, 2) int64 unique edges of the body's triangles.

    They depend on the triangles alone, so they are kept per ``faces``
    array: every pose of a rig shares its rig's (:func:`seatkit.body.pose_rig`).
    """

    def make():
        f = np.asarray(body.faces)
        n = int(f.max()) + 1 if f.size else 1
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
        key = np.unique(e[:, 0] * n + e[:, 1])
        return np.stack([key // n, key % n], 1)

    return _BODY_CACHE.get((body.faces,), make, tag="edges")


def body_tree(body: Body) -> cKDTree:
    """k-d tree of the body's vertices, for distances to the body (:func:`_set_tree`: which of two equally near vertices it names is its shape's)."""
    return _cached(body, "tree", lambda b: _set_tree(np.asarray(b.vertices, dtype=np.float64)))


def body_vertex_normals(body: Body) -> np.ndarray:
    """(n, 3) float64 area-weighted outward vertex normals of a body."""

    return kept_vertex_normals(body.vertices, body.faces)


def _body_segments(body: Body) -> np.ndarray:
    """(n,) segment of largest skinning weight of each body vertex, once per body (read-only)."""

    def make(b):
        seg = np.asarray(b.weights).argmax(1)
        seg.flags.writeable = False
        return seg

    return _cached(body, "segments", make)


def _body_triangle_spheres(body: Body) -> tuple[np.ndarray, np.ndarray]:
    return _cached(body, "spheres", lambda b: _triangle_spheres(np.asarray(b.vertices, dtype=np.float64), np.asarray(b.faces)))


def _body_edge_bins(body: Body) -> list:
    """:func:`_target_bins` of the body's edges (midpoints, half lengths), once per body."""

    def make(b):
        bv = np.asarray(b.vertices, dtype=np.float64)
        be = body_edges(b)
        e0, e1 = bv[be[:, 0]], bv[be[:, 1]]
        return _target_bins(0.5 * (e0 + e1), 0.5 * np.linalg.norm(e1 - e0, axis=1), make_tree=_set_tree)

    return _cached(body, "edge_bins", make)


def _body_triangle_bins(body: Body) -> list:
    """:func:`_target_bins` of the body's triangles (bounding spheres), once per body."""
    return _cached(body, "triangle_bins", lambda b: _target_bins(*_body_triangle_spheres(b), make_tree=_set_tree))


def prepare_body(body: Body) -> None:
    """Make what the checks derive from ``body`` alone, kept per body object: its k-d tree and vertex normals (the clearance step), its edges' and triangles' k-d trees (:func:`crossing_faces`).

    A program with a core to spare (``seatkit serve``) calls it beside the
    template fit, which asks for them in this order; the values are the
    same whichever thread makes them.
    """
    body_tree(body)
    body_vertex_normals(body)
    _body_edge_bins(body)
    _body_triangle_bins(body)


#: Quads :func:`crossing_faces` answered, per body: at most this many kept (then forgotten, all at once).
_CROSSING_MEMO = 50_000


def crossing_faces(vertices: np.ndarray, quads: np.ndarray, body: Body, tolerance: float) -> np.ndarray:
    """(k,) int64 quads that cross the body deeper than ``tolerance``.

    Every quad is moved back by ``tolerance`` along its own normal (away
    from the body) so that faces resting in the skin within the allowed
    sink depth do not count; then every body edge is tested against the
    cage's triangles and every cage edge against the body's triangles.
    Only numpy and scipy's k-d tree.

    Whether a quad crosses depends on its four corners, the body and
    ``tolerance`` alone (each quad is tested apart from the others), so the
    answer is kept per body, by the corners' coordinates to the bit: the
    template's final check after a repair tests only the quads the repair
    moved, and the next start's check only those it has not seen.
    """
    if len(quads) == 0:
        return np.zeros(0, np.int64)
    V = np.asarray(vertices, dtype=np.float64)
    corners = np.ascontiguousarray(V[np.asarray(quads)])  # (f, 4, 3)
    memo = _cached(body, "crossing", lambda b: {})
    if len(memo) > _CROSSING_MEMO:
        memo.clear()
    tag = np.float64(tolerance).tobytes()
    keys = [tag + q.tobytes() for q in corners]
    known = [memo.get(k) for k in keys]
    todo = np.array([i for i, k in enumerate(known) if k is None], dtype=np.int64)
    bad = np.array([bool(k) for k in known])
    if len(todo):
        fresh = _crossing_quads(corners[todo], body, tolerance)
        bad[todo] = fresh
        memo.update(zip((keys[i] for i in todo), fresh.tolist()))
    return np.flatnonzero(bad).astype(np.int64)


def _crossing_quads(Q: np.ndarray, body: Body, tolerance: float) -> np.ndarray:
    """(f,) bool: which quads (their corners, (f, 4, 3) float64) cross the body (:func:`crossing_faces`)."""
    nq = len(Q)
    # every quad moved back along its own normal (quads come apart, which is
    # fine here): a face may rest ``tolerance`` deep in the skin
    fn = cross(Q[:, 2] - Q[:, 0], Q[:, 3] - Q[:, 1])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-12)
    Q = Q - tolerance * fn[:, None, :]
    points, tris, owner = quad_triangles(Q.reshape(-1, 3), np.arange(4 * nq).reshape(-1, 4))
    bv = np.asarray(body.vertices, dtype=np.float64)
    bf = np.asarray(body.faces)
    bad = np.zeros(nq, bool)
    spacing = 0.03
    # only cage triangles near the body can cross it
    centres, radius = _triangle_spheres(points, tris)
    d, _ = body_tree(body).query(centres, distance_upper_bound=float(radius.max()) + 0.1)
    near = np.flatnonzero(d <= radius + 0.05)
    if len(near) == 0:
        return bad
    # body edges against cage triangles: candidates from samples of the triangles
    be = body_edges(body)
    # every point of a near triangle lies within ``spacing`` of one of its
    # samples, so an edge crossing it is within ``spacing`` + its half
    # length of a sample: the candidates are a superset of the crossings,
    # and the exact test below decides (any superset gives the same faces)
    samples, s_owner = _cover_triangles(points, tris[near], spacing)
    si, ej = _close_pairs(samples, spacing, _body_edge_bins(body), make_tree=_set_tree)
    ti, ej = _unique_pairs(near[s_owner[si]], ej, len(be))
    e0, e1 = bv[be[ej, 0]], bv[be[ej, 1]]
    T = points[tris[ti]]
    hit = segments_cross_triangles(e0, e1, T[:, 0], T[:, 1], T[:, 2])
    bad[owner[ti[hit]]] = True
    # edges of those cage triangles against body triangles; the spokes (a
    # corner to its quad's centre) are shared by two triangles of one quad:
    # tested once
    sub = tris[near]
    edges = np.concatenate([sub[:, [0, 1]], sub[:, [1, 2]], sub[:, [2, 0]]])
    edges, first = np.unique(np.sort(edges, 1), axis=0, return_index=True)
    eo = np.tile(owner[near], 3)[first]
    p0, p1 = points[edges[:, 0]], points[edges[:, 1]]
    # a point of an edge lies within half a gap (spacing / 2) of a sample
    es, e_owner = _sample_segments(p0, p1, spacing)
    si, tj = _close_pairs(es, 0.5 * spacing * (1.0 + 1e-6), _body_triangle_bins(body), make_tree=_set_tree)
    ei, tj = _unique_pairs(e_owner[si], tj, len(bf))
    B = bv[bf[tj]]
    hit = segments_cross_triangles(p0[ei], p1[ei], B[:, 0], B[:, 1], B[:, 2])
    bad[eo[ei[hit]]] = True
    return bad


def faces_cross_body(vertices: np.ndarray, quads: np.ndarray, body: Body, tolerance: float) -> bool:
    """Whether any of ``quads`` crosses ``body`` (see :func:`crossing_faces`)."""
    return len(crossing_faces(vertices, quads, body, tolerance)) > 0


def cast_parallel(body: Body, origins: np.ndarray, direction: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First body triangle hit by parallel rays.

    Parameters
    ----------
    origins : (k, 3) float64
    direction : (3,) float64
        Common unit direction of the rays.
    lengths : (k,) float64
        Length of each ray, m.

    Returns
    -------
    t : (k,) float64
        Distance to the first hit (inf where none within the length).
    triangle : (k,) int64
        Triangle hit (-1 where none).
    """
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = cross(d, helper)
    e1 /= np.linalg.norm(e1)
    e2 = cross(d, e1)
    B = np.asarray(body.vertices, dtype=np.float64)
    F = np.asarray(body.faces)
    t_hit = np.full(len(origins), np.inf)
    tri = np.full(len(origins), -1, np.int64)
    if len(origins) == 0:
        return t_hit, tri
    # only triangles in the box swept by the rays
    proj = B @ np.stack([e1, e2, d], 1)
    o3 = origins @ np.stack([e1, e2, d], 1)
    lo = np.minimum(o3.min(0), (o3 + np.outer(lengths, [0.0, 0.0, 1.0])).min(0))
    hi = np.maximum(o3.max(0), (o3 + np.outer(lengths, [0.0, 0.0, 1.0])).max(0))
    # a triangle's box overlaps the rays' where, on every axis, some corner
    # is >= lo and some corner <= hi: six bits per vertex, OR-ed per triangle
    bits = ((proj >= lo) * np.array([1, 2, 4], np.uint8) + (proj <= hi) * np.array([8, 16, 32], np.uint8)).sum(1, dtype=np.uint8)
    inbox = (bits[F[:, 0]] | bits[F[:, 1]] | bits[F[:, 2]]) == 63
    F = F[inbox]
    P = proj[F]
    if len(F) == 0:
        return t_hit, tri
    T = P[:, :, :2]
    c = T.mean(1)
    r = np.linalg.norm(T - c[:, None], axis=2).max(1)
    o = o3[:, :2]
    k, t = _close_pairs(o, 0.0, c, r)
    if len(k) == 0:
        return t_hit, tri
    a, b, cc = T[t, 0], T[t, 1], T[t, 2]
    v0, v1, v2 = b - a, cc - a, o[k] - a
    den = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    ok = np.abs(den) > 1e-16
    den = np.where(ok, den, 1.0)
    beta = (v2[:, 0] * v1[:, 1] - v2[:, 1] * v1[:, 0]) / den
    gamma = (v0[:, 0] * v2[:, 1] - v0[:, 1] * v2[:, 0]) / den
    alpha = 1 - beta - gamma
    inside = ok & (alpha >= 0) & (beta >= 0) & (gamma >= 0)
    depth = P[t, :, 2]
    hit_depth = alpha * depth[:, 0] + beta * depth[:, 1] + gamma * depth[:, 2] - o3[k, 2]
    good = inside & (hit_depth > 0) & (hit_depth <= lengths[k])
    k, t, h = k[good], t[good], hit_depth[good]
    if len(k) == 0:
        return t_hit, tri
    order = np.lexsort((h, k))
    k, t, h = k[order], t[order], h[order]
    first = np.r_[True, k[1:] != k[:-1]]
    t_hit[k[first]] = h[first]
    tri[k[first]] = np.flatnonzero(inbox)[t[first]]
    return t_hit, tri


def check_cage(mesh: ControlMesh, bodies, *, tolerance: float) -> None:
    """Raise unless ``mesh`` is a connected manifold that crosses neither itself nor a body.

    Raises
    ------
    UnsupportedPoseError
        Naming the faces (and the body segments they support) at fault.
    """
    problems = topology_problems(mesh.faces, len(mesh.vertices))
    if problems:
        msg = f"the fitted cage is not a connected manifold: {'; '.join(problems)}"
        raise UnsupportedPoseError(msg, diagnostics={"topology": problems, **mesh.meta})
    pairs = self_intersecting_faces(mesh.vertices, mesh.faces)
    if len(pairs):
        names = sorted({mesh.face_labels[i] for i in pairs.ravel()})
        msg = f"the fitted cage intersects itself at faces {', '.join(names)}: this topology cannot support the pose"
        raise UnsupportedPoseError(msg, parts=_parts(mesh, pairs.ravel()), diagnostics={"self_intersections": pairs.tolist(), **mesh.meta})
    for person, body in enumerate(bodies):
        bad = crossing_faces(mesh.vertices, mesh.faces, body, tolerance)
        if len(bad):
            names = sorted({mesh.face_labels[i] for i in bad})
            msg = f"{person_label(person, body)}: the fitted cage crosses the body at faces {', '.join(names)}: this topology cannot support the pose"
            raise UnsupportedPoseError(msg, parts=_parts(mesh, bad), diagnostics={"crossing_faces": bad.tolist(), **mesh.meta})
    wrong = wrong_side_faces(mesh, bodies)
    if wrong:
        face, person, why = wrong[0]
        segment = SEGMENTS[mesh.face_segments[face]]
        more = f"; and {len(wrong) - 1} more face(s)" if len(wrong) > 1 else ""
        msg = (
            f"{person_label(person, bodies[person])}: face {mesh.face_labels[face]!r} supports {segment} from the wrong side: "
            f"{why}{more}; this topology cannot support the pose"
        )
        faces = np.array([f for f, _, _ in wrong])
        raise UnsupportedPoseError(msg, parts=_parts(mesh, faces), diagnostics={"wrong_side_faces": faces.tolist(), **mesh.meta})


#: A face supports its segment from the wrong side when the segment's body
#: vertices nearest its centre lie behind its plane: their median more than
#: this deep, m (a face touching the skin has them on both sides, within
#: millimetres; a face crossing the limb is refused by the crossing check).
WRONG_SIDE_DEPTH = 0.02

#: Body vertices of the segment, nearest the face's centre, that the side is read from.
WRONG_SIDE_SAMPLES = 30

#: ... and at most this share of them in front of the face.
WRONG_SIDE_FRONT_SHARE = 0.2

#: A supporting face whose normal points within this of straight down (to
#: the body below it: a seat on the lap) holds nothing up, rad. The library
#: chairs' lowest supporting normal is a lumbar face's, about 30 deg below
#: the horizontal (60 deg from straight down).
DOWN_ANGLE = np.radians(30.0)


def face_normals(vertices: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Unit normals ``(c - a) x (d - b)`` of the quads (the side the body is on), (m, 3) float64."""
    corner = vertices[quads]  # (m, 4, 3)
    n = cross(corner[:, 2] - corner[:, 0], corner[:, 3] - corner[:, 1])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def wrong_side_faces(mesh: ControlMesh, bodies) -> list[tuple[int, int, str]]:
    """Faces that support their segment from the wrong side: ``(face, person, why)``, in face order.

    A face supporting a segment (``face_segments`` >= 0) of person
    ``face_person`` (person 0 when it is -1 and there is one person) is on
    the wrong side when

    * the segment lies behind it: the :data:`WRONG_SIDE_SAMPLES` body
      vertices of that segment nearest its centre have a median signed
      distance to its plane below ``-WRONG_SIDE_DEPTH`` and at most
      :data:`WRONG_SIDE_FRONT_SHARE` of them lie in front (the surface is
      oriented away from the body there); or
    * it holds the segment from above: its normal (towards the body) points
      within :data:`DOWN_ANGLE` of straight down (a seat on the lap).
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    quads = np.asarray(mesh.faces)
    normals = face_normals(vertices, quads)
    centres = vertices[quads].mean(axis=1)
    person_of = np.asarray(mesh.face_person) if mesh.face_person is not None else np.full(len(quads), -1)
    found = []
    for face in np.flatnonzero(np.asarray(mesh.face_segments) >= 0):
        person = int(person_of[face]) if person_of[face] >= 0 else (0 if len(bodies) == 1 else -1)
        if person < 0 or person >= len(bodies):
            continue
        if normals[face, 1] < -np.cos(DOWN_ANGLE):
            down = np.degrees(np.arccos(np.clip(-normals[face, 1], -1.0, 1.0)))
            found.append((int(face), person, f"it holds it from above, its normal {down:.0f} deg from straight down (a support pushes a body up or sideways)"))
            continue
        body = bodies[person]
        points = body.vertices[_body_segments(body) == mesh.face_segments[face]]
        if len(points) == 0:
            continue
        # the segment's vertices nearest the face's centre, and their signed distances to its plane
        near = points[np.argsort(np.linalg.norm(points - centres[face], axis=1))[:WRONG_SIDE_SAMPLES]]
        signed = (near - centres[face]) @ normals[face]
        depth = -float(np.median(signed))
        if depth > WRONG_SIDE_DEPTH and np.mean(signed > 0) <= WRONG_SIDE_FRONT_SHARE:
            found.append((int(face), person, f"the segment lies {depth * 100:.1f} cm behind it (its normal points away from the body)"))
    return found


#: A refined cage's ground vertices stay on the floor within this, m.
FLOOR_TOLERANCE = 1e-6

#: ... and within this of the template's ground ring (they may slide along it), m.
BORDER_TOLERANCE = 1e-3

#: Other fixed vertices stay where the template put them, within this, m.
FIXED_TOLERANCE = 1e-6


def refined_problems(before: ControlMesh, after: ControlMesh) -> list[str]:
    """What a refined cage ``after`` breaks of the template's cage ``before``'s constraints (empty: none).

    A refiner returns the same topology (faces, vertex count), finite
    positions, its ground vertices on the floor (``|y|`` within
    :data:`FLOOR_TOLERANCE`) and on the template's ground ring (within
    :data:`BORDER_TOLERANCE` of the polyline of ``before``'s ground edges, in
    plan: the walls stand where they stood, a vertex may slide along its
    side), and its other fixed vertices where they were (within
    :data:`FIXED_TOLERANCE`).
    """
    if not isinstance(before, ControlMesh):
        return []  # no template cage to hold it to (a stand-in of the build's stages)
    if not isinstance(after, ControlMesh):
        return [f"it returned {type(after).__name__}, not a ControlMesh"]
    v0 = np.asarray(before.vertices, dtype=np.float64)
    v1 = np.asarray(after.vertices, dtype=np.float64)
    if v1.shape != v0.shape or np.asarray(after.faces).shape != np.asarray(before.faces).shape or not np.array_equal(after.faces, before.faces):
        return [f"its cage has {v1.shape[0]} vertices and {len(after.faces)} faces; the template's has {v0.shape[0]} and {len(before.faces)} with the same faces (a refiner keeps the topology)"]
    bad = ~np.isfinite(v1).all(axis=1)
    if bad.any():
        return [f"{int(bad.sum())} vertices are not finite (vertex {int(np.flatnonzero(bad)[0])})"]
    problems = []
    ground = np.asarray(before.ground, bool)
    off_floor = np.abs(v1[ground, 1])
    if off_floor.size and off_floor.max() > FLOOR_TOLERANCE:
        i = np.flatnonzero(ground)[int(np.argmax(off_floor))]
        problems.append(f"ground vertex {i} is {off_floor.max() * 1000:.1f} mm off the floor (y = {v1[i, 1]:.4f} m)")
    # ground edges of the template: both ends on the ground
    corners = np.asarray(before.faces)
    edges = np.stack([corners, np.roll(corners, -1, axis=1)], axis=-1).reshape(-1, 2)
    edges = edges[ground[edges].all(axis=1)]
    if len(edges) and ground.any():
        a, b = v0[edges[:, 0]][:, [0, 2]], v0[edges[:, 1]][:, [0, 2]]  # (e, 2) in plan
        p = v1[ground][:, [0, 2]]  # (g, 2)
        ab = b - a
        t = np.clip(np.einsum("gec,ec->ge", p[:, None] - a[None], ab) / np.maximum(np.einsum("ec,ec->e", ab, ab), 1e-300), 0.0, 1.0)
        closest = a[None] + t[..., None] * ab[None]  # (g, e, 2)
        away = np.linalg.norm(p[:, None] - closest, axis=-1).min(axis=1)  # (g,)
        if away.max() > BORDER_TOLERANCE:
            i = np.flatnonzero(ground)[int(np.argmax(away))]
            problems.append(f"ground vertex {i} left the template's ground ring by {away.max() * 100:.1f} cm (the walls must stand where they stood)")
    fixed = np.asarray(before.fixed, bool) & ~ground
    if fixed.any():
        moved = np.linalg.norm(v1[fixed] - v0[fixed], axis=1)
        if moved.max() > FIXED_TOLERANCE:
            i = np.flatnonzero(fixed)[int(np.argmax(moved))]
            problems.append(f"fixed vertex {i} moved {moved.max() * 1000:.1f} mm")
    return problems


def check_refined(before: ControlMesh, after: ControlMesh, *, refiner: str) -> None:
    """Raise unless the cage ``after`` of ``refiner`` (how messages name it: ``refiner 'x' of plugin "p"``) keeps the template's constraints (:func:`refined_problems`).

    Raises
    ------
    PluginError
        ``refiner 'x' of plugin "p" broke the template's constraints: ...``:
        a refiner bug, not a refusal of the cage (that is a SolverError), so
        the build stops.
    """
    problems = refined_problems(before, after)
    if problems:
        msg = f"{refiner} broke the template's constraints: {'; '.join(problems)}"
        raise PluginError(msg)


#: Subdivision level of the limit surface the enclosure check reads (16 quads per cage face).
ENCLOSURE_LEVEL = 2


def held_segments(meta: dict, face_segments) -> set:
    """Segments a cage holds: every segment a fitted face lists (``meta["supported_segments"]``), carries (``face_segments``), or an armrest holds.

    The rest (hands, forearms and arms without an armrest, the head...) is
    what the cage does not hold: it must stay outside the furniture.
    """
    held = {int(s) for s in meta.get("supported_segments", [])}
    held |= {int(s) for s in np.asarray(face_segments).ravel() if s >= 0}
    for case in meta.get("special_cases", []):
        if case.get("case") == "armrests":
            held |= {SEGMENT_INDEX[n] for side in case.get("sides", []) if side.get("taken") for n in side.get("segments", [])}
    return held


def enclosed_vertices(vertices: np.ndarray, quads: np.ndarray, body: Body, free: np.ndarray, *, level: int = ENCLOSURE_LEVEL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body vertices of ``free`` segments inside the furniture the cage's limit surface closes with the floor.

    The furniture is read as the refiners' final check reads it
    (:func:`seatkit.geometry.surface.inside_furniture`: a vertex is inside
    when the ray from it straight up crosses the surface an odd number of
    times), on the limit surface of the cage ``(vertices, quads)`` (no
    creases: a template's cage) at ``level``: the refiners start from the
    limit surface, not from the faces, and where the cage dips under a
    hanging hand between two vertices the limit surface does not follow.

    Parameters
    ----------
    free : (s,) bool
        Per segment, whether it is checked (the segments the cage does not hold).

    Returns
    -------
    index : (k,) int64
        The enclosed body vertices.
    depth : (k,) float64
        Their distance to the limit surface, m.
    face : (k,) int64
        The cage face whose limit patch is nearest to each.
    """
    from seatkit.subdivision import Cage, build_operators

    none = np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64)
    seg = np.asarray(body.weights).argmax(1)
    cand = np.flatnonzero(np.asarray(free)[seg])
    if not len(cand):
        return none
    ops = build_operators(Cage(np.asarray(vertices, dtype=np.float64), np.asarray(quads, dtype=np.int64)), level)
    X = ops.limit_points(vertices)
    surface = Surface(X, np.zeros_like(X), ops.faces, level)
    points = np.asarray(body.vertices, dtype=np.float64)[cand]
    inside = inside_furniture(surface, points)
    if not inside.any():
        return none
    depth, _ = SurfaceQuery(surface).query(points[inside])
    _, nearest = cKDTree(X[ops.faces].mean(1)).query(points[inside])
    return cand[inside], depth, ops.face_origin[nearest].astype(np.int64)


def free_segments(held) -> np.ndarray:
    """(s,) bool: the segments not in ``held``."""
    return np.array([s not in held for s in range(len(SEGMENTS))])


def enclosed_parts(mesh: ControlMesh, bodies, tolerance: float) -> list:
    """Per body, the parts the cage does not hold that lie inside the furniture deeper than ``tolerance`` (:func:`enclosed_vertices`).

    The crossing check finds cage faces that pass through the body; a hand
    hanging beside the seat, under the wall that runs from the seat's edge
    out and down to the ground rectangle, crosses no face: it is wholly
    inside the solid the surface closes with the floor. The held parts are
    left out: they rest on their faces and sink into the limit surface by
    design until the surface fit.

    Returns
    -------
    list of dict
        ``vertices`` (the enclosed body vertices), ``depth_m`` (the deepest,
        m), ``parts`` ({segment name: [vertices, depth in mm]}) and
        ``faces`` (names of the cage faces nearest to them).
    """
    free = free_segments(held_segments(mesh.meta, mesh.face_segments))
    out = []
    for body in bodies:
        index, depth, face = enclosed_vertices(mesh.vertices, mesh.faces, body, free)
        deep = depth > tolerance
        seg = np.asarray(body.weights).argmax(1)[index[deep]]
        out.append({
            "vertices": index[deep].tolist(),
            "depth_m": float(depth[deep].max()) if deep.any() else 0.0,
            "parts": {SEGMENTS[s]: [int((seg == s).sum()), round(1000 * float(depth[deep][seg == s].max()), 1)] for s in np.unique(seg)},
            "faces": sorted({mesh.face_labels[i] for i in np.unique(face[deep])}),
        })
    return out


def _parts(mesh: ControlMesh, faces) -> list:
    segs = sorted({int(mesh.face_segments[i]) for i in faces if mesh.face_segments[i] >= 0})
    return [SEGMENTS[s] for s in segs] or sorted({mesh.face_labels[i] for i in faces})


#: Parts that never occlude a supported part: the arms. A hand or forearm
#: under a supported part (hanging beside or behind the calf, tucked under
#: the thigh) is not something the chair holds (:data:`NOT_HELD`); whether
#: the cage meets it is the final check's (and its repair's) question, and
#: refusing here would refuse chairs that pass it. An upper arm hanging
#: beside the torso is beside the backrest, not behind it, though the back
#: row's casts from the flank can reach it (flank skin turned sideways into
#: the arm); an arm between the back and the backrest would be crossed by
#: the backrest's faces, which the final check refuses by name.
_NOT_OCCLUDING = set(NOT_HELD) | {SEGMENT_INDEX[a] for a in ("RightArm", "LeftArm")}


def _cast_along(body: Body, verts: np.ndarray, n: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cast_parallel` along ``-n`` from the body vertices ``verts``, 2 mm in front of them, ``depth`` long (read-only).

    The casts depend on the body, the vertices, the direction and the
    depths alone, and the template's starts ask for the same ones (the
    important vertices under seat-like faces; a row's, in the starts of one
    random stream until the first step they drop): kept per body, by their bytes.
    """
    memo = _cached(body, "casts", lambda b: {})
    key = content_key(verts, n, depth)
    if key not in memo:
        if len(memo) > 256:
            memo.clear()
        t, tri = cast_parallel(body, body.vertices[verts] - 2e-3 * n, -n, depth)
        t.flags.writeable = tri.flags.writeable = False
        memo[key] = (t, tri)
    return memo[key]


def _cast_down(body: Body, down: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_cast_along` straight down to the ground from the body vertices ``down`` (ascending), 2 mm under them."""
    return _cast_along(body, down, np.array([0.0, 1.0, 0.0]), np.maximum(body.vertices[down, 1], 1e-6))


def check_supportability(state, max_occluded_fraction: float, max_roll: float, joint_reach: float = 0.1) -> None:
    """Detect poses this topology cannot support (paper Secs. 5.1 and 6).

    Two tests per person: the body's left-right axis (hips and shoulders)
    must be within ``max_roll`` of horizontal (a side-lying body would stack
    the grid's columns), and for every fitted face, the important vertices
    of its segments must reach the support without crossing another body
    part: straight down to the ground under seat-like faces (normal within
    45 deg of up, the paper's "shortest line to the ground"), along the
    face normal to the plane otherwise. A part adjacent in the skeleton may
    be crossed within ``joint_reach`` (m) of the joint (skin folds); in rows where the crossed-legs case merged the legs, the legs may
    rest on each other; the arms (:data:`_NOT_OCCLUDING`) never occlude.

    Raises
    ------
    UnsupportedPoseError
        Naming the segments, with per-segment diagnostics.
    """
    p = state.params
    legs = {s for s in range(len(PARENTS)) if SEGMENTS[s].endswith(("UpLeg", "Leg", "Foot"))}
    for block in state.blocks:
        body = block.body
        j = body.joints
        lat = [j[SEGMENT_INDEX["LeftUpLeg"]] - j[SEGMENT_INDEX["RightUpLeg"]], j[SEGMENT_INDEX["LeftArm"]] - j[SEGMENT_INDEX["RightArm"]]]
        lat = np.mean([v / max(np.linalg.norm(v), 1e-9) for v in lat], axis=0)
        roll = float(np.arcsin(min(1.0, abs(lat[1]) / max(np.linalg.norm(lat), 1e-9))))
        diag = {"person": block.person, "roll_deg": float(np.degrees(roll)), "max_roll_deg": float(np.degrees(max_roll)), "segments": {}}
        merged = set(block.cases.get("merged_rows", []))
        # the important vertices of every fitted face and the direction of their line to the support
        tests = []
        for (r, c), face in sorted(block.faces.items()):
            if r not in block.rows or face.plane is None:
                continue
            mine = block.vertices_of(face.segments)  # ascending, kept per block
            imp = mine[block.importance[mine] >= p["important_threshold"]]
            if face.spec.role == "outer":
                # an outer face answers for the important vertices it supports
                imp = np.intersect1d(imp, face.supported)
            if len(imp) == 0:
                continue
            allowed = set(face.segments) | _NOT_OCCLUDING
            if r in merged:
                allowed |= legs
            vertical = face.plane.normal[1] >= np.cos(np.pi / 4)
            tests.append((face, imp, allowed, vertical))
        # one cast straight down for every seat-like face, one along the normal for each other face
        down = np.unique(np.concatenate([t[1] for t in tests if t[3]] or [np.zeros(0, np.int64)]))
        hit_down = np.full(len(body.vertices), -1, np.int64)
        t_down = np.full(len(body.vertices), np.inf)
        up = np.array([0.0, 1.0, 0.0])
        if len(down):
            t_down[down], hit_down[down] = _cast_down(body, down)
        bad = []
        # faces of a row that are not seat-like share one direction: the mean
        # normal of all the row's fitted faces that are not seat-like, with or
        # without important vertices of their own (the mean of only the faces
        # with tests leaned a back row's casts 20 deg towards the one outer
        # face that had some, into a hanging upper arm beside the torso)
        row_normal = {}
        for face, imp, allowed, vertical in tests:
            if not vertical:
                row_normal.setdefault(face.spec.row, [])
        for (r, c), face in sorted(block.faces.items()):
            if r in block.rows and face.plane is not None and face.spec.row in row_normal and face.plane.normal[1] < np.cos(np.pi / 4):
                row_normal[face.spec.row].append(face.plane.normal)
        row_cast = {}
        for r, normals in row_normal.items():
            n = unit(np.mean(normals, axis=0))
            verts = np.unique(np.concatenate([t[1] for t in tests if not t[3] and t[0].spec.row == r]))
            planes = [t[0].plane for t in tests if not t[3] and t[0].spec.row == r]
            depth = np.max([np.maximum(pl.signed_distance(body.vertices[verts]), 1e-6) for pl in planes], axis=0)
            t_r, tri_r = _cast_along(body, verts, n, depth)
            row_cast[r] = (n, verts, t_r, tri_r)
        for face, imp, allowed, vertical in tests:
            if vertical:
                n = up
                t, tri = t_down[imp], hit_down[imp]
            else:
                n, verts, t_r, tri_r = row_cast[face.spec.row]
                at = np.searchsorted(verts, imp)
                t, tri = t_r[at], tri_r[at]
            hit = tri >= 0
            seg = block.segment[body.faces[np.where(hit, tri, 0), 0]]
            occluded = hit & ~np.isin(seg, list(allowed))
            # skin folds at a joint: an adjacent segment hit near the joint does not count
            for s in set(block.neighbours_of(face.segments)) - allowed:
                on = occluded & (seg == s)
                if on.any():
                    joint = block.joint_between(set(face.segments), {s})
                    point = body.vertices[imp[on]] - (t[on] + 2e-3)[:, None] * n
                    occluded[np.flatnonzero(on)[np.linalg.norm(point - joint, axis=1) <= joint_reach]] = False
            w = block.importance[imp]
            frac = float(w[occluded].sum() / w.sum()) if w.sum() > 0 else 0.0
            # which parts are in the way, by their share of the face's importance
            by = {SEGMENTS[int(s)]: float(w[occluded & (seg == s)].sum() / w.sum()) for s in np.unique(seg[occluded])} if frac > 0 else {}
            for s in face.segments:
                diag["segments"].setdefault(SEGMENTS[s], []).append({"face": state.face_name(face), "occluded_fraction": frac, "occluded_by": by})
            if frac > max_occluded_fraction:
                bad.append((state.face_name(face), frac, face.segments, by))
        state.meta.setdefault("supportability", []).append(diag)
        if roll > max_roll:
            parts = ["Hips", "Spine", "RightUpLeg", "LeftUpLeg"]
            diag["supportable"] = []
            msg = (
                f"{person_label(block.person, block.body)}: the body lies on its side (left-right axis tilted {np.degrees(roll):.0f} deg, "
                f"at most {np.degrees(max_roll):.0f} allowed): the {state.spec.name} template cannot support {', '.join(parts)} in this pose "
                f"(its columns would stack on top of each other)"
            )
            raise UnsupportedPoseError(msg, parts=parts, diagnostics=diag)
        if bad:
            parts = sorted({SEGMENTS[s] for _, _, segs, _ in bad for s in segs})
            ok = sorted(set(diag["segments"]) - set(parts))
            detail = ", ".join(f"{name} {100 * f:.0f}% by {', '.join(sorted(by, key=by.get, reverse=True))}" for name, f, _, by in bad)
            msg = (
                f"{person_label(block.person, block.body)}: cannot support {', '.join(parts)}: their important vertices lie above other body parts "
                f"(occluded share: {detail}); a support there would cross the body. Supportable: {', '.join(ok) or 'nothing'}"
            )
            diag["supportable"] = ok
            raise UnsupportedPoseError(msg, parts=parts, diagnostics=diag)
        diag["supportable"] = sorted(diag["segments"])
