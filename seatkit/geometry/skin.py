"""Signed distance to a body's closed skin.

The skin of a body is a closed triangle mesh, so "inside the body" is well
defined. :class:`SkinDistance` answers, for points near the skin, how deep
inside (or how far outside) they are: the closest point on the skin's
triangles around the points' nearest vertices (exact wherever the closest
triangle is among them: 99.5% of points near the rest-pose skin; elsewhere,
between fingers or at very long triangles, the distance found is to a
farther triangle, never a nearer one), signed with the *angle-weighted
pseudo-normal* of the feature (face, edge or vertex) the closest point lies
on. That sign is provably right for a closed manifold mesh (Baerentzen and
Aanaes, "Signed distance computation using the angle weighted
pseudonormal", IEEE TVCG 2005), where the normal of the nearest *vertex*
alone is not: in a crease (the crotch, between crossed legs) it calls
outside points inside and the other way round.

Points that the cheap estimate (nearest vertex and its normal) puts farther
than :attr:`SkinDistance.EXACT_WITHIN` outside the skin, with no vertex that
near, keep that estimate: only points near the skin decide contact,
clearance and penetration. Next to the skin's longest triangles (up to 7 cm
on the head and soles) a point a few mm from the skin can be that far from
every vertex and keep the estimate (about 1 point in 30,000 in a review's
sample); asking every point within the longest edge exactly doubled the
fit's time. Where the posed
skin intersects itself (a hand sunk into a thigh), "inside" is the union of
the parts and no local test is exact; the nearest feature's side is used
there too, and :meth:`SkinDistance.max_depth` confirms inside points by
their winding numbers. The nearest feature can then be buried skin (below
crossed legs, a thigh's skin inside the other thigh, facing up): a point
the nearest feature calls inside is called outside when a coarse grid
finds it in open space, connected to infinity without crossing the skin
(its winding number is 0); without that, points 40 cm under such a body
got a depth of +40 cm. Vertices no face uses are ignored; the mesh is
expected to share vertices between its faces (a glTF body with split
normals should be welded first).

open3d's ``RaycastingScene.compute_signed_distance`` does the same job, but
importing open3d costs about 1.2 s, a third of a whole build; tests compare
the two.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from seatkit.cache import IdentityCache
from seatkit.geometry.closest import closest_barycentric, row_norms, vertex_triangle_rings
from seatkit.geometry.normals import sum_rows_at

__all__ = ["SkinDistance"]

#: SkinDistance.of's cache: the last few meshes by the identity of their arrays
#: (a SkinDistance refers to its vertex array, hence the bound)
_CACHE = IdentityCache(maxsize=8)


class SkinDistance:
    """Signed distance queries against a closed triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
        A closed, consistently outward-oriented triangle mesh (a body's skin).
    """

    #: Points whose nearest skin vertex is closer than this (m), or that the
    #: nearest vertex's normal puts less than this outside, get the exact
    #: closest point and pseudo-normal sign.
    EXACT_WITHIN = 0.015
    #: Nearest skin vertices whose triangles are candidates for the closest point.
    CANDIDATE_VERTICES = 2
    #: Cell of the open-space grid that settles the side of points away from the skin, m.
    OPEN_SPACE_CELL = 0.015
    #: Points searched at once by the exact query.
    _BLOCK = 1024

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        # triangles without area (two corners coincide, or all three in a
        # line) add no surface: their edges belong to their neighbours, and
        # closest points on them would be ill-defined
        # (np.take gathers rows several times faster than indexing does)
        corner = [np.take(v, f[:, c], axis=0) for c in range(3)]
        ab, ac = corner[1] - corner[0], corner[2] - corner[0]
        cross = np.cross(ab, ac)
        area2 = np.einsum("ij,ij->i", cross, cross)
        scale = np.einsum("ij,ij->i", ab, ab) + np.einsum("ij,ij->i", ac, ac)
        keep = area2 > 1e-18 * scale**2
        if not keep.all():
            f, cross = f[keep], cross[keep]
            corner = [x[keep] for x in corner]
        self.vertices, self.faces = v, f
        #: (lo, hi): the skin's axis-aligned bounding box, m
        self.bounds = (v.min(axis=0), v.max(axis=0))
        fn = cross / np.maximum(row_norms(cross)[:, None], 1e-300)
        self.face_normals = fn
        # angle-weighted vertex pseudo-normals
        weighted = []
        for c in range(3):
            a = corner[(c + 1) % 3] - corner[c]
            b = corner[(c + 2) % 3] - corner[c]
            cosang = np.einsum("ij,ij->i", a, b) / np.maximum(row_norms(a) * row_norms(b), 1e-300)
            weighted.append(fn * np.arccos(np.clip(cosang, -1.0, 1.0))[:, None])
        vn = sum_rows_at(len(v), f.T, np.concatenate(weighted))  # corner by corner, in turn
        self.vertex_normals = vn / np.maximum(row_norms(vn)[:, None], 1e-300)
        # edge pseudo-normals, per triangle and edge (edge k is opposite corner k)
        m = len(f)
        a_idx = np.stack([f[:, 1], f[:, 2], f[:, 0]], axis=1)  # edge k joins these two corners
        b_idx = np.stack([f[:, 2], f[:, 0], f[:, 1]], axis=1)
        key = np.minimum(a_idx, b_idx) * len(v) + np.maximum(a_idx, b_idx)
        flat = key.ravel()
        order = np.argsort(flat, kind="stable")
        sorted_keys = flat[order]
        owner = order // 3
        edge_n = np.take(fn, owner, axis=0)
        same_next = np.flatnonzero(sorted_keys[1:] == sorted_keys[:-1])
        # manifold edges: two triangles share the key; sum both face normals
        pair_sum = np.take(edge_n, same_next, axis=0) + np.take(edge_n, same_next + 1, axis=0)
        edge_n[same_next] = pair_sum
        edge_n[same_next + 1] = pair_sum
        per_tri = np.empty((m * 3, 3))
        per_tri[order] = edge_n
        self.edge_normals = per_tri.reshape(m, 3, 3)
        self.rings = vertex_triangle_rings(f, len(v))  # vertex -> incident triangles, padded with -1
        # only vertices some face uses (a stray vertex would offer no triangles)
        self._used = np.flatnonzero(np.bincount(f.ravel(), minlength=len(v)))  # np.unique(f), sorted
        self.tree = cKDTree(np.take(v, self._used, axis=0), balanced_tree=False, compact_nodes=False)
        # per triangle: corner a, edges ab and ac and their dot products, for
        # the closest-point regions with two dot products per query
        self._a = corner[0]
        self._ab = corner[1] - self._a
        self._ac = corner[2] - self._a
        self._d00 = np.einsum("ij,ij->i", self._ab, self._ab)
        self._d01 = np.einsum("ij,ij->i", self._ab, self._ac)
        self._d11 = np.einsum("ij,ij->i", self._ac, self._ac)
        # the same, one row per triangle (a, ab, ac, d00, d01, d11): one gather for all of them
        self._table = np.concatenate([self._a, self._ab, self._ac, self._d00[:, None], self._d01[:, None], self._d11[:, None]], axis=1)
        self._open = None  # (origin, cell, open-space mask, clearance per cell), built on first use

    @classmethod
    def of(cls, vertices: np.ndarray, faces: np.ndarray) -> "SkinDistance":
        """The SkinDistance of a mesh, built once per vertex array in this process.

        The fit and the evaluation of one build ask about the same bodies;
        the cache is keyed by the arrays' identity (checked through weak
        references, so a new array at a recycled address is not mistaken
        for an old one) and holds the last few meshes.
        """
        return _CACHE.get((vertices, faces), lambda: cls(vertices, faces), tag=cls)

    def prepare(self) -> "SkinDistance":
        """Build now what is otherwise built on first use (the open-space grid); return self."""
        self._open_space()
        return self

    def query(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Depth below the skin, closest skin point and outward direction.

        Parameters
        ----------
        points : (k, 3) float64

        Returns
        -------
        depth : (k,) float64
            Distance to the skin, positive inside the body, negative outside, m.
        closest : (k, 3) float64
            Closest point on the skin (the nearest vertex for far points).
        normal : (k, 3) float64
            Unit outward direction: the gradient of the signed distance
            (moving a point along it brings it out of, or farther from, the
            body); the pseudo-normal for points on the skin; the nearest
            vertex's normal for far points.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        # the candidate vertices of the exact query come with the nearest one
        # (one tree search per point instead of two for those near the skin)
        gap, candidates = self.tree.query(points, k=self.CANDIDATE_VERTICES, workers=1)
        gap, candidates = gap.reshape(len(points), -1), self._used[candidates.reshape(len(points), -1)]
        near = candidates[:, 0]
        closest = np.take(self.vertices, near, axis=0)
        normal = np.take(self.vertex_normals, near, axis=0)
        depth = -np.einsum("ij,ij->i", normal, points - closest)
        # the exact query where it matters: near the skin, or where the
        # nearest vertex alone would call the point inside or nearly so
        exact = np.flatnonzero((gap[:, 0] < self.EXACT_WITHIN) | (depth > -self.EXACT_WITHIN))
        if exact.size:
            d, q, n = self._exact(np.take(points, exact, axis=0), np.take(candidates, exact, axis=0))
            depth[exact], closest[exact], normal[exact] = d, q, n
        # the nearest feature's side is wrong where it is buried skin (a
        # thigh's skin inside the crossed other thigh faces that thigh): a
        # point the open space connects to infinity is outside whatever it
        # says
        inside = np.flatnonzero(depth > 0.0)
        if inside.size:
            free = inside[self._in_open_space(points[inside])]
            depth[free], normal[free] = -depth[free], -normal[free]
        return depth, closest, normal

    def _in_open_space(self, points: np.ndarray) -> np.ndarray:
        """(k,) bool: points certainly outside the body (winding number 0).

        A grid of :attr:`OPEN_SPACE_CELL` cells over the skin's bounding box
        (one empty layer around it) marks every cell a triangle touches
        (samples at most a cell apart on each triangle, so that every point
        of it is less than a cell from one, their cells dilated by one
        cell: conservative); the unmarked cells connected to
        the outer layer through faces are open space, where the winding
        number is 0 (it changes only across the skin). Built on first use.
        """
        origin, h, open_space, _ = self._open_space()
        within, cell = self._cells(points, origin, h, open_space.shape)
        out = np.ones(len(points), bool)
        out[within] = np.take(open_space, cell)
        return out

    def clear_of(self, points: np.ndarray) -> np.ndarray:
        """(k,) float64: a lower bound on how far points are outside the skin, m (0 where unknown).

        From the open-space grid (see :meth:`_in_open_space`): a point in an
        open cell ``c`` cells (chessboard) from the nearest cell a triangle's
        samples touch is at least ``(c - 1) h`` from those samples, and every
        point of a triangle is within ``h / sqrt(3)`` of one (its samples are
        at most ``h`` apart), so at least ``(c - 1 - 1/sqrt(3)) h`` from the
        skin, and outside; no point is nearer the skin than the skin's
        bounding box. :meth:`query` reports such a point at least
        that far outside (its closest-point search can only find a farther
        triangle), so a caller that needs only points nearer than some
        distance can leave the others out.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        origin, h, _, clear = self._open_space()
        lo, hi = self.bounds
        # the distance to the bounding box, 0 inside it
        out = np.zeros(len(points))
        x, y, z = points.T
        # (column by column: a reduction along the short axis is several times slower)
        off = np.flatnonzero(~((x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1]) & (z >= lo[2]) & (z <= hi[2])))
        if off.size:
            q = np.take(points, off, axis=0)
            out[off] = row_norms(np.maximum(lo - q, 0.0) + np.maximum(q - hi, 0.0))
        within, cell = self._cells(points, origin, h, clear.shape)
        out[within] = np.maximum(out[within], np.take(clear, cell))
        return out

    @staticmethod
    def _cells(points: np.ndarray, origin: np.ndarray, h: float, shape: tuple) -> tuple[np.ndarray, np.ndarray]:
        """The points in a grid of ``shape`` cells of ``h`` from ``origin`` (indices), and their cells (flat indices)."""
        # a negative index is a large unsigned one: one comparison per axis
        i, j, k = np.floor((points - origin) / h).astype(np.int64).view(np.uint64).T
        within = np.flatnonzero((i < shape[0]) & (j < shape[1]) & (k < shape[2]))
        i, j, k = (np.take(c, within).astype(np.int64) for c in (i, j, k))
        return within, (i * shape[1] + j) * shape[2] + k

    def _open_space(self):
        """(origin, cell, open-space mask, clearance per cell) of the open-space grid, built on first use."""
        if self._open is None:
            h = self.OPEN_SPACE_CELL
            v, f = self.vertices, self.faces
            origin = self.bounds[0] - 2.0 * h
            shape = np.ceil((self.bounds[1] - origin) / h).astype(int) + 3
            corners = np.take(v, f, axis=0)  # (m, 3, 3)
            longest = row_norms(corners - np.roll(corners, 1, axis=1)).max(axis=1)
            steps = np.maximum(np.ceil(longest / h).astype(int), 1)
            marked = np.zeros(shape, bool)
            # every triangle's corners are among its samples: the skin's vertices'
            # cells, at once; the samples inside the triangles longer than a cell
            cells = np.floor((np.take(v, self._used, axis=0) - origin) / h).astype(int)
            marked[cells[:, 0], cells[:, 1], cells[:, 2]] = True
            for n in np.unique(steps[steps > 1]):
                i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
                keep = i + j <= n
                bary = np.stack([n - i[keep] - j[keep], i[keep], j[keep]], axis=1) / n  # (s, 3)
                samples = np.einsum("sc,mci->msi", bary, corners[steps == n]).reshape(-1, 3)
                cells = np.floor((samples - origin) / h).astype(int)
                marked[cells[:, 0], cells[:, 1], cells[:, 2]] = True
            # chessboard distance (cells) to the nearest touched cell
            reach = ndimage.distance_transform_cdt(~marked, metric="chessboard")
            marked = reach <= 1  # dilated by one cell (3 x 3 x 3)
            labels, _ = ndimage.label(~marked)  # face-connected components of the unmarked cells
            open_space = labels == labels[0, 0, 0]
            clear = np.where(open_space, np.maximum((reach - 1.0 - 1.0 / np.sqrt(3.0)) * h, 0.0), 0.0)
            self._open = (origin, h, open_space, clear)
        return self._open

    def _nearest_triangle(self, points: np.ndarray, cand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Of the candidate triangles ``cand`` (k, c; -1: none) of each point, the closest (the first of equals) and the barycentric coordinates (k, 3) of its closest point.

        Each point's candidates are the rings of its nearest vertices, one
        after the other (every point's first ring holds a triangle): about
        a third of the slots are padding or a triangle an earlier ring
        already offers (two neighbouring vertices share two), and only the
        others are searched, as one flat list of (point, triangle) pairs in
        the slots' order. The first of equals is then the same triangle as
        over all slots, and each pair's arithmetic is the same, to the bit.
        """
        k, c = cand.shape
        keep = cand >= 0
        width = self.rings.shape[1]
        for j in range(width, c, width):
            # a triangle of this ring that an earlier ring holds: searched there already
            # (slot by slot: a reduction along the short axis is several times slower)
            ring = cand[:, j : j + width]
            seen = ring == cand[:, :1]
            for s in range(1, j):
                seen |= ring == cand[:, s : s + 1]
            keep[:, j : j + width] &= ~seen
        pair = np.flatnonzero(keep)  # in (point, slot) order
        owner = pair // c
        count = np.bincount(owner, minlength=k)
        tri = np.take(cand, pair)
        # each pair's triangle in one gather (np.take: several times faster than indexing)
        g = np.take(self._table, tri, axis=0)
        ap = np.take(points, owner, axis=0) - g[:, 0:3]
        ab, ac = g[:, 3:6], g[:, 6:9]
        d00, d01, d11 = g[:, 9], g[:, 10], g[:, 11]
        d1 = np.einsum("ni,ni->n", ab, ap)
        d2 = np.einsum("ni,ni->n", ac, ap)
        bary = closest_barycentric(d1, d2, d00, d01, d11)
        _, v, w = bary
        # |ap - v ab - w ac|^2 without forming the points:
        # ap . ap - 2 (v d1 + w d2) + v v d00 + 2 v w d01 + w w d11, term by term in
        # that order, in place (the same operations, fewer temporaries)
        d2sq = np.einsum("ni,ni->n", ap, ap)
        term = v * d1
        term += w * d2
        term *= 2.0
        d2sq -= term
        np.multiply(v, v, out=term)
        term *= d00
        d2sq += term
        np.multiply(2.0, v, out=term)
        term *= w
        term *= d01
        d2sq += term
        np.multiply(w, w, out=term)
        term *= d11
        d2sq += term
        odd = ~np.isfinite(d2sq)
        np.maximum(d2sq, 0.0, out=d2sq)
        d2sq[odd] = np.inf
        # the first pair of each point at its smallest distance
        start = np.cumsum(count) - count
        lowest = np.minimum.reduceat(d2sq, start)
        at_min = np.flatnonzero(d2sq == np.repeat(lowest, count))
        who = np.take(owner, at_min)
        best = at_min[np.concatenate([[True], who[1:] != who[:-1]])]
        return np.take(tri, best), np.stack([np.take(x, best) for x in bary], axis=1)

    def _exact(self, points: np.ndarray, near: np.ndarray):
        # in blocks of points whose candidates' arrays stay in the cache
        # (about 2 MB a block: 30-40% faster per point than one pass over
        # ten thousand points, the same answers)
        t = np.empty(len(points), dtype=np.int64)
        w = np.empty((len(points), 3))
        for lo in range(0, len(points), self._BLOCK):
            hi = min(lo + self._BLOCK, len(points))
            cand = np.take(self.rings, near[lo:hi], axis=0).reshape(hi - lo, -1)
            t[lo:hi], w[lo:hi] = self._nearest_triangle(points[lo:hi], cand)
        tri = np.take(self.faces, t, axis=0)
        g = np.take(self._table, t, axis=0)
        qb = g[:, 0:3] + w[:, 1:2] * g[:, 3:6] + w[:, 2:3] * g[:, 6:9]
        zero = w <= 0.0
        nz = zero.sum(axis=1)
        normal = np.take(self.face_normals, t, axis=0)
        on_edge = np.flatnonzero(nz == 1)
        if on_edge.size:
            k = np.argmax(zero[on_edge], axis=1)  # the edge opposite the zero corner
            normal[on_edge] = self.edge_normals[t[on_edge], k]
        at_vertex = np.flatnonzero(nz == 2)
        if at_vertex.size:
            k = np.argmax(w[at_vertex], axis=1)
            normal[at_vertex] = self.vertex_normals[tri[at_vertex, k]]
        normal /= np.maximum(row_norms(normal)[:, None], 1e-300)
        dist = row_norms(points - qb)
        side = np.einsum("ij,ij->i", points - qb, normal)
        inside = side < 0
        depth = np.where(inside, dist, -dist)
        # outward direction: the gradient of the signed distance, (p - q) / |p - q|
        # outside and its opposite inside; the pseudo-normal on the skin itself
        grad = (points - qb) / np.maximum(dist, 1e-300)[:, None]
        grad[inside] *= -1.0
        direction = np.where((dist > 1e-9)[:, None], grad, normal)
        return depth, qb, direction

    def winding_numbers(self, points: np.ndarray, *, batch: int = 16) -> np.ndarray:
        """Generalised winding numbers of points (1 inside, 0 outside).

        The sum of the solid angles the skin's triangles subtend at each
        point, over 4 pi (Van Oosterom and Strackee's formula; Jacobson et
        al. 2013). Unlike a local sign it stays right where the posed skin
        intersects itself (a hand sunk into a thigh, crossed legs pressed
        together): a point inside two overlapping parts gets 2, a point in a
        crease between them 0. Exact and O(triangles) per point: used to
        confirm the few points a local test calls inside.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        tri = self.vertices[self.faces]  # (m, 3, 3)
        out = np.empty(len(points))
        for s in range(0, len(points), batch):
            r = tri[None, :, :, :] - points[s : s + batch, None, None, :]  # (b, m, 3, 3)
            a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
            la, lb, lc = (row_norms(x) for x in (a, b, c))
            num = np.einsum("bmi,bmi->bm", a, np.cross(b, c))
            den = (
                la * lb * lc
                + np.einsum("bmi,bmi->bm", a, b) * lc
                + np.einsum("bmi,bmi->bm", b, c) * la
                + np.einsum("bmi,bmi->bm", c, a) * lb
            )
            out[s : s + batch] = np.arctan2(num, den).sum(axis=1) / (2.0 * np.pi)
        return out

    def max_depth(self, points: np.ndarray, *, confirm: int = 256) -> float:
        """Largest depth of any of ``points`` inside the body, m (0 when none is inside).

        Points the local test (:meth:`query`) calls inside are confirmed by
        their winding number, deepest first: in a crease of a self-touching
        skin the local sign can be wrong. After ``confirm`` unconfirmed
        candidates the next one's depth is reported unconfirmed (the
        conservative answer).
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        # points in open space are outside (query would say so): not asked
        points = points[~self._in_open_space(points)]
        if not len(points):
            return 0.0
        depth, _, _ = self.query(points)
        order = np.argsort(-depth)
        order = order[depth[order] > 0.0]
        start, size = 0, 1  # growing batches: the deepest is usually confirmed at once
        while start < min(order.size, confirm):
            chunk = order[start : min(start + size, confirm)]
            inside = np.flatnonzero(self.winding_numbers(np.asarray(points)[chunk]) > 0.5)
            if inside.size:
                return float(depth[chunk[inside[0]]])
            start, size = start + size, size * 4
        return float(depth[order[confirm]]) if order.size > confirm else 0.0
