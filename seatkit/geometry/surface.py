"""Queries against a designed surface: closest points, and how deep a body and the surface reach into each other.

:class:`SurfaceQuery` finds exact closest points on a tessellated limit
surface (quads split in two triangles) and the side of the surface a point
is on; :func:`surface_depth_in_body` measures how deep the surface reaches
below a body's skin (through :class:`seatkit.geometry.skin.SkinDistance`);
:func:`body_depth_in_surface` how deep a body vertex lies inside the solid
the surface closes with the floor. The refiners (the Catmull-Clark fit's
checks) and the evaluation (Table 1's ``max_penetration_m`` and
``max_body_depth_m``, see :mod:`seatkit.evaluate`) ask the same questions
here.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from seatkit.cache import IdentityCache, content_key

from seatkit.geometry.closest import closest_point_on_triangles, row_norms, vertex_triangle_rings
from seatkit.geometry.skin import SkinDistance
from seatkit.model import Body, Surface

__all__ = ["SurfaceQuery", "surface_depth_in_body", "body_depth_in_surface", "body_inside_furniture", "inside_furniture"]


class SurfaceQuery:
    """Exact closest points on a tessellated surface (quads split in two triangles).

    Candidates for each query point are the triangles around its nearest
    tessellation vertices (3, then :attr:`CANDIDATE_VERTICES` within
    :attr:`EXACT_WITHIN` of the surface); the distance to each is exact
    (point to triangle), so the result is within 0.1 mm of a search over all
    triangles (tests compare with brute force and open3d). The normal at the
    closest point is interpolated from the surface's vertex normals.
    """

    CANDIDATE_VERTICES = 6
    #: Points closer than this (m) get the wider candidate search.
    EXACT_WITHIN = 0.10
    #: Slack (m) for rounding when the nearest vertex's distance alone decides a point's search.
    _ROUNDING = 1e-9

    #: A batch whose candidate vertices are fewer than the surface's vertices over this searches
    #: the rings of those vertices alone (a final check's few body vertices inside the furniture).
    _FEW = 8

    def __init__(self, surface: Surface):
        v = np.asarray(surface.vertices, dtype=np.float64)
        f = np.asarray(surface.faces, dtype=np.int64)
        tris = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]]) if f.shape[1] == 4 else f
        self.vertices, self.normals, self.triangles = v, np.asarray(surface.normals, dtype=np.float64), tris
        self.tree = cKDTree(v, balanced_tree=False, compact_nodes=False)
        # the rings, the corners' table and the reach: on first use (a query of a
        # few points needs none of them whole)
        self._rings = self._table = self._reach = None

    @property
    def rings(self) -> np.ndarray:
        """(v, w) int64: the triangles around each vertex, padded with -1."""
        if self._rings is None:
            self._rings = vertex_triangle_rings(self.triangles, len(self.vertices))
        return self._rings

    @property
    def _corners(self) -> np.ndarray:
        """(T, 9): each triangle's corners, gathered at once by a query."""
        if self._table is None:
            self._table = np.take(self.vertices, self.triangles, axis=0).reshape(len(self.triangles), 9)
        return self._table

    @property
    def reach(self) -> float:
        """The farthest a point of the surface lies from its nearest vertex, at most, m.

        Every point of a triangle lies within its second-longest edge of the
        corner opposite its longest edge (the triangle is the convex hull of
        its corners), so no surface point is farther than this from a vertex.
        """
        if self._reach is None:
            if len(self.triangles):
                corners = self._corners.reshape(-1, 3, 3)
                edges = row_norms(corners - np.roll(corners, -1, axis=1))
                a, b, c = edges[:, 0], edges[:, 1], edges[:, 2]
                # each triangle's middle edge length (a sort along the short axis is several times slower)
                self._reach = float(np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c)).max())
            else:
                self._reach = 0.0
        return self._reach

    def _candidates(self, near: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k, c) candidate triangles of each point (the rings of its ``near`` vertices in turn; -1: none) and (k, c, 9) their corners.

        A batch of few points takes the rings of its own vertices alone, in
        the same order (each ring by triangle index), padded to their own
        width: the same candidates, without the rings of the whole surface.
        """
        k = len(near)
        if self._rings is None and near.size * self._FEW < len(self.vertices):
            need, where = np.unique(near, return_inverse=True)
            local = np.full(len(self.vertices), -1, np.int64)
            local[need] = np.arange(need.size)
            rings = vertex_triangle_rings(np.take(local, self.triangles), need.size)
            cand = np.take(rings, where.reshape(near.shape), axis=0).reshape(k, -1)
            tri_i = np.where(cand >= 0, cand, 0)
            g = np.take(self.vertices, np.take(self.triangles, tri_i, axis=0), axis=0).reshape(k, -1, 9)
            return cand, g
        cand = np.take(self.rings, near, axis=0).reshape(k, -1)
        return cand, np.take(self._corners, np.where(cand >= 0, cand, 0), axis=0)

    def query(self, points: np.ndarray, *, within=None) -> tuple[np.ndarray, np.ndarray]:
        """Distance to the surface and signed offset along its normal.

        Candidates are the triangles around the 3 nearest tessellation
        vertices; points that end up within :data:`EXACT_WITHIN` of the
        surface (where contact and the average distance are decided) are
        searched again with :attr:`CANDIDATE_VERTICES` vertices, which agrees
        with open3d's exact closest points to 0.1 mm (tests). A point whose
        nearest vertex is already that close is certain to end up there, so
        it gets only the wider search (the same answer, with less work).

        Parameters
        ----------
        points : (k, 3) float64
        within : float or (k,) float64, optional
            Only distances up to this matter (m). A point that is certainly
            farther from the surface (its nearest vertex more than
            ``within + reach`` away, see :attr:`reach`) is not searched: its
            distance is ``inf`` and its side ``nan``. Default: every point is
            searched.

        Returns
        -------
        distance : (k,) float64
            Unsigned distance to the closest surface point, m.
        side : (k,) float64
            ``dot(point - closest, normal)``, m: positive on the side the
            normals point to (the body side), negative behind the surface.
        """
        distance, side, _ = self.closest_normals(points, within=within)
        return distance, side

    def closest_normals(self, points: np.ndarray, *, within=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`query`, and the unit surface normal at each closest point, (k, 3) (``nan`` where not searched)."""
        points = np.asarray(points, dtype=np.float64)
        distance = np.full(len(points), np.inf)
        side = np.full(len(points), np.nan)
        normal = np.full((len(points), 3), np.nan)
        if not len(points) or not len(self.triangles):
            return distance, side, normal
        first, near = self.tree.query(points, k=3)
        nearest = first[:, 0] if first.ndim == 2 else first
        near = near.reshape(len(points), -1)
        wanted = np.ones(len(points), dtype=bool)
        if within is not None:
            wanted = nearest - self.reach <= np.broadcast_to(np.asarray(within, dtype=np.float64), nearest.shape)
        sure = wanted & (nearest < self.EXACT_WITHIN - self._ROUNDING)  # within EXACT_WITHIN after any search
        narrow = np.flatnonzero(wanted & ~sure)
        if narrow.size:
            distance[narrow], side[narrow], normal[narrow] = self._closest(points[narrow], near[narrow])
        wide = np.flatnonzero(sure | (distance < self.EXACT_WITHIN))
        if wide.size:
            _, near = self.tree.query(points[wide], k=self.CANDIDATE_VERTICES)
            distance[wide], side[wide], normal[wide] = self._closest(points[wide], near.reshape(len(wide), -1))
        return distance, side, normal

    #: Points searched at once (their candidates' arrays, about 1 MB, stay in the cache: twice as fast
    #: per point as one pass over ten thousand points, the same answers).
    _BLOCK = 512

    def _closest(self, points: np.ndarray, near: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance, side and surface normal of each point over the triangles around its ``near`` vertices."""
        if self._rings is None and near.size * self._FEW >= len(self.vertices):
            self.rings  # noqa: B018 (a large batch: the rings of the whole surface, for every block)
        if len(points) > self._BLOCK:
            parts = [self._closest(points[lo : lo + self._BLOCK], near[lo : lo + self._BLOCK]) for lo in range(0, len(points), self._BLOCK)]
            return tuple(np.concatenate(part) for part in zip(*parts))
        # (np.take gathers rows several times faster than indexing does)
        cand, g = self._candidates(near)  # (k, c), (k, c, 9)
        valid = cand >= 0
        tri_i = np.where(valid, cand, 0)
        a, b, c = g[..., 0:3], g[..., 3:6], g[..., 6:9]
        closest, bary = closest_point_on_triangles(points[:, None, :], a, b, c)
        d2 = np.where(valid, np.einsum("kci,kci->kc", closest - points[:, None, :], closest - points[:, None, :]), np.inf)
        best = np.argmin(d2, axis=1)
        rows = np.arange(len(points))
        q = closest[rows, best]
        w = bary[rows, best]
        t = np.take(self.triangles, tri_i[rows, best], axis=0)
        n = np.einsum("kj,kji->ki", w, np.take(self.normals, t, axis=0))
        n /= row_norms(n)[:, None] + 1e-300
        distance = np.sqrt(d2[rows, best])
        side = np.einsum("ki,ki->k", points - q, n)
        return distance, side, n


def surface_depth_in_body(surface: Surface, body: Body) -> float:
    """Largest depth of the surface below the skin of ``body``, m (see ``max_penetration_m``)."""
    v = np.asarray(surface.vertices, dtype=np.float64)
    f = np.asarray(surface.faces, dtype=np.int64)
    points = np.concatenate([v, v[f].mean(axis=1)])
    if not len(points):
        return 0.0
    return SkinDistance.of(body.vertices, body.faces).max_depth(points)


#: :func:`body_inside_furniture`'s answers, by the body's vertex array (its identity) and the
#: tessellation's contents: the surface fit's final check measures the designed
#: surface at the exported level, the evaluation asks the same of the same
#: surface made again from the same control points, and the surface fit's
#: last repair (``push_out``) starts where the final check of the same control
#: points left off.
_BODY_DEPTHS = IdentityCache(maxsize=16)


def body_depth_in_surface(surface: Surface, body: Body, query: SurfaceQuery | None = None, *, cell: float = 0.02) -> float:
    """Largest depth of a body vertex inside the furniture, m (0 when none is).

    The furniture is the solid the surface closes with the floor: the cage's
    boundary is its ground ring, on the floor, so every vertical ray from a
    point above the floor leaves the solid through the surface. A body
    vertex is inside when a ray from it straight up crosses the surface an
    odd number of times; its depth is its distance to the surface. This is
    the refiners' requirement read literally ("no body vertex more than
    5 mm inside the surface"); it also catches a thin part pushed right
    through the surface (a heel through a foot rest), where the surface
    itself reaches only a limb's radius into the body.

    Candidate triangles come from a grid of ``cell`` (m) over the floor
    plan; the point-in-triangle tests are exact in the plan. The answer is
    kept for the last few vertex arrays and tessellations in this process
    (the surface's normals and ``query`` do not change it):
    :func:`body_inside_furniture`.
    """
    _, dist = body_inside_furniture(surface, body, query, cell=cell)
    return float(dist.max()) if dist.size else 0.0


def body_inside_furniture(surface: Surface, body: Body, query: SurfaceQuery | None = None, *, cell: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """The body vertices inside the furniture (indices, ascending) and their distances to the surface, m.

    What :func:`body_depth_in_surface` reads its answer from, kept for the
    last few vertex arrays and tessellations in this process (the arrays
    are shared: not to be written to).
    """
    return _BODY_DEPTHS.get(
        (body.vertices,), lambda: _body_inside_furniture(surface, body, query, cell), tag=(content_key(surface.vertices, surface.faces), float(cell))
    )


def _body_depth_in_surface(surface: Surface, body: Body, query: SurfaceQuery | None, cell: float) -> float:
    """:func:`body_depth_in_surface` measured anew (nothing kept)."""
    _, dist = _body_inside_furniture(surface, body, query, cell)
    return float(dist.max()) if dist.size else 0.0


def _body_inside_furniture(surface: Surface, body: Body, query: SurfaceQuery | None, cell: float) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(body.vertices, dtype=np.float64)
    inside = np.flatnonzero(inside_furniture(surface, p, cell=cell))
    if not inside.size:
        return inside, np.zeros(0)
    query = query if query is not None else SurfaceQuery(surface)
    dist, _ = query.query(p[inside])
    return inside, dist


#: Slack (m) of :func:`inside_furniture`'s filters, far above the rounding of a crossing's height and barycentrics.
_MARGIN = 1e-6
#: Where :func:`inside_furniture`'s rays start, from each point (m): a hair off it in the plan.
_RAY_OFFSET = np.array([1.2345e-9, 0.0, 2.3456e-9])


def inside_furniture(surface: Surface, points: np.ndarray, *, cell: float = 0.02) -> np.ndarray:
    """(k,) bool: points inside the furniture the surface closes with the floor (see :func:`body_depth_in_surface`).

    A point above the floor is inside when the ray from it straight up
    crosses the surface an odd number of times.
    """
    v = np.asarray(surface.vertices, dtype=np.float64)
    f = np.asarray(surface.faces, dtype=np.int64)
    tris = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]]) if f.shape[1] == 4 else f
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not len(tris) or not len(p):
        return np.zeros(len(p), bool)
    # each corner's coordinates as contiguous columns, (corner, axis) -> (T,): a
    # gather from contiguous arrays is several times faster than from rows or a
    # transposed table, and so are reductions over columns
    vc = [np.ascontiguousarray(v[:, i]) for i in range(3)]
    tc = [np.ascontiguousarray(tris[:, c]) for c in range(3)]
    corner = [[np.take(vc[i], tc[c]) for i in range(3)] for c in range(3)]
    # x and z; corner by corner (a reduction along the short axis is several times slower)
    lo = [np.minimum(np.minimum(corner[0][i], corner[1][i]), corner[2][i]) for i in (0, 2)]
    hi = [np.maximum(np.maximum(corner[0][i], corner[1][i]), corner[2][i]) for i in (0, 2)]
    origin = np.array([np.minimum(lo[0].min(), p[:, 0].min()), np.minimum(lo[1].min(), p[:, 2].min())]) - cell
    c_lo = [np.floor((lo[a] - origin[a]) / cell).astype(np.int64) for a in (0, 1)]
    c_hi = [np.floor((hi[a] - origin[a]) / cell).astype(np.int64) for a in (0, 1)]
    width = int(max(c_hi[0].max(), np.floor((p[:, 0].max() - origin[0]) / cell))) + 2
    # every (triangle, cell) pair of the triangles' plan bounding boxes
    nx, nz = c_hi[0] - c_lo[0] + 1, c_hi[1] - c_lo[1] + 1
    count = nx * nz
    owner = np.repeat(np.arange(len(tris)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    row, col = np.divmod(k, np.take(nx, owner))  # (one integer division for both)
    gx = np.take(c_lo[0], owner) + col
    gz = np.take(c_lo[1], owner) + row
    key = gz * width + gx
    # the body vertices above the floor, their cells, and the triangles there
    up = np.flatnonzero(p[:, 1] > 0.0)
    # the rays start a hair off the body vertices in the plan (a fixed offset
    # far below any feature size), so that no ray runs exactly through a
    # vertex or an edge of the surface, where the parity could count a
    # crossing twice or not at all
    start_points = np.take(p, up, axis=0) + _RAY_OFFSET
    pc = np.floor((start_points[:, [0, 2]] - origin) / cell).astype(np.int64)
    pkey = pc[:, 1] * width + pc[:, 0]
    # a ray crosses only triangles above its start: a (triangle, cell) pair
    # whose triangle lies wholly below the lowest body vertex of the cell
    # (the seat under the thighs) is left out, which changes no parity
    lowest = np.full(int(max(key.max(initial=0), pkey.max(initial=0))) + 1, np.inf)
    np.minimum.at(lowest, pkey, start_points[:, 1])
    tri_top = np.maximum(np.maximum(corner[0][1], corner[1][1]), corner[2][1])
    top = np.take(tri_top, owner)
    above = top > lowest[key]
    key, owner, top = key[above], owner[above], top[above]
    # nor does a ray that starts above every triangle of its cell (the head
    # over the seat): it crosses nothing, and its start is left out (the
    # margins here and below are far above the rounding of a crossing's
    # height and barycentrics, so no parity changes)
    highest = np.full(len(lowest), -np.inf)
    np.maximum.at(highest, key, top)
    under = np.take(highest, pkey) + _MARGIN > start_points[:, 1]
    up, start_points, pkey = up[under], start_points[under], pkey[under]
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    start = np.searchsorted(key, pkey, side="left")
    stop = np.searchsorted(key, pkey, side="right")
    n = stop - start
    if not n.sum():
        return np.zeros(len(p), bool)
    pt = np.repeat(np.arange(up.size), n)
    j = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    tri = owner[np.repeat(start, n) + j]
    # of a cell's triangles, a ray can cross only one that reaches above its
    # start and whose plan bounding box holds it: the others (most of the
    # pairs) are left out before their corners are gathered
    q = [np.take(np.ascontiguousarray(start_points[:, i]), pt) for i in range(3)]
    keep = np.take(tri_top, tri) + _MARGIN > q[1]
    for i, a in ((0, 0), (2, 1)):
        keep &= (np.take(lo[a], tri) - _MARGIN <= q[i]) & (np.take(hi[a], tri) + _MARGIN >= q[i])
    pt, tri = pt[keep], tri[keep]
    qx, qy, qz = (x[keep] for x in q)
    # each gathered column contiguous
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = ([np.take(x, tri) for x in corner[c]] for c in range(3))
    # plan barycentrics of q in (a, b, c)
    e1x, e1z, e2x, e2z, dx, dz = bx - ax, bz - az, cx - ax, cz - az, qx - ax, qz - az
    det = e1x * e2z - e1z * e2x
    ok = np.abs(det) > 1e-18
    det = np.where(ok, det, 1.0)
    s = (dx * e2z - dz * e2x) / det
    r = (e1x * dz - e1z * dx) / det
    within = ok & (s >= 0) & (r >= 0) & (s + r <= 1)
    height = ay + s * (by - ay) + r * (cy - ay)
    crossing = within & (height > qy)
    out = np.zeros(len(p), bool)
    out[up] = np.bincount(pt[crossing], minlength=up.size) % 2 == 1
    return out
