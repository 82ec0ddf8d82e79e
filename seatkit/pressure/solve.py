"""Solvers of the reduced pressure QP (see :mod:`seatkit.pressure.assembly`).

``newton`` (the default): a semi-smooth Newton method on the dual. The
objective is a separable quadratic in the reactions and the constraints
couple them only through ``r`` = 66 equality rows (6 when rigid), so for a
given dual vector ``y`` the primal minimiser splits into one tiny problem per
vertex: minimise ``1/2 sum_i D'_i x_i^2 - q . x`` over the friction pyramid
``|x_1| <= mu x_0``, ``|x_2| <= mu x_0`` with ``q = G_v y``. Its exact
solution is found in closed form (for a fixed normal part the tangential
parts are clipped; the normal part then minimises a convex piecewise
quadratic with two breakpoints). The dual function is concave and piecewise
quadratic; Newton's method on it uses the generalised Hessian ``E J E^T``
(``J`` the per-vertex Jacobian of the clipped solution, a sum of at most
three rank-one terms) with an Armijo line search, warm-started from the
equality-only solution (one ``r x r`` solve). The reactions it returns lie in
the friction pyramid exactly by construction; the equalities hold once the
active set is right (3-5 iterations on a seated body).

``piqp`` / ``clarabel`` / any qpsolvers name: the paper's formulation as
written (joint forces and moments as unknowns, 21 x 6 segment balance rows,
action = reaction built in), solved through :mod:`qpsolvers` with sparse
matrices. It is independent of the reduction, hence the reference in tests
and the fallback when Newton does not converge.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from seatkit.errors import SolverError
from seatkit.pressure.assembly import ReducedProblem
from seatkit.skeleton import N_JOINTS, N_SEGMENTS, PARENTS

__all__ = [
    "solve_dual_newton",
    "solve_equality_only",
    "solve_full_qpsolvers",
    "solve_full_cone",
    "project_to_pyramid",
    "project_to_cone",
]


def _vertex_minimisers(q: np.ndarray, Dp: np.ndarray, mu: float):
    """Exact minimiser of ``1/2 Dp x^2 - q x`` over the friction pyramid.

    Parameters
    ----------
    q : (k, 3) float64
    Dp : (k, 3) float64
        Positive diagonal.
    mu : float

    Returns
    -------
    x : (k, 3) float64
    U : (k, 3, 3) float64
        Jacobian factors: ``dx/dq = U U^T`` per vertex.
    """
    k = len(q)
    z = q / Dp
    x = np.zeros((k, 3))
    U = np.zeros((k, 3, 3))
    if mu <= 0:
        push = z[:, 0] > 0
        x[push, 0] = z[push, 0]
        U[push, 0, 0] = 1.0 / np.sqrt(Dp[push, 0])
        return x, U
    az = np.abs(z[:, 1:])
    s = np.sign(z[:, 1:])
    hi = np.argmax(az, axis=1)  # tangent component clamped last (1 or 2 -> 0/1 here)
    lo = 1 - hi
    rows = np.arange(k)
    b_lo = az[rows, lo] / mu
    b_hi = az[rows, hi] / mu
    Dt = Dp[:, 1:]

    def dphi(x0):
        # derivative of the reduced 1-D objective in the normal component
        return Dp[:, 0] * x0 - q[:, 0] - mu * (Dt * np.maximum(az - mu * x0[:, None], 0.0)).sum(axis=1)

    d_lo = dphi(b_lo)
    d_hi = dphi(b_hi)
    pat_a = d_lo >= 0  # both tangential parts on the pyramid's edges
    pat_c = d_hi < 0  # both inside (unconstrained)
    pat_b = ~pat_a & ~pat_c  # only the larger one clamped

    # pattern A: x0 from both clamped, possibly at the apex (x = 0)
    den_a = Dp[:, 0] + mu**2 * Dt.sum(axis=1)
    x0_a = (q[:, 0] + mu * (Dt * az).sum(axis=1)) / den_a
    a_push = pat_a & (x0_a > 0)
    x[a_push, 0] = x0_a[a_push]
    x[a_push, 1:] = mu * s[a_push] * x0_a[a_push, None]
    u = np.zeros((k, 3))
    u[:, 0] = 1.0
    u[:, 1:] = mu * s
    U[a_push, :, 0] = u[a_push] / np.sqrt(den_a[a_push, None])

    # pattern B: the larger tangential part clamped, the other free
    if pat_b.any():
        r = rows[pat_b]
        h = hi[pat_b] + 1  # component index in 0..2
        lidx = lo[pat_b] + 1
        Dh = Dp[r, h]
        den_b = Dp[r, 0] + mu**2 * Dh
        x0_b = (q[r, 0] + mu * Dh * np.abs(z[r, h])) / den_b
        sh = np.sign(z[r, h])
        x[r, 0] = x0_b
        x[r, h] = mu * sh * x0_b
        x[r, lidx] = z[r, lidx]
        ub = np.zeros((len(r), 3))
        ub[:, 0] = 1.0
        ub[np.arange(len(r)), h] = mu * sh
        U[r, :, 0] = ub / np.sqrt(den_b[:, None])
        U[r, lidx, 1] = 1.0 / np.sqrt(Dp[r, lidx])

    # pattern C: unconstrained
    if pat_c.any():
        x[pat_c] = z[pat_c]
        inv = 1.0 / np.sqrt(Dp[pat_c])
        U[pat_c, 0, 0] = inv[:, 0]
        U[pat_c, 1, 1] = inv[:, 1]
        U[pat_c, 2, 2] = inv[:, 2]
    return x, U


def _moment_diag(prob: ReducedProblem) -> np.ndarray:
    """Diagonal of the (E H^-1 E^T) contribution of the moment unknowns."""
    d = np.zeros(len(prob.e))
    if not prob.rigid:
        d[: prob.n_moment_rows] = 1.0 / (2.0 * prob.moment_weight)
    return d


def solve_equality_only(prob: ReducedProblem) -> tuple[np.ndarray, np.ndarray]:
    """The equality-constrained minimiser (no pyramid): one r x r solve.

    Returns
    -------
    y : (r,) float64
        Dual vector.
    rbar : (k, 3) float64
        Reactions in tangent coordinates (may violate the pyramid).
    """
    Dp = 2.0 * prob.D
    U = np.zeros((len(Dp), 3, 3))
    idx = np.arange(3)
    U[:, idx, idx] = 1.0 / np.sqrt(Dp)
    schur = prob.normal_matrix(U) + np.diag(_moment_diag(prob))
    y = np.linalg.solve(schur, prob.e)
    rbar = prob.apply_transpose(y) / Dp
    return y, rbar


def _dual_value(prob, y, q, x, Dp, mdiag):
    # g(y) = min_z L(z, y): separable vertex part + moment part + y.e
    vertex = (0.5 * Dp * x * x - q * x).sum()
    moment = -0.5 * (mdiag * y * y).sum()
    return vertex + moment + y @ prob.e


def solve_dual_newton(
    prob: ReducedProblem,
    mu: float,
    *,
    tol: float = 1e-10,
    max_iter: int = 50,
) -> dict:
    """Semi-smooth Newton on the dual of the reduced QP.

    Parameters
    ----------
    prob : ReducedProblem
    mu : float
    tol : float
        Stop when every equality residual is below ``tol`` times the body
        weight (N, and N m for moment rows).
    max_iter : int

    Returns
    -------
    result : dict
        ``rbar`` (k, 3), ``y`` (r,), ``iterations``, ``converged`` (bool),
        ``residual`` (max abs equality residual), ``diverged`` (bool: the
        dual grew without bound, a sign of an infeasible contact set).
    """
    Dp = 2.0 * prob.D
    r = prob.n_rows
    mdiag = _moment_diag(prob)
    weight = float(np.linalg.norm(prob.e[-6:-3]))
    scale = max(weight, 1.0)
    y, _ = solve_equality_only(prob)

    def evaluate(yv):
        q = prob.apply_transpose(yv)
        x, U = _vertex_minimisers(q, Dp, mu)
        grad = prob.e - mdiag * yv - prob.apply(x)
        return q, x, U, grad, _dual_value(prob, yv, q, x, Dp, mdiag)

    q, x, U, grad, value = evaluate(y)
    converged = False
    diverged = False
    it = 0
    for it in range(1, max_iter + 1):
        if np.abs(grad).max() <= tol * scale:
            converged = True
            it -= 1
            break
        # generalised Hessian E J E^T with J = U U^T per vertex
        hess = prob.normal_matrix(U) + np.diag(mdiag)
        hess[np.diag_indices(r)] += 1e-12 * max(np.trace(hess) / r, 1e-300)
        try:
            step = np.linalg.solve(hess, grad)
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(hess, grad, rcond=None)[0]
        slope = grad @ step
        t = 1.0
        accepted = False
        for _ in range(40):
            y_new = y + t * step
            q_n, x_n, U_n, grad_n, value_n = evaluate(y_new)
            if value_n >= value + 1e-4 * t * slope - 1e-15 * abs(value):
                accepted = True
                break
            t *= 0.5
        if not accepted:
            break
        y, q, x, U, grad, value = y_new, q_n, x_n, U_n, grad_n, value_n
        if not np.all(np.isfinite(y)) or np.abs(y).max() > 1e14 * max(1.0, np.abs(prob.e).max()):
            diverged = True
            break
    else:
        converged = bool(np.abs(grad).max() <= tol * scale)
    return {
        "rbar": x,
        "y": y,
        "iterations": it,
        "converged": converged,
        "residual": float(np.abs(grad).max()),
        "diverged": diverged,
    }


def project_to_pyramid(rbar: np.ndarray, mu: float) -> np.ndarray:
    """Clip tangent-frame reactions into the friction pyramid (round-off clean-up).

    Parameters
    ----------
    rbar : (k, 3) float64
    mu : float

    Returns
    -------
    (k, 3) float64
        ``n >= 0`` and ``|t_i| <= mu n``.
    """
    out = rbar.copy()
    out[:, 0] = np.maximum(out[:, 0], 0.0)
    lim = mu * out[:, 0:1]
    out[:, 1:] = np.clip(out[:, 1:], -lim, lim)
    return out


def _skew_blocks(a: np.ndarray) -> np.ndarray:
    """(k, 3, 3) cross-product matrices: ``_skew_blocks(a)[i] @ b = a[i] x b``."""
    k = len(a)
    m = np.zeros((k, 3, 3))
    m[:, 0, 1], m[:, 0, 2] = -a[:, 2], a[:, 1]
    m[:, 1, 0], m[:, 1, 2] = a[:, 2], -a[:, 0]
    m[:, 2, 0], m[:, 2, 1] = -a[:, 1], a[:, 0]
    return m


def _full_problem(body, prob: ReducedProblem, gravity: np.ndarray):
    """The paper's formulation as written: equality rows, right-hand side and objective diagonal.

    Unknowns ``F`` (20, 3), ``M`` (20, 3) per joint, then ``rbar`` (k, 3).

    Returns
    -------
    A : (126, 120 + 3k) scipy.sparse.csc_matrix
    b : (126,) float64
    pdiag : (120 + 3k,) float64
        Diagonal of the objective's quadratic form (``1/2 x P x``).
    offset : int
        Index of the first reaction unknown (120).
    """
    k = len(prob.index)
    nF = 3 * N_JOINTS
    n_var = 2 * nF + 3 * k
    com = body.segment_com
    alpha = body.weights[prob.index]  # (k, 21)
    x = prob.points
    T = prob.frames  # world = T @ rbar

    rows, cols, vals = [], [], []

    def add(r, c, v):
        rows.append(np.asarray(r).ravel())
        cols.append(np.asarray(c).ravel())
        vals.append(np.asarray(v, dtype=np.float64).ravel())

    eye = np.eye(3)
    for j in range(N_JOINTS):
        child, parent = j + 1, PARENTS[j + 1]
        Jpos = body.joints[child]
        for seg, sign in ((child, 1.0), (parent, -1.0)):
            fr = 6 * seg + np.arange(3)  # force rows
            mr = fr + 3  # moment rows
            fc = 3 * j + np.arange(3)
            mc = nF + fc
            add(np.repeat(fr, 3), np.tile(fc, 3), sign * eye)
            add(np.repeat(mr, 3), np.tile(fc, 3), sign * _skew_blocks((Jpos - com[seg])[None])[0])
            add(np.repeat(mr, 3), np.tile(mc, 3), sign * eye)
    # reactions: alpha_bv T_v rbar_v in force rows, alpha_bv [x_v - com_b] T_v rbar_v in moment rows
    vv, bb = np.nonzero(alpha > 0)
    a = alpha[vv, bb]
    rc = 2 * nF + 3 * vv[:, None] + np.arange(3)[None, :]  # (p, 3) columns
    blockF = a[:, None, None] * T[vv]  # (p, 3, 3)
    blockM = a[:, None, None] * (_skew_blocks(x[vv] - com[bb]) @ T[vv])
    fr = 6 * bb[:, None] + np.arange(3)[None, :]
    add(np.repeat(fr, 3, axis=1), np.tile(rc, (1, 3)), blockF)
    add(np.repeat(fr + 3, 3, axis=1), np.tile(rc, (1, 3)), blockM)
    A = sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(6 * N_SEGMENTS, n_var),
    )
    b = np.zeros(6 * N_SEGMENTS)
    for seg in range(N_SEGMENTS):
        b[6 * seg : 6 * seg + 3] = -gravity[seg]

    pdiag = np.zeros(n_var)
    if not prob.rigid:
        pdiag[nF : 2 * nF] = 2.0 * prob.moment_weight
    pdiag[2 * nF :] = 2.0 * prob.D.ravel()
    return A, b, pdiag, 2 * nF


def solve_full_qpsolvers(
    body,
    prob: ReducedProblem,
    mu: float,
    *,
    solver: str = "piqp",
    gravity: np.ndarray,
) -> dict:
    """The paper's formulation as written, solved with :mod:`qpsolvers`.

    Unknowns: ``F`` (20, 3), ``M`` (20, 3) per joint (what the parent exerts
    on the child; action = reaction built in) and ``rbar`` (k, 3). Equalities:
    force and moment balance of each segment about its centre of mass
    (Eqs. 5-6, 126 rows). Inequalities: ``-n <= 0`` and the four faces of the
    pyramid per vertex. Objective: ``c_M |M|^2 + sum D rbar^2`` (no ``M``
    term when rigid).

    Returns
    -------
    result : dict
        ``rbar`` (k, 3), ``status`` (str), ``found`` (bool).
    """
    import qpsolvers

    k = len(prob.index)
    A, b, pdiag, off = _full_problem(body, prob, gravity)
    n_var = A.shape[1]
    nF = off // 2
    P = sp.diags(pdiag).tocsc()
    qvec = np.zeros(n_var)
    # inequalities per vertex: -n <= 0, t1 - mu n <= 0, -t1 - mu n <= 0, same for t2
    base = 2 * nF + 3 * np.arange(k)
    gr = np.arange(5 * k).reshape(k, 5)
    g_rows = np.concatenate([gr[:, 0], gr[:, 1], gr[:, 1], gr[:, 2], gr[:, 2], gr[:, 3], gr[:, 3], gr[:, 4], gr[:, 4]])
    g_cols = np.concatenate([base, base + 1, base, base + 1, base, base + 2, base, base + 2, base])
    ones = np.ones(k)
    g_vals = np.concatenate([-ones, ones, -mu * ones, -ones, -mu * ones, ones, -mu * ones, -ones, -mu * ones])
    Gin = sp.csc_matrix((g_vals, (g_rows, g_cols)), shape=(5 * k, n_var))
    h = np.zeros(5 * k)
    problem = qpsolvers.Problem(P, qvec, Gin, h, A, b)
    try:
        solution = qpsolvers.solve_problem(problem, solver=solver)
    except Exception as exc:  # a backend crash is a solver failure, reported by name
        msg = f"pressure QP backend {solver!r} failed: {exc}"
        raise SolverError(msg) from exc
    found = bool(solution.found) and solution.x is not None
    rbar = solution.x[2 * nF :].reshape(k, 3) if solution.x is not None else np.zeros((k, 3))
    status = "optimal" if found else "failed"
    extras = getattr(solution, "extras", {}) or {}
    info = extras.get("info") if isinstance(extras, dict) else None
    if info is not None and hasattr(info, "status"):
        status = str(info.status)
    return {"rbar": rbar, "status": status, "found": found}




def solve_full_cone(body, prob: ReducedProblem, mu: float, *, gravity: np.ndarray) -> dict:
    """The paper's formulation with the exact Coulomb cone instead of the pyramid, solved with Clarabel.

    The same unknowns, equalities and objective as :func:`solve_full_qpsolvers`;
    each reaction lies in the circular cone ``|(t1, t2)| <= mu n`` (a
    second-order cone, which Clarabel handles exactly), so no reaction is
    up to ``sqrt(2)`` times Coulomb's limit as at the pyramid's corners.

    Returns
    -------
    result : dict
        ``rbar`` (k, 3), ``status`` (str), ``found`` (bool).
    """
    import clarabel

    k = len(prob.index)
    A, b, pdiag, off = _full_problem(body, prob, gravity)
    n_var = A.shape[1]
    P = sp.diags(pdiag).tocsc()
    # s = b - A x in the cones: zero for the 126 balance rows, (mu n, t1, t2) per vertex
    cols = off + np.arange(3 * k)
    vals = np.tile(np.array([-mu, -1.0, -1.0]), k)
    cone_rows = sp.csc_matrix((vals, (np.arange(3 * k), cols)), shape=(3 * k, n_var))
    Aall = sp.vstack([A, cone_rows]).tocsc()
    ball = np.concatenate([b, np.zeros(3 * k)])
    cones = [clarabel.ZeroConeT(A.shape[0])] + [clarabel.SecondOrderConeT(3)] * k
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solution = clarabel.DefaultSolver(P, np.zeros(n_var), Aall, ball, cones, settings).solve()
    status = str(solution.status)
    found = "Solved" in status
    rbar = np.asarray(solution.x)[off:].reshape(k, 3) if found else np.zeros((k, 3))
    return {"rbar": rbar, "status": "optimal" if found else status, "found": found}


def project_to_cone(rbar: np.ndarray, mu: float) -> np.ndarray:
    """Scale tangent-frame reactions into the circular friction cone (round-off clean-up).

    Parameters
    ----------
    rbar : (k, 3) float64
    mu : float

    Returns
    -------
    (k, 3) float64
        ``n >= 0`` and ``|(t1, t2)| <= mu n``.
    """
    out = rbar.copy()
    out[:, 0] = np.maximum(out[:, 0], 0.0)
    t = np.linalg.norm(out[:, 1:], axis=1)
    over = t > mu * out[:, 0]
    out[over, 1:] *= (mu * out[over, 0] / np.maximum(t[over], 1e-300))[:, None]
    return out
