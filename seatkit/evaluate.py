"""Evaluation of a designed surface: the paper's Section 6 and Table 1.

For each person the pressure is recomputed with the contact set restricted to
the body vertices within the support distance of the designed surface, and
the paper's quantities are reported:

``avg_distance_m``
    Mean distance from the *supported* body vertices (those that carry load
    in the "supported everywhere" importance map: pressure of at least
    :data:`seatkit.pressure.contact.SUPPORTED_FRACTION` of its maximum) to the closest point of the
    surface, m. The paper measures to the closest surface vertex; we measure
    to the surface itself (closest point on the tessellated limit
    surface), which is never larger.
``avg_moment_nm``, ``max_moment_nm``
    Mean and largest joint-moment magnitude over the 20 joints, N m.
``avg_pressure_pa``, ``max_pressure_pa``
    Mean pressure over the contact set (the body vertices within the support
    distance of the surface, as the paper computes it: a surface that meets
    more of the body spreads the same weight over more vertices) and the
    largest, Pa.
``avg_loaded_pressure_pa``
    Mean over the vertices that actually carry load (above 1 Pa), Pa.
``max_penetration_m``
    How deep the surface reaches into the body, m (0 when it stays outside):
    the largest depth below the skin of any surface point (tessellation
    vertices and quad centres): the exact distance to the skin's triangles,
    inside as the angle-weighted pseudo-normal of the closest feature says,
    confirmed by the point's winding number where the posed skin touches
    itself (:class:`seatkit.geometry.skin.SkinDistance`). Measured from the body side
    because the closed skin has a well-defined inside, where a folded
    support surface does not; a body vertex more than this deep "inside the
    surface" would need the surface to be at least as deep inside the body.
``max_body_depth_m``
    How deep any body vertex lies inside the furniture, m (0 when none
    does): the solid the surface closes with the floor (its boundary is the
    ground ring), inside by the parity of a vertical ray, depth the
    distance to the surface (:func:`seatkit.geometry.surface.body_depth_in_surface`). The refiners'
    requirement read literally; it also catches a thin part pushed right
    through the surface, where ``max_penetration_m`` sees only the limb's
    radius.
``contact_vertices``, ``contact_area_m2``
    Size of the recomputed contact set.

A design whose contact set cannot hold the person is reported with
``supported: false`` and the solver's reason, never with made-up numbers.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from seatkit.constants import DEFAULT_SUPPORT_DISTANCE
from seatkit.errors import InfeasibleSupportError
from seatkit.geometry.surface import SurfaceQuery, body_depth_in_surface, surface_depth_in_body
from seatkit.metrics import PAPER_TABLE1, columns
from seatkit.model import Body, PressureField, Surface
from seatkit.pressure.contact import supported_vertices

#: Pressure below which a contact vertex counts as unloaded, Pa.
LOADED_PRESSURE = 1.0


def design_segments(mesh) -> list[int]:
    """Segment indices a cage supports (``meta['supported_segments']`` or its faces)."""
    segs = mesh.meta.get("supported_segments") if isinstance(mesh.meta, dict) else None
    if segs is None:
        segs = np.unique(mesh.face_segments[mesh.face_segments >= 0]).tolist()
    return sorted(int(s) for s in segs)


def evaluate_person(
    body: Body,
    importance: PressureField,
    surface: Surface,
    *,
    solver,
    support_distance: float = DEFAULT_SUPPORT_DISTANCE,
    pressure_settings: Mapping[str, Any] | None = None,
    query: SurfaceQuery | None = None,
    segments=None,
) -> tuple[dict, PressureField | None]:
    """Table 1 figures of one person on one surface (see the module docstring).

    Returns
    -------
    metrics : dict
    field : PressureField or None
        The pressure recomputed on the surface's contact set (None when the
        surface cannot hold the person).
    """
    settings = dict(pressure_settings or {})
    query = query if query is not None else SurfaceQuery(surface)
    supported = supported_vertices(importance, body, segments)
    # distances matter for the supported vertices (their mean) and, for the
    # rest, only up to the support distance (contact or not)
    dist, _ = query.query(body.vertices, within=np.where(supported, np.inf, support_distance))
    contact = dist <= support_distance
    out: dict[str, Any] = {
        "avg_distance_m": float(dist[supported].mean()) if supported.any() else float("nan"),
        "supported_vertices": int(supported.sum()),
        "max_penetration_m": surface_depth_in_body(surface, body),
        "max_body_depth_m": body_depth_in_surface(surface, body, query),
        "contact_vertices": int(contact.sum()),
        "contact_area_m2": float(importance.area[contact].sum()),
    }
    try:
        field = solver.solve(
            body,
            contact=contact,
            lam=settings.get("lambda"),
            mu=settings.get("mu"),
            exclude=settings.get("exclude"),
            options=settings.get("options") or {},
        )
    except InfeasibleSupportError as e:
        out.update(supported=False, reason=str(e))
        return out, None
    moments = np.linalg.norm(field.joint_moment, axis=1)
    loaded = field.pressure > LOADED_PRESSURE
    out.update(
        supported=True,
        avg_moment_nm=float(moments.mean()),
        max_moment_nm=float(moments.max()),
        avg_pressure_pa=float(field.pressure[contact].mean()) if contact.any() else 0.0,
        avg_loaded_pressure_pa=float(field.pressure[loaded].mean()) if loaded.any() else 0.0,
        max_pressure_pa=float(field.pressure.max()),
        loaded_vertices=int(loaded.sum()),
    )
    return out, field


def evaluate_design(
    bodies: Sequence[Body],
    importances: Sequence[PressureField],
    surface: Surface,
    *,
    solver,
    support_distance: float = DEFAULT_SUPPORT_DISTANCE,
    pressure_settings: Mapping[str, Any] | None = None,
    segments=None,
) -> tuple[list[dict], list]:
    """:func:`evaluate_person` for every person on a shared surface.

    Returns
    -------
    metrics : list of dict
        One per person.
    fields : list of PressureField or None
        The recomputed contact pressure of each person.
    """
    query = SurfaceQuery(surface)
    pairs = [
        evaluate_person(
            b,
            p,
            surface,
            solver=solver,
            support_distance=support_distance,
            pressure_settings=pressure_settings,
            query=query,
            segments=segments,
        )
        for b, p in zip(bodies, importances)
    ]
    return [m for m, _ in pairs], [f for _, f in pairs]


def evaluate_interface(bodies: Sequence[Body], surface: Surface, *, mu: float | None = None) -> tuple[list, list]:
    """Interface pressure of every person on a surface, from the soft-tissue contact model.

    Not the paper's model: :mod:`seatkit.pressure.compliant` (soft tissue
    over the skeleton, rigid surface, exact Coulomb cone) gives pressures
    comparable with a pressure mat, where the figures above are the paper's
    relative importance.

    Returns
    -------
    figures : list of dict
        One per person (:func:`seatkit.pressure.compliant.interface_figures`),
        or ``{"supported": False, "reason": ...}``.
    fields : list of PressureField or None
    """
    from seatkit.constants import DEFAULT_MU
    from seatkit.pressure.compliant import contact_with_surface, interface_figures, solve_compliant

    query = SurfaceQuery(surface)
    mu = DEFAULT_MU if mu is None else float(mu)
    figures, fields = [], []
    for body in bodies:
        try:
            field = solve_compliant(body, contact_with_surface(body, surface, query=query), mu=mu)
        except InfeasibleSupportError as e:
            figures.append({"supported": False, "reason": str(e)})
            fields.append(None)
            continue
        figures.append({"supported": True, **interface_figures(body, field)})
        fields.append(field)
    return figures, fields


#: The paper's Table 1 columns, in its order: ``(key, label, unit, scale)`` (:mod:`seatkit.metrics`).
TABLE_COLUMNS = columns(PAPER_TABLE1)

