"""Linear elasticity on quadratic hexahedra (scikit-fem), locking-free, assembled in bulk.

scikit-fem supplies the element (``ElementHex2``, 27 nodes: its shape
functions and their reference gradients), the curved mesh (``MeshHex2``)
and the numbering of its degrees of freedom. Its generic form assembly calls
Python once per pair of basis functions (81 x 81 for a vector triquadratic
element: about 30 s for a chair), so the mapping of every element and its
stiffness are computed here with batched products instead; a test checks
the fully integrated stiffness against ``skfem.asm(linear_elasticity)``
entry by entry.

Fully integrated, a thin quadratic brick locks: in transverse shear (a
clamped plate 8 elements across deflects 6% too little) and, curved, in
membrane action (the Scordelis-Lo roof at 8 x 8 elements 19% too little; a
3 mm chair half as much at level 1 as at level 3). The default element uses
the MITC9 assumed strains (Bucalem & Bathe 1993): at each height of the
3-point rule through the thickness, the covariant membrane strains ``rr``,
``ss``, ``rs`` and transverse shears ``rz``, ``sz`` are sampled at their
tying points and interpolated from there, ``zz`` is the element's own. The
stiffness keeps exactly six zero-energy modes, the rigid motions (a test
counts them), the plate deflects as Timoshenko says and the roof as its
reference at 8 elements across.

Degrees of freedom are numbered ``3 d + c``: component ``c`` (x, y, z) of
scikit-fem's scalar degree of freedom ``d``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from seatkit.constants import GRAVITY
from seatkit.errors import StructureError
from seatkit.structure.materials import Material
from seatkit.structure.mesh import ShellMesh
from seatkit.structure.solvers import blocks_to_csr, factorise

__all__ = ["Elasticity", "Solution"]

@functools.cache
def _gauss(points: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [0, 1] (read-only: shared between calls)."""
    x, w = np.polynomial.legendre.leggauss(points)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    x.flags.writeable = w.flags.writeable = False
    return x, w


_G2 = _gauss(2)[0]
_G3 = _gauss(3)[0]

#: The covariant strain components, in the order of the rows: rr, ss, zz, rs, sz, rz
#: (r, s the element's surface directions, z its thickness: reference x, y, z).
_COVARIANT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))
#: Tensor-normalised Voigt components (k, l, factor): xx, yy, zz, sqrt2 xy, sqrt2 yz, sqrt2 xz.
_VOIGT = ((0, 0, 1.0), (1, 1, 1.0), (2, 2, 1.0), (0, 1, np.sqrt(2.0)), (1, 2, np.sqrt(2.0)), (0, 2, np.sqrt(2.0)))
#: MITC9 tying grids (Gauss points in r, in s; at each of the 3 Gauss heights) and the
#: covariant components sampled on each (Bucalem & Bathe, Int. J. Numer. Meth. Eng. 36, 1993):
#: rr and rz on 2 x 3 points, ss and sz on 3 x 2, rs on 2 x 2.
_TYING_SETS = {(2, 3): ((0, 0), (0, 2)), (3, 2): ((1, 1), (1, 2)), (2, 2): ((0, 1),)}
_TYING_OF = {comp: grid for grid, comps in _TYING_SETS.items() for comp in comps}
#: Largest relative miss of the floor reaction against the applied load that a solution may have
#: (the rounding of a sound solve is below 1e-6, docs/structure.md "Solve").
IMBALANCE_LIMIT = 1e-4
#: Elements per chunk when building the assumed-strain stiffness and stresses.
CHUNK = 128
#: No element is stiffer than this many times a typical one (the median over the elements of
#: their largest diagonal entry): beyond it an element is rigid to its neighbours, and more only
#: costs digits (docs/structure.md, "Solve"; :meth:`Elasticity._cap_stiffness`).
STIFFNESS_CAP = 1e7


def _full_rule() -> tuple[np.ndarray, np.ndarray]:
    """The 3 x 3 x 3 Gauss rule on the reference cube [0, 1]^3."""
    g3, w3 = _gauss(3)
    X = np.array(np.meshgrid(g3, g3, g3, indexing="ij")).reshape(3, -1)
    return X, np.einsum("i,j,k->ijk", w3, w3, w3).ravel()


def _stress_rule() -> tuple[np.ndarray, np.ndarray]:
    """The stress points: 2 x 2 Gauss points in the element's surface directions (reference x, y), on its bottom face, middle and top face (z = 0, 1/2, 1).

    In-plane, the reduced rule's points are where a quadratic element's
    bending strains are most accurate (Barlow points); through the
    thickness, the faces, where a bent shell is stressed most (at the Gauss
    heights a bending stress reads 23% low). The weights are not used.
    """
    g2, w2 = _gauss(2)
    z = np.array([0.0, 0.5, 1.0])
    X = np.array(np.meshgrid(g2, g2, z, indexing="ij")).reshape(3, -1)
    return X, np.einsum("i,j,k->ijk", w2, w2, np.full(3, 1.0 / 3.0)).ravel()


@functools.cache
def _tying_grid(grid: tuple[int, int]) -> np.ndarray:
    """(3, nr ns 3) reference points of a tying grid: Gauss points in r and s, at the 3 Gauss heights (read-only)."""
    X = np.array(np.meshgrid(_gauss(grid[0])[0], _gauss(grid[1])[0], _G3, indexing="ij")).reshape(3, -1)
    X.flags.writeable = False
    return X


def _lagrange_1d(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(len(x), len(nodes)) Lagrange basis on ``nodes`` at ``x``."""
    out = np.ones((len(x), len(nodes)))
    for k, xk in enumerate(nodes):
        for m, xm in enumerate(nodes):
            if m != k:
                out[:, k] *= (x - xm) / (xk - xm)
    return out


def _tying_matrix(comp: tuple[int, int], X: np.ndarray) -> np.ndarray:
    """(P, T) interpolation of component ``comp`` from its tying points to the points ``X``.

    Lagrange in r and s over the tying grid, and in z over the 3 Gauss
    heights (at a Gauss height: that height's points only; elsewhere, the
    faces for the stresses: the quadratic through the three, exact for the
    linear and quadratic variation of a shell's strains through its thickness).
    """
    nr, ns = _TYING_OF[comp]
    Lr = _lagrange_1d(_gauss(nr)[0], X[0])
    Ls = _lagrange_1d(_gauss(ns)[0], X[1])
    Lz = _lagrange_1d(_G3, X[2])
    return np.einsum("pa,pb,pc->pabc", Lr, Ls, Lz).reshape(X.shape[1], -1)


def _to_cartesian(inv: np.ndarray) -> np.ndarray:
    """(e, P, 6, 6): tensor-normalised Voigt strains from the covariant ones of :data:`_COVARIANT`.

    ``eps_kl = sum_ij e_ij g^i_k g^j_l`` with the contravariant base vectors
    ``g^i_k = inv[..., i, k]`` (the inverse of the mapping's Jacobian).
    """
    out = np.empty(inv.shape[:2] + (6, 6))
    for v, (k, l, f) in enumerate(_VOIGT):
        for c, (i, j) in enumerate(_COVARIANT):
            term = inv[..., i, k] * inv[..., j, l]
            if i != j:
                term = term + inv[..., j, k] * inv[..., i, l]
            out[..., v, c] = f * term
    return out


def _voigt_elasticity(lam: float, mu: float) -> np.ndarray:
    """Isotropic elasticity (6, 6) in tensor-normalised Voigt form: energy density ``eps . D eps / 2``."""
    D = 2.0 * mu * np.eye(6)
    D[:3, :3] += lam
    return D


def _covariant(g: np.ndarray, ref: np.ndarray, i: int, j: int) -> np.ndarray:
    """(e, P, 81) rows of the covariant strain ``e_ij = (g_i . du/dxi_j + g_j . du/dxi_i) / 2``, unknowns node-major.

    ``g`` (e, P, 3, 3): covariant base vectors ``g[..., j, :] = dx/dxi_j``;
    ``ref`` (P, 27, 3): reference gradients ``dN_a/dxi_j`` (the same in every element).
    """
    rows = ref[:, :, j, None] * g[:, :, None, i, :]
    if i != j:
        rows = 0.5 * (rows + ref[:, :, i, None] * g[:, :, None, j, :])
    return rows.reshape(*rows.shape[:2], -1)


@dataclass
class _Points:
    """An element's shape functions and mapping at reference points ``X`` (3, P), in every element."""

    X: np.ndarray
    weights: np.ndarray
    values: np.ndarray  # (P, 27)
    ref: np.ndarray  # (P, 27, 3): dN_a / dxi_j
    g: np.ndarray  # (E, P, 3, 3): g[e, p, j] = dx / dxi_j
    inv: np.ndarray  # (E, P, 3, 3): inv[e, p, i, k] = dxi_i / dx_k
    det: np.ndarray  # (E, P)
    cache: dict = field(default_factory=dict, repr=False)  # constants derived from X (per rule)

    @property
    def dx(self) -> np.ndarray:
        """(E, P) quadrature weight times |det J|."""
        return self.weights[None, :] * np.abs(self.det)

    def grads(self, elements=slice(None)) -> np.ndarray:
        """(e, P, 27, 3) physical gradients ``dN_a / dx_k``."""
        return np.matmul(self.ref[None], self.inv[elements])

    @functools.cached_property
    def tying(self) -> dict:
        """Per assumed covariant component, its (P, T) interpolation from the tying points (:func:`_tying_matrix`)."""
        return {comp: _tying_matrix(comp, self.X) for comp in _TYING_OF}


def _chunks(n: int, size: int = CHUNK):
    return [slice(i, min(i + size, n)) for i in range(0, n, size)]


@dataclass
class Solution:
    """The solved shell.

    Attributes
    ----------
    displacement : (N, 3) float64
        Per mesh node, m.
    reaction : (N, 3) float64
        Force the supports exert on each held node, N (zero elsewhere).
    load : (N, 3) float64
        Applied nodal forces, N.
    von_mises : (E, Q) float64
        Von Mises stress at every quadrature point of every element, Pa.
    volume : float
        m^3.
    solver : str
        The factorisation that solved it (:func:`seatkit.structure.solvers.factorise`).
    """

    displacement: np.ndarray
    reaction: np.ndarray
    load: np.ndarray
    von_mises: np.ndarray
    volume: float
    solver: str = ""


class Elasticity:
    """The stiffness of a :class:`ShellMesh` of one material, ready to solve.

    scikit-fem supplies the element (``ElementHex2``: its shape functions
    and their reference gradients), the mesh (``MeshHex2``) and the
    numbering of its degrees of freedom; the mapping (``dx/dxi``, its
    inverse and determinant at each point) is computed here once per rule
    from the element's nodes, in one batched product.
    """

    def __init__(self, mesh: ShellMesh, material: Material, *, assumed_strain: bool = True):
        import skfem

        self.mesh = mesh
        self.material = material
        self.skmesh = mesh.skfem_mesh()
        self.element = skfem.ElementHex2()
        dofs = skfem.assembly.Dofs(self.skmesh, self.element)
        element_dofs = np.asarray(dofs.element_dofs)  # (27, E) scalar degrees of freedom
        self.n_scalar = int(dofs.N)
        self.assumed_strain = bool(assumed_strain)
        # the element's own nodes (the slots whose node is in no other element: the centre and,
        # with one layer, the centres of the top and bottom faces) last, so that the static
        # condensation of :meth:`solve` reads contiguous blocks of the element matrices
        count = np.bincount(element_dofs.ravel(), minlength=self.n_scalar)
        own = (count[element_dofs] == 1).all(axis=1)
        self.slots = np.concatenate([np.flatnonzero(~own), np.flatnonzero(own)])  # element slot order used here
        self.n_outer = int((~own).sum())
        self.element_dofs = element_dofs  # scikit-fem's slot order
        self._edofs = element_dofs[self.slots]  # the order of :attr:`slots`, used by the element matrices
        elements = mesh.elements[self.slots]
        # mesh node -> scalar degree of freedom (MeshHex2 renumbers the nodes)
        self.dof = np.empty(len(mesh.nodes), np.int64)
        self.dof[mesh.elements.ravel()] = element_dofs.ravel()
        self._x = np.ascontiguousarray(mesh.nodes[elements.T])  # (E, 27, 3) element nodes
        self.full = self._points(*_full_rule())
        self.dx = self.full.dx
        self.volume = float(self.dx.sum())
        self.stress_points = self._points(*_stress_rule()) if assumed_strain else self.full
        self._tying = None
        self.element_stiffness = self._cap_stiffness(self._element_stiffness())  # (E, 81, 81)

    def _points(self, X: np.ndarray, W: np.ndarray) -> _Points:
        shapes = [self.element.lbasis(X, a) for a in self.slots]
        values = np.stack([v for v, _ in shapes], axis=1)  # (P, 27)
        ref = np.stack([d for _, d in shapes], axis=1).transpose(2, 1, 0)  # (P, 27, 3)
        n_p = X.shape[1]
        # g[e, p, j, m] = sum_a dN_a/dxi_j(p) x[e, a, m]: one (3 P, 27) x (27, 3) product per element
        g = np.matmul(ref.transpose(0, 2, 1).reshape(3 * n_p, 27), self._x).reshape(-1, n_p, 3, 3)
        # the inverse of jac[m, j] = dx_m / dxi_j, row by row: the contravariant base vectors
        # g^i = (g_j x g_k) / det with det = g_0 . (g_1 x g_2)
        adj = np.stack([np.cross(g[:, :, 1], g[:, :, 2]), np.cross(g[:, :, 2], g[:, :, 0]), np.cross(g[:, :, 0], g[:, :, 1])], axis=2)
        det = np.einsum("epm,epm->ep", g[:, :, 0], adj[:, :, 0])
        with np.errstate(divide="ignore", invalid="ignore"):  # a degenerate point: inf, as the element is
            inv = adj / det[:, :, None, None]
        return _Points(X, W, values, ref, g, inv, det)

    @property
    def det(self) -> np.ndarray:
        """(E, Q) determinant of the mapping at the full rule's points."""
        return self.full.det

    @property
    def n_dofs(self) -> int:
        return 3 * self.n_scalar

    def _vector_dofs(self) -> np.ndarray:
        d = self._edofs.T  # (E, 27)
        return (3 * d[:, :, None] + np.arange(3)).reshape(len(d), -1)  # (E, 81): node-major, then component

    @functools.cached_property
    def stiffness(self) -> sp.csr_matrix:
        """The global stiffness (every degree of freedom); :meth:`solve` assembles only the free ones."""
        return self._assemble(np.ones(self.n_scalar, bool))

    def _element_stiffness(self) -> np.ndarray:
        """(E, 81, 81) element stiffness matrices, rows and columns numbered node-major then component."""
        if self.assumed_strain:
            return self._assumed_strain_stiffness()
        lam, mu = self.material.lame
        g = self.full.grads()  # (E, Q, a, i)
        n_el, n_q, n_b, _ = g.shape
        flat = g.reshape(n_el, n_q, n_b * 3)
        # H[e, a, i, b, j] = sum_q dx g[a, i] g[b, j]
        H = np.matmul((flat * self.dx[:, :, None]).transpose(0, 2, 1), flat).reshape(n_el, n_b, 3, n_b, 3)
        trace = np.einsum("eakbk->eab", H)
        K = np.zeros((n_el, 3 * n_b, 3 * n_b))
        # K[a i, b j] = lam g_ai g_bj + mu g_aj g_bi + mu delta_ij (g_a . g_b)
        K5 = K.reshape(H.shape)
        K5 += mu * H.transpose(0, 1, 4, 3, 2)
        K5 += lam * H
        del H
        for i in range(3):
            K5[:, :, i, :, i] += mu * trace
        return K

    def _cap_stiffness(self, K: np.ndarray) -> np.ndarray:
        """``K`` (E, 81, 81) with every element's stiffness above :data:`STIFFNESS_CAP` times a typical one's cut to it.

        An element whose mapping nearly vanishes at a quadrature point (the
        offset folded through itself) has a stiffness growing as the inverse
        cube of that point's determinant (the assumed strains are carried to
        Cartesian ones by the inverse mapping twice): 4.8e12 times a typical
        element's on one build of the default chair in 2 cm plywood. No displacement
        in double precision balances such a matrix (the rounding of ``u``
        alone, times it, is newtons), and ten million times its neighbours'
        stiffness is rigid to them already (the figures do not move, to 1e-8,
        with the cap anywhere from 1e5 to 1e10). So its
        stiffness on its deformations (the complement of its rigid motions,
        which stay exactly free) has its eigenvalues above the cap set to the
        cap: rigid stays rigid, its soft directions are untouched. Elements
        with no eigenvalue above the cap (every one, on a sound mesh) are
        left as they are.
        """
        if not np.isfinite(STIFFNESS_CAP) or not len(K):
            return K
        diagonal = np.einsum("eii->ei", K)
        cap = STIFFNESS_CAP * float(np.median(diagonal.max(axis=1)))
        candidates = np.flatnonzero(diagonal.sum(axis=1) > cap)  # the trace bounds the largest eigenvalue
        if not candidates.size:
            return K
        # an orthonormal basis of each element's deformations: the complement of its rigid motions
        N = np.linalg.qr(self._rigid[candidates], mode="complete")[0][:, :, 6:]  # (c, 81, 75)
        Kd = np.matmul(N.transpose(0, 2, 1), np.matmul(K[candidates], N))
        w, V = np.linalg.eigh(0.5 * (Kd + Kd.transpose(0, 2, 1)))
        over = (w > cap).any(axis=1)
        NV = np.matmul(N[over], V[over])
        K[candidates[over]] = np.matmul(NV * np.minimum(w[over], cap)[:, None, :], NV.transpose(0, 2, 1))
        return K

    def _assumed_strain_stiffness(self) -> np.ndarray:
        """(E, 81, 81) stiffness of the assumed-strain (MITC9) element, full 3 x 3 x 3 rule.

        Element by element in chunks (the strain rows of one chunk are a few
        MB): ``K = sum_q dx_q B_q^T D B_q`` with ``B`` the assumed strains
        of :meth:`strain_rows` and ``D`` the isotropic elasticity in
        tensor-normalised Voigt form, factorised once (``D = L L^T``) so that
        the sum is one batched product ``(L^T B)^T (L^T B)``.
        """
        L = np.linalg.cholesky(_voigt_elasticity(*self.material.lame))
        n_el = len(self._x)
        K = np.empty((n_el, 81, 81))
        root = np.sqrt(self.dx)
        for chunk in _chunks(n_el):
            B = self.strain_rows(self.full, chunk, left=L.T, weight=root[chunk])  # (e, Q, 6, 81)
            B = B.reshape(len(B), -1, 81)
            np.matmul(B.transpose(0, 2, 1), B, out=K[chunk])
        return K

    def _tying_points(self) -> _Points:
        """The mapping at every MITC9 tying point (the grids of :data:`_TYING_SETS` one after the other), computed once."""
        if self._tying is None:
            T = np.concatenate([_tying_grid(grid) for grid in _TYING_SETS], axis=1)
            self._tying = self._points(T, np.ones(T.shape[1]))
        return self._tying

    @staticmethod
    def _tying_parts() -> list[tuple[slice, tuple]]:
        """(slice of the tying points, covariant components tied there) per grid of :data:`_TYING_SETS`."""
        out, start = [], 0
        for grid, comps in _TYING_SETS.items():
            stop = start + _tying_grid(grid).shape[1]
            out.append((slice(start, stop), comps))
            start = stop
        return out

    def strains(self, points: _Points, u: np.ndarray) -> np.ndarray:
        """(E, P, 6) assumed Cartesian strains of the displacement ``u`` (3 N_dofs,) at ``points``.

        The same strains as ``strain_rows(points) @ u_e``, computed from the
        displacement's covariant strains at the tying points directly: no
        rows over the element's unknowns (a test checks the two agree).
        """
        U = u.reshape(-1, 3)[self._edofs.T]  # (E, 27, 3)
        tying = self._tying_points()
        dU = np.einsum("taj,eac->etjc", tying.ref, U)  # du / dxi_j at the tying points
        g = tying.g  # g[e, t, j] = dx / dxi_j
        cov = np.empty((len(U), points.X.shape[1], 6))
        for part, comps in self._tying_parts():
            for i, j in comps:
                e_ij = np.einsum("etc,etc->et", g[:, part, i], dU[:, part, j])
                if i != j:
                    e_ij = 0.5 * (e_ij + np.einsum("etc,etc->et", g[:, part, j], dU[:, part, i]))
                cov[:, :, _COVARIANT.index((i, j))] = e_ij @ points.tying[(i, j)].T
        cov[:, :, 2] = np.einsum("epc,pa,eac->ep", points.g[:, :, 2], points.ref[:, :, 2], U)
        return np.einsum("epvc,epc->epv", _to_cartesian(points.inv), cov)

    def _assumed_gradients(self, points: _Points, comp: tuple[int, int]) -> np.ndarray:
        """(P 27, T) or (P 27, 2 T): the reference gradients of :func:`_covariant` at the tying points of ``comp``, interpolated to ``points``.

        The assumed covariant strain ``e_ij`` at point ``p``, as a row over
        node ``a``'s displacement, is ``sum_t I[p, t] (dN_a/dxi_j g_i + dN_a/dxi_i g_j)(t) / 2``
        (``I`` the tying interpolation): this constant times the stacked
        base vectors ``[g_i(t); g_j(t)]`` of the element, one product per
        element instead of rows at the tying points then their interpolation.
        """
        key = ("assumed", comp)
        if key not in points.cache:
            i, j = comp
            part = dict((c, p) for p, cs in self._tying_parts() for c in cs)[comp]
            ref = self._tying_points().ref[part]  # (T, 27, 3)
            I = points.tying[comp]  # (P, T)
            C = I[:, None, :] * ref[None, :, :, j].transpose(0, 2, 1)  # (P, 27, T): I[p, t] dN_a/dxi_j(t)
            if i != j:
                C = 0.5 * np.concatenate([C, I[:, None, :] * ref[None, :, :, i].transpose(0, 2, 1)], axis=2)
            points.cache[key] = np.ascontiguousarray(C.reshape(-1, C.shape[2]))
        return points.cache[key]

    def strain_rows(self, points: _Points, elements: slice, left=None, weight=None) -> np.ndarray:
        """(e, P, 6, 81) assumed Cartesian strains at ``points`` of ``elements``, as rows over the element's unknowns.

        Tensor-normalised Voigt order ``xx, yy, zz, sqrt2 xy, sqrt2 yz,
        sqrt2 xz``. The covariant strains in the element's surface directions
        (``rr``, ``ss``, ``rs``) and the transverse shears (``rz``, ``sz``)
        are interpolated from their MITC9 tying points (Bucalem & Bathe
        1993; at the 3 Gauss heights, :func:`_tying_matrix`); ``zz`` is the
        element's own.
        ``left`` (6, 6) multiplies the rows from the left and ``weight``
        (e, P) scales them (both folded into the small transform).
        """
        g_t = self._tying_points().g[elements]
        n, n_p = len(g_t), points.X.shape[1]
        cov = np.empty((n, n_p, 6, 81))
        for part, comps in self._tying_parts():
            for i, j in comps:
                # the tying points' base vectors g_i (and g_j) times the constant interpolated gradients,
                # every element's in one product: (P 27, T) x (T, e 3)
                G = g_t[:, part, i] if i == j else np.concatenate([g_t[:, part, i], g_t[:, part, j]], axis=1)
                rows = self._assumed_gradients(points, (i, j)) @ G.transpose(1, 0, 2).reshape(G.shape[1], -1)
                cov[:, :, _COVARIANT.index((i, j))] = rows.reshape(n_p * 27, n, 3).transpose(1, 0, 2).reshape(n, n_p, 81)
        cov[:, :, 2] = _covariant(points.g[elements], points.ref, 2, 2)
        T = _to_cartesian(points.inv[elements])  # (e, P, 6, 6)
        if left is not None:
            T = np.matmul(left, T)
        if weight is not None:
            T = T * weight[:, :, None, None]
        return np.matmul(T, cov)

    def _assemble(self, kept: np.ndarray, element_matrices=None, element_nodes=None) -> sp.csr_matrix:
        """The stiffness of the scalar degrees of freedom ``kept`` ((N,) bool; all 3 components of each), in CSR.

        See :meth:`_assemble_blocks`; rows and columns follow the kept
        degrees of freedom in order, 3 per node.
        """
        return blocks_to_csr(*self._assemble_blocks(kept, element_matrices, element_nodes))

    def _assemble_blocks(self, kept: np.ndarray, element_matrices=None, element_nodes=None):
        """The stiffness of the scalar degrees of freedom ``kept`` in 3 x 3 blocks: (rows, cols, blocks, n).

        ``element_matrices`` (E, 3 m, 3 m) on the scalar degrees of freedom
        ``element_nodes`` (E, m): by default the element stiffness on all 27
        nodes. The sparsity pattern is found among the m x m node pairs of
        every element (9 times fewer than the entries), and each block is
        the sum of its pairs' by one sparse product with the pairs' incidence.
        ``rows``, ``cols``: the blocks' positions among the ``n`` kept nodes,
        sorted by row then column; ``blocks`` (B, 3, 3).
        """
        d = self._edofs.T if element_nodes is None else element_nodes  # (E, m)
        Ke = self.element_stiffness if element_matrices is None else element_matrices
        n_el, n_b = d.shape
        index = np.full(self.n_scalar, -1, np.int64)
        index[kept] = np.arange(int(kept.sum()))
        n = int(kept.sum())
        loc = index[d]
        pair = (loc[:, :, None] >= 0) & (loc[:, None, :] >= 0)  # (E, m, m)
        rows = np.broadcast_to(loc[:, :, None], pair.shape)[pair]
        cols = np.broadcast_to(loc[:, None, :], pair.shape)[pair]
        keys, block = np.unique(rows * n + cols, return_inverse=True)
        K = Ke.reshape(n_el, n_b, 3, n_b, 3).transpose(0, 1, 3, 2, 4)[pair]  # (pairs, 3, 3)
        # each block the sum of its pairs': one sparse product with the pairs -> blocks incidence
        # (in CSC, one entry per pair's column: no sorting needed)
        S = sp.csc_matrix((np.ones(len(block)), block, np.arange(len(block) + 1)), shape=(len(keys), len(block)))
        data = (S @ K.reshape(-1, 9)).reshape(-1, 3, 3)
        return (keys // n, keys % n, data, n) if n else (keys, keys, data, n)

    def weight_load(self, g: float = GRAVITY) -> np.ndarray:
        """(N, 3) nodal forces of the shell's own weight (along -Y), N."""
        per_dof = np.zeros(self.n_scalar)
        np.add.at(per_dof, self._edofs.T, self.dx @ self.full.values)
        out = np.zeros((len(self.mesh.nodes), 3))
        out[:, 1] = -self.material.density_kg_m3 * g * per_dof[self.dof]
        return out

    def solve(self, load: np.ndarray, held_nodes: np.ndarray) -> Solution:
        """Displacements for nodal forces ``load`` (N, 3) with ``held_nodes`` fixed in every direction.

        The nodes that belong to one element only, at the same place in
        every element (the centre, and with one layer the centres of the
        top and bottom faces: a quarter of the unknowns), are eliminated
        element by element first (static condensation, exact), what remains
        is factorised (CHOLMOD or SuperLU, :mod:`seatkit.structure.solvers`),
        and they are recovered from it. One step
        of iterative refinement follows, its residual from the stable
        element product (:meth:`_element_product`), and the reactions are
        that product less the load at the held nodes; a solution whose
        reaction misses the load by more than :data:`IMBALANCE_LIMIT` is
        refused (:meth:`_check_equilibrium`).
        """
        self._check_held(np.asarray(held_nodes, dtype=np.int64))
        n = self.n_dofs
        f = np.zeros(n)
        f.reshape(-1, 3)[self.dof] = load
        held_node = np.zeros(self.n_scalar, bool)
        held_node[self.dof[np.asarray(held_nodes, dtype=np.int64)]] = True
        held = np.repeat(held_node, 3)
        d = self._edofs.T  # (E, 27)
        no = 3 * self.n_outer  # the element's own nodes are its last slots (see __init__)
        bi, bo = slice(no, None), slice(None, no)
        Ke = self.element_stiffness
        dofs = self._vector_dofs()
        # a held inner unknown: its row and column replaced by the identity, its force by 0 (so it stays 0)
        fixed = held[dofs[:, bi]]  # (E, 3 k)
        Kii = Ke[:, no:, no:].copy()
        Kio = Ke[:, no:, :no].copy()
        Kii[fixed] = 0.0
        Kii.transpose(0, 2, 1)[fixed] = 0.0
        diagonal = np.arange(81 - no)
        Kii[:, diagonal, diagonal] += fixed
        Kio[fixed] = 0.0
        X = np.linalg.solve(Kii, Kio)  # Kii^-1 Kio
        Koo = Ke[:, :no, :no] - np.matmul(Kio.transpose(0, 2, 1), X)
        Koo += Koo.transpose(0, 2, 1).copy()  # symmetric but for rounding: exactly, so every solver has the same matrix
        Koo *= 0.5
        kept = ~held_node
        kept[d[:, self.n_outer :].ravel()] = False
        free = np.flatnonzero(np.repeat(kept, 3))
        # the free outer block only, assembled directly, and factorised (symmetric positive definite);
        # the condensed element matrices freed first (50 MB on the default chair: the factorisation is the peak)
        blocks = self._assemble_blocks(kept, Koo, d[:, : self.n_outer])
        del Koo
        factor = factorise(*blocks)
        del blocks

        def condensed_solve(rhs: np.ndarray) -> np.ndarray:
            """``u`` with ``K u = rhs`` at the free unknowns (0 at the held ones), through the condensation."""
            y = np.linalg.solve(Kii, np.where(fixed, 0.0, rhs[dofs[:, bi]])[:, :, None])  # Kii^-1 f_i
            ro = rhs - np.bincount(dofs[:, bo].ravel(), weights=np.matmul(Kio.transpose(0, 2, 1), y).ravel(), minlength=n)
            out = np.zeros(n)
            out[free] = factor.solve(ro[free])
            # the inner unknowns: Kii u_i = f_i - Kio u_o
            out[dofs[:, bi]] = y[:, :, 0] - np.matmul(X, out[dofs[:, bo]][:, :, None])[:, :, 0]
            return out

        u = condensed_solve(f)
        # one step of iterative refinement on the whole system, its residual from the stable element
        # product: a nearly folded element's matrix has entries up to 1e10 times a sound one's, so
        # K u carries rounding of eps |K_e| |u_e| (tens of mN on the 2 cm plywood bench) unless
        # each element's rigid motion, which its matrix maps to zero, is taken out of u_e first
        residual = f - self._element_product(u)
        residual[held] = 0.0
        u += condensed_solve(residual)
        reaction = self._element_product(u) - f
        reaction[~held] = 0.0
        self._check_equilibrium(reaction, f)
        disp = u.reshape(-1, 3)[self.dof]
        load = np.asarray(load, dtype=np.float64)
        return Solution(disp, reaction.reshape(-1, 3)[self.dof], load, self.von_mises(u), self.volume, factor.name)

    @functools.cached_property
    def _rigid(self) -> np.ndarray:
        """(E, 81, 6) orthonormal basis of each element's rigid motions (translations and rotations about its centre)."""
        c = self._x - self._x.mean(axis=1, keepdims=True)  # (E, 27, 3)
        R = np.zeros(c.shape + (6,))
        for k in range(3):
            R[:, :, k, k] = 1.0
            w = np.zeros(3)
            w[k] = 1.0
            R[:, :, :, 3 + k] = np.cross(w, c)
        return np.linalg.qr(R.reshape(len(c), 81, 6))[0]

    def _element_product(self, u: np.ndarray) -> np.ndarray:
        """``K @ u`` from the element matrices (3 N_dofs,), without the global matrix, in a stable way.

        Each element's displacement less its rigid motion (its projection on
        :attr:`_rigid`) is multiplied by its matrix: the same product in
        exact arithmetic (a rigid motion has no strain, :meth:`strain_rows`),
        but the rounding is that of the element's deformation instead of its
        whole displacement. A nearly folded element is stiff enough (entries
        up to 1e10 times a sound element's) that ``K_e u_e`` directly loses
        the floor reaction's sixth digit (docs/structure.md, "Solve").
        """
        dofs = self._vector_dofs()
        ue = u[dofs][:, :, None]
        Q = self._rigid
        ue = ue - np.matmul(Q, np.matmul(Q.transpose(0, 2, 1), ue))
        Ku = np.matmul(self.element_stiffness, ue)[:, :, 0]
        return np.bincount(dofs.ravel(), weights=Ku.ravel(), minlength=self.n_dofs)

    def stress_basis(self) -> _Points:
        """The points the stresses are evaluated at.

        With assumed strains, the 2 x 2 x 3 points of :func:`_stress_rule`
        (in-plane Barlow points, on both faces and the middle). Without, the
        stiffness' own 3 x 3 x 3 points.
        """
        return self.stress_points

    @staticmethod
    def _check_equilibrium(reaction: np.ndarray, f: np.ndarray) -> None:
        """Refuse a solution whose supports do not carry the load: the stiffness was singular or nearly so.

        A mesh with an element whose mapping nearly vanishes at a quadrature
        point (an offset folded exactly through itself) can have a nearly
        singular stiffness, and SuperLU, without pivoting, then returns
        displacements that balance nothing; the reaction says so.
        """
        applied = f.reshape(-1, 3).sum(axis=0)
        scale = float(np.linalg.norm(applied))
        if scale == 0.0:
            return
        miss = float(np.linalg.norm(reaction.reshape(-1, 3).sum(axis=0) + applied)) / scale
        if not miss <= IMBALANCE_LIMIT:
            msg = (
                f"the solve is not to be trusted: the floor reaction misses the applied load by {miss:.1e} of it "
                "(a nearly singular stiffness: the shell folds through itself where the surface curls about as tight "
                "as it is thick); try another --thickness or --level"
            )
            raise StructureError(msg)

    def _check_held(self, held_nodes: np.ndarray) -> None:
        """Refuse a mesh with a connected piece that the held nodes do not fix (it could move freely)."""
        from scipy.sparse.csgraph import connected_components

        el = self.mesh.elements
        n_nodes = len(self.mesh.nodes)
        graph = sp.coo_matrix((np.ones(el.size), (np.repeat(el[0][None, :], el.shape[0], axis=0).ravel(), el.ravel())), shape=(n_nodes, n_nodes))
        count, label = connected_components(graph, directed=False)
        held = np.zeros(n_nodes, bool)
        held[held_nodes] = True
        for c in range(count):
            points = self.mesh.nodes[held & (label == c)]
            # three points not on one line fix a body; fewer leave it free to turn or slide
            if len(points) < 3 or np.linalg.matrix_rank(points - points.mean(axis=0), tol=1e-9) < 2:
                size = int((label == c).sum())
                msg = f"a part of the shell ({size} of {n_nodes} nodes) is not connected to where it is held: nothing holds it"
                raise StructureError(msg)

    def von_mises(self, u: np.ndarray) -> np.ndarray:
        """(E, Q) von Mises stress of the displacement ``u`` (3 N_dofs,) at :meth:`stress_basis`'s points."""
        lam, mu = self.material.lame
        points = self.stress_basis()
        if self.assumed_strain:
            stress = self.strains(points, u) @ _voigt_elasticity(lam, mu)  # D is symmetric
            stress[:, :, :3] -= stress[:, :, :3].mean(axis=2, keepdims=True)  # the deviator
            return np.sqrt(1.5 * np.einsum("eqv,eqv->eq", stress, stress))
        grads = self.full.grads()
        U = u.reshape(-1, 3)[self._edofs.T]  # (E, 27, 3)
        grad = np.einsum("eqai,eaj->eqji", grads, U)  # du_j/dx_i -> [j, i]
        strain = 0.5 * (grad + grad.transpose(0, 1, 3, 2))
        tr = np.trace(strain, axis1=2, axis2=3)
        stress = 2 * mu * strain
        for i in range(3):
            stress[:, :, i, i] += lam * tr
        dev = stress - (np.trace(stress, axis1=2, axis2=3) / 3.0)[:, :, None, None] * np.eye(3)
        return np.sqrt(1.5 * np.einsum("eqij,eqij->eq", dev, dev))
