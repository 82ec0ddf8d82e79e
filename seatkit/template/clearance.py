"""Lift a fitted cage off the bodies by one small linear programme.

Each face's plane is pushed to touch its own segment, but the face itself
spans more than its segment (up to the row and column lines) and can cut
into a neighbouring one (the lumbar face into the buttocks, the foot face
into the ankle). Pushing faces one by one moves shared corners in
conflicting directions; instead every movable cage vertex ``k`` gets one
unknown ``t_k >= 0``, a distance along its own direction ``-m_k`` (``m_k``
is the vertex normal, pointing at the body), and one linear programme
(:func:`scipy.optimize.linprog`, HiGHS) finds the smallest total move that
puts every body vertex above every face it lies over at least ``target``
above the face (negative: an allowed sink into the soft skin).

Faces are the four triangles around each quad's centre, as in
:mod:`seatkit.template.checks`. A body vertex ``b`` over triangle ``T``
(its projection along the triangle normal ``n_T`` falls inside ``T``, with
barycentric weights giving each quad corner a share ``phi_k``) at height
``s = (b - a_T) . n_T`` in ``(-depth, target)`` whose skin faces the
triangle (body vertex normal . n_T < ``facing``) gives the row, provided
some body vertex lies over the triangle on its normal's side (else the
triangle faces away from the body, a border wall folded over the feet)

    sum_k phi_k (m_k . n_T) t_k >= target - s.

Heights deeper than ``depth`` belong to body parts on the far side of the
face (a calf below the seat's front edge) and are left to the final check.
The constraint is linear in the moves for fixed barycentric weights; a few
rounds re-linearise it at the moved cage.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog
from scipy.spatial import cKDTree

from seatkit.geometry.normals import quad_vertex_normals
from seatkit.template.checks import _sample_triangles, _triangle_spheres, body_tree, body_vertex_normals, quad_triangles

__all__ = ["ClearanceResult", "lift_off_bodies"]

_FLOOR_BAND = 0.02  # m: vertices this low (the ground is y = 0) may also slide along the floor
_SPACING = 0.05  # m: samples of the cage used to find the triangles over a body vertex
_NEAREST = 6  # nearest samples whose triangles are tested for each body vertex



@dataclass(frozen=True)
class ClearanceResult:
    """What :func:`lift_off_bodies` did.

    Attributes
    ----------
    vertices : (v, 3) float64
        The moved cage vertices, m.
    moves : (v,) float64
        Distance each vertex moved (raised to the floor, then away from the bodies), m.
    rows : int
        Constraints of the last round.
    rounds : int
        Rounds run.
    feasible : bool
        Whether every round's programme was feasible within ``max_move``.
    worst : float
        Deepest remaining sink below ``target`` over the constrained body vertices, m (0 if none).
    """

    vertices: np.ndarray
    moves: np.ndarray
    rows: int
    rounds: int
    feasible: bool
    worst: float


def _within_reach(points: np.ndarray, samples: np.ndarray, reach: float, low: np.ndarray | None = None, high: np.ndarray | None = None) -> np.ndarray:
    """(k,) bool: a superset of the points within ``reach`` of some sample, from a grid of cells at least a quarter of ``reach`` wide.

    A point within ``reach`` of a sample is, on every axis, at most four
    cells from the sample's cell (a cell of margin for round-off), so the
    points outside the samples' cells grown by four cells are farther than
    ``reach`` from every sample: a k-d tree query need not be asked about
    them (the far points of the body are most of its cost). Cells are
    wider when the samples span more than 100 quarter reaches (at most
    about 110 cells a side). ``low`` and ``high`` are the samples' least
    and greatest coordinates when the caller has them.
    """
    low = samples.min(0) if low is None else low
    high = samples.max(0) if high is None else high
    h = max(reach / 4.0, float((high - low).max()) / 100.0)
    origin = low - reach
    shape = np.floor((high + reach - origin) / h).astype(np.int64) + 2
    grid = np.zeros(shape, bool)
    cell = np.floor((samples - origin) / h).astype(np.int64)
    grid[cell[:, 0], cell[:, 1], cell[:, 2]] = True
    for axis in range(3):  # grown by 4 cells along each axis in turn: a box of 9 x 9 x 9 cells around every sample's cell
        grown = grid.copy()
        for step in range(1, 5):
            head = (slice(None),) * axis + (slice(step, None),)
            tail = (slice(None),) * axis + (slice(None, -step),)
            grown[head] |= grid[tail]
            grown[tail] |= grid[head]
        grid = grown
    cell = np.floor((points - origin) / h).astype(np.int64)
    inside = ((cell >= 0) & (cell < shape)).all(1)
    out = np.zeros(len(points), bool)
    c = cell[inside]
    out[inside] = grid[c[:, 0], c[:, 1], c[:, 2]]
    return out


def _constraints(V, quads, col_vertex, col_dir, bodies, normals, *, target, depth, facing, cache):
    """Rows (A, rhs) of ``A t <= -rhs`` over the move columns, and the deepest sink.

    Column ``j`` moves vertex ``col_vertex[j]`` along ``col_dir[j]`` (the
    constraint is ``s + sum_k phi_k (d_k . n_T)``, written with ``d`` pointing
    away from the body, hence ``<= -rhs``). ``cache`` keeps each body's
    vertices near the cage from the first round (later rounds move the cage
    by centimetres).
    """
    points, tris, owner = quad_triangles(V, quads)
    nq = len(quads)
    T = points[tris]
    # first corners, edges and their dot products, once per triangle (gathered per pair below)
    T0 = np.ascontiguousarray(T[:, 0])
    E1, E2 = T[:, 1] - T0, T[:, 2] - T0
    n_t = np.cross(E1, E2)
    area2 = np.linalg.norm(n_t, axis=1)
    good = area2 > 1e-10
    n_t = n_t / np.maximum(area2, 1e-12)[:, None]
    centres, radius = _triangle_spheres(points, tris)
    D00, D01, D11 = np.einsum("ij,ij->i", E1, E1), np.einsum("ij,ij->i", E1, E2), np.einsum("ij,ij->i", E2, E2)
    rows, cols, vals, rhs = [], [], [], []
    worst = 0.0
    for person, (body, bn) in enumerate(zip(bodies, normals)):
        B = np.asarray(body.vertices, dtype=np.float64)
        # cage triangles that come within ``depth`` of the body
        d, _ = body_tree(body).query(centres, distance_upper_bound=float(radius.max()) + depth)
        close = np.flatnonzero(good & (d <= radius + depth))
        if len(close) == 0:
            continue
        samples, s_owner = _sample_triangles(points, tris[close], _SPACING)
        s_owner = close[s_owner]
        stree = cKDTree(samples)
        # body vertices near those triangles, and the triangles of their
        # nearest samples. Only samples within ``reach`` count: a triangle
        # all of whose samples lie farther is farther than ``depth`` from the
        # vertex (each point of a triangle is within _SPACING of one of its
        # samples), so it could give no row (|s| < depth over the triangle)
        reach = depth + _SPACING + 0.02
        k = min(_NEAREST, len(samples))
        if person not in cache:
            low, high = samples.min(0), samples.max(0)
            cand = np.flatnonzero(((B >= low - depth) & (B <= high + depth)).all(1))
            cand = cand[_within_reach(B[cand], samples, reach, low, high)]  # the others would not be found
            d, nearest = stree.query(B[cand], k=k, distance_upper_bound=reach)
            d, nearest = d.reshape(len(cand), k), nearest.reshape(len(cand), k)
            found = np.isfinite(d[:, 0])
            cache[person] = cand[found]
            nearest = nearest[found]
        elif len(cache[person]):
            nearest = stree.query(B[cache[person]], k=k, distance_upper_bound=reach)[1].reshape(len(cache[person]), k)
        near = cache[person]
        if len(near) == 0:
            continue
        # (body vertex, triangle) pairs, each once, in the order of
        # bi * len(tris) + ti (near is ascending): the rows' order
        # a missing neighbour (index len(samples)) owns the sentinel len(tris)
        owners = np.sort(np.append(s_owner, len(tris))[nearest], axis=1)
        fresh = np.ones(owners.shape, bool)
        fresh[:, 1:] = owners[:, 1:] != owners[:, :-1]
        fresh &= owners < len(tris)
        bi, ti = np.broadcast_to(near[:, None], owners.shape)[fresh], owners[fresh]
        keep = good[ti]
        bi, ti = bi[keep], ti[keep]
        a, n = T0[ti], n_t[ti]
        rel = B[bi] - a
        s = np.einsum("ij,ij->i", rel, n)
        sel = (s < depth) & (s > -depth)
        bi, ti, s, rel, n = bi[sel], ti[sel], s[sel], rel[sel], n[sel]
        e1, e2 = E1[ti], E2[ti]
        # barycentric coordinates of the projection
        d00, d01, d11 = D00[ti], D01[ti], D11[ti]
        d20, d21 = np.einsum("ij,ij->i", rel, e1), np.einsum("ij,ij->i", rel, e2)
        den = d00 * d11 - d01 * d01
        beta = (d11 * d20 - d01 * d21) / den
        gamma = (d00 * d21 - d01 * d20) / den
        alpha = 1.0 - beta - gamma
        inside = (alpha >= -1e-9) & (beta >= -1e-9) & (gamma >= -1e-9)
        # a triangle with no body above it (on its normal's side) faces away
        # from the body (a border wall folded over the feet): it is left to
        # the final check
        above = np.zeros(len(tris), bool)
        above[ti[inside & (s >= target)]] = True
        sinks = inside & (s < target) & above[ti]
        cand_sink = np.flatnonzero(sinks)  # the skin's turn is asked only of these
        sinks[cand_sink] = np.einsum("ij,ij->i", bn[bi[cand_sink]], n[cand_sink]) < facing
        if not sinks.any():
            continue
        ti, s, n = ti[sinks], s[sinks], n[sinks]
        alpha, beta, gamma = alpha[sinks], beta[sinks], gamma[sinks]
        worst = max(worst, float((target - s).max()))
        q = owner[ti]
        corner = (ti // nq)  # triangle i of a quad joins corners i and i+1 and the centre
        k0 = quads[q, corner]
        k1 = quads[q, (corner + 1) % 4]
        m = len(ti)
        base = sum(len(r) for r in rhs)
        # phi: alpha on k0, beta on k1, gamma / 4 on each corner
        ks = np.stack([k0, k1, quads[q, 0], quads[q, 1], quads[q, 2], quads[q, 3]], 1)
        ph = np.stack([alpha, beta] + [gamma / 4.0] * 4, 1)
        rows.append(np.repeat(np.arange(m), 6) + base)
        cols.append(ks.ravel())
        vals.append((ph[:, :, None] * n[:, None, :]).reshape(-1, 3))
        rhs.append(target - s)
    if not rhs:
        return None, None, 0.0
    rhs = np.concatenate(rhs)
    r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    # row . (phi_k n_T) per vertex and axis, times each move column's
    # direction, summed over the axes in order, kept sparse. A corner of a
    # quad (four distinct corners) takes two shares, its triangle's and the
    # centre's, summed in the order of their entries; shares of vertices
    # that do not move are dropped
    moved, column = np.unique(col_vertex, return_inverse=True)
    slot = np.full(len(V), -1)
    slot[moved] = np.arange(len(moved))
    keep = slot[c] >= 0
    width = max(len(moved), 1)
    key = r[keep] * width + slot[c[keep]]
    v = v[keep]
    order = np.argsort(key, kind="stable")
    key, v = key[order], v[order]
    first = np.ones(len(key), bool)
    first[1:] = key[1:] != key[:-1]
    shares = np.zeros((int(first.sum()), 3))
    np.add.at(shares, np.cumsum(first) - 1, v)  # each (row, vertex)'s shares, summed in the order of their entries
    key = key[first]
    # every (row, vertex) to each of the vertex's columns (a vertex on the floor has two)
    by_slot = np.argsort(column, kind="stable")
    count = np.bincount(column, minlength=len(moved))
    start = np.cumsum(count) - count
    vertex = key % width
    many = count[vertex]
    entry = np.repeat(np.arange(len(key)), many)
    to_col = by_slot[np.repeat(start[vertex], many) + np.arange(len(entry)) - np.repeat(np.cumsum(many) - many, many)]
    to_row = key[entry] // width
    value = np.zeros(len(entry))
    for axis in range(3):
        value += shares[entry, axis] * col_dir[to_col, axis]
    order = np.lexsort((to_col, to_row))
    to_row, to_col, value = to_row[order], to_col[order], value[order]
    nz = value != 0.0
    A = sp.csr_matrix((value[nz], to_col[nz], np.concatenate([[0], np.cumsum(np.bincount(to_row[nz], minlength=len(rhs)))])), shape=(len(rhs), len(col_vertex)))
    return A, rhs, worst


def lift_off_bodies(
    vertices: np.ndarray,
    quads: np.ndarray,
    bodies,
    movable: np.ndarray,
    *,
    target: float,
    depth: float = 0.08,
    facing: float = -0.1,
    max_move: float = 0.15,
    rounds: int = 2,
    weights: np.ndarray | None = None,
    floor: float | None = None,
) -> ClearanceResult:
    """Move cage vertices away from the bodies so that no face sinks deeper than ``-target``.

    Parameters
    ----------
    vertices : (v, 3) float64
        Cage vertices, m.
    quads : (f, 4) int64
        Faces, counter-clockwise seen from the body (normals at the body).
    bodies : sequence of Body
    movable : (v,) bool
        Vertices that may move (the ground ring stays).
    target : float
        Required height of every covered body vertex above its face, m
        (negative: the allowed sink into the skin).
    depth : float
        Body vertices deeper than this below a face are on its far side, m.
    facing : float
        Only body vertices whose outward normal has a dot product with the
        face normal below this count (the skin turned towards the face).
    max_move : float
        Largest move of one vertex, m.
    rounds : int
        Linear programmes solved, each at the cage moved by the previous.
    weights : (v,) float64, optional
        Cost of moving each vertex by 1 m (default 1): heavier vertices
        (those carrying importance) move less.
    floor : float, optional
        No movable vertex ends below this height, m (the ground, less the
        allowed sink): vertices below it are raised first, and no move
        takes one below it.

    Returns
    -------
    ClearanceResult
    """
    V = np.array(vertices, dtype=np.float64)
    quads = np.asarray(quads, dtype=np.int64)
    start = V.copy()
    if floor is not None:
        V[movable, 1] = np.maximum(V[movable, 1], floor)
    directions = -quad_vertex_normals(V, quads)
    normals = [body_vertex_normals(b) for b in bodies]
    cost = np.ones(len(V)) if weights is None else np.asarray(weights, dtype=np.float64)
    # move columns: every movable vertex along its direction; a vertex on the
    # floor may also slide along it, away from the walls it bounds (the heel
    # line of a chair moves back under the calves when it cannot go down)
    col_vertex = np.flatnonzero(movable)
    col_dir = directions[col_vertex]
    if floor is not None:
        Q = V[quads]
        fn = np.cross(Q[:, 2] - Q[:, 0], Q[:, 3] - Q[:, 1])
        fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-12)
        wall = np.where((np.abs(fn[:, 1]) < 0.8)[:, None], fn * [1.0, 0.0, 1.0], 0.0)
        push = np.zeros_like(V)
        for i in range(4):
            np.add.at(push, quads[:, i], -wall)
        length = np.linalg.norm(push, axis=1)
        slide = np.flatnonzero(movable & (V[:, 1] <= _FLOOR_BAND) & (length > 1e-6))
        col_vertex = np.concatenate([col_vertex, slide])
        col_dir = np.vstack([col_dir, push[slide] / length[slide, None]])
    col_cost = cost[col_vertex]
    cache: dict = {}
    total = np.zeros(len(col_vertex))
    feasible = True
    rows = 0
    worst = 0.0
    done = 0
    for done in range(1, rounds + 1):
        A, rhs, worst = _constraints(V, quads, col_vertex, col_dir, bodies, normals, target=target, depth=depth, facing=facing, cache=cache)
        if A is None:
            worst = 0.0
            break
        rows = A.shape[0]
        ub = np.maximum(max_move - total, 0.0)
        if floor is not None:
            down = col_dir[:, 1] < -1e-9
            room = np.maximum(V[col_vertex, 1] - floor, 0.0) / np.where(down, -col_dir[:, 1], 1.0)
            ub = np.where(down, np.minimum(ub, room), ub)
        nc = len(col_vertex)
        res = linprog(col_cost, A_ub=A, b_ub=-rhs, bounds=np.stack([np.zeros(nc), ub], 1), method="highs")
        if res.status != 0:
            # infeasible within max_move: satisfy what can be, by a penalised version
            feasible = False
            m = A.shape[0]
            c = np.concatenate([col_cost, np.full(m, 1e3)])
            A2 = sp.hstack([A, -sp.identity(m, format="csr")], format="csr")
            bounds = np.vstack([np.stack([np.zeros(nc), ub], 1), np.stack([np.zeros(m), np.full(m, np.inf)], 1)])
            res = linprog(c, A_ub=A2, b_ub=-rhs, bounds=bounds, method="highs")
            if res.status != 0:
                break
        t = res.x[:nc]
        np.add.at(V, col_vertex, t[:, None] * col_dir)
        total += t
        if t.max() < 1e-3:
            break
    moves = np.linalg.norm(V - start, axis=1)
    return ClearanceResult(V, moves, rows, done, feasible, worst)
