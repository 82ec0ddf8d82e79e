"""Border rings and the ground rectangle (paper Sec. 5.2, refinement stage).

The fitted grid is extended by two rings of faces. The first ring continues
the surface outwards by ``width``: the first and last rows along their
faces, the side columns horizontally outwards (never below the ground).
Before the ring is built, the grid's side columns are made to run
monotonically from the front row to the back row (an outer back face
wrapping forward past the seat's edge would make the walls below it
overlap); the ring then envelops the grid (its back row behind every grid
vertex of its column, and so on) and its walls, which hang down to the
ground, are moved outside the bodies.

The second ring lies on the ground (y = 0) on a rectangle around
everything, axis-aligned (the body faces +Z: sides along X, front along Z).
Along each side of the rectangle the ground vertices are placed by a linear
programme (:func:`scipy.optimize.linprog`): as close as possible to below
their ring vertex, in order with at least ``min_spacing`` between them, and
such that every outer face is convex, seen from the side for wall faces and
from above for faces lying near the ground (the paper's convexity
correction).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from seatkit.template.grid import NOT_HELD, GridMesh, segment_of_vertex
from seatkit.template.planes import unit

__all__ = ["add_border", "keep_back_behind", "place_ground_side"]

_FLAT = 0.03  # m: a wall face lower than this is checked from above


def place_ground_side(profile_t, profile_h, profile_u, length, min_spacing, eps=1e-5):
    """Positions of the ground vertices along one side of the rectangle.

    Parameters
    ----------
    profile_t : (m,) float64
        Coordinate along the side of each ring-1 vertex above it, m.
    profile_h : (m,) float64
        Their height above the ground, m.
    profile_u : (m,) float64
        Their horizontal distance inside the rectangle's side, m (> 0).
    length : float
        Length of the side; the two corners are at 0 and ``length``.
    min_spacing : float
        Smallest distance between consecutive ground vertices, m.
    eps : float
        Smallest corner cross product accepted, m^2.

    Returns
    -------
    t : (m,) float64
        Ground positions along the side.
    convex : bool
        Whether the convexity constraints could be met (else only the order).
    """
    m = len(profile_t)
    P = np.concatenate([[0.0], profile_t, [length]])
    # the corners' own ring-1 points sit over the corners
    H = np.concatenate([[profile_h[0]], profile_h, [profile_h[-1]]])
    U = np.concatenate([[profile_u[0]], profile_u, [profile_u[-1]]])
    # variables x = (t_1..t_m, e_1..e_m); objective sum e (|t - P|)
    nvar = 2 * m
    c = np.concatenate([np.zeros(m), np.ones(m)])
    A, b = [], []

    def row(coef_t: dict, const: float, lower: float):
        # sum coef * t + const >= lower  ->  -sum coef t <= const - lower
        a = np.zeros(nvar)
        rhs = const - lower
        for j, v in coef_t.items():
            if 1 <= j <= m:
                a[j - 1] -= v
            else:
                rhs += v * (0.0 if j == 0 else length)
        A.append(a)
        b.append(rhs)

    for j in range(m):  # |t_j - P_j| <= e_j
        a = np.zeros(nvar)
        a[j], a[m + j] = 1.0, -1.0
        A.append(a), b.append(P[j + 1])
        a = np.zeros(nvar)
        a[j], a[m + j] = -1.0, -1.0
        A.append(a), b.append(-P[j + 1])
    for j in range(m + 1):  # t_{j+1} - t_j >= min_spacing
        row({j + 1: 1.0, j: -1.0}, 0.0, min_spacing)
    n_order = len(A)
    for j in range(1, m):  # convexity of the wall face over (t_j, t_{j+1}); corner faces excluded
        flat = min(H[j], H[j + 1]) < _FLAT
        Y = U if flat else H  # height seen from the side, or depth seen from above
        Pj, Pk = P[j], P[j + 1]
        Yj, Yk = Y[j], Y[j + 1]
        # g_j=(t_j,0) -> g_k=(t_k,0) -> p_k=(Pk,Yk) -> p_j=(Pj,Yj): counter-clockwise
        row({j + 1: Yj, j: -Yj}, 0.0, eps)  # at g_j: Y_j (t_k - t_j)
        row({j + 1: Yk, j: -Yk}, 0.0, eps)  # at g_k
        # at p_k: (Pk - t_k)(Yj - Yk) - Yk (Pj - Pk)
        row({j + 1: -(Yj - Yk)}, Pk * (Yj - Yk) - Yk * (Pj - Pk), eps)
        # at p_j: (Pj - Pk)(-Yj) - (Yj - Yk)(t_j - Pj)
        row({j: -(Yj - Yk)}, -(Pj - Pk) * Yj + (Yj - Yk) * Pj, eps)
    A, b = np.array(A), np.array(b)
    bounds = [(0.0, length)] * m + [(0.0, None)] * m
    res = linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")
    if res.status == 0:
        return res.x[:m], True
    res = linprog(c, A_ub=A[:n_order], b_ub=b[:n_order], bounds=bounds, method="highs")
    if res.status == 0:
        return res.x[:m], False
    # too many vertices for the side at this spacing: spread them evenly
    return np.linspace(0, length, m + 2)[1:-1], False


def _envelop(line: np.ndarray, lines: np.ndarray, direction: np.ndarray) -> None:
    """Move each vertex of ``line`` (m, 3) along ``direction`` until it is not behind ``lines[i]`` (m, k, 3), in place."""
    pos = line @ direction
    reach = (lines @ direction).max(1)
    line += np.outer(np.maximum(reach - pos, 0.0), direction)


def _monotone(ring: np.ndarray, *, axis: int, direction: np.ndarray, step: float) -> None:
    """Make the ring's outer lines advance along ``direction`` by ``step`` at least, in place.

    ``axis`` 0: the first and last vertex columns (the sides), walked along
    the rows; ``axis`` 1: the first and last vertex rows, walked along the
    columns. A vertex that falls behind its predecessor is moved forward
    along ``direction`` (horizontal), nothing else changes.
    """
    lines = [ring[:, 0], ring[:, -1]] if axis == 0 else [ring[0], ring[-1]]
    for line in lines:
        pos = line @ direction
        want = pos.copy()
        for i in range(1, len(want)):
            want[i] = max(want[i], want[i - 1] + step)
        line += np.outer(want - pos, direction)


def _clear_bodies(line: np.ndarray, along: np.ndarray, across: np.ndarray, points: np.ndarray, clearance: float, top=None) -> None:
    """Move ``line`` (m, 3) along ``along`` until its walls pass outside the body ``points``, in place.

    A wall hangs from each vertex of the ring down to the ground; it must
    lie beyond (along ``along``) every body vertex in the vertex's strip
    (between the midpoints to its neighbours along ``across``) lower than
    the vertex (and above 2 cm: skin resting on the floor under a lying
    body is below every wall). With ``top`` ((m,) heights), the strip reaches
    up to ``top`` instead (a face rises from the vertex to that height).
    """
    if len(points) == 0:
        return
    lo, hi = _strips(line @ across)
    pa, pc, py = points @ along, points @ across, points[:, 1]
    top = line[:, 1] if top is None else np.asarray(top)
    for i in range(len(line)):
        sel = (pc >= lo[i]) & (pc <= hi[i]) & (py >= 0.02) & (py <= top[i])
        if sel.any():
            need = float(pa[sel].max()) + clearance - float(line[i] @ along)
            if need > 0:
                line[i] += need * along


def _strips(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of each ring vertex's strip, from its coordinates ``c`` across the ring: the midpoints to its neighbours (open at the ends)."""
    mid = 0.5 * (c[1:] + c[:-1])
    lo = np.concatenate([[-np.inf], mid])
    hi = np.concatenate([mid, [np.inf]])
    return np.minimum(lo, hi), np.maximum(lo, hi)


def _drop_beside(line: np.ndarray, edge: np.ndarray, out: np.ndarray, across: np.ndarray, points: np.ndarray, gap: float, loose=None) -> None:
    """Lower the side ring's vertices where its face would pass through a body part hanging beside the seat, in place.

    The first ring continues the seat outwards from its edge ``edge[i]``
    along ``out``; a body part hanging beside the edge at the edge's height
    (a hand or an arm beside the thigh) has skin both above and below that
    face in the vertex's strip (between the midpoints to its neighbours
    along ``across``), more than ``gap`` outside the edge and within the
    ring's reach. No lift helps there (lifting the face over the hand folds
    it over the seat): the ring vertex goes straight down from the edge
    instead, ``gap`` below the lowest such skin, and the wall hangs inside
    the hanging part. Skin of the parts the chair does not hold (``loose``,
    (k,) bool: hands and forearms) counts below the edge alone too: a hand
    hanging wholly below the ring would be closed into the furniture by
    the ring and the wall outside it. The strips of the two end vertices
    reach as far beyond them as towards their neighbour, not on to
    infinity: the vertex at the backrest's top answers for what hangs
    beside it, not for every hand behind the hips (and its drop takes the
    ring's corner down with it, into the back wall).
    """
    if len(points) == 0:
        return
    loose = np.zeros(len(points), bool) if loose is None else loose
    c = line @ across
    lo, hi = _strips(c)
    if len(line) > 1:
        for i, j in ((0, 1), (len(line) - 1, len(line) - 2)):
            half = abs(c[i] - c[j]) / 2
            lo[i], hi[i] = c[i] - half, c[i] + half
    po, pc, py = points @ out, points @ across, points[:, 1]
    for i in range(len(line)):
        e = edge[i]
        reach = float((line[i] - e) @ out) + gap
        sel = (pc >= lo[i]) & (pc <= hi[i]) & (po > e @ out + gap) & (po < e @ out + reach) & (py >= 0.02)
        below = sel & (py < e[1])
        if below.any() and ((py[sel] > e[1]).any() or loose[below].any()):
            low = max(float(py[below].min()) - gap, 0.0)
            line[i] = e
            line[i, 1] = low


#: Share of the side face's width a wall keeps under the seat when it passes inside a hanging hand.
_KEEP = 0.1
#: Smallest gap between a wall and the body on either side of it, m (the surface fit keeps 6 mm; its limit is 5 mm).
_MIN_GAP = 0.006


def _nearest_vertex_along(plan: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(k,) index of the vertex of a polyline (m, 2) each point (k, 2) belongs to: the nearer end of its nearest segment."""
    a, b = plan[:-1], plan[1:]
    d = b - a
    t = np.clip(np.einsum("kmi,mi->km", points[:, None, :] - a[None], d) / np.maximum((d * d).sum(1), 1e-12), 0.0, 1.0)
    foot = a[None] + t[..., None] * d[None]
    i = np.argmin(((points[:, None, :] - foot) ** 2).sum(2), axis=1)
    return i + (t[np.arange(len(i)), i] > 0.5)


def _walls_inside(V: np.ndarray, col: int, out: np.ndarray, across: np.ndarray, free: np.ndarray, trigger: np.ndarray, held: np.ndarray, gap: float, seat: np.ndarray, *, span: int = 1, skip=None, every_row: bool = False) -> dict:
    """Where one side of the seat has hands hanging beside or under it, the walls that pass inside them.

    ``V[:, col]`` is the grid's side (the seat's edge, one vertex per row
    line), ``V[:, col -+ 1]`` the vertices inside it, ``out`` the horizontal
    direction out of that side, ``across`` the horizontal direction along
    it. ``free`` are the body vertices the cage does not hold (hands,
    forearms), ``trigger`` (bool per ``free`` vertex) those found inside the
    furniture, ``held`` every other body vertex. ``seat`` (one per face row)
    says which rows are seat-like (their planes face up, within 45 deg).

    Seen from above, each free vertex belongs to the edge vertex nearest to
    it along the side (the nearer end of the nearest edge segment). An edge
    vertex ``k`` of the seat (a row line of a seat-like row or of the row
    next to one; not the first or last, which the ring's corners follow)
    with a triggering vertex belonging to ``k - span .. k + span`` (the limit
    surface near ``k`` blends those ring vertices) gets a wall: its ring
    vertex goes from the edge down, and in under the seat, to ``gap`` inside
    the free vertices belonging to ``k`` that hang below the edge (so that a
    hand under the thigh's flank is outside the furniture: the seat
    overhangs it, as any seat narrower than its sitter; at most to
    ``_KEEP`` of the side face's width from its inner vertex), and to
    ``gap`` below everything outside the wall in its strip (the free
    vertices of ``k - span .. k + span`` too), at least to the floor: the
    outer face, from the wall's foot to the ground, passes under them. Where
    there is no room for ``gap`` the wall stands ``_MIN_GAP`` inside the
    hand. No wall cuts the held body (within ``_MIN_GAP`` of it, in the
    vertex's strip between the midpoints to its neighbours) or passes
    inside a grid vertex under the edge (a backrest over the seat's back).
    ``skip`` maps edge vertices to 1 (the wall only drops, straight down
    from the edge) or 2 (no wall). With ``every_row``, the row lines of the
    backrest get walls too (a hand hanging beside the hips behind the
    seat): the walls against a rejected surface (docs/templates.md, "Walls
    against a rejected surface").

    Returns
    -------
    dict
        ``{k: (height, position)}``: the ring vertex ``k``'s height (m) and
        its position along ``out`` (m).
    """
    skip = skip or {}
    edge, inner = V[:, col], V[:, 1 if col == 0 else col - 1]
    n = len(edge)
    plan = np.stack([edge @ out, edge @ across], 1)
    fo, fc, fy = free @ out, free @ across, free[:, 1]
    own = _nearest_vertex_along(plan, np.stack([fo, fc], 1)) if len(free) else np.zeros(0, np.int64)
    lo_strip, hi_strip = _strips(edge @ across)
    ho, hc, hy = held @ out, held @ across, held[:, 1]
    grid = V.reshape(-1, 3)
    go, gc, gy = grid @ out, grid @ across, grid[:, 1]
    walls = {}
    for k in range(1, n - 1):
        if skip.get(k, 0) >= 2 or not (every_row or seat[max(k - 2, 0) : k + 2].any()):
            continue
        # this side's: outside the side face's inner line
        near = (own >= k - span) & (own <= k + span) & (fo > float(inner[k] @ out))
        below = edge[k, 1] - gap
        mine = near & (fy < below)
        if not (near & trigger).any() or not mine.any():
            continue
        e = float(edge[k] @ out)
        keep = float((_KEEP * edge[k] + (1.0 - _KEEP) * inner[k]) @ out)
        own_k = mine & (own == k)
        hand = float(fo[own_k].min()) if own_k.any() else e + gap
        strip = (hc >= lo_strip[k]) & (hc <= hi_strip[k]) & (hy >= 0.02) & (hy < below)
        under = (gc >= lo_strip[k]) & (gc <= hi_strip[k]) & (gy < below)
        beside = (fc >= lo_strip[k]) & (fc <= hi_strip[k])
        for wall in (min(hand - gap, e), min(hand - _MIN_GAP, e)) if not skip.get(k) else (e,):
            outside = np.concatenate([fy[beside & (fo > wall)], hy[strip & (ho > wall)], fy[mine]])
            drop = max(float(outside.min()) - gap, 0.0)
            cut = strip & (_distance_to_segment(ho, hy, (e, float(edge[k, 1])), (wall, drop)) < _MIN_GAP)
            blocked = under.any() and float(go[under].max()) > wall - gap
            if wall >= keep and not cut.any() and not blocked:
                walls[k] = (drop, wall)
                break
    return walls


def _distance_to_segment(x: np.ndarray, y: np.ndarray, a: tuple, b: tuple) -> np.ndarray:
    """Distance of the points (x, y) to the segment a -> b in a plane."""
    d = np.array(b) - np.array(a)
    p = np.stack([x - a[0], y - a[1]], 1)
    t = np.clip(p @ d / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.linalg.norm(p - t[:, None] * d, axis=1)


def _set_back_front_edge(V: np.ndarray, points: np.ndarray, back: np.ndarray, across: np.ndarray, gap: float, *, most: float = 0.8) -> None:
    """Move the first vertex row back along the first face row until the legs hang in front of it, in place.

    A body point below the seat (lower than the line from ``V[0]`` to
    ``V[1]`` of its strip by more than ``gap``, and above 2 cm) hangs from
    the seat: the seat's front edge must lie ``gap`` behind it, so that a
    wall straight down from the edge passes behind the lower legs. Each
    vertex moves at most ``most`` of the way to ``V[1]``.
    """
    if len(points) == 0 or len(V) < 2:
        return
    lo, hi = _strips(V[0] @ across)
    pa, pc, py = points @ back, points @ across, points[:, 1]
    for k in range(V.shape[1]):
        p0, p1 = V[0, k], V[1, k]
        a0, a1 = float(p0 @ back), float(p1 @ back)
        if a1 - a0 < 1e-6:
            continue
        t = np.clip((pa - a0) / (a1 - a0), 0.0, 1.0)
        seat = p0[1] + t * (p1[1] - p0[1])
        sel = (pc >= lo[k]) & (pc <= hi[k]) & (py >= 0.02) & (py < seat - gap)
        if not sel.any():
            continue
        need = float(pa[sel].max()) + gap
        if need > a0:
            f = min(most, (need - a0) / (a1 - a0))
            V[0, k] = p0 + f * (p1 - p0)


#: Where the front wall stands (the border step's ``front_wall`` option).
FRONT_WALLS = ("before-feet", "behind-calves")


def add_border(
    grid: GridMesh,
    *,
    width: float,
    margin: float,
    min_spacing: float,
    meta: dict,
    bodies=(),
    front_wall: str = "before-feet",
    front_drop: float = 0.08,
    body_clearance: float | None = None,
    drop_beside: bool = False,
    hanging=None,
    no_wall=None,
    every_row: bool = False,
) -> GridMesh:
    """The grid with two border rings, the outer one on a ground rectangle.

    Parameters
    ----------
    grid : GridMesh
        (R, C) faces.
    width : float
        Extension of the first ring, m.
    margin : float
        Ground rectangle margin around the surface, m.
    min_spacing : float
        Smallest spacing of ground vertices, m.
    meta : dict
        Receives ``border`` facts (rectangle, convexity per side).
    bodies : sequence of Body
        The walls from the ring down to the ground pass outside them.
    front_wall : str
        ``before-feet``: the first ring continues the first row forwards and
        its wall hangs in front of every body part below it (a chair's feet).
        ``behind-calves``: the first ring lies ``front_drop`` below the first
        row's edge, moved back until its wall passes behind every body part
        below the edge; the legs hang in front of it (a saddle stool). The
        ground rectangle's front edge is then ``margin`` in front of that
        ring, not of the seat's edge.
    front_drop : float
        ``behind-calves``: height of the front face, m.
    body_clearance : float, optional
        Gap between walls and bodies, m (default ``min_spacing``).
    drop_beside : bool
        Where a body part hangs beside the seat's edge at its height (a hand
        beside the thigh: skin above and below the first ring's side face),
        the ring vertex goes straight down from the edge, below that skin
        (:func:`_drop_beside`). The clearance step's repair rebuilds the
        border this way after the final check refused border faces.
    hanging : sequence of ((n,) bool, (n,) bool) per body, optional
        The body vertices the cage does not hold (a hand, a forearm), and of
        those the ones found inside the furniture. Given, where one was
        found the side ring goes from the seat's edge down and in under it,
        inside the hands hanging beside or under that side
        (:func:`_walls_inside`); the faces around those ring vertices weigh
        as much as the most loaded face (``face_weight`` 1), so that the
        mesh optimisation keeps the walls where they stand. The clearance
        step's ``repair_enclosure`` rebuilds the border this way when a
        cage that passed the checks encloses a hand.
    no_wall : mapping, optional
        ``{"right": {k: level}, "left": {...}}``: edge vertices whose wall
        only drops (level 1) or that get none (2): their wall crossed the
        cage or the body.
    every_row : bool
        With ``hanging``: walls on the row lines of every row, the
        backrest's too, not only beside the seat-like rows
        (:func:`_walls_inside`; the walls against a surface the design
        search rejected).

    Returns
    -------
    GridMesh
        (R + 4, C + 4) faces; ``ground`` marks the outer ring.
    """
    if front_wall not in FRONT_WALLS:
        raise ValueError(f"front_wall {front_wall!r}: expected one of {', '.join(FRONT_WALLS)}")
    behind = front_wall == "behind-calves"
    gap = min_spacing if body_clearance is None else float(body_clearance)
    V = grid.vertices.copy()
    R, C = grid.shape
    # rectangle axes: the body faces +Z, so the rectangle is axis-aligned:
    # side = +-X (along the columns), front = +-Z (towards row 0)
    side = np.array([1.0, 0.0, 0.0]) if (V[:, -1] - V[:, 0]).sum(0)[0] >= 0 else np.array([-1.0, 0.0, 0.0])
    front = np.array([0.0, 0.0, 1.0]) if (V[0] - V[-1]).sum(0)[2] >= 0 else np.array([0.0, 0.0, -1.0])
    # the grid's side columns must run monotonically from the front row to
    # the back row: a side that doubles back (an outer back face wrapping
    # forward past the seat's edge) would make the walls below it overlap
    _monotone(V, axis=0, direction=-front, step=min_spacing)
    pts = np.concatenate([np.asarray(b.vertices, dtype=np.float64) for b in bodies]) if len(bodies) else np.zeros((0, 3))
    loose = np.concatenate([np.isin(segment_of_vertex(b), list(NOT_HELD)) for b in bodies]) if drop_beside and len(bodies) else None
    if behind:
        _set_back_front_edge(V, pts, -front, side, gap)
    walls = {}
    no_wall = no_wall or {}
    if hanging is not None:
        free = np.concatenate([np.asarray(h[0], bool) for h in hanging]) if len(hanging) else np.zeros(0, bool)
        trigger = np.concatenate([np.asarray(h[1], bool) for h in hanging]) if len(hanging) else np.zeros(0, bool)
        with np.errstate(invalid="ignore"):
            seat = np.nanmean(grid.plane_normal[..., 1], axis=1) >= np.cos(np.pi / 4)
        for col, out_dir in ((0, -side), (-1, side)):
            walls[col] = _walls_inside(V, col, out_dir, front, pts[free], trigger[free], pts[~free], gap, seat, skip=no_wall.get("right" if col == 0 else "left", {}), every_row=every_row)
    ring = np.full((R + 3, C + 3, 3), np.nan)  # ring-1 grid: original at [1:-1, 1:-1]
    ring[1:-1, 1:-1] = V
    ring[1:-1, 0] = V[:, 0] - width * side
    ring[1:-1, -1] = V[:, -1] + width * side
    if behind:
        ring[0, 1:-1] = V[0] - np.array([0.0, front_drop, 0.0])
    else:
        ring[0, 1:-1] = V[0] + width * unit(V[0] - V[1])
    ring[-1, 1:-1] = V[-1] + width * unit(V[-1] - V[-2])
    # the ring envelops the grid: its back row lies behind every grid vertex
    # of the same column (a wall hanging from a backrest that wraps forward
    # would cut the back), its front row in front, its sides outside the rows
    _envelop(ring[-1, 1:-1], V.transpose(1, 0, 2), -front)
    if not behind:
        _envelop(ring[0, 1:-1], V.transpose(1, 0, 2), front)
    _envelop(ring[1:-1, 0], V, -side)
    _envelop(ring[1:-1, -1], V, side)
    _clear_bodies(ring[-1, 1:-1], -front, side, pts, gap)
    if behind:
        # the wall hangs from the ring, front_drop below the seat's edge:
        # everything below the ring in its strip (the lower legs) stays in front of it
        _clear_bodies(ring[0, 1:-1], -front, side, pts, gap)
    else:
        _clear_bodies(ring[0, 1:-1], front, side, pts, gap)
    _clear_bodies(ring[1:-1, 0], -side, front, pts, gap)
    _clear_bodies(ring[1:-1, -1], side, front, pts, gap)
    dropped = 0
    if drop_beside:
        for line, edge, out in ((ring[1:-1, 0], V[:, 0], -side), (ring[1:-1, -1], V[:, -1], side)):
            before = line.copy()
            _drop_beside(line, edge, out, front, pts, gap, loose)
            dropped += int(np.any(line != before, axis=1).sum())
            _clear_bodies(line, out, front, pts, gap)
    for col, placed in walls.items():
        out_dir = -side if col == 0 else side
        for k, (height, wall) in placed.items():
            ring[1 + k, col] = V[k, col] + (wall - float(V[k, col] @ out_dir)) * out_dir
            ring[1 + k, col, 1] = min(height, V[k, col, 1])
        if placed:
            _clear_bodies(ring[1:-1, col], out_dir, front, pts, gap)
    for i, k, ii in ((0, 0, 1), (0, -1, 1), (-1, 0, -2), (-1, -1, -2)):
        kk = 1 if k == 0 else -2
        ring[i, k] = ring[i, kk] + (ring[ii, k] - ring[ii, kk])
    ring[..., 1] = np.maximum(ring[..., 1], 0.0)

    # the same for the ring, and its front and back rows from right to left
    _monotone(ring, axis=0, direction=-front, step=min_spacing)
    _monotone(ring, axis=1, direction=side, step=min_spacing)
    flat = ring.reshape(-1, 3)
    s_all, f_all = flat @ side, flat @ front
    s0, s1 = s_all.min() - margin, s_all.max() + margin
    f0, f1 = f_all.min() - margin, f_all.max() + margin
    if behind:
        # the front wall hangs from the first ring down and back, to the
        # ground's front edge under its rearmost vertex: never forwards into
        # the legs (and not in front of the seat's edge above them)
        f1 = float((ring[0] @ front).min())

    out = np.zeros((R + 5, C + 5, 3))
    out[1:-1, 1:-1] = ring

    def point(s, f):
        return np.outer(s, side) + np.outer(f, front)

    convex = {}
    # right side (column 0): from the front corner (f1) backwards; t = f1 - f
    prof = ring[:, 0]
    t, convex["right"] = place_ground_side(f1 - prof @ front, prof[:, 1], prof @ side - s0, f1 - f0, min_spacing)
    out[1:-1, 0] = point(np.full(len(t), s0), f1 - t)
    prof = ring[:, -1]
    t, convex["left"] = place_ground_side(f1 - prof @ front, prof[:, 1], s1 - prof @ side, f1 - f0, min_spacing)
    out[1:-1, -1] = point(np.full(len(t), s1), f1 - t)
    prof = ring[0]
    t, convex["front"] = place_ground_side(prof @ side - s0, prof[:, 1], f1 - prof @ front, s1 - s0, min_spacing)
    out[0, 1:-1] = point(s0 + t, np.full(len(t), f1))
    prof = ring[-1]
    t, convex["back"] = place_ground_side(prof @ side - s0, prof[:, 1], prof @ front - f0, s1 - s0, min_spacing)
    out[-1, 1:-1] = point(s0 + t, np.full(len(t), f0))
    out[0, 0], out[0, -1] = point([s0], [f1])[0], point([s1], [f1])[0]
    out[-1, 0], out[-1, -1] = point([s0], [f0])[0], point([s1], [f0])[0]
    ground = np.zeros(out.shape[:2], bool)
    ground[0, :] = ground[-1, :] = ground[:, 0] = ground[:, -1] = True
    out[ground, 1] = 0.0

    def pad(a, fill):
        shape = (R + 4, C + 4) + a.shape[2:]
        res = np.full(shape, fill, dtype=a.dtype)
        res[2:-2, 2:-2] = a
        return res

    label = pad(grid.label, "border")
    weight = pad(grid.face_weight, 0.0)
    for col, placed in walls.items():
        for k in placed:
            # the four faces around the ring vertex (ring[1 + k, col] is out[2 + k, 1] or out[2 + k, C + 3])
            j = 0 if col == 0 else C + 2
            weight[1 + k : 3 + k, j : j + 2] = 1.0
    meta["border"] = {
        "rectangle": [[float(x) for x in point([s], [f])[0]] for s, f in ((s0, f1), (s1, f1), (s1, f0), (s0, f0))],
        "convex_sides": convex,
        "width": width,
        "margin": margin,
        "front_wall": front_wall,
    }
    if drop_beside:
        meta["border"]["dropped_beside"] = dropped
    if hanging is not None:
        meta["border"]["walls_inside"] = {("right" if col == 0 else "left"): sorted(int(k) for k in placed) for col, placed in walls.items()}
        if every_row:
            meta["border"]["walls_every_row"] = True
    return GridMesh(
        out,
        pad(grid.segment, -1),
        pad(grid.person, -1),
        label,
        pad(grid.plane_point, np.nan),
        pad(grid.plane_normal, np.nan),
        weight,
        ground,
    )


def keep_back_behind(grid: GridMesh, bodies=(), *, width: float, margin: float, gap: float, tolerance: float = 1e-3) -> int:
    """Put the back ring behind the back rows again after the grid's vertices moved (the clearance lift), in place.

    :func:`add_border` builds the first ring behind every vertex of its
    column; the lift then moves vertices off the bodies along their
    normals, and where it pushes a backrest's top rows back past the ring
    (a tilted back lifted off an arm behind it), the wall from the ring
    down to the ground passes through them: a fold. Each column of the
    first ring (its corners too) with a vertex above the ground behind
    that wall (by more than ``tolerance``, at the vertex's height) gets
    its ring vertex again as the border first makes it, from the moved
    column: its last vertex continued by ``width`` along its last edge,
    moved back behind every vertex of the column, its wall outside the
    bodies. A vertex behind the ring but in front of its wall (the wall
    slopes back to the ground rectangle) is no fold and is left alone. The ground rectangle's back edge then moves back
    to ``margin`` behind the ring where it is closer. ``grid`` is a grid
    :func:`add_border` made, ``width``, ``margin`` and ``gap`` (its
    ``body_clearance``) as it was made with. Returns how many ring
    vertices moved.
    """
    G = grid.vertices
    if G.shape[0] < 5 or G.shape[1] < 5 or not grid.ground[-1].all():
        return 0
    inner = G[2:-2, 2:-2]
    front = np.array([0.0, 0.0, 1.0]) if (inner[0] - inner[-1]).sum(0)[2] >= 0 else np.array([0.0, 0.0, -1.0])
    back = -front
    side = np.array([1.0, 0.0, 0.0])
    column = G[1:-2, 1:-1]  # (rows, m, 3): each column of the first ring's back row, above the ground
    reach = (column @ back).max(0)  # the furthest back of each column
    ring, foot = G[-2, 1:-1], G[-1, 1:-1]
    # the wall from each ring vertex down to its ground vertex, at the height of each vertex of its column
    rb, fb, ry = ring @ back, foot @ back, ring[:, 1]
    t = np.clip((ry[None] - column[..., 1]) / np.maximum(ry[None], 1e-9), 0.0, 1.0)
    late = np.flatnonzero((column @ back - (rb[None] + t * (fb - rb)[None])).max(0) > tolerance)
    if len(late) == 0:
        return 0
    line = ring.copy()
    for j in late:
        k = j + 1
        p, q = G[-3, k], G[-4, k]
        line[j] = p + width * unit(p - q)
        line[j] += max(float(reach[j] - line[j] @ back), 0.0) * back
        line[j, 1] = max(line[j, 1], 0.0)
    pts = np.concatenate([np.asarray(b.vertices, dtype=np.float64) for b in bodies]) if len(bodies) else np.zeros((0, 3))
    cleared = line.copy()
    _clear_bodies(cleared, back, side, pts, gap)
    ring[late] = cleared[late]
    # the ground's back edge stays margin behind the ring
    f0 = float((G[-1, 0] @ front))
    want = float((ring @ front).min()) - margin
    if want < f0:
        G[-1] += np.outer(np.full(G.shape[1], want - f0), front)
    return int(len(late))
