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

__all__ = ["SeatStep", "seat_point", "seat_bodies", "SEAT_BAND", "FLOOR_TOLERANCE"]

#: Pelvis skin within this of its lowest point makes up the seat point (its mean x and z), m.
SEAT_BAND = 0.01

#: How far below the floor the lowest point of a lowered body may go before it is refused, m.
FLOOR_TOLERANCE = 0.001


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
