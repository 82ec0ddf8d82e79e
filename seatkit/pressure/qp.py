"""The built-in pressure solver ``qp``: the paper's Section 4 model.

:func:`solve_pressure` is the public entry point; :class:`QPPressureSolver`
wraps it as a :class:`seatkit.interfaces.PressureSolver` component.
"""

from __future__ import annotations

import math
import time
from typing import Any, Mapping, Sequence

import numpy as np

from seatkit.constants import (
    DEFAULT_LAMBDA,
    DEFAULT_MU,
    FORCE_TOL_RELATIVE,
    FRICTION_TOL,
    GRAVITY,
    LAMBDA_RANGE,
    MU_RANGE,
    NORMAL_FORCE_TOL,
)
from seatkit.errors import InfeasibleSupportError, InputError, SolverError
from seatkit.model import PressureField
from seatkit.options import Option
from seatkit.pressure.assembly import assemble, body_geometry, joint_loads, segment_gravity
from seatkit.pressure.field import equilibrium_residuals
from seatkit.pressure.regions import DEFAULT_EXCLUDE, exclusion_mask
from seatkit.pressure.solve import (
    project_to_cone,
    project_to_pyramid,
    solve_dual_newton,
    solve_full_cone,
    solve_full_qpsolvers,
)
from seatkit.pressure.weights import DEFAULT_WEIGHT_CAP
from seatkit.skeleton import N_SEGMENTS, SEGMENTS

__all__ = ["solve_pressure", "QPPressureSolver", "check_support", "BACKENDS"]

#: ``auto``: Newton, falling back to PIQP; ``newton``: Newton only; any other
#: name is handed to qpsolvers (``piqp``, ``clarabel`` ...).
BACKENDS = ("auto", "newton", "piqp", "clarabel")

#: Friction models: ``pyramid`` (the paper's linearised cone, four facets,
#: up to sqrt(2) times Coulomb's limit at its corners) and ``cone`` (the exact
#: circular Coulomb cone, a second-order cone solved with Clarabel).
FRICTION_MODELS = ("pyramid", "cone")

#: Tolerance of the equality residuals relative to the body weight (N, N m).
EQUALITY_TOL_RELATIVE = 1e-9


def _coerce_body(body):
    n = len(body.vertices)
    w = np.asarray(body.weights, dtype=np.float64)
    if w.shape != (n, N_SEGMENTS):
        msg = f"body {body.name!r}: weights must be (n, {N_SEGMENTS}) = ({n}, {N_SEGMENTS}), got {w.shape}"
        raise InputError(msg)
    sums = w.sum(axis=1)
    if np.any(sums <= 0) or np.any(w < 0):
        bad = int(np.flatnonzero((sums <= 0) | (w < 0).any(axis=1))[0])
        msg = f"body {body.name!r}: skinning weights must be non-negative with a positive sum; vertex {bad} has {w[bad].round(3).tolist()}"
        raise InputError(msg)
    return w / sums[:, None]


def check_support(body, prob, mu: float) -> None:
    """Raise InfeasibleSupportError when the contacts cannot hold the body.

    Only whole-body balance can fail (joint loads are free), so this is a
    6-row linear feasibility problem over the pyramid's edge rays
    ``n +- mu t1 +- mu t2`` (weights >= 0), solved with HiGHS.
    """
    from scipy.optimize import linprog

    weight = float(body.segment_mass.sum() * GRAVITY)
    k = len(prob.index)
    missing = _unsupported_segments(body, prob.index)
    _check_rests_on_support(body, prob)
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=np.float64)
    T = prob.frames
    rays = T[:, :, 0][:, None, :] + mu * (
        signs[None, :, 0, None] * T[:, None, :, 1] + signs[None, :, 1, None] * T[:, None, :, 2]
    )  # (k, 4, 3)
    x = body.vertices[prob.index]
    rays = rays.reshape(-1, 3)
    arms = np.repeat(x - prob.reference, 4, axis=0)
    A = np.concatenate([rays.T, np.cross(arms, rays).T])  # (6, 4k)
    b = prob.e[-6:]
    # scale the moment rows to newtons with the body's size
    size = max(float(np.ptp(body.vertices, axis=0).max()), 1e-3)
    A[3:] /= size
    b = b.copy()
    b[3:] /= size
    res = linprog(np.zeros(A.shape[1]), A_eq=A, b_eq=b, bounds=(0, None), method="highs")
    if res.status == 2:
        touched = [SEGMENTS[s] for s in range(N_SEGMENTS) if SEGMENTS[s] not in missing]
        msg = (
            f"body {body.name!r}: the contact set ({k} vertices, on {', '.join(touched) or 'no segment'}) "
            f"cannot hold the body in equilibrium: no pushing reactions within the friction pyramid (mu = {mu}) "
            f"balance its weight of {weight:.2f} N and the moment of gravity about its centre of mass; "
            f"missing support under: {', '.join(missing) or '(every segment touches, but in the wrong places)'}"
        )
        raise InfeasibleSupportError(msg)


def _check_rests_on_support(body, prob) -> None:
    """Cheap necessary conditions, checked before every solve.

    The contact set must be non-empty, and some contact able to carry a
    downward load (outward normal with a downward component, i.e. a finite
    local weight) must lie below the centre of mass: a seat carries a body
    from below. Contacts that are all above the centre of mass could only
    hold the body by clamping or hanging it (a head gripped from all sides),
    which statics allows but no support surface does.
    """
    weight = float(body.segment_mass.sum() * GRAVITY)
    if len(prob.index) == 0:
        msg = (
            f"body {body.name!r}: the contact set is empty, nothing can carry the body's weight of {weight:.2f} N; "
            "give a contact mask or a support surface that touches the body (seat, floor)"
        )
        raise InfeasibleSupportError(msg)
    bearing = prob.frames[:, 1, 0] > 0  # inward normal points up: can push against gravity
    below = prob.points[:, 1] < prob.reference[1]
    if not np.any(bearing & below):
        missing = _unsupported_segments(body, prob.index[bearing & below])
        touched = sorted({SEGMENTS[s] for s in np.argmax(body.weights[prob.index], axis=1)})
        msg = (
            f"body {body.name!r}: the contact set ({len(prob.index)} vertices, on {', '.join(touched)}) cannot hold the pose: "
            f"no contact below the centre of mass (y = {prob.reference[1]:.3f} m) faces downwards, so nothing carries the "
            f"body's weight of {weight:.2f} N from below; missing support under: "
            + ", ".join(s for s in ("Hips", "RightUpLeg", "LeftUpLeg", "RightFoot", "LeftFoot") if s in missing)
        )
        raise InfeasibleSupportError(msg)


def _unsupported_segments(body, index) -> list[str]:
    """Segments with no contact vertex among those they mostly own."""
    owner = np.argmax(body.weights, axis=1)
    has = np.zeros(N_SEGMENTS, dtype=bool)
    has[np.unique(owner[index])] = True
    return [SEGMENTS[s] for s in range(N_SEGMENTS) if not has[s]]


def solve_pressure(
    body,
    *,
    contact: np.ndarray | None = None,
    lam: float | None = None,
    mu: float | None = None,
    exclude: Sequence[str] | None = None,
    backend: str = "auto",
    weight_cap: float = DEFAULT_WEIGHT_CAP,
    tol: float = EQUALITY_TOL_RELATIVE,
    friction: str = "pyramid",
) -> PressureField:
    """Reaction forces holding a body in equilibrium (paper Section 4).

    Parameters
    ----------
    body : Body
    contact : (n,) bool, optional
        Vertices that may carry a reaction; default every vertex.
    lam : float, optional
        The paper's lambda (default 0.013, SI units); ``inf``: rigid body.
    mu : float, optional
        Friction coefficient (default 0.5).
    exclude : sequence of str, optional
        Regions with user weight nu = 0; default
        :data:`seatkit.pressure.regions.DEFAULT_EXCLUDE`. ``[]`` excludes none.
    backend : str
        ``auto`` (dual Newton, PIQP fallback), ``newton``, or a qpsolvers
        solver name (``piqp``, ``clarabel``).
    weight_cap : float
        Cap of the local reaction weights.
    tol : float
        Equality residual tolerance relative to the body weight.
    friction : str
        ``pyramid`` (the paper's, default) or ``cone`` (the exact Coulomb
        cone; the backend is then Clarabel's second-order cone solver,
        whatever ``backend`` says).

    Returns
    -------
    PressureField

    Raises
    ------
    InfeasibleSupportError
        The contact set cannot hold the body.
    SolverError
        No backend produced a solution meeting the constraints.
    """
    t0 = time.perf_counter()
    lam = DEFAULT_LAMBDA if lam is None else float(lam)
    mu = DEFAULT_MU if mu is None else float(mu)
    if not (lam == math.inf or LAMBDA_RANGE[0] <= lam <= LAMBDA_RANGE[1]):
        msg = f"lambda must be from {LAMBDA_RANGE[0]:g} to {LAMBDA_RANGE[1]:g} (or inf for a rigid body), got {lam}"
        raise InputError(msg)
    if not MU_RANGE[0] <= mu <= MU_RANGE[1]:
        msg = f"mu must be from {MU_RANGE[0]:g} to {MU_RANGE[1]:g}, got {mu}"
        raise InputError(msg)
    if friction not in FRICTION_MODELS:
        msg = f"friction must be one of {', '.join(FRICTION_MODELS)}, got {friction!r}"
        raise InputError(msg)
    exclude = DEFAULT_EXCLUDE if exclude is None else tuple(exclude)
    weights = _coerce_body(body)
    if weights is not body.weights:
        from dataclasses import replace

        body = replace(body, weights=weights)
    n = len(body.vertices)
    if contact is None:
        contact = np.ones(n, dtype=bool)
    else:
        contact = np.asarray(contact, dtype=bool)
        if contact.shape != (n,):
            msg = f"contact must be a (n,) = ({n},) bool mask, got shape {contact.shape}"
            raise InputError(msg)
    geometry = body_geometry(body.vertices, body.faces)
    excluded, sources = exclusion_mask(body, exclude, geometry.normal)
    usable = contact & ~excluded & (geometry.area > 0) & (np.linalg.norm(geometry.normal, axis=1) > 0)
    prob = assemble(body, contact=usable, lam=lam, mu=mu, geometry=geometry, weight_cap=weight_cap)
    t_assembled = time.perf_counter()
    _check_rests_on_support(body, prob)

    used = backend
    iterations = 0
    rbar = None
    status = "failed"
    if friction == "cone":
        check_support(body, prob, mu)
        out = solve_full_cone(body, prob, mu, gravity=segment_gravity(body.segment_mass))
        if not out["found"]:
            msg = f"pressure SOCP (exact friction cone, Clarabel) returned status {out['status']!r} without a solution"
            raise SolverError(msg)
        rbar, status, used = project_to_cone(out["rbar"], mu), out["status"], "clarabel-cone"
    elif backend in ("auto", "newton"):
        res = solve_dual_newton(prob, mu, tol=tol)
        iterations = res["iterations"]
        if res["converged"]:
            rbar, status, used = res["rbar"], "optimal", "newton"
        else:
            check_support(body, prob, mu)
            if backend == "newton":
                msg = f"dual Newton did not converge in {iterations} iterations (equality residual {res['residual']:.3g})"
                raise SolverError(msg)
            used = "piqp"
    if rbar is None:
        if backend not in ("auto", "newton"):
            check_support(body, prob, mu)
        out = solve_full_qpsolvers(body, prob, mu, solver=used, gravity=segment_gravity(body.segment_mass))
        if not out["found"]:
            msg = f"pressure QP backend {used!r} returned status {out['status']!r} without a solution"
            raise SolverError(msg)
        rbar = project_to_pyramid(out["rbar"], mu)
        status = out["status"]

    force = np.zeros((n, 3))
    force[prob.index] = np.einsum("kdi,ki->kd", prob.frames, rbar)
    joint_force, joint_moment = joint_loads(body, force)
    residuals = equilibrium_residuals(
        body,
        force=force,
        joint_force=joint_force,
        joint_moment=joint_moment,
        frames=prob.frames,
        index=prob.index,
        contact=usable,
        mu=mu,
    )
    if friction == "cone":
        # the pyramid's check above is implied; the cone's own excess, N
        residuals["cone_excess"] = float((np.linalg.norm(rbar[:, 1:], axis=1) - mu * rbar[:, 0]).max()) if len(rbar) else 0.0
    weight = float(body.segment_mass.sum() * GRAVITY)
    # moments are compared in N m with the weight times 1 m
    limits = {
        "segment_force": 1e-7 * weight,
        "segment_moment": 1e-7 * weight,
        "total_force_relative": FORCE_TOL_RELATIVE,
        "net_moment": 1e-7 * weight,
        "friction_excess": FRICTION_TOL,
        "force_outside_contact": 0.0,
        **({"cone_excess": FRICTION_TOL} if friction == "cone" else {}),
    }
    bad = {k: residuals[k] for k, lim in limits.items() if residuals[k] > lim}
    if residuals["min_normal_force"] < -NORMAL_FORCE_TOL:
        bad["min_normal_force"] = residuals["min_normal_force"]
    if bad:
        msg = f"pressure solution from backend {used!r} violates its constraints: " + ", ".join(
            f"{k} = {v:.3g}" for k, v in bad.items()
        )
        raise SolverError(msg)

    area = geometry.area
    inward = np.zeros((n, 3))
    inward[prob.index] = prob.frames[:, :, 0]
    normal_force = np.einsum("nd,nd->n", force, inward)
    tangential = force - normal_force[:, None] * inward
    safe_area = np.where(area > 0, area, 1.0)
    pressure = np.where(area > 0, normal_force / safe_area, 0.0)
    shear = np.where(area > 0, np.linalg.norm(tangential, axis=1) / safe_area, 0.0)
    seconds = time.perf_counter() - t0
    return PressureField(
        force=force,
        normal_force=normal_force,
        pressure=pressure,
        shear=shear,
        area=area,
        contact=usable,
        joint_force=joint_force,
        joint_moment=joint_moment,
        status=status,
        residuals=residuals,
        solve_seconds=seconds,
        params={
            "lambda": lam,
            "mu": mu,
            "backend": used,
            "iterations": iterations,
            "exclude": list(exclude),
            "exclude_sources": sources,
            "weight_cap": weight_cap,
            "friction": friction,
            "n_contact": int(usable.sum()),
            "assembly_seconds": t_assembled - t0,
        },
    )


#: Options of the ``qp`` solver (a recipe's ``pressure.options``): their one declaration.
QP_OPTIONS: dict[str, Option] = {
    "backend": Option("choice", "QP backend: auto (dual Newton, PIQP fallback), newton, piqp or clarabel", "auto", choices=BACKENDS),
    "weight_cap": Option("number", "largest local reaction weight (caps the paper's 1/|r|)", DEFAULT_WEIGHT_CAP, "1", 1.0, 1e12),
    "tol": Option("number", "relative tolerance of the equilibrium equalities", EQUALITY_TOL_RELATIVE, "1", 1e-15, 1e-2),
    "friction": Option("choice", "friction model: pyramid (the paper's linearised pyramid) or cone (the exact Coulomb cone, Clarabel)", "pyramid", choices=FRICTION_MODELS),
}


class QPPressureSolver:
    """The paper's equilibrium QP (Section 4, Appendix A) as a component."""

    name = "qp"
    options = QP_OPTIONS
    description = (
        "Paper Section 4: joint moments + weighted reactions with Coulomb friction pyramid "
        "(dual Newton, PIQP fallback)"
    )

    def solve(
        self,
        body,
        *,
        contact: np.ndarray | None = None,
        lam: float | None = None,
        mu: float | None = None,
        exclude: Sequence[str] | None = None,
        options: Mapping[str, Any] | None = None,
    ) -> PressureField:
        """See :class:`seatkit.interfaces.PressureSolver`.

        ``options``: :data:`QP_OPTIONS` (``backend``, ``weight_cap``,
        ``tol``, ``friction``: ``pyramid``, the paper's, or ``cone``); another key or a bad value is a :class:`RecipeError`.
        """
        from seatkit.params import component_params

        options = component_params("pressure solver 'qp'", QP_OPTIONS, options, where=("pressure", "options"))
        return solve_pressure(body, contact=contact, lam=lam, mu=mu, exclude=exclude, **options)
