"""Outer columns and the paper's special cases: crossed legs, armrests.

(The third special case, no backrest when leaning forward, only drops rows;
it lives in :class:`seatkit.template.steps.NoBackrestStep`.)
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from seatkit.template.grid import Block, FaceState, FitState, GridMesh
from seatkit.template.planes import Plane, fit_support_plane, cross, unit

__all__ = ["fit_outer_face", "merge_crossed_legs", "add_armrests", "minimal_rectangle"]


def fit_outer_face(state: FitState, block: Block, face: FaceState, options) -> None:
    """Fit an outer-column face with its two inner vertices fixed (paper Sec. 5.2).

    The plane goes through the shared inner vertices and the body vertex
    that gives the best quality w_P; the inner vertices are then shifted
    outwards in that plane by the segment's remaining width.
    """
    p = state.params
    r, c = face.spec.row, face.spec.column
    C = block.n_columns
    k_in, k_out, c_in, sign = (1, 0, 1, -1.0) if c == 0 else (C - 1, C, C - 2, 1.0)
    A, B = block.vertex(r, k_in), block.vertex(r + 1, k_in)
    inner = block.faces[(r, c_in)]
    side_out = sign * (inner.d_side if inner.d_side is not None else unit(cross(B - A, [0.0, 1.0, 0.0])))
    idx = block.vertices_of(face.segments)
    pts = block.body.vertices[idx]
    outer = (pts - A) @ side_out > 0
    cand_idx = idx[outer] if outer.sum() >= 3 else idx
    n_cand = int(options.get("candidates", 400))
    if len(cand_idx) > n_cand:
        w = block.importance[cand_idx] + p["importance_floor"]
        cand_idx = np.sort(state.rng.choice(cand_idx, size=n_cand, replace=False, p=w / w.sum()))
    i = block.rows.index(r)
    prev = block.neighbour_plane(block.rows[i - 1], c) if i > 0 else None
    res = fit_support_plane(
        pts,
        block.importance[idx],
        rng=state.rng,
        iterations=0,
        support_distance=p["support_distance"],
        max_penetration=p["support_distance"],
        body_side=pts.mean(0),
        bone=block.row_axis(face.segments, r),
        reference=block.frame_normal(face.segments, r),
        side_hint=block.lateral(),
        max_side_angle=p["max_wrap"],
        lambda_r=p["lambda_r"],
        lambda_d=p["lambda_d"] if prev is not None else 0.0,
        m_alpha=p["m_alpha"],
        previous_normal=None if prev is None else prev.normal,
        max_row_angle=p["max_row_angle"],
        fixed=np.stack([A, B]),
        fallback_normal=inner.plane.normal if inner.plane is not None else np.array([0.0, 1.0, 0.0]),
        candidates=block.body.vertices[cand_idx],
        importance_floor=p["importance_floor"],
    )
    n = res.plane.normal
    e = unit(cross(n, B - A))
    if e @ side_out < 0:
        e = -e
    near = pts[np.abs(res.plane.signed_distance(pts)) <= 2 * p["support_distance"]]
    reach = float(((near - A) @ e).max()) if len(near) else 0.0
    width = max(reach + float(options.get("margin", 0.02)), float(options.get("min_width", 0.06)))
    face.plane = res.plane
    face.d_up = unit(B - A)
    face.d_side = cross(face.d_up, n)
    face.centre = (A + B) / 2
    face.side_range = np.array([0.0, width])
    face.supported = idx[res.supported]
    face.weight = float(block.importance[face.supported].sum())
    face.info = {"candidates": res.candidates, "rejected": res.rejected, "quality": res.plane.quality, "width": width}
    block.estimates.setdefault((r, k_out), []).append(A + width * e)
    block.estimates.setdefault((r + 1, k_out), []).append(B + width * e)


def merge_crossed_legs(state: FitState, block: Block, rows, cols, min_distance: float, fit_face) -> None:
    """One plane for both legs in rows where their faces are closer than ``min_distance``.

    The gap is measured along the two faces' mean ``d_side`` between the
    right face's outer (left) column line and the left face's inner one; it
    is negative when the legs cross. A merged row's plane is fitted to the
    vertices of both legs; its width is split in thirds (right face, bridge,
    left face).
    """
    merged = []
    for r in rows:
        a, b = block.faces[(r, cols[0])], block.faces[(r, cols[1])]
        if a.plane is None or b.plane is None:
            continue
        s = unit(a.d_side + b.d_side)
        a_hi = max((a.centre + x * a.d_side) @ s for x in a.side_range)
        b_lo = min((b.centre + x * b.d_side) @ s for x in b.side_range)
        gap = float(b_lo - a_hi)
        if gap >= min_distance:
            continue
        union = tuple(sorted(set(a.segments) | set(b.segments)))
        fit_face(state, block, a, direction_penalty=False, segments=union)
        pts = block.body.vertices[block.vertices_of(union)]
        x = (pts - a.centre) @ a.d_side
        lo, hi = float(x.min()), float(x.max())
        third = (hi - lo) / 3
        a.side_range = np.array([lo, lo + third])
        b.segments = union
        b.plane, b.d_up, b.d_side, b.centre = a.plane, a.d_up, a.d_side, a.centre
        b.side_range = np.array([hi - third, hi])
        b.supported, b.weight, b.info = a.supported, a.weight, dict(a.info)
        merged.append({"row": state.spec.rows[r], "gap": gap})
        block.cases.setdefault("merged_rows", []).append(r)
    state.meta.setdefault("special_cases", []).append(
        {"case": "crossed-legs", "person": block.person, "taken": bool(merged), "rows": merged, "min_distance": min_distance}
    )


def minimal_rectangle(points: np.ndarray) -> np.ndarray:
    """Minimum-area rectangle around 2-D ``points`` (k, 2) by rotating calipers.

    Returns
    -------
    (4, 2) float64
        Corners, counter-clockwise.
    """
    hull = points[ConvexHull(points).vertices]
    edges = np.diff(np.vstack([hull, hull[:1]]), axis=0)
    angles = np.unique(np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2))
    c, s = np.cos(angles), np.sin(angles)
    rot = np.stack([np.stack([c, s], 1), np.stack([-s, c], 1)], 1)  # (a, 2, 2)
    proj = np.einsum("aij,kj->aki", rot, hull)
    lo, hi = proj.min(1), proj.max(1)
    area = np.prod(hi - lo, axis=1)
    i = int(np.argmin(area))
    (x0, y0), (x1, y1) = lo[i], hi[i]
    box = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    return box @ rot[i]


def _point_rectangle_distance(points, corners) -> np.ndarray:
    """(k,) distance of 3-D points to a 3-D rectangle given by 4 corners."""
    o = corners[0]
    u, v = corners[1] - o, corners[3] - o
    lu, lv = np.linalg.norm(u), np.linalg.norm(v)
    u, v = u / lu, v / lv
    rel = points - o
    a = np.clip(rel @ u, 0, lu)
    b = np.clip(rel @ v, 0, lv)
    return np.linalg.norm(rel - np.outer(a, u) - np.outer(b, v), axis=1)


def add_armrests(state: FitState, options) -> None:
    """Armrests (paper Sec. 5.2, refinement stage) for a one-person grid.

    For each side: a RANSAC plane for the arm (PCA reference, no hierarchy),
    the minimal spanning rectangle of the supported arm vertices in it, and,
    when the arm carries enough load, the plane is nearly horizontal, the
    rectangle does not cut the body and stays ``min_distance`` away from the
    grid, two columns: the armrest and a connector to the grid. The grid
    row lines at the armrest's height (the seat's edge, the lower backrest)
    are spread along the rectangle; the rows before and after continue the
    armrest column beside the grid (a side panel down to the feet, a wing
    beside the backrest): see :func:`_armrest_edges`.
    """
    from seatkit.skeleton import SEGMENT_INDEX

    from seatkit.template.checks import faces_cross_body
    from seatkit.template.clearance import lift_off_bodies

    p = state.params
    grid = state.grid
    records = []
    if len(state.blocks) != 1:
        state.meta.setdefault("special_cases", []).append({"case": "armrests", "taken": False, "reason": "armrests are fitted for one person only"})
        return
    block = state.blocks[0]
    total = float(block.normal_force.sum()) or 1.0
    for side in ("right", "left"):
        names = options.get(side, [f"{side.capitalize()}Arm", f"{side.capitalize()}ForeArm"])
        segs = [SEGMENT_INDEX[n] for n in names]
        rec = {"side": side, "taken": False, "segments": list(names)}
        records.append(rec)
        idx = block.vertices_of(segs)
        share = float(block.normal_force[idx].sum()) / total
        rec["load_fraction"] = share
        if share < float(options.get("min_load_fraction", 0.02)):
            rec["reason"] = "the arm carries too little load"
            continue
        pts = block.body.vertices[idx]
        max_tilt = float(options.get("max_tilt_deg", 30.0))
        up = np.array([0.0, 1.0, 0.0])
        res = fit_support_plane(
            pts, block.importance[idx], rng=state.rng, iterations=p["ransac_iterations"],
            support_distance=p["support_distance"], max_penetration=p["max_penetration"],
            body_side=pts.mean(0) + up, bone=block.bone(segs), lambda_r=p["lambda_r"], importance_floor=p["importance_floor"],
            reference=up, cone=(up, np.radians(max_tilt)),
        )
        plane = res.plane
        tilt = float(np.degrees(np.arccos(np.clip(plane.normal[1], -1, 1))))
        rec["tilt_deg"] = tilt
        if tilt > max_tilt or res.supported.sum() < 3:
            rec["reason"] = "no nearly horizontal plane supports the arm"
            continue
        # in-plane frame: e1 along the grid's rows projected, e2 = n x e1
        V = grid.vertices
        rows_dir = V[-1].mean(0) - V[0].mean(0)
        e1 = unit(rows_dir - plane.normal * (plane.normal @ rows_dir))
        e2 = cross(plane.normal, e1)
        sup = plane.project(pts[res.supported])
        uv = np.stack([(sup - plane.point) @ e1, (sup - plane.point) @ e2], 1)
        box = minimal_rectangle(uv)
        corners = plane.point + box[:, :1] * e1 + box[:, 1:] * e2
        # order: along e1 (front = towards row 0), inner/outer along the side
        side_dir = unit(V[:, -1].mean(0) - V[:, 0].mean(0)) * (-1.0 if side == "right" else 1.0)
        t = (corners - corners.mean(0)) @ e1
        front = corners[t <= np.median(t)]
        back = corners[t > np.median(t)]
        if len(front) != 2:
            rec["reason"] = "degenerate armrest rectangle"
            continue
        f_in, f_out = sorted(front, key=lambda q: q @ side_dir)
        b_in, b_out = sorted(back, key=lambda q: q @ side_dir)
        rect = np.array([f_in, b_in, b_out, f_out])
        others = np.ones(len(block.body.vertices), bool)  # every vertex but the arm's and the hand's
        others[block.vertices_of(segs + [SEGMENT_INDEX[f"{side.capitalize()}Hand"]])] = False
        body_pts = block.body.vertices[others]
        # the armrest and its support below it must not pass through the body
        below = plane.signed_distance(body_pts) < -p["max_penetration"]
        o, u, v = rect[0], rect[1] - rect[0], rect[3] - rect[0]
        a_, b_ = (body_pts - o) @ u / (u @ u), (body_pts - o) @ v / (v @ v)
        inside = (a_ > 0) & (a_ < 1) & (b_ > 0) & (b_ < 1)
        if (below & inside).any():
            rec["reason"] = "the body lies under the armrest (the arm rests on the body)"
            continue
        outer_col = V[:, 0] if side == "right" else V[:, -1]
        gap = float(_point_rectangle_distance(outer_col, rect).min())
        rec["distance_to_grid"] = gap
        if gap < float(options.get("min_distance", 0.04)):
            rec["reason"] = "the armrest is too close to the grid"
            continue
        edges = _armrest_edges(outer_col, rect, side_dir, float(options.get("reach_below", 0.35)), float(options.get("reach_above", 0.1)))
        if edges is None:
            rec["reason"] = "fewer than two row lines of the grid reach the armrest's height"
            continue
        inner_edge, outer_edge, span = edges
        cols = [outer_edge, inner_edge] if side == "right" else [inner_edge, outer_edge]
        trial = _with_columns(grid, cols, side, plane, SEGMENT_INDEX[f"{side.capitalize()}ForeArm"], block.person, span)
        new = slice(0, 2) if side == "right" else slice(trial.shape[1] - 2, trial.shape[1])
        quads = _grid_quads(trial)[new]
        # the clearance step lifts shallow crossings: test the new columns
        # once the trial grid is lifted, as it will be
        trial_quads = _grid_quads(trial).transpose(1, 0, 2).reshape(-1, 4)
        lifted = lift_off_bodies(
            trial.vertices.reshape(-1, 3), trial_quads, [block.body], np.ones(trial_quads.max() + 1, bool),
            target=-0.5 * p["max_penetration"], rounds=2,
        )
        if faces_cross_body(lifted.vertices, quads.reshape(-1, 4), block.body, p["max_penetration"] + 1e-3):
            rec["reason"] = "the connector to the armrest would cross the body"
            continue
        grid = trial
        rec["taken"] = True
        rec["rectangle"] = rect.tolist()
    state.grid = grid
    state.meta.setdefault("special_cases", []).append({"case": "armrests", "taken": any(r["taken"] for r in records), "sides": records})


def _armrest_edges(outer_col: np.ndarray, rect: np.ndarray, side_dir: np.ndarray, reach_below: float, reach_above: float):
    """Inner and outer edge vertices (R+1, 3) of an armrest column, or None.

    The grid's outer vertices whose height is within ``reach_below`` below
    and ``reach_above`` above the armrest (a contiguous run of row lines:
    the seat's edge and the lower backrest) are spread evenly along the
    rectangle from its front end to its back end. The row lines before and
    after the run (the legs, the upper backrest) continue the armrest
    column beside the grid: their outer vertex moved sideways to the
    armrest's inner and outer lines, a side panel and a backrest wing.
    """
    f_in, b_in, b_out, f_out = rect
    height = float(rect[:, 1].mean())
    y = outer_col[:, 1]
    within = (y >= height - reach_below) & (y <= height + reach_above)
    runs, start = [], None
    for i, w in enumerate(list(within) + [False]):
        if w and start is None:
            start = i
        if not w and start is not None:
            runs.append((start, i - 1))
            start = None
    if not runs:
        return None
    i0, i1 = max(runs, key=lambda r: (r[1] - r[0], -r[0]))
    if i1 - i0 < 1:
        return None
    n = len(outer_col)
    inner = np.empty((n, 3))
    outer = np.empty((n, 3))
    s = np.linspace(0.0, 1.0, i1 - i0 + 1)[:, None]
    inner[i0 : i1 + 1] = f_in + s * (b_in - f_in)
    outer[i0 : i1 + 1] = f_out + s * (b_out - f_out)
    lat_in = float(np.mean([f_in @ side_dir, b_in @ side_dir]))
    width = float(np.mean([(f_out - f_in) @ side_dir, (b_out - b_in) @ side_dir]))
    rest = np.r_[0:i0, i1 + 1 : n]
    shift = np.maximum(lat_in - outer_col[rest] @ side_dir, 0.02)
    inner[rest] = outer_col[rest] + shift[:, None] * side_dir
    outer[rest] = inner[rest] + max(width, 0.02) * side_dir
    return inner, outer, (i0, i1)


def _grid_quads(grid: GridMesh) -> np.ndarray:
    """(C, R, 4) int64 quads of a structured grid, column-major (for slicing columns)."""
    R, C = grid.shape
    ids = np.arange((R + 1) * (C + 1)).reshape(R + 1, C + 1)
    q = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1)
    return q.transpose(1, 0, 2)


def _with_columns(grid: GridMesh, cols, side, plane: Plane, segment: int, person: int, span) -> GridMesh:
    """``grid`` with two vertex columns (and two face columns) added on one side.

    Faces of rows ``span[0]`` to ``span[1] - 1`` of the outer column are the
    armrest (forearm segment, the arm plane); the column's other faces are
    the side panel and wing that carry it (structural, no plane).
    """
    R, C = grid.shape
    newV = np.stack(cols, axis=1)
    nan = np.full((R, 1, 3), np.nan)
    rest = np.ones((R, 1), bool)
    rest[span[0] : span[1]] = False
    arm_pp = np.where(rest[..., None], np.nan, np.broadcast_to(plane.point, (R, 1, 3)))
    arm_pn = np.where(rest[..., None], np.nan, np.broadcast_to(plane.normal, (R, 1, 3)))
    arm_seg = np.where(rest, -1, segment)
    arm_lab = np.where(rest, f"armrest-panel.{side}", f"armrest.{side}").astype(object)
    arm_fw = np.where(rest, 0.0, 0.5)
    arm_per = np.where(rest, -1, person)
    if side == "right":
        V = np.concatenate([newV, grid.vertices], axis=1)
        seg = [arm_seg, np.full((R, 1), -1), grid.segment]
        lab = [arm_lab, np.full((R, 1), "armrest-connector.right", object), grid.label]
        pp, pn = [arm_pp, nan, grid.plane_point], [arm_pn, nan, grid.plane_normal]
        fw = [arm_fw, np.zeros((R, 1)), grid.face_weight]
        per = [arm_per, np.full((R, 1), -1), grid.person]
    else:
        V = np.concatenate([grid.vertices, newV], axis=1)
        seg = [grid.segment, np.full((R, 1), -1), arm_seg]
        lab = [grid.label, np.full((R, 1), "armrest-connector.left", object), arm_lab]
        pp, pn = [grid.plane_point, nan, arm_pp], [grid.plane_normal, nan, arm_pn]
        fw = [grid.face_weight, np.zeros((R, 1)), arm_fw]
        per = [grid.person, np.full((R, 1), -1), arm_per]
    return GridMesh(
        V, np.concatenate(seg, 1).astype(np.int64), np.concatenate(per, 1).astype(np.int64), np.concatenate(lab, 1),
        np.concatenate(pp, 1), np.concatenate(pn, 1), np.concatenate(fw, 1), np.zeros(V.shape[:2], bool),
    )
