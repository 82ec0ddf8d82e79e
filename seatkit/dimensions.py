"""The main dimensions of a seat where it carries the person, from the evaluation's contact pressure.

A furniture designer compares chairs by a few numbers: how high the seat is,
how deep and wide, how high the back reaches. They are read off the body
vertices the final surface actually carries (the evaluation's recomputed
contact pressure above 1 Pa, :mod:`seatkit.evaluate`), grouped by the
segment whose skinning weight is largest (metres, +Y up, the person faces
+Z, the floor at y = 0):

``seat_height_m``
    The front edge of the seat: the mean height of the loaded thigh (UpLeg)
    vertices within 3 cm of the frontmost one (under the knees).
``seat_depth_m``, ``seat_width_m``
    The front-to-back (z) and side-to-side (x) extent of the loaded hips and
    thighs (Hips, UpLeg).
``back_height_m``
    The top of the loaded back (Spine .. Spine3) above the lowest loaded hips
    or thigh vertex; 0 when the back is not carried.

A person the design does not carry on the seat (no loaded hips or thighs)
gets ``None`` for every figure.

:func:`person_fit` sets these beside the person's own dimensions, measured on
the bare-skin body as ANSUR II measures a person (:mod:`seatkit.body.measure`),
the way ergonomic standards relate them (ANSI/HFES 100-2007, section 8.3.3:
a seat height of popliteal height plus a 25 mm shoe allowance, a seat depth
short of the buttock-popliteal length so that the front edge clears the
back of the knee, a seat at least as wide as the hips):

``popliteal_height_m``, ``shoe_allowance_m``, ``seat_height_for_shoes_m``
    The person's popliteal height, the allowance, and their sum (the seat
    height the standard asks for a person wearing shoes).
``seat_height_difference_m``
    ``seat_height_m - seat_height_for_shoes_m``: negative, the seat front is
    lower than the standard's (the design follows the bare-skin body, whose
    feet stand on the floor the chair stands on).
``buttock_popliteal_length_m``, ``seat_depth_difference_m``
    The person's buttock-popliteal length and ``seat_depth_m`` less it
    (negative: the loaded seat ends before the back of the knee).
``hip_breadth_sitting_m``, ``seat_width_difference_m``
    The person's hip breadth (sitting) and ``seat_width_m`` less it.
``measurements``
    Every measurement of :func:`seatkit.body.measure.measure_rig` (m, kg,
    m^3), so a report names the person the chair is for.
"""

from __future__ import annotations

import numpy as np

from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.grid import segment_of_vertex

__all__ = ["support_dimensions", "person_fit", "LOADED_PA", "SHOE_ALLOWANCE"]

#: Contact pressure above which a body vertex counts as carried, Pa.
LOADED_PA = 1.0
#: Depth of the seat's front edge band, m.
FRONT_BAND = 0.03
#: Shoe allowance added to the popliteal height for a seat height, m (ANSI/HFES 100-2007, 8.3.3.1).
SHOE_ALLOWANCE = 0.025
#: The standard the seat-vs-person figures follow (written into report.json).
FIT_STANDARD = (
    "ANSI/HFES 100-2007 section 8.3.3: seat height = popliteal height + 25 mm shoe allowance; "
    "seat depth short of the buttock-popliteal length; seat width at least the hip breadth, sitting"
)

_THIGHS = [SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]]
_SEAT = [SEGMENT_INDEX["Hips"], *_THIGHS]
_BACK = [SEGMENT_INDEX[s] for s in ("Spine", "Spine1", "Spine2", "Spine3")]
_NONE = {"seat_height_m": None, "seat_depth_m": None, "seat_width_m": None, "back_height_m": None}


def support_dimensions(bodies, fields) -> list[dict]:
    """Seat height, depth, width and back height for each person.

    Parameters
    ----------
    bodies : list of Body
    fields : list of PressureField or None
        The evaluation's contact pressure per person (None: not carried).

    Returns
    -------
    list of dict
        One per person, keys as in the module docstring.
    """
    out = []
    for body, field in zip(bodies, fields):
        if field is None:
            out.append(dict(_NONE))
            continue
        loaded = np.asarray(field.pressure) > LOADED_PA
        segment = segment_of_vertex(body)
        v = body.vertices
        seat = loaded & np.isin(segment, _SEAT)
        thighs = loaded & np.isin(segment, _THIGHS)
        back = loaded & np.isin(segment, _BACK)
        if not seat.any():
            out.append(dict(_NONE))
            continue
        if thighs.any():
            front = thighs & (v[:, 2] > v[thighs, 2].max() - FRONT_BAND)
            height = float(v[front, 1].mean())
        else:
            height = None
        bottom = float(v[seat, 1].min())
        out.append(
            {
                "seat_height_m": height,
                "seat_depth_m": float(np.ptp(v[seat, 2])),
                "seat_width_m": float(np.ptp(v[seat, 0])),
                "back_height_m": float(v[back, 1].max() - bottom) if back.any() else 0.0,
            }
        )
    return out


def _difference(a, b):
    return None if a is None or b is None else float(a - b)


def person_fit(measurements: list, dimensions: list[dict]) -> list[dict]:
    """The seat's dimensions beside each person's (see the module docstring).

    Parameters
    ----------
    measurements : list of Measurements or None
        Per person, :func:`seatkit.body.measure.measure_rig` of the person's
        rig (None: not measured, e.g. a body that cannot be posed upright).
    dimensions : list of dict
        :func:`support_dimensions` of the same people.

    Returns
    -------
    list of dict
        One per person; an unmeasured person gets only the seat's figures.
    """
    out = []
    for m, dims in zip(measurements, dimensions):
        if m is None:
            out.append({"standard": FIT_STANDARD, **dims})
            continue
        pop = float(m.popliteal_height)
        for_shoes = pop + SHOE_ALLOWANCE
        out.append(
            {
                "standard": FIT_STANDARD,
                "seat_height_m": dims.get("seat_height_m"),
                "popliteal_height_m": pop,
                "shoe_allowance_m": SHOE_ALLOWANCE,
                "seat_height_for_shoes_m": for_shoes,
                "seat_height_difference_m": _difference(dims.get("seat_height_m"), for_shoes),
                "seat_depth_m": dims.get("seat_depth_m"),
                "buttock_popliteal_length_m": float(m.buttock_popliteal_length),
                "seat_depth_difference_m": _difference(dims.get("seat_depth_m"), m.buttock_popliteal_length),
                "seat_width_m": dims.get("seat_width_m"),
                "hip_breadth_sitting_m": float(m.hip_breadth_sitting),
                "seat_width_difference_m": _difference(dims.get("seat_width_m"), m.hip_breadth_sitting),
                "measurements": {k: float(v) for k, v in m.as_dict().items()},
            }
        )
    return out
