"""Catmull-Clark refinement as sparse matrices, with OpenSubdiv's Sdc rules.

One uniform refinement step maps the points of a level to the points of the
next: ``child = S @ parent`` with ``S`` a scipy.sparse CSR matrix. The rows
follow OpenSubdiv's child ordering (``Far::TopologyRefiner::RefineUniform``
with default options): first one child per parent vertex, then one per
face, then one per edge. The weights are those of ``Sdc::Scheme<CATMARK>``:

* face points: the average of the face's vertices;
* edge points: the smooth mask (1/4 each end, 1/4 each adjacent face point),
  the crease mask (1/2, 1/2) when the edge's sharpness is above 1, and for
  0 < s <= 1 the blend ``s * crease + (1 - s) * smooth``;
* vertex points: by the vertex's rule (Smooth or Dart: the smooth mask;
  Crease: 3/4 and 1/8 along the two sharp edges; Corner: the point itself),
  and where the rule of the child differs from the parent's (a semi-sharp
  feature decays), ``w * parent_mask + (1 - w) * child_mask`` with the
  fractional weight ``w`` of ``Sdc::Crease::ComputeFractionalWeightAtVertex``
  (Uniform creasing: the mean of the decaying sharpness values, at most 1).

Sharpness drops by one per level (``Crease::decrementSharpness``),
computed in float32 as OpenSubdiv does.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from seatkit.cache import LRUCache
from seatkit.errors import InputError
from seatkit.model import Surface
from seatkit.subdivision.limit import limit_masks
from seatkit.subdivision.topology import (
    RULE_CORNER,
    RULE_CREASE,
    Cage,
    MeshLevel,
    build_level,
    decrement_sharpness,
)

__all__ = ["SubdivisionOperators", "build_operators", "limit_surface", "refine_level"]


def _fractional_weight(level: MeshLevel, child_vs: np.ndarray, child_es: np.ndarray) -> np.ndarray:
    """(v,) float32 fractional weight of each vertex (Uniform creasing).

    Sum, in OpenSubdiv's order and in float32, of the parent vertex
    sharpness if it decays to zero and of every incident edge sharpness in
    (0, 1]; divided by how many there are; clamped to 1.
    """
    vs = level.vertex_sharpness
    total = np.where((vs > 0) & (child_vs <= 0), vs, np.float32(0)).astype(np.float32)
    count = ((vs > 0) & (child_vs <= 0)).astype(np.int64)
    ring_s = level.edge_sharpness[level.ring_edge]
    decays = (ring_s > 0) & (ring_s <= np.float32(1.0))
    vert = level.edge_ring_vertex
    np.add.at(total, vert[decays], ring_s[decays])  # float32, in ring order
    count += np.bincount(vert[decays], minlength=level.n_vertices)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (total / count.astype(np.float32)).astype(np.float32)
    w[count == 0] = 0
    return np.minimum(w, np.float32(1.0))


def _vertex_mask_coefficients(level: MeshLevel, rule, ends, which):
    """Coefficients of one mask type for a subset of vertices.

    Returns the weight of the vertex itself (v,), of each edge-ring entry
    (s,) and of each face-ring entry (r,) for mask ``which`` (per vertex: 0
    smooth, 1 crease, 2 corner). The smooth face weights apply to face points.
    """
    nv = level.n_vertices
    n = level.n_vertex_faces.astype(np.float64)
    smooth = which == 0
    crease = which == 1
    corner = which == 2
    w_v = np.zeros(nv)
    w_v[smooth] = (n[smooth] - 2.0) / n[smooth]
    w_v[crease] = 0.75
    w_v[corner] = 1.0
    ev = level.edge_ring_vertex
    epos = level.edge_ring_position
    nn = level.n_vertex_faces[ev]
    w_e = np.where(smooth[ev], 1.0 / (nn * nn).astype(np.float64), 0.0)
    is_end = (epos == ends[ev, 0]) | (epos == ends[ev, 1])
    w_e = np.where(crease[ev] & is_end, 0.125, w_e)
    fv = level.ring_vertex
    nf = level.n_vertex_faces[fv]
    w_f = np.where(smooth[fv], 1.0 / (nf * nf).astype(np.float64), 0.0)
    return w_v, w_e, w_f


def refine_level(level: MeshLevel) -> tuple[sp.csr_matrix, MeshLevel, np.ndarray]:
    """One uniform Catmull-Clark step.

    Parameters
    ----------
    level : MeshLevel
        The parent level, with its sharpness.

    Returns
    -------
    S : (n_child, n_parent) scipy.sparse.csr_matrix
        Child points = ``S @ parent points``.
    child : MeshLevel
        The refined level (all quads) with its decayed sharpness.
    child_face_parent : (q,) int64
        Parent face of each child face.
    """
    nv, nf, ne, nc = level.n_vertices, level.n_faces, level.n_edges, level.n_corners
    cv, cf = level.corner_vertex, level.corner_face
    sizes = level.face_sizes
    # Child vertex numbering: vertex children, then face children, then edge children.
    v_child = np.arange(nv)
    f_child = nv + np.arange(nf)
    e_child = nv + nf + np.arange(ne)
    n_child = nv + nf + ne

    # ---- child faces: one per parent corner (OpenSubdiv's rotation for quads)
    rot = np.where(sizes[cf] == 4, level.corner_local, 0)
    child_faces = np.empty((nc, 4), np.int64)
    rows = np.arange(nc)
    child_faces[rows, rot % 4] = v_child[cv]
    child_faces[rows, (rot + 1) % 4] = e_child[level.corner_edge]
    child_faces[rows, (rot + 2) % 4] = f_child[cf]
    child_faces[rows, (rot + 3) % 4] = e_child[level.corner_edge[level.corner_prev]]

    # ---- child edges: face-interior ones (one per corner), then two halves per edge
    ev = level.edge_vertices
    child_ev = np.empty((nc + 2 * ne, 2), np.int64)
    child_ev[:nc, 0] = f_child[cf]
    child_ev[:nc, 1] = e_child[level.corner_edge]
    child_ev[nc::2, 0] = e_child
    child_ev[nc::2, 1] = v_child[ev[:, 0]]
    child_ev[nc + 1 :: 2, 0] = e_child
    child_ev[nc + 1 :: 2, 1] = v_child[ev[:, 1]]

    # Edge leaving each child corner (child face c walks vch, e_next, fch, e_prev).
    half_next = nc + 2 * level.corner_edge + (ev[level.corner_edge, 0] != cv)
    e_prev = level.corner_edge[level.corner_prev]
    half_prev = nc + 2 * e_prev + (ev[e_prev, 0] != cv)
    child_corner_edge = np.empty((nc, 4), np.int64)
    child_corner_edge[rows, rot % 4] = half_next
    child_corner_edge[rows, (rot + 1) % 4] = rows
    child_corner_edge[rows, (rot + 2) % 4] = level.corner_prev
    child_corner_edge[rows, (rot + 3) % 4] = half_prev

    # First incident face of each child edge, as the child corner whose
    # outgoing edge it is (OpenSubdiv's edge-face 0).
    child_edge_first = np.empty(nc + 2 * ne, np.int64)
    child_edge_first[:nc] = 4 * rows + (rot + 1) % 4
    c0 = level.edge_corners[:, 0]
    for k in (0, 1):
        at_second = cv[c0] != ev[:, k]  # the half's end is the next corner of the first face
        cface = np.where(at_second, level.corner_next[c0], c0)
        crot = rot[cface]
        child_edge_first[nc + k :: 2] = 4 * cface + np.where(at_second, (crot + 3) % 4, crot)

    # First face of each child vertex's ring.
    child_vfirst = np.empty(n_child, np.int64)
    vfc = level.ring_corner[level.ring_offsets[:-1]]
    child_vfirst[:nv] = 4 * vfc + rot[vfc]
    fc0 = level.face_offsets[:-1]
    child_vfirst[nv : nv + nf] = 4 * fc0 + (rot[fc0] + 2) % 4
    nc0 = level.corner_next[c0]
    child_vfirst[nv + nf :] = 4 * nc0 + (rot[nc0] + 3) % 4

    # ---- decayed sharpness
    child_es = np.zeros(nc + 2 * ne, np.float32)
    dec_e = decrement_sharpness(level.edge_sharpness)
    child_es[nc::2] = dec_e
    child_es[nc + 1 :: 2] = dec_e
    child_vs = np.zeros(n_child, np.float32)
    child_vs[:nv] = decrement_sharpness(level.vertex_sharpness)

    # ---- weights over the extended parent [points (nv); face points (nf)]
    rows_l, cols_l, vals_l = [], [], []

    # Face points.
    rows_l.append(f_child)
    cols_l.append(nv + np.arange(nf))
    vals_l.append(np.ones(nf))

    # Edge points: blend of crease and smooth masks by the edge sharpness.
    s = level.edge_sharpness.astype(np.float64)
    w = np.where(s <= 0, 0.0, np.where(s > 1.0, 1.0, s))
    w_vert = w * 0.5 + (1.0 - w) * 0.25
    w_face = 0.25 * (1.0 - w)
    rows_l += [e_child, e_child]
    cols_l += [ev[:, 0], ev[:, 1]]
    vals_l += [w_vert, w_vert]
    has2 = level.edge_corners[:, 1] >= 0
    for k in (0, 1):
        e_idx = np.flatnonzero(has2) if k == 1 else np.arange(ne)
        rows_l.append(e_child[e_idx])
        cols_l.append(nv + cf[level.edge_corners[e_idx, k]])
        vals_l.append(w_face[e_idx])

    # Vertex points: parent rule mask, blended with the child rule mask.
    p_rule = level.rules()
    dec_ring_vs = child_vs[:nv]
    c_rule = level.rules(dec_ring_vs, dec_e)
    p_which = np.where(p_rule == RULE_CORNER, 2, np.where(p_rule == RULE_CREASE, 1, 0))
    c_which = np.where(c_rule == RULE_CORNER, 2, np.where(c_rule == RULE_CREASE, 1, 0))
    transition = (p_which != 0) & (c_rule != p_rule)
    alpha = np.ones(nv)
    if transition.any():
        frac = _fractional_weight(level, dec_ring_vs, dec_e).astype(np.float64)
        alpha[transition] = frac[transition]
    pv, pe, pf = _vertex_mask_coefficients(level, p_rule, level.crease_ends(), p_which)
    cvw, ce_, cfw = _vertex_mask_coefficients(level, c_rule, level.crease_ends(dec_e), c_which)
    beta = 1.0 - alpha
    wv = alpha * pv + beta * cvw
    we = alpha[level.edge_ring_vertex] * pe + beta[level.edge_ring_vertex] * ce_
    wf = alpha[level.ring_vertex] * pf + beta[level.ring_vertex] * cfw
    rows_l += [v_child, level.edge_ring_vertex, level.ring_vertex]
    cols_l += [np.arange(nv), level.ring_opposite, nv + cf[level.ring_corner]]
    vals_l += [wv, we, wf]

    rows_all = np.concatenate(rows_l)
    cols_all = np.concatenate(cols_l)
    vals_all = np.concatenate(vals_l)
    keep = vals_all != 0
    ext = sp.csr_matrix((vals_all[keep], (rows_all[keep], cols_all[keep])), shape=(n_child, nv + nf))
    face_avg = sp.csr_matrix(
        (1.0 / sizes[cf].astype(np.float64), (cf, cv)),
        shape=(nf, nv),
    )
    S = (ext[:, :nv] + ext[:, nv:] @ face_avg).tocsr()
    S.sum_duplicates()
    S.sort_indices()

    child = build_level(
        n_child,
        np.full(nc, 4, np.int64),
        child_faces.reshape(-1),
        edge_vertices=child_ev,
        corner_edge=child_corner_edge.reshape(-1),
        edge_first_corner=child_edge_first,
        vertex_first_corner=child_vfirst,
        edge_sharpness=child_es,
        vertex_sharpness=child_vs,
    )
    return S, child, cf.copy()


@dataclass(frozen=True)
class SubdivisionOperators:
    """Sparse Catmull-Clark operators of one cage topology at one level.

    All matrices act on the (v, 3) control points of the cage.

    Attributes
    ----------
    level : int
        Refinement level.
    refine : (p, v) scipy.sparse.csr_matrix
        Refined points (OpenSubdiv's vertex order at ``level``).
    limit : (p, v) scipy.sparse.csr_matrix
        Limit positions of the refined vertices (``Far::PrimvarRefiner::Limit``).
    du, dv : (p, v) scipy.sparse.csr_matrix
        Limit tangents of the refined vertices (OpenSubdiv's first and second
        tangent); ``cross(du @ P, dv @ P)`` is the surface normal, pointing
        to the side from which the faces are counter-clockwise. Made on
        first use (from ``tangent_masks`` and ``refine``): a level whose
        normals are never asked for (the surface fit's level-4 check of
        positions) does without them.
    tangent_masks : tuple of two (p, p) scipy.sparse.csr_matrix
        The limit tangent masks at ``level`` (``du = tangent_masks[0] @ refine``).
    faces : (q, 4) int64
        Quads of the refined mesh (OpenSubdiv's face order and winding).
    face_origin : (q,) int64
        Cage face each refined quad lies in.
    steps : tuple of scipy.sparse.csr_matrix
        The per-level matrices whose product is ``refine``.
    rules : (p,) int64
        Sdc rule of each refined vertex at ``level`` (1 smooth, 2 dart,
        4 crease, 8 corner); it selects the limit mask.
    """

    level: int
    refine: sp.csr_matrix
    limit: sp.csr_matrix
    tangent_masks: tuple = field(repr=False)
    faces: np.ndarray
    face_origin: np.ndarray
    steps: tuple = field(repr=False)
    rules: np.ndarray = field(repr=False)

    @cached_property
    def du(self) -> sp.csr_matrix:
        """(p, v): the first limit tangent of each refined vertex."""
        return (self.tangent_masks[0] @ self.refine).tocsr()

    @cached_property
    def dv(self) -> sp.csr_matrix:
        """(p, v): the second limit tangent of each refined vertex."""
        return (self.tangent_masks[1] @ self.refine).tocsr()

    @property
    def n_points(self) -> int:
        """Number of refined vertices."""
        return self.refine.shape[0]

    def limit_points(self, points) -> np.ndarray:
        """(p, 3) float64 limit positions for control points (v, 3)."""
        return self.limit @ np.asarray(points, dtype=np.float64)

    def limit_normals(self, points, limit_points=None) -> np.ndarray:
        """(p, 3) float64 unit limit normals for control points (v, 3).

        Where the two tangents are parallel (degenerate geometry) the normal
        is the area-weighted mean of the normals of the limit quads around
        the vertex. ``limit_points``, when given, are :meth:`limit_points`
        of the same control points (not computed again).
        """
        P = np.asarray(points, dtype=np.float64)
        X = self.limit @ P if limit_points is None else limit_points
        n = np.cross(self.du @ P, self.dv @ P)
        # np.linalg.norm(n, axis=1) to the bit, several times faster (no reduction along the short axis)
        length = np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1] + n[:, 2] * n[:, 2])
        scale = np.maximum(np.abs(X).max(), 1.0)
        bad = length <= 1e-12 * scale * scale
        if bad.any():
            q = self.faces
            fn = np.cross(X[q[:, 2]] - X[q[:, 0]], X[q[:, 3]] - X[q[:, 1]])
            acc = np.zeros_like(X)
            for k in range(4):
                np.add.at(acc, q[:, k], fn)
            n[bad] = acc[bad]
            length = np.linalg.norm(n, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            out = n / length[:, None]
        out[~np.isfinite(out)] = 0.0
        return out


#: build_operators' cache: (topology key, level) -> SubdivisionOperators
_OPS_CACHE = LRUCache(maxsize=64)
#: The topology of the levels refined last, from which a finer level's operators go on:
#: (topology key, level) -> (MeshLevel, cage face of each quad). A few: a MeshLevel is
#: about 60% the size of its level's operators.
_LEVEL_CACHE = LRUCache(maxsize=4)


#: Most quads a refinement may make: the operators take about 2.3 kB per
#: refined quad (a 10,000-quad cage at level 3 makes 640,000 quads and peaks
#: at 1.5 GB), so this caps one refinement near 2.5 GB.
MAX_REFINED_FACES = 1_000_000


def refined_face_count(cage: Cage, level: int) -> int:
    """Quads of ``cage`` refined ``level`` times: each n-gon gives n quads, then every quad 4."""
    if level <= 0:
        return int(cage.n_faces)
    return int(cage.face_sizes.sum()) * 4 ** (int(level) - 1)


def build_operators(cage: Cage, level: int = 3) -> SubdivisionOperators:
    """Catmull-Clark refinement and limit operators of ``cage`` at ``level``.

    Topology only: the result depends on the faces, creases, corners and
    boundary mode, not on the control points, and is cached (the same
    topology gives the same object).

    Parameters
    ----------
    cage : Cage
    level : int
        Uniform refinement level, >= 1 (0 is allowed for all-quad cages).

    Returns
    -------
    SubdivisionOperators
    """
    if isinstance(level, bool) or int(level) != level or level < 0:
        msg = f"subdivision level must be a non-negative integer, got {level!r}"
        raise InputError(msg)
    level = int(level)
    quads = refined_face_count(cage, level)
    if quads > MAX_REFINED_FACES:
        msg = (
            f"a cage of {cage.n_faces:,} faces refined {level} times makes {quads:,} quads; seatkit refines to at "
            f"most {MAX_REFINED_FACES:,} (about 2.5 GB): use fewer levels or a coarser cage"
        )
        raise InputError(msg)
    if level == 0 and not np.all(cage.face_sizes == 4):
        msg = "subdivision level 0 needs an all-quad cage; use level >= 1"
        raise InputError(msg)
    return _OPS_CACHE.get((cage.topology_key, level), lambda: _make_operators(cage, level))


def _make_operators(cage: Cage, level: int) -> SubdivisionOperators:
    """The operators of ``cage`` at ``level``, refined on from the finest coarser level of this topology still cached.

    Level ``k + 1`` is level ``k`` refined once, and ``refine`` is the same
    product of the steps whichever level it goes on from: the surface fit's
    level 4 (its final check) goes on from its level 3, at a quarter less
    work than from the cage, with the same operators to the bit.
    """
    key = cage.topology_key
    current, origin, refine, steps, start = None, None, None, [], 0
    for lower in range(level - 1, 0, -1):
        known, ops = _LEVEL_CACHE.peek((key, lower)), _OPS_CACHE.peek((key, lower))
        if known is not None and ops is not None:
            (current, origin), refine, steps, start = known, ops.refine, list(ops.steps), lower
            break
    if current is None:
        current = cage.base_level()
        origin = np.arange(current.n_faces)
        refine = sp.identity(current.n_vertices, format="csr")
    for _ in range(start, level):
        S, current, parent_face = refine_level(current)
        steps.append(S)
        origin = origin[parent_face]
        refine = (S @ refine).tocsr()
    if level > 0:
        _LEVEL_CACHE.get((key, level), lambda: (current, origin))
    L, T1, T2, rules = limit_masks(current)
    return SubdivisionOperators(
        level=level,
        refine=refine,
        limit=(L @ refine).tocsr(),
        tangent_masks=(T1, T2),
        faces=current.corner_vertex.reshape(-1, 4).copy(),
        face_origin=origin,
        steps=tuple(steps),
        rules=rules,
    )


def limit_surface(control_mesh, level: int = 3, *, boundary: str = "edge-and-corner") -> Surface:
    """The tessellated Catmull-Clark limit surface of a control mesh.

    Parameters
    ----------
    control_mesh : seatkit.model.ControlMesh or Cage
        The cage (its creases and corners are used).
    level : int
        Refinement level of the tessellation.
    boundary : {"edge-and-corner", "edge-only"}
        Boundary interpolation (for a ControlMesh).

    Returns
    -------
    seatkit.model.Surface
        Limit positions and unit normals of the level-``level`` vertices and
        the quads joining them.
    """
    cage = control_mesh if isinstance(control_mesh, Cage) else Cage.from_control_mesh(control_mesh, boundary=boundary)
    ops = build_operators(cage, level)
    P = cage.vertices
    X = ops.limit_points(P)
    return Surface(
        vertices=X,
        normals=ops.limit_normals(P, X),
        faces=ops.faces.copy(),
        level=int(level),
    )
