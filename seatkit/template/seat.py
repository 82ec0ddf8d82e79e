"""The seat's height: a designer's dimension, declared as the ``seat`` step's option.

The method fits the furniture to the body in its pose, so the seat is where
the body's buttocks are: with the feet on the floor (the body is grounded,
its lowest point at y = 0), the seat height follows from the pose and the
body's legs. A designer who wants another seat height sets the ``seat``
step's ``height`` (``template_params: {steps: {seat: {height: 0.55}}}``):

- **the seat height** is the height above the floor of the body's *seat
  point*, the lowest skin of the pelvis (under the ischial tuberosities when
  sitting; :func:`seat_point`). The designed surface carries the body there,
  within the 5 mm the design is held to, so this is the height of the seat
  surface under the ischia;
- **set higher** than the pose gives, the body and its design are lifted
  and the floor stays at y = 0: the feet leave the floor and the template's
  foot faces become a footrest on the furniture (the importance map, the
  pressure "supported everywhere", does not change with a vertical move);
- **set lower**, the feet would go through the floor: refused with one line
  naming the option, how far below the floor the lowest point would be and
  the lowest seat height this body in this pose allows (bend the knees or
  choose a shorter body to lower the seat).

The lift is applied when the bodies are placed, before the pressure
(:func:`seat_bodies`, called by :func:`seatkit.stages.place_bodies`), so every
later stage, the evaluation and the files see the lifted body; the step's
own ``run`` records the seat height of each person in the template's
``meta`` (report.json ``control_mesh.meta.seat``).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from seatkit.errors import RecipeError
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.options import Option

__all__ = ["SeatStep", "seat_point", "seat_bodies", "set_backrest_height", "check_design", "SEAT_BAND", "FLOOR_TOLERANCE", "BACKREST_TOLERANCE"]

#: Pelvis skin within this of its lowest point makes up the seat point (its mean x and z), m.
SEAT_BAND = 0.01

#: How far below the floor the lowest point of a lowered body may go before it is refused, m.
FLOOR_TOLERANCE = 0.001

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
    from seatkit.template.steps import grid_quads

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


def check_design(recipe: Mapping, registry, bodies, surface) -> None:
    """Refuse a built design whose backrest's top is not where the ``seat`` step's ``backrest_height`` put it (a repair moved it), within :data:`BACKREST_TOLERANCE`."""
    template = registry.get("template", recipe["template"])
    options = template.step_options("seat", recipe.get("template_params")) if hasattr(template, "step_options") else None
    if not options or options.get("backrest_height") is None:
        return
    seat_y, seat_z = seat_height_of(bodies)
    got = backrest_top(surface.vertices, seat_z) - seat_y
    want = float(options["backrest_height"])
    if not abs(got - want) <= BACKREST_TOLERANCE:
        raise RecipeError(f"template_params.steps.seat.backrest_height: the design's backrest ends {got:.3f} m above the seat, not {want:g} m (the cage was repaired around the body there); try another height")
