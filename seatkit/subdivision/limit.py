"""Catmull-Clark limit positions and tangents (the masks; the limit surface: catmull_clark.limit_surface).

The limit masks are those of ``Sdc::Scheme<CATMARK>::ComputeVertexLimitMask``
as applied by ``Far::PrimvarRefiner::Limit`` at the last refinement level,
selected by each vertex's rule at that level:

* Smooth and Dart: the interior limit mask (valence 4: 4/9, 1/9 per edge
  neighbour, 1/36 per opposite face corner; valence n: 1/(n(n+5)) per face
  corner, four times that per edge neighbour) and the tangents of Halstead
  et al. (cosine weights; valence 4 is the bicubic B-spline case);
* Crease: 2/3 and 1/6 along the two sharp edges; the tangent along the
  crease, and the cross tangent of Biermann et al. over the faces between
  the two sharp edges (counter-clockwise from the first);
* Corner: the point itself; tangents along its first two edges.

The first tangent points along the vertex's first edge (OpenSubdiv's
order), and ``cross(first, second)`` is the normal on the side from which
the faces are counter-clockwise.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from seatkit.subdivision.topology import RULE_CORNER, RULE_CREASE, MeshLevel

__all__ = ["limit_masks"]


def limit_masks(level: MeshLevel) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """Limit position and tangent masks of every vertex of ``level``.

    Parameters
    ----------
    level : MeshLevel
        The last refinement level (its faces are quads unless it is level 0).

    Returns
    -------
    position, tangent1, tangent2 : (p, p) scipy.sparse.csr_matrix
        Applied to the points of ``level``.
    rules : (p,) int64
        The rule each vertex's masks were chosen by.
    """
    nv = level.n_vertices
    rules = level.rules()
    ends = level.crease_ends()
    n_faces = level.n_vertex_faces
    verts = np.arange(nv)

    smooth = (rules != RULE_CREASE) & (rules != RULE_CORNER)
    # A smooth vertex of valence 2 takes the corner masks.
    corner = (rules == RULE_CORNER) | (smooth & (n_faces == 2))
    smooth &= ~corner
    crease = rules == RULE_CREASE

    e_vert = level.edge_ring_vertex
    e_pos = level.edge_ring_position
    e_opp = level.ring_opposite
    f_vert = level.ring_vertex
    f_pos = level.ring_position
    f_opp = level.face_opposite(level.ring_corner)

    pos_r, pos_c, pos_w = [], [], []
    t1_r, t1_c, t1_w = [], [], []
    t2_r, t2_c, t2_w = [], [], []

    def add(lst, rows, cols, vals):
        lst[0].append(rows)
        lst[1].append(cols)
        lst[2].append(np.broadcast_to(np.asarray(vals, dtype=np.float64), rows.shape))

    POS = (pos_r, pos_c, pos_w)
    T1 = (t1_r, t1_c, t1_w)
    T2 = (t2_r, t2_c, t2_w)

    # ---- corners: the point; tangents along edges 0 and 1
    cv_ = verts[corner]
    add(POS, cv_, cv_, 1.0)
    add(T1, cv_, cv_, -1.0)
    add(T2, cv_, cv_, -1.0)
    sel = corner[e_vert] & (e_pos == 0)
    add(T1, e_vert[sel], e_opp[sel], 1.0)
    sel = corner[e_vert] & (e_pos == 1)
    add(T2, e_vert[sel], e_opp[sel], 1.0)

    # ---- smooth interior vertices
    n = n_faces.astype(np.float64)
    sv = verts[smooth]
    reg = smooth & (n_faces == 4)
    fw = np.where(reg, 1.0 / 36.0, 1.0 / (n * (n + 5.0)))
    ew = np.where(reg, 1.0 / 9.0, 4.0 * fw)
    vw = np.where(reg, 4.0 / 9.0, 1.0 - n * (ew + fw))
    add(POS, sv, sv, vw[sv])
    sel = smooth[e_vert]
    add(POS, e_vert[sel], e_opp[sel], ew[e_vert[sel]])
    sel = smooth[f_vert]
    add(POS, f_vert[sel], f_opp[sel], fw[f_vert[sel]])
    # Tangents: tan1 edge i: 4 cos(i theta); face i: (cos(i theta) + cos((i+1) theta)) / (4 lambda - 1);
    # tan2 is tan1 rotated by one position (valence 4: the B-spline weights).
    theta = 2.0 * np.pi / np.where(n > 0, n, 1.0)
    cos_t = np.cos(theta)
    lam = 5.0 / 16.0 + (1.0 / 16.0) * (cos_t + np.cos(theta * 0.5) * np.sqrt(2.0 * (9.0 + cos_t)))
    with np.errstate(divide="ignore"):
        face_scale = 1.0 / (4.0 * lam - 1.0)  # used for smooth vertices only
    # (the cosines only where the valence is not 4: after a refinement or
    # two almost every vertex has the B-spline weights)
    sel = smooth[e_vert]
    ev_s, ep_s, eo_s = e_vert[sel], e_pos[sel], e_opp[sel]
    is4 = n_faces[ev_s] == 4
    w1 = np.array([4.0, 0.0, -4.0, 0.0])[ep_s % 4]
    w2 = np.array([0.0, 4.0, 0.0, -4.0])[ep_s % 4]
    odd = np.flatnonzero(~is4)
    if odd.size:
        th, p = theta[ev_s[odd]], ep_s[odd]
        w1[odd] = 4.0 * np.cos(p * th)
        w2[odd] = 4.0 * np.cos((p - 1) * th)
    add(T1, ev_s, eo_s, w1)
    add(T2, ev_s, eo_s, w2)
    sel = smooth[f_vert]
    fv_s, fp_s, fo_s = f_vert[sel], f_pos[sel], f_opp[sel]
    is4 = n_faces[fv_s] == 4
    w1 = np.array([1.0, -1.0, -1.0, 1.0])[fp_s % 4]
    w2 = np.array([1.0, 1.0, -1.0, -1.0])[fp_s % 4]
    odd = np.flatnonzero(~is4)
    if odd.size:
        th, p, fs = theta[fv_s[odd]], fp_s[odd], face_scale[fv_s[odd]]
        w1[odd] = fs * (np.cos(p * th) + np.cos((p + 1) * th))
        w2[odd] = fs * (np.cos((p - 1) * th) + np.cos(p * th))
    add(T1, fv_s, fo_s, w1)
    add(T2, fv_s, fo_s, w2)

    # ---- creases
    kv = verts[crease]
    add(POS, kv, kv, 2.0 / 3.0)
    c0 = ends[:, 0]
    c1 = ends[:, 1]
    sel = crease[e_vert]
    ev_c, ep_c, eo_c = e_vert[sel], e_pos[sel], e_opp[sel]
    at0 = ep_c == c0[ev_c]
    at1 = ep_c == c1[ev_c]
    add(POS, ev_c[at0 | at1], eo_c[at0 | at1], 1.0 / 6.0)
    add(T1, ev_c[at0], eo_c[at0], 0.5)
    add(T1, ev_c[at1], eo_c[at1], -0.5)
    # Cross tangent: k = number of face spans between the two sharp edges.
    k_span = (c1 - c0).astype(np.float64)
    one = crease & (k_span == 1)  # a single face: average of the sharp edges
    two = crease & (k_span == 2)  # regular: uniform B-spline cross tangent
    many = crease & (k_span > 2)  # Biermann et al.
    add(T2, verts[one], verts[one], -6.0)
    sel1 = one[ev_c] & (at0 | at1)
    add(T2, ev_c[sel1], eo_c[sel1], 3.0)
    add(T2, verts[two], verts[two], -4.0 / 6.0)
    sel2 = two[ev_c]
    inner = sel2 & (ep_c == c0[ev_c] + 1)
    add(T2, ev_c[sel2 & (at0 | at1)], eo_c[sel2 & (at0 | at1)], -1.0 / 6.0)
    add(T2, ev_c[inner], eo_c[inner], 4.0 / 6.0)
    fsel = two[f_vert] & (f_pos >= c0[f_vert]) & (f_pos < c1[f_vert])
    add(T2, f_vert[fsel], f_opp[fsel], 1.0 / 6.0)
    if many.any():
        kk = np.where(many, k_span, 3.0)
        th = np.pi / kk
        cos_t, sin_t = np.cos(th), np.sin(th)
        denom = 1.0 / (kk * (3.0 + cos_t))
        R = (cos_t + 1.0) / sin_t
        add(T2, verts[many], verts[many], (4.0 * R * (cos_t - 1.0) * denom)[many])
        selm = many[ev_c]
        ends_m = selm & (at0 | at1)
        vv = ev_c[ends_m]
        add(T2, vv, eo_c[ends_m], (-R * (1.0 + 2.0 * cos_t) * denom)[vv])
        mid = selm & (ep_c > c0[ev_c]) & (ep_c < c1[ev_c])
        vv = ev_c[mid]
        i = (ep_c[mid] - c0[vv]).astype(np.float64)
        add(T2, vv, eo_c[mid], 4.0 * np.sin(i * th[vv]) * denom[vv])
        fsel = many[f_vert] & (f_pos >= c0[f_vert]) & (f_pos < c1[f_vert])
        vv = f_vert[fsel]
        i = (f_pos[fsel] - c0[vv]).astype(np.float64)
        add(T2, vv, f_opp[fsel], (np.sin(i * th[vv]) + np.sin((i + 1.0) * th[vv])) * denom[vv])

    def assemble(lst):
        rows = np.concatenate(lst[0])
        cols = np.concatenate(lst[1])
        vals = np.concatenate(lst[2])
        keep = vals != 0
        return sp.coo_matrix((vals[keep], (rows[keep], cols[keep])), shape=(nv, nv)).tocsr()

    return assemble(POS), assemble(T1), assemble(T2), rules
