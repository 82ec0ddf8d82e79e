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
"""

from __future__ import annotations

import numpy as np

from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.grid import segment_of_vertex

__all__ = ["support_dimensions", "LOADED_PA"]

#: Contact pressure above which a body vertex counts as carried, Pa.
LOADED_PA = 1.0
#: Depth of the seat's front edge band, m.
FRONT_BAND = 0.03

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
