"""The seat's height and the backrest's: a designer's dimensions, declared as the ``seat`` step's options.

The method fits the furniture to the body in its pose, so the seat is where
the body's buttocks are: with the feet on the floor (the body is grounded,
its lowest point at y = 0), the seat height follows from the pose and the
body's legs. A designer who wants another seat height sets the ``seat``
step's ``height`` (``template_params: {steps: {seat: {height: 0.55}}}``):

- **the seat height** is the height above the floor of the designed surface
  under the body's *seat point*, the lowest skin of the pelvis (under the
  ischial tuberosities when sitting; :func:`seat_point`);
- **set higher** than the pose gives, the body and its design are lifted
  and the floor stays at y = 0: the feet leave the floor and the template's
  foot faces become a footrest on the furniture (the importance map, the
  pressure "supported everywhere", does not change with a vertical move);
- **set lower**, the feet would go through the floor: refused with one line
  naming the option, how far below the floor the lowest point would be and
  the lowest seat height this body in this pose allows.

The bodies are lifted when they are placed, before the pressure
(:func:`seat_bodies`, called by :func:`seatkit.stages.place_bodies`), so that
the seat point is at the height; after the design search the design is moved
by the gap between the seat point and the surface under it
(:func:`seat_design`), so that the built surface is there. The step's own
``run`` records the seat point of each person in the template's ``meta``
(report.json ``control_mesh.meta.seat``) and, with ``backrest_height``, moves
the backrest's top (:func:`set_backrest_height`; docs/templates.md, "seat").

The seat's ``depth`` is measured along the thighs from the back of the
buttocks to the crest of the seat's rounded front edge (:func:`seat_axis`,
:func:`seat_depth_of`). A shorter seat does not carry the thigh ahead of its
front edge, so that skin leaves the pressure the design is guided by
(:func:`seat_contact`, applied when the importance is solved); each refined
candidate of the design search gets its front edge put at the depth, kept,
and the surface fitted around it (:func:`refined_seat`); the built design is
measured again (:func:`check_design`).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from seatkit.errors import RecipeError
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.options import Option

__all__ = ["SeatStep", "seat_point", "seat_bodies", "seat_design", "set_backrest_height", "check_design", "surface_below", "seat_axis", "seat_contact", "seat_depth_of", "front_edge", "recline_of", "depth_range", "place_front_edge", "refined_seat", "reclined_pose", "recline_to", "back_recline", "built_recline", "SEAT_BAND", "FLOOR_TOLERANCE", "BACKREST_TOLERANCE"]

#: Pelvis skin within this of its lowest point makes up the seat point (its mean x and z), m.
SEAT_BAND = 0.01

#: How far below the floor the lowest point of a lowered body may go before it is refused, m.
FLOOR_TOLERANCE = 0.001

#: How far below the seat point the surface may be and still be the seat that carries it, m.
SEAT_REACH = 0.04

#: Shortest the backrest's last row may be made along its plane by a lower backrest height, m.
MIN_TOP_ROW = 0.03

#: How far the built design's backrest top may end from the height set, m.
BACKREST_TOLERANCE = 0.005

#: How far the built seat's front edge may end from the depth set, m.
DEPTH_TOLERANCE = 0.005

#: Least a seat depth may reach beyond the seat point (the ischia), m: a shorter seat does not carry the thighs' roots.
MIN_DEPTH_AHEAD = 0.08

#: The shank skin this close to its knee joint and ahead of a shorter seat's front edge is not carried (the back of the knee, the top of the calf), m.
KNEE_CLEARANCE = 0.12

#: Shortest the thigh row may be made along its faces by a shorter seat, m.
MIN_THIGH_ROW = 0.03

#: Rounds of putting the front edge at the depth and fitting the surface around it (a refit moves the front edge's neighbours, which shifts it by millimetres; the second round's shift is smaller).
REFITS = 2

#: Farthest the front edge may be moved ahead of where the refiners put it, along the seat, m.
MAX_DEEPER = 0.2

#: How far the built backrest's recline may end from the recline set, deg.
RECLINE_TOLERANCE_DEG = 2.0

#: Most builds a recline set may take: each one after the first with the back reclined by the last built backrest's miss.
RECLINE_BUILDS = 3

#: A trunk further than this from vertical (lying) has no back above the seat to recline, deg.
MAX_TRUNK_DEG = 60.0

#: How near the back's recline the trunk's search stops, deg (the built backrest is held to :data:`RECLINE_TOLERANCE_DEG`).
RECLINE_SEARCH_DEG = 0.25

#: Heights above the seat point between which the backrest's recline is measured, m.
RECLINE_BAND = (0.15, 0.40)

#: Half-width of the strip about the seat point's x in which the recline is measured, m.
RECLINE_STRIP = 0.08

#: Height of the bins whose frontmost surface (rearmost skin) points make the recline's line, m.
RECLINE_BIN = 0.025


def seat_point(body) -> np.ndarray:
    """The body's seat point: below the lowest pelvis (``Hips``) skin, at the mean x and z of the skin within :data:`SEAT_BAND` of it.

    Sitting, that is the skin under the ischial tuberosities; its height is
    the seat height the designed surface carries the body at.
    """
    from seatkit.template.grid import segment_of_vertex

    v = np.asarray(body.vertices, dtype=np.float64)
    hips = v[segment_of_vertex(body) == SEGMENT_INDEX["Hips"]]
    if len(hips) == 0:
        hips = v
    low = float(hips[:, 1].min())
    band = hips[hips[:, 1] <= low + SEAT_BAND]
    return np.array([band[:, 0].mean(), low, band[:, 2].mean()])


def seat_axis(body) -> tuple[np.ndarray, np.ndarray]:
    """(s, back): the seat's direction and the back of the buttocks, what a seat depth is measured along and from.

    ``s`` is the unit direction of the thighs (the mean of the two hip-to-knee
    joint lines) in the side view (its x dropped): along the seat, from back
    to front. ``back`` is the body's rearmost pelvis (``Hips``) skin along
    ``s``: the back of the buttocks, where the sitter meets the backrest
    (the point the buttock-popliteal length is measured from).
    """
    from seatkit.template.grid import segment_of_vertex

    j = np.asarray(body.joints, dtype=np.float64)
    thigh = 0.5 * (j[SEGMENT_INDEX["RightLeg"]] + j[SEGMENT_INDEX["LeftLeg"]]) - 0.5 * (j[SEGMENT_INDEX["RightUpLeg"]] + j[SEGMENT_INDEX["LeftUpLeg"]])
    s = np.array([0.0, thigh[1], thigh[2]])
    s = s / max(float(np.linalg.norm(s)), 1e-12)
    v = np.asarray(body.vertices, dtype=np.float64)
    hips = v[segment_of_vertex(body) == SEGMENT_INDEX["Hips"]]
    if len(hips) == 0:
        hips = v
    return s, hips[int(np.argmin(hips @ s))]


def recline_of(points: np.ndarray, seat: np.ndarray, *, skin: bool) -> float | None:
    """The recline of a backrest (or of a back), degrees from vertical, positive with its top behind its bottom; None when it cannot be measured.

    In the strip :data:`RECLINE_STRIP` either side of the seat point's x,
    behind the seat point, between :data:`RECLINE_BAND` above it, each
    :data:`RECLINE_BIN` of height gives one point: the frontmost of
    ``points`` (a surface: the backrest's face the sitter leans on) or,
    with ``skin``, the rearmost (a body: the back that leans on it). The
    recline is the angle from vertical of their least-squares line in the
    side view (z against y). Fewer than four bins: None.
    """
    p = np.asarray(points, dtype=np.float64)
    h = p[:, 1] - seat[1]
    keep = (np.abs(p[:, 0] - seat[0]) <= RECLINE_STRIP) & (p[:, 2] < seat[2]) & (h >= RECLINE_BAND[0]) & (h <= RECLINE_BAND[1])
    p, h = p[keep], h[keep]
    ys, zs = [], []
    for lo in np.arange(RECLINE_BAND[0], RECLINE_BAND[1] - 1e-9, RECLINE_BIN):
        inside = (h >= lo) & (h < lo + RECLINE_BIN)
        if inside.any():
            q = p[inside]
            k = int(np.argmin(q[:, 2])) if skin else int(np.argmax(q[:, 2]))
            ys.append(q[k, 1])
            zs.append(q[k, 2])
    if len(ys) < 4:
        return None
    slope = np.polyfit(np.asarray(ys), np.asarray(zs), 1)[0]  # dz/dy
    return float(np.degrees(np.arctan(-slope)))


def reclined_pose(pose, degrees: float):
    """``pose`` with the trunk reclined ``degrees`` further back about the pelvis's own lateral axis and the thighs kept where they were (their rotations take the difference), as the web app's trunk-recline slider does."""
    from dataclasses import replace

    from scipy.spatial.transform import Rotation

    tilt = Rotation.from_rotvec([-np.radians(degrees), 0.0, 0.0])  # about the pelvis's x (its right-to-left axis): back
    rot = np.array(pose.rotations, dtype=np.float64)
    rot[0] = (Rotation.from_rotvec(rot[0]) * tilt).as_rotvec()
    for thigh in ("RightUpLeg", "LeftUpLeg"):
        k = SEGMENT_INDEX[thigh]
        rot[k] = (tilt.inv() * Rotation.from_rotvec(rot[k])).as_rotvec()
    return replace(pose, rotations=rot)


def back_recline(body) -> float | None:
    """The recline of ``body``'s back (:func:`recline_of` on its skin), degrees; None when it cannot be measured."""
    return recline_of(np.asarray(body.vertices), seat_point(body), skin=True)


def recline_to(pose_body, pose, target: float, *, where: str = "template_params.steps.seat.recline"):
    """``pose`` with the trunk reclined so that the back's recline (:func:`back_recline` of ``pose_body(pose)``) is ``target`` degrees, and that body.

    A secant search on the trunk's angle (:func:`reclined_pose`); the back's
    line turns about as the trunk does.

    Raises
    ------
    RecipeError
        The back cannot be measured (lying, or no back above the seat
        point), or no trunk angle within 60 deg of the pose's gives it.
    """
    body = pose_body(pose)
    r0 = back_recline(body)
    j = np.asarray(body.joints, dtype=np.float64)
    trunk = np.asarray(body.tips, dtype=np.float64)[SEGMENT_INDEX["Spine3"]] - j[SEGMENT_INDEX["Hips"]]
    if r0 is None or trunk[1] < np.cos(np.radians(MAX_TRUNK_DEG)) * np.linalg.norm(trunk):
        raise RecipeError(f"{where}: this pose has no back above the seat to recline (lying, or leaning forward); leave the recline out")
    d0, f0 = 0.0, r0 - target
    best = (abs(f0), 0.0, body)
    d1 = -f0
    for _ in range(10):
        if abs(f0) <= RECLINE_SEARCH_DEG or abs(d1) > 60.0:
            break
        body = pose_body(reclined_pose(pose, d1))
        r1 = back_recline(body)
        if r1 is None:
            d1 = 0.5 * (d0 + d1)  # no back there (turned past lying): a smaller step
            continue
        f1 = r1 - target
        best = min(best, (abs(f1), d1, body), key=lambda b: b[0])
        if f1 == f0:
            break
        d0, f0, d1 = d1, f1, d1 - f1 * (d1 - d0) / (f1 - f0)
    if best[0] <= 2 * RECLINE_SEARCH_DEG:
        return reclined_pose(pose, best[1]), best[2]
    raise RecipeError(f"{where}: no recline of this pose's trunk gives a back at {target:g} deg (it is at {r0:.1f} deg as posed); allowed: -10 to 50 deg, near the pose's own")


def seat_bodies(bodies: Sequence, height: float | None, *, where: str = "template_params.steps.seat.height") -> list:
    """``bodies`` lifted so that each one's seat point is ``height`` above the floor (as they are for None).

    Raises
    ------
    RecipeError
        The height is lower than the pose allows: the lowest point of a body
        would be below the floor.
    """
    if height is None:
        return list(bodies)
    out = []
    for i, body in enumerate(bodies):
        seat = float(seat_point(body)[1])
        lift = float(height) - seat
        lowest = float(np.asarray(body.vertices)[:, 1].min())
        if lowest + lift < -FLOOR_TOLERANCE:
            who = f"person {i + 1} ({body.name})" if len(bodies) > 1 else f"{body.name}"
            least = seat - lowest
            msg = (
                f"{where}: {height:g} m puts {who}'s feet {1000 * -(lowest + lift):.0f} mm below the floor; "
                f"in this pose the seat is at least {least:.3f} m high (bend the knees more, or choose a shorter body, for a lower seat)"
            )
            raise RecipeError(msg)
        out.append(body.translated([0.0, lift, 0.0]) if lift != 0.0 else body)
    return out


class SeatStep:
    """The seat's height above the floor (applied when the bodies are placed; see the module doc)."""

    name = "seat"
    description = "a designer's dimensions: the seat height (the body and its design lifted, the feet on a footrest), the backrest height, the seat depth (the front edge moved back along the thighs) and the backrest recline (the trunk reclined about the hips); a value this body in this pose cannot take is refused"
    stage = "grid"  # records only; listed last, so that no other step's index moves
    requires = ()
    options = {
        "height": Option(
            "number",
            "seat height: the seat surface under the ischia (the lowest pelvis skin) above the floor; default: as the pose has it, the feet on the floor. Higher lifts the body (the foot faces become a footrest); lower than the pose allows is refused",
            None,
            "m",
            0.0,
            1.5,
        ),
        "backrest_height": Option(
            "number",
            "backrest height: the top of the designed surface behind the seat, above the seat point; default: where the fit ends the last row (the upper back). Set, the last row's top edge and the border above it move along the row's plane and the refiners keep them",
            None,
            "m",
            0.1,
            1.5,
        ),
        "recline": Option(
            "number",
            "backrest recline: its angle behind vertical, in the side view: the least-squares line through the backrest's surface 15-40 cm above the seat point, in the middle 16 cm; default: as the pose has it. Set, the sitter's trunk reclines about the hips, the thighs kept (as the web app's trunk-recline slider), until the built backrest meets it within 2 deg; a pose without a backrest, or one whose built backrest cannot meet it, is refused",
            None,
            "deg",
            -10.0,
            50.0,
        ),
        "depth": Option(
            "number",
            "seat depth: along the seat (the thighs' direction, side view), from the back of the buttocks (where the sitter meets the backrest) to the seat's front edge (the crest of its rounded front); default: where the fit ends it, at the back of the knee. Set shorter, the front edge moves back and clears the knee (ANSI/HFES 100: below the buttock-popliteal length) and the thigh ahead of it is not carried; deeper than the knee allows, or too short to carry the thighs' roots, is refused",
            None,
            "m",
            0.1,
            1.0,
        ),
    }

    def run(self, state, *, options: Mapping[str, Any]) -> None:
        seats = []
        for block in state.blocks:
            p = seat_point(block.body)
            seats.append({"person": block.person, "seat_height_m": round(float(p[1]), 4), "set": options.get("height") is not None})
        state.meta["seat"] = seats
        if options.get("backrest_height") is not None:
            state.meta["backrest"] = set_backrest_height(state, float(options["backrest_height"]))
        edge = front_edge(state)
        if edge is not None:
            state.meta["seat_front_edge"] = edge


def seat_height_of(bodies) -> tuple[float, float]:
    """(height, z) of the highest seat point of ``bodies``: what the backrest's height is measured from, and the plane behind which the backrest is."""
    points = [seat_point(b) for b in bodies]
    top = max(points, key=lambda p: p[1])
    return float(top[1]), float(max(p[2] for p in points))


def backrest_top(vertices: np.ndarray, behind_z: float) -> float:
    """The highest of ``vertices`` (a limit surface's) behind ``behind_z`` (z below it: the backrest side), m; nan if none."""
    v = np.asarray(vertices)
    back = v[v[:, 2] < behind_z]
    return float(back[:, 1].max()) if len(back) else float("nan")


def set_backrest_height(state, height: float, *, where: str = "template_params.steps.seat.backrest_height") -> dict:
    """Move the top edge of the grid's last row (the backrest's) and the border ring beyond it along the row's plane, so that the limit surface's top is ``height`` above the seat; keep them for the refiners (``grid.fixed``).

    The rows of vertices that make the top of the limit surface (the last
    row's lower and upper edges, the border ring above) are marked fixed, so
    that the refiners do not move the top; the pipeline measures the built
    design's top again (:func:`check_design`).

    Raises
    ------
    RecipeError
        The design has no backrest (the template's last row was dropped:
        leaning forward), or the height is lower than the last row allows.
    """
    from seatkit.subdivision import Cage, build_operators
    from seatkit.template.grid import grid_quads

    grid = state.grid
    kept = state.blocks[0].rows
    if not kept or kept[-1] != len(state.spec.rows) - 1 or grid.vertices.shape[0] < 5:
        raise RecipeError(f"{where}: this design has no backrest (the body leans forward and does not rest its back); leave the backrest height out")
    seat_y, seat_z = seat_height_of([b.body for b in state.blocks])
    target = seat_y + height
    V = np.array(grid.vertices, dtype=np.float64)
    below, top, ring = V.shape[0] - 4, V.shape[0] - 3, V.shape[0] - 2
    move = np.zeros(V.shape[:2], bool)
    move[[top, ring]] = True
    move &= ~grid.ground
    direction = V[top] - V[below]
    length = np.linalg.norm(direction, axis=1)
    direction = direction / np.maximum(length, 1e-12)[:, None]
    quads = grid_quads(grid.shape)
    ops = build_operators(Cage(V.reshape(-1, 3), quads), 3)

    def moved(t: float) -> np.ndarray:
        W = V.copy()
        for r in (top, ring):
            W[r, move[r]] += t * direction[move[r]]
        return W

    def top_of(t: float) -> float:
        return backrest_top(ops.limit_points(moved(t).reshape(-1, 3)), seat_z)

    shortest = float(length[move[top]].min())
    t_min = MIN_TOP_ROW - shortest  # the last row no shorter than MIN_TOP_ROW along its plane
    lowest = top_of(t_min)
    if target < lowest - 1e-4:
        raise RecipeError(f"{where}: {height:g} m is lower than this backrest's last row allows; the backrest is at least {lowest - seat_y:.3f} m above the seat in this pose")
    # the top rises monotonically with t: a secant search from the template's own top
    t0, f0 = 0.0, top_of(0.0) - target
    t1 = max(t_min, -f0 / max(float(direction[move[top], 1].max()), 0.1))
    f1 = top_of(t1) - target
    for _ in range(12):
        if abs(f1) < 1e-4 or f1 == f0:
            break
        t0, f0, t1 = t1, f1, max(t_min, t1 - f1 * (t1 - t0) / (f1 - f0))
        f1 = top_of(t1) - target
    if abs(f1) > 1e-3:
        raise RecipeError(f"{where}: the backrest's top cannot be put {height:g} m above the seat in this pose (it reaches {f1 + target - seat_y:.3f} m)")
    grid.vertices = moved(t1)
    fixed = np.zeros(V.shape[:2], bool) if grid.fixed is None else np.array(grid.fixed, bool)
    fixed[[below, top, ring]] = True
    grid.fixed = fixed & ~grid.ground
    return {"height_m": height, "seat_height_m": round(seat_y, 4), "moved_m": round(float(t1), 4)}


def _thigh_row(spec) -> int | None:
    """The template row whose faces fit the thighs (UpLeg), or None."""
    thighs = {SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]}
    for (r, _c), face in sorted(spec.faces.items()):
        if face.role == "fit" and thighs & set(face.segments):
            return int(r)
    return None


def front_edge(state) -> dict | None:
    """The seat's front edge in the grid: the thigh row's boundary towards the feet, its inner vertices (flat indices) and whose seat each is; None when the design has no thigh row.

    The row boundary is the cage's knee line (the chair's thigh faces meet
    the shank faces there); its limit points are the crest of the seat's
    rounded front (:func:`seat_depth_of`).
    """
    grid = state.grid
    row = _thigh_row(state.spec)
    kept = state.blocks[0].rows
    if grid is None or row is None or row not in kept:
        return None
    R, C = grid.shape
    b = kept.index(row) + 2  # two border rings before the first kept row
    vertices, people = [], []
    for k in range(2, C - 1):  # the inner vertices of the row (not the border's two rings either side)
        faces = [grid.person[b, c] for c in (k - 1, k) if 0 <= c < C]
        person = next((int(p) for p in faces if p >= 0), -1)
        if person < 0:
            continue
        vertices.append(int(b * (C + 1) + k))
        people.append(person)
    return {"row": int(b), "columns": int(C + 1), "vertices": vertices, "person": people}


def seat_depth_of(mesh, bodies) -> list[float]:
    """The seat depth of a built design, per person: along :func:`seat_axis` from the back of the buttocks to the frontmost point of the seat's front edge (the limit surface over the cage's front-edge vertices, ``meta["seat_front_edge"]``), m; nan for a person without one."""
    from seatkit.subdivision import limit_surface

    edge = (mesh.meta or {}).get("seat_front_edge")
    out = [float("nan")] * len(bodies)
    if not edge:
        return out
    points = limit_surface(mesh, level=0).vertices
    for i, body in enumerate(bodies):
        s, back = seat_axis(body)
        idx = [v for v, p in zip(edge["vertices"], edge["person"]) if p == i]
        if idx:
            out[i] = float(((points[idx] - back) @ s).max())
    return out


def depth_range(body) -> tuple[float, float]:
    """(least, most) seat depth for ``body`` in its pose, m: :data:`MIN_DEPTH_AHEAD` beyond the seat point (the ischia), and the nearer knee joint (a front edge beyond it would cut the shin), both along :func:`seat_axis` from the back of the buttocks."""
    s, back = seat_axis(body)
    j = np.asarray(body.joints, dtype=np.float64)
    knees = [float((j[SEGMENT_INDEX[k]] - back) @ s) for k in ("RightLeg", "LeftLeg")]
    return float((seat_point(body) - back) @ s) + MIN_DEPTH_AHEAD, min(knees)


def seat_contact(bodies: Sequence, depth: float | None, *, where: str = "template_params.steps.seat.depth") -> list:
    """Per body, the vertices a seat of ``depth`` may carry (None: every vertex): all but the thigh skin ahead of its front edge.

    A shorter seat leaves the distal thigh unsupported, so its skin leaves the
    importance map (the pressure is solved without it): neither the template,
    the refiners nor the flat patch it is compared with are guided by a load
    the seat does not carry. So does the shank skin ahead of the front edge
    within :data:`KNEE_CLEARANCE` of the knee joint (the back of the knee and
    the top of the calf, which the front edge clears).

    Raises
    ------
    RecipeError
        The depth is outside :func:`depth_range` for a body: too short to
        carry the thighs' roots, or past the back of the knee.
    """
    from seatkit.template.grid import segment_of_vertex

    if depth is None:
        return [None] * len(bodies)
    thighs = [SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]]
    out = []
    for i, body in enumerate(bodies):
        least, most = depth_range(body)
        if not least - 1e-9 <= depth <= most + 1e-9:
            who = f"person {i + 1} ({body.name})" if len(bodies) > 1 else f"{body.name}"
            why = f"does not carry {who}'s thighs" if depth < least else f"reaches past the back of {who}'s knee (the seat's front would cut the shin)"
            raise RecipeError(f"{where}: {depth:g} m {why}; in this pose the seat depth is from {least:.3f} to {most:.3f} m")
        s, back = seat_axis(body)
        v = np.asarray(body.vertices, dtype=np.float64)
        segment = segment_of_vertex(body)
        beyond = (v - back) @ s > depth
        ahead = np.isin(segment, thighs) & beyond
        j = np.asarray(body.joints, dtype=np.float64)
        for shank in ("RightLeg", "LeftLeg"):  # the back of the knee and the top of the calf, which the front edge clears
            k = SEGMENT_INDEX[shank]
            ahead |= (segment == k) & beyond & (np.linalg.norm(v - j[k], axis=1) < KNEE_CLEARANCE)
        out.append(~ahead)
    return out


def place_front_edge(V: np.ndarray, ground: np.ndarray, edge: dict, axes: Sequence, depth: float, *, limit=None) -> tuple[np.ndarray, float]:
    """``V`` (a grid's (R+1, C+1, 3) vertices) with its front-edge row moved along the seat so that each inner front-edge vertex's limit point is ``depth`` from the back of its person's buttocks (a straight front edge); and the largest miss, m.

    Each inner vertex of the row moves along its person's seat axis
    (:func:`seat_axis`: back for a shorter seat, forward for a deeper one, at
    most :data:`MAX_DEEPER`; the row stays :data:`MIN_THIGH_ROW` ahead of the
    row behind it), the border's vertices with the nearest inner one, so the
    surface's heights under the thighs stay. The limit points are linear in
    the vertices: a fixed-point iteration on them.
    """
    from seatkit.subdivision import Cage, build_operators
    from seatkit.template.grid import grid_quads

    V = np.asarray(V, dtype=np.float64)
    C = V.shape[1] - 1
    b = edge["row"]
    free = ~np.asarray(ground[b], bool)
    cols = np.array([v - b * (C + 1) for v in edge["vertices"]])
    nearest = np.array([cols[int(np.argmin(np.abs(cols - k)))] for k in range(C + 1)])
    s_of = {c: axes[p][0] for c, p in zip(cols, edge["person"])}
    direction = np.array([-s_of[int(k)] for k in nearest])  # back along the seat
    room = np.maximum(np.einsum("ij,ij->i", V[b] - V[b + 1], -direction) - MIN_THIGH_ROW, 0.0)  # the row behind stays behind
    if limit is None:
        limit = build_operators(Cage(V.reshape(-1, 3), grid_quads((V.shape[0] - 1, C))), 0).limit
    s = np.array([axes[p][0] for p in edge["person"]])
    back = np.array([axes[p][1] for p in edge["person"]])
    rows = limit[edge["vertices"]]

    def moved(t):
        W = V.copy()
        W[b] += (t[nearest] * free)[:, None] * direction  # the border's vertices as their nearest inner one
        return W

    def depths(t):
        return np.einsum("ij,ij->i", rows @ moved(t).reshape(-1, 3) - back, s)

    t = np.zeros(C + 1)
    for _ in range(80):
        miss = depths(t) - depth
        if np.abs(miss).max() <= 1e-4:
            break
        t[cols] = np.clip(t[cols] + 1.5 * miss, -MAX_DEEPER, room[cols])  # the limit point follows about 2/3 of its row's move
    return moved(t), float(np.abs(depths(t) - depth).max())


def seat_depth_of_grid(V: np.ndarray, edge: dict, axes: Sequence) -> float:
    """The deepest front-edge point of a grid's vertices (``(R+1, C+1, 3)``) along its person's seat axis, m."""
    from seatkit.subdivision import Cage, build_operators
    from seatkit.template.grid import grid_quads

    C = V.shape[1] - 1
    points = build_operators(Cage(V.reshape(-1, 3), grid_quads((V.shape[0] - 1, C))), 0).limit_points(V.reshape(-1, 3))[edge["vertices"]]
    return float(max((p - axes[i][1]) @ axes[i][0] for p, i in zip(points, edge["person"])))


def surface_below(surface_vertices: np.ndarray, surface_faces: np.ndarray, point: np.ndarray, *, reach: float) -> float | None:
    """Height of the highest point of a (quad or triangle) surface on the vertical through ``point``, at most ``reach`` below it (or 5 cm above it); None if there is none."""
    v = np.asarray(surface_vertices, dtype=np.float64)
    f = np.asarray(surface_faces)
    tris = v[np.vstack([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])] if f.shape[1] == 4 else v[f]
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    x, z = float(point[0]), float(point[2])
    det = (b[:, 0] - a[:, 0]) * (c[:, 2] - a[:, 2]) - (c[:, 0] - a[:, 0]) * (b[:, 2] - a[:, 2])
    ok = np.abs(det) > 1e-14
    det = np.where(ok, det, 1.0)
    u = ((x - a[:, 0]) * (c[:, 2] - a[:, 2]) - (c[:, 0] - a[:, 0]) * (z - a[:, 2])) / det
    w = ((b[:, 0] - a[:, 0]) * (z - a[:, 2]) - (x - a[:, 0]) * (b[:, 2] - a[:, 2])) / det
    hit = ok & (u >= 0) & (w >= 0) & (u + w <= 1)
    y = (a[:, 1] + u * (b[:, 1] - a[:, 1]) + w * (c[:, 1] - a[:, 1]))[hit]
    y = y[(y < point[1] + 0.05) & (y >= point[1] - reach)]
    return float(y.max()) if len(y) else None


def _seat_options(recipe: Mapping, registry) -> dict | None:
    template = registry.get("template", recipe["template"])
    return template.step_options("seat", recipe.get("template_params")) if hasattr(template, "step_options") else None


def seat_design(recipe: Mapping, registry, bodies: Sequence, initial, mesh, *, depths, limit: float = 0.005) -> tuple[list, Any, Any, float]:
    """The design moved up or down so that its seat surface under the seat point is at the height set (as it is when none is set).

    The bodies were lifted so that their seat point is at the height
    (:func:`seat_bodies`); the surface carries the body there within a
    few millimetres, more where the lowest pelvis skin is not where the
    seat carries it (crossed legs: one buttock higher). That gap is the
    design's own, so the design (bodies and cage, the ground ring left on
    the floor) is moved by it, and the surface's depths are measured again.

    ``depths(mesh, bodies, level)`` gives the surface's two depths
    (``surface_in_body``, ``body_in_surface``, m): the surface fit's
    :func:`seatkit.refine.ccfit.final_depths`, passed in by the pipeline.

    Returns
    -------
    bodies, initial, mesh, moved
        ``moved`` in metres (0.0 when nothing was set or moved).

    Raises
    ------
    RecipeError
        The design does not carry the pelvis (no surface within
        :data:`SEAT_REACH` below the seat point: a standing or leaning pose),
        or the moved design reaches deeper than ``limit`` into a body.
    """
    from seatkit.subdivision import limit_surface

    options = _seat_options(recipe, registry)
    level = int(recipe.get("surface_level", 3))
    if not options or options.get("height") is None:
        return list(bodies), initial, mesh, 0.0
    height = float(options["height"])
    surface = limit_surface(mesh, level=level)
    point = seat_point(max(bodies, key=lambda b: seat_point(b)[1]))
    under = surface_below(surface.vertices, surface.faces, point, reach=SEAT_REACH)
    if under is None:
        raise RecipeError(
            f"template_params.steps.seat.height: this design does not carry the pelvis (no seat within {SEAT_REACH * 100:.0f} cm under it: a standing or leaning pose); leave the seat height out"
        )
    moved = height - under
    if abs(moved) < 1e-6:
        return list(bodies), initial, mesh, 0.0
    if float(min(np.asarray(b.vertices)[:, 1].min() for b in bodies)) + moved < -FLOOR_TOLERANCE:
        raise RecipeError(f"template_params.steps.seat.height: {height:g} m puts the feet below the floor once the seat carries the body; in this pose the seat is at least {height - moved - float(min(np.asarray(b.vertices)[:, 1].min() for b in bodies)):.3f} m high")
    before = max(depths(mesh, bodies, level).values())
    bodies = [b.translated([0.0, moved, 0.0]) for b in bodies]
    initial, mesh = _lifted_cage(initial, moved), _lifted_cage(mesh, moved)
    after = depths(mesh, bodies, level)
    if max(after.values()) > max(limit, before + 0.0005):  # only the base's walls change: no deeper than before, or than the limit
        raise RecipeError(f"template_params.steps.seat.height: at {height:g} m the design's base reaches {1000 * max(after.values()):.1f} mm into the body (above the {1000 * limit:.0f} mm limit); try another height")
    return bodies, initial, mesh, moved


def refined_seat(recipe: Mapping, registry, mesh, bodies, refit=None, *, where: str = "template_params.steps.seat.depth"):
    """A refined cage with the seat depth the ``seat`` step sets (``mesh`` itself when none is set).

    The front edge of the refined cage is put at the depth
    (:func:`place_front_edge`) and kept there (its row ``fixed``); ``refit``
    (the recipe's last refiner, the surface fit) then fits the surface
    around it. The refit's moves of the front edge's neighbours shift it by
    millimetres, so it is put at the depth and fitted around once more
    (:data:`REFITS`); the shift left is checked after the surface is made
    (:func:`check_design`). Called on every
    candidate of the design search, so the search's acceptance check (the
    5 mm limits) judges the cage with its front edge where it was put.

    Raises
    ------
    RecipeError
        The design has no thigh row, or the front edge cannot be put at the
        depth (the row behind it is in the way).
    """
    from dataclasses import replace

    options = _seat_options(recipe, registry)
    if not options or options.get("depth") is None:
        return mesh
    depth = float(options["depth"])
    edge = (mesh.meta or {}).get("seat_front_edge")
    if not edge:
        raise RecipeError(f"{where}: this design has no seat under the thighs (no thigh row); leave the seat depth out")
    axes = [seat_axis(b) for b in bodies]
    C1 = int(edge["columns"])
    ground = np.asarray(mesh.ground, bool).reshape(-1, C1)
    for _ in range(REFITS if refit is not None else 1):
        V = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, C1, 3)
        W, miss = place_front_edge(V, ground, edge, axes, depth)
        if miss > 1e-3:
            least, most = depth_range(bodies[0])
            raise RecipeError(f"{where}: this seat's front edge cannot be put {depth:g} m from the back of the buttocks (it stays {miss * 1000:.0f} mm from there); in this pose the seat depth is from {least:.3f} to {most:.3f} m")
        fixed = np.zeros(ground.shape, bool) if mesh.fixed is None else np.array(mesh.fixed, bool).reshape(ground.shape)
        fixed[edge["row"]] = True
        mesh = replace(mesh, vertices=W.reshape(-1, 3), fixed=(fixed & ~ground).ravel())
        if refit is not None:
            mesh = refit(mesh)
    return mesh


def _lifted_cage(mesh, dy: float):
    """``mesh`` with every vertex but the ground ring moved up by ``dy``."""
    from dataclasses import replace

    v = np.array(mesh.vertices, dtype=np.float64)
    v[~np.asarray(mesh.ground, bool), 1] += dy
    return replace(mesh, vertices=v)


def built_recline(surface, bodies) -> float | None:
    """The recline of a built design's backrest (:func:`recline_of` on its surface, from the highest person's seat point), degrees; None when it has none there."""
    point = max((seat_point(b) for b in bodies), key=lambda p: p[1])
    return recline_of(np.asarray(surface.vertices), point, skin=False)


def recline_miss(recipe: Mapping, registry, bodies, surface, *, where: str = "template_params.steps.seat.recline") -> tuple[float, float] | None:
    """The built backrest's recline (:func:`built_recline`) and the ``seat`` step's ``recline``, degrees (None when none is set).

    Raises
    ------
    RecipeError
        The built design has no backrest where the recline is measured.
    """
    options = _seat_options(recipe, registry)
    if not options or options.get("recline") is None:
        return None
    got = built_recline(surface, bodies)
    if got is None:
        raise RecipeError(f"{where}: this design has no backrest 15-40 cm above the seat (the body leans forward, or lies); leave the recline out")
    return got, float(options["recline"])


def check_design(recipe: Mapping, registry, bodies, surface, mesh=None) -> None:
    """Refuse a built design whose seat depth or backrest top is not where the ``seat`` step's ``depth`` and ``backrest_height`` put them (a refiner or a repair moved them), within :data:`DEPTH_TOLERANCE` and :data:`BACKREST_TOLERANCE`."""
    options = _seat_options(recipe, registry)
    if not options:
        return
    if options.get("depth") is not None and mesh is not None:
        want = float(options["depth"])
        got = seat_depth_of(mesh, bodies)
        far = max((g for g in got if np.isfinite(g)), key=lambda g: abs(g - want), default=float("nan"))
        if not abs(far - want) <= DEPTH_TOLERANCE:
            least, most = depth_range(bodies[0])
            raise RecipeError(f"template_params.steps.seat.depth: the design's seat is {far:.3f} m deep, not {want:g} m (fitting the surface around its front edge moved it more than {1000 * DEPTH_TOLERANCE:.0f} mm); in this pose the seat depth is from {least:.3f} to {most:.3f} m, try another")
    if options.get("backrest_height") is None:
        return
    seat_y, seat_z = seat_height_of(bodies)
    got = backrest_top(surface.vertices, seat_z) - seat_y
    want = float(options["backrest_height"])
    if not abs(got - want) <= BACKREST_TOLERANCE:
        raise RecipeError(f"template_params.steps.seat.backrest_height: the design's backrest ends {got:.3f} m above the seat, not {want:g} m (the cage was repaired around the body there); try another height")
