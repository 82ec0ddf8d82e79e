"""Subdivision cages and their mesh topology, with OpenSubdiv's orderings.

A :class:`Cage` is the input of Catmull-Clark subdivision: control points,
polygons, edge creases and corner vertices. :class:`MeshLevel` is the
half-edge style topology of one refinement level, built with exactly the
component orderings of OpenSubdiv's ``Vtr::Level`` (edges numbered in order
of first appearance, the incident faces and edges of each vertex walked
counter-clockwise from OpenSubdiv's first face), so that refined vertex
indices and the tangents of the limit masks match ``Far::PrimvarRefiner``.

Every array is numpy; nothing loops over vertices in Python. The only loop
is the counter-clockwise walk around the vertices, vectorised over all
vertices at once (as many iterations as the largest valence).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from seatkit.cache import LRUCache
from seatkit.errors import InputError

__all__ = [
    "Cage",
    "MeshLevel",
    "SHARPNESS_INFINITE",
    "BOUNDARY_MODES",
    "RULE_SMOOTH",
    "RULE_DART",
    "RULE_CREASE",
    "RULE_CORNER",
]

#: OpenSubdiv's infinite sharpness (Sdc::Crease::SHARPNESS_INFINITE); any
#: sharpness at or above it is an infinitely sharp crease or corner.
SHARPNESS_INFINITE = np.float32(10.0)

#: Boundary interpolation modes, named as in USD's ``interpolateBoundary``
#: (``edgeAndCorner`` / ``edgeOnly``) and OpenSubdiv's VTX_BOUNDARY_* options.
BOUNDARY_MODES = ("edge-and-corner", "edge-only")

#: Vertex subdivision rules, with OpenSubdiv's Sdc::Crease::Rule values.
RULE_SMOOTH, RULE_DART, RULE_CREASE, RULE_CORNER = 1, 2, 4, 8

_BOUNDARY_ALIASES = {
    "edge-and-corner": "edge-and-corner",
    "edge_and_corner": "edge-and-corner",
    "edgeandcorner": "edge-and-corner",
    "edge-only": "edge-only",
    "edge_only": "edge-only",
    "edgeonly": "edge-only",
}


def decrement_sharpness(sharpness: np.ndarray) -> np.ndarray:
    """Sharpness of the children after one uniform refinement step.

    OpenSubdiv's ``Crease::decrementSharpness`` in float32: smooth stays 0,
    infinite (>= 10) stays 10, s > 1 becomes s - 1, anything else 0.

    Parameters
    ----------
    sharpness : (k,) float32

    Returns
    -------
    (k,) float32
    """
    s = np.asarray(sharpness, dtype=np.float32)
    out = np.where(s > np.float32(1.0), s - np.float32(1.0), np.float32(0.0)).astype(np.float32)
    out[s >= SHARPNESS_INFINITE] = SHARPNESS_INFINITE
    return out


def _as_polygons(faces) -> tuple[np.ndarray, np.ndarray]:
    """Face sizes and flattened indices from an (f, k) array or a list of polygons."""
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        arr = faces
        if arr.size and not np.issubdtype(arr.dtype, np.integer):
            if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
                msg = "cage faces must hold integer vertex indices"
                raise InputError(msg)
        arr = arr.astype(np.int64)
        sizes = np.full(len(arr), arr.shape[1], dtype=np.int64)
        return sizes, arr.reshape(-1)
    polys = []
    for i, poly in enumerate(faces):
        p = np.asarray(poly)
        if p.ndim != 1:
            msg = f"cage face {i} must be a flat list of vertex indices, got shape {p.shape}"
            raise InputError(msg)
        if p.size and not np.issubdtype(p.dtype, np.integer):
            if not np.all(np.isfinite(p)) or np.any(p != np.round(p)):
                msg = f"cage face {i} holds non-integer vertex indices {p.tolist()}"
                raise InputError(msg)
        polys.append(p.astype(np.int64))
    sizes = np.array([len(p) for p in polys], dtype=np.int64)
    flat = np.concatenate(polys) if polys else np.zeros(0, np.int64)
    return sizes, flat


class Cage:
    """A Catmull-Clark control cage with OpenSubdiv's sharpness semantics.

    Parameters
    ----------
    vertices : (v, 3) float64
        Control points.
    faces : (f, k) int64 or sequence of sequences of int
        Polygons (3 or more vertices each), counter-clockwise seen from the
        side the normals point to.
    crease_edges : (c, 2) int64, optional
        Creased edges as vertex pairs (either direction).
    crease_sharpness : (c,) float, optional
        OpenSubdiv sharpness of each creased edge; 10 or more is infinitely
        sharp, 0 < s < 10 semi-sharp (sharp for ``s`` levels, then blended).
        Default 10 for every listed edge.
    corners : (k,) int64, optional
        Corner vertices.
    corner_sharpness : (k,) float, optional
        OpenSubdiv sharpness of each corner; default 10.
    boundary : {"edge-and-corner", "edge-only"}
        Boundary interpolation: OpenSubdiv's VTX_BOUNDARY_EDGE_AND_CORNER
        (boundary vertices of one face are kept as sharp corners; the
        default, also USD's and Blender's "Keep Corners") or
        VTX_BOUNDARY_EDGE_ONLY.

    Raises
    ------
    InputError
        Non-finite coordinates, a face with fewer than 3 vertices or a
        repeated vertex, an index out of range, an unused vertex, an edge
        shared by more than two faces or by two faces of opposite winding, a
        vertex whose faces do not form one fan, a crease naming an edge that
        does not exist, or a negative/NaN sharpness.

    Notes
    -----
    Sharpness values are stored as float32, as OpenSubdiv stores them, so
    that semi-sharp decay (2.3 -> 1.3 -> 0.3) rounds as it does there.
    """

    def __init__(
        self,
        vertices,
        faces,
        crease_edges=None,
        crease_sharpness=None,
        corners=None,
        corner_sharpness=None,
        boundary: str = "edge-and-corner",
    ):
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3:
            msg = f"cage vertices must be (v, 3), got shape {v.shape}"
            raise InputError(msg)
        bad = ~np.isfinite(v).all(axis=1)
        if bad.any():
            idx = np.flatnonzero(bad)
            msg = f"cage vertex {idx[0]} has non-finite coordinates {v[idx[0]].tolist()} ({len(idx)} such vertices)"
            raise InputError(msg)
        sizes, flat = _as_polygons(faces)
        if len(sizes) == 0:
            msg = "cage has no faces"
            raise InputError(msg)
        small = np.flatnonzero(sizes < 3)
        if len(small):
            msg = f"cage face {small[0]} has {sizes[small[0]]} vertices; a face needs at least 3"
            raise InputError(msg)
        out = (flat < 0) | (flat >= len(v))
        if out.any():
            corner = int(np.flatnonzero(out)[0])
            face = int(np.searchsorted(np.cumsum(sizes), corner, side="right"))
            msg = f"cage face {face} refers to vertex {flat[corner]}, out of range for {len(v)} vertices"
            raise InputError(msg)
        mode = _BOUNDARY_ALIASES.get(str(boundary).strip().lower().replace(" ", "-"))
        if mode is None:
            msg = f"boundary must be one of {BOUNDARY_MODES}, got {boundary!r}"
            raise InputError(msg)

        ce = np.zeros((0, 2), np.int64) if crease_edges is None else np.asarray(crease_edges, dtype=np.int64)
        if ce.size == 0:
            ce = np.zeros((0, 2), np.int64)
        if ce.ndim != 2 or ce.shape[1] != 2:
            msg = f"crease_edges must be (c, 2) vertex pairs, got shape {ce.shape}"
            raise InputError(msg)
        cs = _sharpness(crease_sharpness, len(ce), "crease_sharpness")
        co = np.zeros(0, np.int64) if corners is None else np.asarray(corners, dtype=np.int64).reshape(-1)
        cos_ = _sharpness(corner_sharpness, len(co), "corner_sharpness")
        if len(co) and ((co < 0) | (co >= len(v))).any():
            bad_c = co[(co < 0) | (co >= len(v))][0]
            msg = f"corner vertex {bad_c} is out of range for {len(v)} vertices"
            raise InputError(msg)

        self.vertices = v
        self.face_sizes = sizes
        self.face_indices = flat
        self.crease_edges = ce
        self.crease_sharpness = cs
        self.corners = co
        self.corner_sharpness = cos_
        self.boundary = mode
        self.topology_key = _topology_key(len(v), sizes, flat, ce, cs, co, cos_, mode)
        # Builds (and caches) the base level: the topology checks live there.
        self.base_level()

    # ------------------------------------------------------------------ API
    @classmethod
    def from_control_mesh(cls, mesh, *, boundary: str = "edge-and-corner") -> "Cage":
        """The cage of a :class:`seatkit.model.ControlMesh` (its creases and corners)."""
        return cls(
            mesh.vertices,
            mesh.faces,
            crease_edges=mesh.crease_edges,
            crease_sharpness=mesh.crease_sharpness,
            corners=mesh.corners,
            corner_sharpness=mesh.corner_sharpness,
            boundary=boundary,
        )

    @property
    def n_vertices(self) -> int:
        """Number of control points."""
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        """Number of polygons."""
        return len(self.face_sizes)

    @property
    def polygons(self) -> list[np.ndarray]:
        """The faces as a list of (k,) int64 arrays."""
        return np.split(self.face_indices, np.cumsum(self.face_sizes)[:-1])

    @property
    def faces(self):
        """(f, k) int64 if every face has k vertices, else a list of polygons."""
        if np.all(self.face_sizes == self.face_sizes[0]):
            return self.face_indices.reshape(-1, int(self.face_sizes[0]))
        return self.polygons

    def with_vertices(self, vertices) -> "Cage":
        """The same topology and creases with new control points (v, 3)."""
        return Cage(
            vertices,
            self.faces,
            self.crease_edges,
            self.crease_sharpness,
            self.corners,
            self.corner_sharpness,
            self.boundary,
        )

    def base_level(self) -> "MeshLevel":
        """Level-0 topology with boundary and crease sharpness applied (cached)."""
        return _LEVEL_CACHE.get(self.topology_key, lambda: _build_base_level(self))

    def __repr__(self) -> str:
        return (
            f"Cage({self.n_vertices} vertices, {self.n_faces} faces, {len(self.crease_edges)} creases, "
            f"{len(self.corners)} corners, boundary={self.boundary!r})"
        )


#: Cage.base_level's cache: topology key -> MeshLevel
_LEVEL_CACHE = LRUCache(maxsize=64)


def _sharpness(values, n: int, name: str) -> np.ndarray:
    if values is None:
        return np.full(n, SHARPNESS_INFINITE, dtype=np.float32)
    s = np.asarray(values, dtype=np.float64).reshape(-1)
    if s.shape != (n,):
        msg = f"{name} must have one value per item ({n}), got shape {s.shape}"
        raise InputError(msg)
    if np.isnan(s).any() or (s < 0).any():
        msg = f"{name} must be >= 0 (OpenSubdiv sharpness), got {s[np.isnan(s) | (s < 0)][0]}"
        raise InputError(msg)
    return s.astype(np.float32)


def _topology_key(nv, sizes, flat, ce, cs, co, cos_, mode) -> str:
    h = hashlib.blake2b(digest_size=20)
    h.update(np.int64(nv).tobytes())
    for arr in (sizes, flat, ce, cs, co, cos_):
        a = np.ascontiguousarray(arr)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    h.update(mode.encode())
    return h.hexdigest()


@dataclass
class MeshLevel:
    """Topology and sharpness of one refinement level (OpenSubdiv orderings).

    Attributes
    ----------
    n_vertices : int
    face_offsets : (f + 1,) int64
        Face ``i`` owns corners ``face_offsets[i]:face_offsets[i + 1]``.
    face_sizes : (f,) int64
    corner_vertex : (c,) int64
        Vertex at each face corner (the flattened face lists).
    corner_face, corner_next, corner_prev, corner_local : (c,) int64
        Owning face, next / previous corner in the face, position in it.
    corner_edge : (c,) int64
        Edge from the corner's vertex to the next corner's vertex (OpenSubdiv's
        face-edge ``i`` of the face).
    edge_vertices : (e, 2) int64
        Edge end points in OpenSubdiv's order.
    edge_corners : (e, 2) int64
        Corners whose outgoing half-edge is the edge: OpenSubdiv's first
        incident face first, -1 for a boundary edge's missing second.
    ring_offsets : (v + 1,) int64
        Vertex ``i`` owns ring entries ``ring_offsets[i]:ring_offsets[i+1]``
        of ``ring_corner`` (its incident face corners, counter-clockwise,
        starting at OpenSubdiv's first face).
    ring_corner : (r,) int64
    edge_ring_offsets : (v + 1,) int64
        Vertex ``i`` owns entries ``edge_ring_offsets[i]:...[i+1]`` of
        ``ring_edge`` / ``ring_opposite``: its incident edges in
        OpenSubdiv's order (edge ``k`` leads face ``k``; a boundary vertex has
        one more edge than faces).
    ring_edge, ring_opposite : (s,) int64
        Incident edge and the vertex at its other end.
    n_vertex_faces, n_vertex_edges : (v,) int64
    edge_sharpness : (e,) float32
    vertex_sharpness : (v,) float32
    """

    n_vertices: int
    face_offsets: np.ndarray
    face_sizes: np.ndarray
    corner_vertex: np.ndarray
    corner_face: np.ndarray
    corner_next: np.ndarray
    corner_prev: np.ndarray
    corner_local: np.ndarray
    corner_edge: np.ndarray
    edge_vertices: np.ndarray
    edge_corners: np.ndarray
    ring_offsets: np.ndarray
    ring_corner: np.ndarray
    edge_ring_offsets: np.ndarray
    ring_edge: np.ndarray
    ring_opposite: np.ndarray
    n_vertex_faces: np.ndarray
    n_vertex_edges: np.ndarray
    edge_sharpness: np.ndarray
    vertex_sharpness: np.ndarray

    @property
    def n_faces(self) -> int:
        return len(self.face_sizes)

    @property
    def n_edges(self) -> int:
        return len(self.edge_vertices)

    @property
    def n_corners(self) -> int:
        return len(self.corner_vertex)

    @property
    def ring_vertex(self) -> np.ndarray:
        """(r,) int64 vertex of each face-ring entry."""
        return np.repeat(np.arange(self.n_vertices), self.n_vertex_faces)

    @property
    def edge_ring_vertex(self) -> np.ndarray:
        """(s,) int64 vertex of each edge-ring entry."""
        return np.repeat(np.arange(self.n_vertices), self.n_vertex_edges)

    @property
    def edge_ring_position(self) -> np.ndarray:
        """(s,) int64 position of each edge-ring entry around its vertex."""
        return np.arange(len(self.ring_edge)) - np.repeat(self.edge_ring_offsets[:-1], self.n_vertex_edges)

    @property
    def ring_position(self) -> np.ndarray:
        """(r,) int64 position of each face-ring entry around its vertex."""
        return np.arange(len(self.ring_corner)) - np.repeat(self.ring_offsets[:-1], self.n_vertex_faces)

    def rules(self, vertex_sharpness=None, edge_sharpness=None) -> np.ndarray:
        """(v,) int64 Sdc vertex rule from sharpness (OpenSubdiv's DetermineVertexVertexRule).

        Corner if the vertex is sharp, else by the number of sharp incident
        edges: 0 smooth, 1 dart, 2 crease, more corner.
        """
        vs = self.vertex_sharpness if vertex_sharpness is None else vertex_sharpness
        es = self.edge_sharpness if edge_sharpness is None else edge_sharpness
        sharp_count = self.sharp_edge_count(es)
        rule = np.select(
            [sharp_count == 0, sharp_count == 1, sharp_count == 2],
            [RULE_SMOOTH, RULE_DART, RULE_CREASE],
            default=RULE_CORNER,
        )
        rule[vs > 0] = RULE_CORNER
        return rule.astype(np.int64)

    def sharp_edge_count(self, edge_sharpness=None) -> np.ndarray:
        """(v,) int64 number of incident edges with sharpness > 0."""
        es = self.edge_sharpness if edge_sharpness is None else edge_sharpness
        sharp = (es[self.ring_edge] > 0).astype(np.int64)
        return np.bincount(self.edge_ring_vertex, weights=sharp, minlength=self.n_vertices).astype(np.int64)

    def crease_ends(self, edge_sharpness=None) -> np.ndarray:
        """(v, 2) int64 ring positions of the first and last sharp incident edge (-1 if none)."""
        es = self.edge_sharpness if edge_sharpness is None else edge_sharpness
        sharp = es[self.ring_edge] > 0
        pos = self.edge_ring_position
        vert = self.edge_ring_vertex
        first = np.full(self.n_vertices, np.iinfo(np.int64).max, np.int64)
        last = np.full(self.n_vertices, -1, np.int64)
        np.minimum.at(first, vert[sharp], pos[sharp])
        np.maximum.at(last, vert[sharp], pos[sharp])
        first[last < 0] = -1
        return np.stack([first, last], axis=1)

    def face_opposite(self, corners: np.ndarray) -> np.ndarray:
        """Vertex two places after each corner in its face (the quad's opposite corner)."""
        f = self.corner_face[corners]
        loc = (self.corner_local[corners] + 2) % self.face_sizes[f]
        return self.corner_vertex[self.face_offsets[f] + loc]


def _corner_arrays(face_sizes: np.ndarray):
    offsets = np.concatenate([[0], np.cumsum(face_sizes)]).astype(np.int64)
    nc = int(offsets[-1])
    face = np.repeat(np.arange(len(face_sizes), dtype=np.int64), face_sizes)
    local = np.arange(nc, dtype=np.int64) - offsets[face]
    size = face_sizes[face]
    nxt = offsets[face] + (local + 1) % size
    prv = offsets[face] + (local - 1) % size
    return offsets, face, local, nxt, prv


def build_level(
    n_vertices: int,
    face_sizes: np.ndarray,
    corner_vertex: np.ndarray,
    *,
    edge_vertices: np.ndarray | None = None,
    corner_edge: np.ndarray | None = None,
    edge_first_corner: np.ndarray | None = None,
    vertex_first_corner: np.ndarray | None = None,
    edge_sharpness: np.ndarray | None = None,
    vertex_sharpness: np.ndarray | None = None,
) -> MeshLevel:
    """Build a :class:`MeshLevel` from polygons.

    With only the polygons (level 0) edges are numbered in order of first
    appearance and each interior vertex's ring starts at its lowest-numbered
    face, as OpenSubdiv's ``completeTopologyFromFaceVertices`` does; a refined
    level passes the orderings its refinement defines.

    Raises
    ------
    InputError
        For the non-manifold and badly oriented configurations listed in
        :class:`Cage`.
    """
    face_sizes = np.asarray(face_sizes, dtype=np.int64)
    cv = np.asarray(corner_vertex, dtype=np.int64)
    offsets, cface, clocal, cnext, cprev = _corner_arrays(face_sizes)
    nc = len(cv)
    nv = int(n_vertices)
    a, b = cv, cv[cnext]

    if edge_vertices is None:
        # Level 0: validate the polygons and number edges by first appearance.
        dup_key = cface * nv + cv
        if len(np.unique(dup_key)) != nc:
            srt = np.sort(dup_key)
            rep = srt[1:][srt[1:] == srt[:-1]][0]
            msg = f"cage face {rep // nv} uses vertex {rep % nv} more than once"
            raise InputError(msg)
        used = np.zeros(nv, bool)
        used[cv] = True
        if not used.all():
            unused = np.flatnonzero(~used)
            msg = f"cage vertex {unused[0]} is not used by any face ({len(unused)} unused vertices); remove it"
            raise InputError(msg)
        key = np.minimum(a, b) * nv + np.maximum(a, b)
        _, first_idx, inverse = np.unique(key, return_index=True, return_inverse=True)
        order = np.argsort(first_idx, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        corner_edge = rank[inverse.reshape(-1)]
        edge_first_corner = first_idx[order]
        edge_vertices = np.stack([a[edge_first_corner], b[edge_first_corner]], axis=1)
    elif corner_edge is not None:
        corner_edge = np.asarray(corner_edge, dtype=np.int64)
    else:
        ev = np.asarray(edge_vertices, dtype=np.int64)
        ekey = np.minimum(ev[:, 0], ev[:, 1]) * nv + np.maximum(ev[:, 0], ev[:, 1])
        sorter = np.argsort(ekey)
        key = np.minimum(a, b) * nv + np.maximum(a, b)
        corner_edge = sorter[np.searchsorted(ekey[sorter], key)]
        edge_vertices = ev
    ne = len(edge_vertices)

    # Faces per edge: at most two, with opposite directions.
    count = np.bincount(corner_edge, minlength=ne)
    if (count > 2).any():
        e = int(np.flatnonzero(count > 2)[0])
        faces = np.unique(cface[corner_edge == e]).tolist()
        msg = (
            f"cage edge ({edge_vertices[e, 0]}, {edge_vertices[e, 1]}) is shared by {count[e]} faces "
            f"{faces}: non-manifold edge (a subdivision cage needs at most two faces per edge)"
        )
        raise InputError(msg)
    edge_corners = np.full((ne, 2), -1, np.int64)
    edge_corners[:, 0] = edge_first_corner
    others = np.flatnonzero(edge_first_corner[corner_edge] != np.arange(nc))
    edge_corners[corner_edge[others], 1] = others
    two = edge_corners[:, 1] >= 0
    same_dir = two & (cv[edge_corners[:, 0].clip(0)] == cv[edge_corners[:, 1].clip(0)])
    if same_dir.any():
        e = int(np.flatnonzero(same_dir)[0])
        f0, f1 = cface[edge_corners[e]]
        msg = (
            f"cage faces {f0} and {f1} share edge ({edge_vertices[e, 0]}, {edge_vertices[e, 1]}) in the same "
            "direction: their windings disagree (flip one so that the cage is consistently oriented)"
        )
        raise InputError(msg)

    # Where each vertex's ring starts (OpenSubdiv's vertex-face 0).
    boundary_out = edge_corners[corner_edge, 1] < 0  # the corner's outgoing edge is a boundary
    if vertex_first_corner is None:
        first = np.full(nv, -1, np.int64)
        # Interior: the lowest-numbered incident face (corners are in face order).
        _, first_occ = np.unique(cv, return_index=True)
        first[cv[first_occ]] = first_occ
        # Boundary: the corner whose outgoing edge is the leading boundary edge.
        bc = np.flatnonzero(boundary_out)
        first[cv[bc[::-1]]] = bc[::-1]  # lowest such corner wins
        vertex_first_corner = first

    # Counter-clockwise walk: the corner after c around its vertex owns the
    # other half of the edge arriving at c.
    e_in = corner_edge[cprev]
    ec = edge_corners[e_in]
    ring_next = np.where(ec[:, 1] < 0, -1, ec[:, 0] + ec[:, 1] - cprev)

    n_corners_at = np.bincount(cv, minlength=nv)
    start = np.asarray(vertex_first_corner, dtype=np.int64)
    cur = start.copy()
    verts = np.arange(nv)
    walk_v, walk_pos, walk_c = [], [], []
    pos = 0
    active = cur >= 0
    while active.any():
        idx = verts[active]
        walk_v.append(idx)
        walk_pos.append(np.full(len(idx), pos))
        walk_c.append(cur[idx])
        nxt = ring_next[cur[idx]]
        done = (nxt < 0) | (nxt == start[idx])
        cur[idx] = nxt
        active[idx[done]] = False
        pos += 1
        if pos > nc:
            break
    walk_v = np.concatenate(walk_v)
    walk_c = np.concatenate(walk_c)
    walk_pos = np.concatenate(walk_pos)
    reached = np.bincount(walk_v, minlength=nv)
    if (reached != n_corners_at).any():
        v = int(np.flatnonzero(reached != n_corners_at)[0])
        msg = (
            f"cage vertex {v} is non-manifold: its {n_corners_at[v]} faces do not form a single fan "
            "(two surface pieces touch at this vertex)"
        )
        raise InputError(msg)
    order = np.lexsort((walk_pos, walk_v))
    ring_corner = walk_c[order]
    n_vf = n_corners_at.astype(np.int64)
    ring_offsets = np.concatenate([[0], np.cumsum(n_vf)]).astype(np.int64)

    # Incident edges: edge k leads face k; a boundary vertex adds the edge
    # arriving at its last face.
    last_corner = ring_corner[ring_offsets[1:] - 1]
    is_boundary = ring_next[last_corner] < 0
    n_ve = n_vf + is_boundary
    edge_ring_offsets = np.concatenate([[0], np.cumsum(n_ve)]).astype(np.int64)
    ring_vert = np.repeat(np.arange(nv), n_vf)
    ring_pos = np.arange(len(ring_corner)) - ring_offsets[ring_vert]
    ring_edge = np.empty(int(edge_ring_offsets[-1]), np.int64)
    ring_opp = np.empty_like(ring_edge)
    slot = edge_ring_offsets[ring_vert] + ring_pos
    ring_edge[slot] = corner_edge[ring_corner]
    ring_opp[slot] = cv[cnext[ring_corner]]
    bverts = np.flatnonzero(is_boundary)
    bslot = edge_ring_offsets[bverts + 1] - 1
    ring_edge[bslot] = corner_edge[cprev[last_corner[bverts]]]
    ring_opp[bslot] = cv[cprev[last_corner[bverts]]]

    es = np.zeros(ne, np.float32) if edge_sharpness is None else np.asarray(edge_sharpness, np.float32)
    vs = np.zeros(nv, np.float32) if vertex_sharpness is None else np.asarray(vertex_sharpness, np.float32)
    return MeshLevel(
        n_vertices=nv,
        face_offsets=offsets,
        face_sizes=face_sizes,
        corner_vertex=cv,
        corner_face=cface,
        corner_next=cnext,
        corner_prev=cprev,
        corner_local=clocal,
        corner_edge=corner_edge,
        edge_vertices=edge_vertices,
        edge_corners=edge_corners,
        ring_offsets=ring_offsets,
        ring_corner=ring_corner,
        edge_ring_offsets=edge_ring_offsets,
        ring_edge=ring_edge,
        ring_opposite=ring_opp,
        n_vertex_faces=n_vf,
        n_vertex_edges=n_ve,
        edge_sharpness=es,
        vertex_sharpness=vs,
    )


def _build_base_level(cage: Cage) -> MeshLevel:
    """Level 0 of ``cage``: topology, creases, corners and boundary sharpening."""
    level = build_level(cage.n_vertices, cage.face_sizes, cage.face_indices)
    nv, ne = level.n_vertices, level.n_edges
    ev = level.edge_vertices
    es = np.zeros(ne, np.float32)
    if len(cage.crease_edges):
        ce = cage.crease_edges
        if ((ce < 0) | (ce >= nv)).any():
            i = int(np.flatnonzero(((ce < 0) | (ce >= nv)).any(axis=1))[0])
            msg = f"crease {i} names vertex pair {ce[i].tolist()}, out of range for {nv} vertices"
            raise InputError(msg)
        ekey = np.minimum(ev[:, 0], ev[:, 1]) * nv + np.maximum(ev[:, 0], ev[:, 1])
        ckey = np.minimum(ce[:, 0], ce[:, 1]) * nv + np.maximum(ce[:, 0], ce[:, 1])
        sorter = np.argsort(ekey)
        pos = np.searchsorted(ekey[sorter], ckey).clip(0, ne - 1)
        found = ekey[sorter][pos] == ckey
        if not found.all():
            i = int(np.flatnonzero(~found)[0])
            msg = f"crease {i} names edge ({ce[i, 0]}, {ce[i, 1]}), which is not an edge of any cage face"
            raise InputError(msg)
        # A repeated crease keeps its largest sharpness.
        np.maximum.at(es, sorter[pos], cage.crease_sharpness)
    vs = np.zeros(nv, np.float32)
    if len(cage.corners):
        np.maximum.at(vs, cage.corners, cage.corner_sharpness)
    # Boundary edges are always infinitely sharp (Crease::SharpenBoundaryEdge).
    es[level.edge_corners[:, 1] < 0] = SHARPNESS_INFINITE
    if cage.boundary == "edge-and-corner":
        # A vertex of a single face on the boundary is a sharp corner.
        corner = (level.n_vertex_faces == 1) & (level.n_vertex_edges == 2)
        vs[corner] = SHARPNESS_INFINITE
    es = np.minimum(es, SHARPNESS_INFINITE).astype(np.float32)
    vs = np.minimum(vs, SHARPNESS_INFINITE).astype(np.float32)
    level.edge_sharpness = es
    level.vertex_sharpness = vs
    return level
