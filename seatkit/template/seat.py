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
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from seatkit.errors import RecipeError
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.options import Option

__all__ = ["SeatStep", "seat_point", "seat_bodies", "seat_design", "set_backrest_height", "check_design", "surface_below", "SEAT_BAND", "FLOOR_TOLERANCE", "BACKREST_TOLERANCE"]

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
    description = "the seat height a designer sets: the body and its design lifted so that the seat is that high, the feet on a footrest (lower than the pose allows is refused)"
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
    }

    def run(self, state, *, options: Mapping[str, Any]) -> None:
        seats = []
        for block in state.blocks:
            p = seat_point(block.body)
            seats.append({"person": block.person, "seat_height_m": round(float(p[1]), 4), "set": options.get("height") is not None})
        state.meta["seat"] = seats
        if options.get("backrest_height") is not None:
            state.meta["backrest"] = set_backrest_height(state, float(options["backrest_height"]))


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
    if not options or options.get("height") is None:
        return list(bodies), initial, mesh, 0.0
    height = float(options["height"])
    level = int(recipe.get("surface_level", 3))
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


def _lifted_cage(mesh, dy: float):
    """``mesh`` with every vertex but the ground ring moved up by ``dy``."""
    from dataclasses import replace

    v = np.array(mesh.vertices, dtype=np.float64)
    v[~np.asarray(mesh.ground, bool), 1] += dy
    return replace(mesh, vertices=v)


def check_design(recipe: Mapping, registry, bodies, surface) -> None:
    """Refuse a built design whose backrest's top is not where the ``seat`` step's ``backrest_height`` put it (a repair moved it), within :data:`BACKREST_TOLERANCE`."""
    options = _seat_options(recipe, registry)
    if not options or options.get("backrest_height") is None:
        return
    seat_y, seat_z = seat_height_of(bodies)
    got = backrest_top(surface.vertices, seat_z) - seat_y
    want = float(options["backrest_height"])
    if not abs(got - want) <= BACKREST_TOLERANCE:
        raise RecipeError(f"template_params.steps.seat.backrest_height: the design's backrest ends {got:.3f} m above the seat, not {want:g} m (the cage was repaired around the body there); try another height")
