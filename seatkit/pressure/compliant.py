"""Interface pressure with soft tissue: an elastic (Winkler) foundation over the skeleton.

The paper's model (:mod:`seatkit.pressure.qp`) answers "which skin should a
support carry, and how much": a *relative importance* that spreads the weight
by a weighted least-squares objective. It is not a contact model: its
pressures do not depend on how hard the support is or how soft the body is,
so they cannot be compared with a pressure mat. This module evaluates a
finished support the way a pressure mat would see it.

Model
-----
- The support is rigid (the designed surface, or planes for a flat test
  seat). The body is rigid bone under a layer of soft tissue; the pose is held
  (the whole body moves as one rigid body: the paper's ``lambda = inf``
  setting). Its joint forces and moments are those that hold every segment
  in equilibrium under the resulting reactions
  (:func:`seatkit.pressure.assembly.joint_loads`), as in the paper.
- The tissue under skin vertex ``v`` is a column of thickness ``h_v`` (the
  distance from the skin to the skeleton's bones, clipped to
  :data:`THICKNESS_RANGE_M`) and Young's modulus ``E``: a normal spring of
  stiffness ``k_v = E / h_v`` per unit area (Pa/m) and a tangential one of
  ``G / h_v`` (``G = E / (2 (1 + nu))``), a Winkler elastic foundation.
- Contact is unilateral and frictional: the normal force ``N_v >= 0`` is
  ``k_v A_v`` times the tissue's compression (the body's approach minus the
  initial gap ``g_v`` along the support's normal) where that is positive,
  and the tangential force lies in the exact Coulomb cone ``|T_v| <= mu N_v``
  (a circular cone, not a pyramid).
- One load step from the unloaded pose: the body is placed with the support
  just touching (or at the initial gaps the design leaves) and gravity is
  applied.

Solving it
----------
The equilibrium state minimises the complementary energy over statically
admissible reactions::

    minimise  sum_v  N_v^2 / (2 k_v A_v) + |T_v|^2 / (2 k_t,v A_v) + g_v N_v
    subject to  sum_v (forces, moments) = - (weight, its moment)    6 rows
                (mu N_v, T_v) in the second-order cone                 per vertex

The multipliers of the 6 rows are the body's rigid displacement; stationarity
gives ``N_v = k_v A_v (approach_v - g_v)`` where it is positive, the Winkler
law. Friction enters through its (associated) cone, the convex
approximation of Coulomb friction. It is a second-order cone program, solved
with Clarabel (a dependency already, through qpsolvers) directly: the cones
are exact, not linearised.

Limits: the tissue columns do not interact (no spreading to neighbours, the
Winkler assumption), the stiffness is linear (real tissue stiffens as it is
compressed), the skeleton is line segments (no bony landmarks such as the
ischial tuberosities), and the pose does not adapt to the support.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from seatkit.constants import (
    DEFAULT_MU,
    FORCE_TOL_RELATIVE,
    GRAVITY,
    TISSUE_POISSON,
    TISSUE_THICKNESS_RANGE_M,
    TISSUE_YOUNGS_MODULUS_PA,
)
from seatkit.errors import InfeasibleSupportError, InputError, SolverError
from seatkit.geometry.normals import kept_vertex_normals
from seatkit.model import PressureField
from seatkit.pressure.assembly import body_geometry, joint_loads, segment_gravity
from seatkit.pressure.solve import project_to_cone

__all__ = [
    "MODEL_NAME",
    "SupportContact",
    "bone_distance",
    "contact_with_planes",
    "contact_with_surface",
    "solve_compliant",
    "load_shares",
    "friction_state",
    "interface_figures",
    "SHARE_REGIONS",
]

#: The model's name in reports and report.json.
MODEL_NAME = "winkler-soft-tissue"

#: How far from the support (m) a skin vertex is a candidate contact: the
#: body sinks by a few centimetres at most under its weight.
CONTACT_REACH_M = 0.04

#: A skin vertex more than this far behind a designed surface (m) is on its
#: far side (outside a thin part of the furniture, e.g. in front of the
#: seat's front edge), not pressed into it: a design reaches at most a few
#: millimetres into the body (its ``max_penetration_m``).
BEHIND_M = 0.01

#: A support whose normal makes less than this cosine with the skin's inward
#: normal does not face that skin (the other side of a thin part).
FACING_COS = 0.2


@dataclass(frozen=True)
class SupportContact:
    """Candidate contacts of a body with a rigid support.

    Attributes
    ----------
    index : (k,) int64
        Body vertices that may touch.
    gap : (k,) float64
        Initial gap along the support normal, m (negative: the support is
        already inside the skin by that much).
    normal : (k, 3) float64
        Unit support normal at the contact, pointing into the body (the
        direction the support pushes).
    part : (k,) int64
        Which support part each contact belongs to (an index into ``parts``).
    parts : tuple of str
        Names of the support parts (``surface``, or the planes' names).
    """

    index: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    part: np.ndarray
    parts: tuple


def _point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, s) distances from each point to each segment ``a[j]..b[j]``."""
    d = b - a  # (s, 3)
    length2 = np.maximum(np.einsum("sd,sd->s", d, d), 1e-18)
    rel = points[:, None, :] - a[None, :, :]  # (n, s, 3)
    t = np.clip(np.einsum("nsd,sd->ns", rel, d) / length2, 0.0, 1.0)
    closest = a[None] + t[..., None] * d[None]
    off = points[:, None, :] - closest
    off *= off
    # np.linalg.norm(..., axis=2) to the bit: the squares summed in order, without a reduction along the short axis
    return np.sqrt(off[..., 0] + off[..., 1] + off[..., 2])


def bone_distance(body) -> np.ndarray:
    """(n,) float64 distance from each skin vertex to the nearest bone, m.

    The skeleton is the 21 segments' bones, each the line segment from the
    segment's proximal joint to its tip (``body.joints``, ``body.tips``).
    """
    v = np.asarray(body.vertices, dtype=np.float64)
    out = np.empty(len(v))
    for start in range(0, len(v), 4096):  # bounded memory: (4096, 21, 3)
        stop = start + 4096
        out[start:stop] = _point_segment_distance(v[start:stop], body.joints, body.tips).min(axis=1)
    return out


def _outward_normals(body) -> np.ndarray:
    # read-only, computed once per process for the body's arrays (its importance solve asked first)
    return kept_vertex_normals(body.vertices, body.faces)


def contact_with_surface(body, surface, *, reach: float = CONTACT_REACH_M, query=None) -> SupportContact:
    """Candidate contacts of a body with a designed surface.

    Skin vertices within ``reach`` of the surface whose closest surface point
    faces them (the surface normal there and the skin's inward normal agree
    to within :data:`FACING_COS`) and that are not more than :data:`BEHIND_M`
    behind it; the gap is the signed offset along the surface normal, which
    points to the body side
    (:meth:`seatkit.geometry.surface.SurfaceQuery.closest_normals`).
    """
    from seatkit.geometry.surface import SurfaceQuery

    query = query if query is not None else SurfaceQuery(surface)
    distance, side, normal = query.closest_normals(body.vertices, within=reach)
    outward = _outward_normals(body)
    # the surface's normals point to the body side (the side it pushes
    # towards); skin facing away from it (the top of a foot above a floor)
    # is never pushed by it
    facing = -np.einsum("nd,nd->n", np.nan_to_num(normal), outward) >= FACING_COS
    near = np.isfinite(distance) & (distance <= reach) & facing & (side >= -BEHIND_M)
    index = np.flatnonzero(near)
    return SupportContact(index, side[index], normal[index], np.zeros(len(index), dtype=np.int64), ("surface",))


def contact_with_planes(body, planes, *, reach: float = CONTACT_REACH_M) -> SupportContact:
    """Candidate contacts of a body with rigid planes (a flat test seat, a floor, a backrest).

    Parameters
    ----------
    body : Body
    planes : sequence of (name, point (3,), normal (3,), region)
        Each plane's normal points to the body side; ``region`` is an (n,)
        bool mask of the vertices that may touch it, or None for every
        vertex. A vertex within ``reach`` of a plane, in front of it and
        facing it, is a candidate; a vertex near two planes touches the
        nearer.
    """
    v = np.asarray(body.vertices, dtype=np.float64)
    outward = _outward_normals(body)
    best = np.full(len(v), np.inf)
    which = np.full(len(v), -1)
    normals = np.zeros((len(planes), 3))
    names = []
    for i, (name, point, normal, region) in enumerate(planes):
        n = np.asarray(normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        normals[i] = n
        names.append(str(name))
        gap = (v - np.asarray(point, dtype=np.float64)) @ n
        ok = (np.abs(gap) <= reach) & (-(outward @ n) >= FACING_COS)
        if region is not None:
            ok &= np.asarray(region, dtype=bool)
        better = ok & (np.abs(gap) < np.abs(best))
        best[better] = gap[better]
        which[better] = i
    index = np.flatnonzero(which >= 0)
    return SupportContact(index, best[index], normals[which[index]], which[index], tuple(names))


def _tangents(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents completing each normal to a right-handed frame."""
    helper = np.where(np.abs(normal[:, 1:2]) < 0.9, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    t1 = np.cross(helper, normal)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(normal, t1)


def solve_compliant(
    body,
    contact: SupportContact,
    *,
    youngs_modulus: float = TISSUE_YOUNGS_MODULUS_PA,
    poisson: float = TISSUE_POISSON,
    thickness=None,
    mu: float = DEFAULT_MU,
) -> PressureField:
    """Interface pressure of a body on a rigid support with a soft-tissue layer (module docstring).

    Parameters
    ----------
    body : Body
    contact : SupportContact
    youngs_modulus : float
        Tissue Young's modulus E, Pa.
    poisson : float
        Tissue Poisson ratio (tangential stiffness ``E / (2 (1 + nu))``).
    thickness : (n,) float64, optional
        Tissue thickness per body vertex, m; default the distance to the
        bones (:func:`bone_distance`) clipped to the documented range.
    mu : float
        Coulomb friction coefficient (>= 0; 0: frictionless).

    Returns
    -------
    PressureField
        ``force`` (world, N), ``normal_force`` along the support normal (N),
        ``pressure`` (Pa: interface pressure), ``params`` with the model's
        name and parameters, ``max_compression_m`` and ``max_strain`` (the
        most compressed tissue column, m and as a fraction of its
        thickness), ``at_friction_limit`` (share of the loaded contacts on
        the cone) and ``part_force_n`` (N, the vertical force on each
        support part).

    Raises
    ------
    InfeasibleSupportError
        The candidate contacts cannot hold the body (the solver finds no
        equilibrium).
    """
    import clarabel

    t0 = time.perf_counter()
    if not (youngs_modulus > 0 and 0 <= poisson < 0.5 and mu >= 0):
        msg = f"compliant contact needs E > 0, 0 <= nu < 0.5 and mu >= 0; got E = {youngs_modulus}, nu = {poisson}, mu = {mu}"
        raise InputError(msg)
    n = len(body.vertices)
    area = body_geometry(body.vertices, body.faces).area
    if thickness is None:
        thickness = np.clip(bone_distance(body), *TISSUE_THICKNESS_RANGE_M)
    thickness = np.asarray(thickness, dtype=np.float64)
    keep = area[contact.index] > 0
    idx = contact.index[keep]
    k = len(idx)
    weight = float(body.segment_mass.sum() * GRAVITY)
    if k == 0:
        msg = f"body {body.name!r}: no skin within reach of the support, nothing carries its weight of {weight:.2f} N"
        raise InfeasibleSupportError(msg)
    gap = contact.gap[keep]
    nrm = contact.normal[keep]
    t1, t2 = _tangents(nrm)
    frames = np.stack([nrm, t1, t2], axis=2)  # (k, 3, 3), columns n, t1, t2
    a = area[idx]
    kn = youngs_modulus / thickness[idx] * a  # N/m per vertex
    kt = kn / (2.0 * (1.0 + poisson))
    # objective: 1/2 x P x + q x with x = (N, T1, T2) per vertex
    P = sp.diags(np.stack([1.0 / kn, 1.0 / kt, 1.0 / kt], axis=1).ravel()).tocsc()
    q = np.zeros(3 * k)
    q[0::3] = gap
    # whole-body balance about the centre of mass: sum f = -G, sum (x - c) x f = -sum (c_s - c) x g_s
    gravity = segment_gravity(body.segment_mass)
    com = (body.segment_mass @ body.segment_com) / float(body.segment_mass.sum())
    arm = body.vertices[idx] - com
    moment_cols = np.cross(arm[:, :, None], frames, axis=1)  # (k, 3, 3): moment of each unit component
    E = np.concatenate([frames, moment_cols], axis=1).transpose(1, 0, 2).reshape(6, 3 * k)
    b = np.concatenate([-gravity.sum(axis=0), -np.cross(body.segment_com - com, gravity).sum(axis=0)])
    # scale the moment rows to newtons with the body's size
    size = max(float(np.ptp(body.vertices, axis=0).max()), 1e-3)
    E[3:] /= size
    b[3:] /= size
    # cones: s = b - A x; zero cone for the 6 rows, N >= 0 (needed when mu = 0),
    # and (mu N, T1, T2) in the second-order cone per vertex
    cone_vals = np.tile(np.array([-mu, -1.0, -1.0]), k)
    push = sp.csc_matrix((-np.ones(k), (np.arange(k), 3 * np.arange(k))), shape=(k, 3 * k))
    coulomb = sp.csc_matrix((cone_vals, (np.arange(3 * k), np.arange(3 * k))), shape=(3 * k, 3 * k))
    A = sp.vstack([sp.csc_matrix(E), push, coulomb]).tocsc()
    bb = np.concatenate([b, np.zeros(4 * k)])
    cones = [clarabel.ZeroConeT(6), clarabel.NonnegativeConeT(k)] + [clarabel.SecondOrderConeT(3)] * k
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = 1e-10
    settings.tol_feas = 1e-10
    solver = clarabel.DefaultSolver(P, q, A, bb, cones, settings)
    sol = solver.solve()
    status = str(sol.status)
    if "Infeasible" in status:
        msg = (
            f"body {body.name!r}: the support ({k} candidate skin vertices, on "
            f"{', '.join(contact.parts)}) cannot hold its weight of {weight:.2f} N with friction mu = {mu}"
        )
        raise InfeasibleSupportError(msg)
    if "Solved" not in status:
        msg = f"compliant contact: Clarabel returned {status}"
        raise SolverError(msg)
    x = project_to_cone(np.asarray(sol.x).reshape(k, 3), mu)  # round-off into the exact cone
    force = np.zeros((n, 3))
    force[idx] = np.einsum("kdi,ki->kd", frames, x)
    normal_force = np.zeros(n)
    normal_force[idx] = x[:, 0]
    shear_force = np.zeros(n)
    shear_force[idx] = np.linalg.norm(x[:, 1:], axis=1)
    pressure = np.where(area > 0, normal_force / np.where(area > 0, area, 1.0), 0.0)
    shear = np.where(area > 0, shear_force / np.where(area > 0, area, 1.0), 0.0)
    joint_force, joint_moment = joint_loads(body, force)
    total = force.sum(axis=0) + gravity.sum(axis=0)
    net = np.cross(body.vertices - com, force).sum(axis=0) + np.cross(body.segment_com - com, gravity).sum(axis=0)
    residuals = {
        "total_force_relative": float(np.linalg.norm(total) / weight),
        "net_moment": float(np.linalg.norm(net)),
        "min_normal_force": float(x[:, 0].min()),
        "friction_excess": float((np.linalg.norm(x[:, 1:], axis=1) - mu * x[:, 0]).max()),
    }
    if residuals["total_force_relative"] > 1e3 * FORCE_TOL_RELATIVE or residuals["net_moment"] > 1e-3 * weight:
        msg = f"compliant contact solution violates equilibrium: {residuals}"
        raise SolverError(msg)
    compression = np.where(x[:, 0] > 0, x[:, 0] / kn, 0.0)  # m, the Winkler law read backwards
    loaded = x[:, 0] > 1.0 * a  # above 1 Pa
    mask = np.zeros(n, dtype=bool)
    mask[idx] = True
    part_force = {name: float(force[idx[contact.part[keep] == i], 1].sum()) for i, name in enumerate(contact.parts)}
    return PressureField(
        force=force,
        normal_force=normal_force,
        pressure=pressure,
        shear=shear,
        area=area,
        contact=mask,
        joint_force=joint_force,
        joint_moment=joint_moment,
        status=status,
        residuals=residuals,
        solve_seconds=time.perf_counter() - t0,
        params={
            "model": MODEL_NAME,
            "youngs_modulus_pa": float(youngs_modulus),
            "poisson": float(poisson),
            "mu": float(mu),
            "n_contact": int(k),
            "max_compression_m": float(compression.max()),
            "max_strain": float((compression / thickness[idx]).max()),
            "part_force_n": part_force,
            "at_friction_limit": float(np.mean(np.linalg.norm(x[loaded, 1:], axis=1) >= mu * x[loaded, 0] * (1 - 1e-4))) if loaded.any() else 0.0,
        },
    )


#: Body regions of the load shares, by each vertex's dominant segment.
SHARE_REGIONS = {
    "seat": ("Hips", "RightUpLeg", "LeftUpLeg"),
    "back": ("Spine", "Spine1", "Spine2", "Spine3", "Neck", "Head"),
    "feet": ("RightLeg", "RightFoot", "LeftLeg", "LeftFoot"),
    "arms": ("RightShoulder", "RightArm", "RightForeArm", "RightHand", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand"),
}

#: Pressure above which a vertex counts as loaded, Pa.
LOADED_PA = 1.0


def load_shares(body, field) -> dict:
    """Vertical reaction carried under each body region, as a fraction of the body weight.

    Regions (:data:`SHARE_REGIONS`): ``seat`` buttocks and thighs, ``back``
    trunk, neck and head, ``feet`` shanks and feet, ``arms`` shoulders to
    hands; each vertex counts for its dominant skinning segment.
    """
    from seatkit.skeleton import SEGMENT_INDEX

    weight = float(body.segment_mass.sum() * GRAVITY)
    owner = np.argmax(body.weights, axis=1)
    fy = np.asarray(field.force)[:, 1]
    return {
        name: float(fy[np.isin(owner, [SEGMENT_INDEX[s] for s in segs])].sum() / weight)
        for name, segs in SHARE_REGIONS.items()
    }


def friction_state(field, *, mu: float, tol: float = 1e-4) -> dict:
    """How many loaded contacts sit at the friction limit.

    Parameters
    ----------
    field : PressureField
        Its ``normal_force`` is the part of ``force`` along each contact's
        normal (both models' fields are), so the rest is tangential.
    mu : float
    tol : float
        Relative tolerance of "at the limit".

    Returns
    -------
    dict
        ``loaded`` (count of vertices above 1 Pa), ``at_limit_share``
        (``|t| >= (1 - tol) mu n``: on the circular Coulomb cone, or beyond
        it), ``above_coulomb_share`` (``|t| > (1 + tol) mu n``: outside the
        circular cone, which only the linearised pyramid allows),
        ``force_at_limit_share`` (share of the normal force those contacts
        carry).
    """
    force = np.asarray(field.force)
    n_force = np.asarray(field.normal_force)
    loaded = np.asarray(field.pressure) > LOADED_PA
    tangential = np.sqrt(np.maximum((force**2).sum(axis=1) - n_force**2, 0.0))
    at = loaded & (tangential >= (1 - tol) * mu * n_force)
    above = loaded & (tangential > (1 + tol) * mu * n_force)
    count = int(loaded.sum())
    total = float(n_force[loaded].sum())
    return {
        "loaded": count,
        "at_limit_share": float(at.sum() / count) if count else 0.0,
        "above_coulomb_share": float(above.sum() / count) if count else 0.0,
        "force_at_limit_share": float(n_force[at].sum() / total) if total > 0 else 0.0,
    }


def interface_figures(body, field) -> dict:
    """The figures of an interface-pressure field for report.json (units in the keys)."""
    loaded = field.pressure > LOADED_PA
    owner = np.argmax(body.weights, axis=1)
    from seatkit.skeleton import SEGMENT_INDEX

    seat = loaded & np.isin(owner, [SEGMENT_INDEX[s] for s in SHARE_REGIONS["seat"]])
    return {
        "model": MODEL_NAME,
        "meaning": "interface pressure: soft tissue (Winkler foundation over the skeleton) on the rigid design, comparable with a pressure mat",
        "peak_pa": float(field.pressure.max()),
        "mean_loaded_pa": float(field.pressure[loaded].mean()) if loaded.any() else 0.0,
        "seat_peak_pa": float(field.pressure[seat].max()) if seat.any() else 0.0,
        "contact_area_m2": float(field.area[loaded].sum()),
        "load_share": load_shares(body, field),
        "friction": friction_state(field, mu=field.params["mu"]),
        "max_joint_moment_nm": float(np.linalg.norm(field.joint_moment, axis=1).max()),
        "max_compression_m": field.params["max_compression_m"],
        "max_strain": field.params["max_strain"],
        "youngs_modulus_pa": field.params["youngs_modulus_pa"],
    }
