"""Linear elasticity on quadratic hexahedra (scikit-fem), assembled in bulk.

scikit-fem supplies the element (``ElementHex2``, 27 nodes), the curved
geometry (``MeshHex2``), the quadrature and the mapped basis gradients. Its
generic form assembly calls Python once per pair of basis functions (81 x 81
for a vector triquadratic element: about 30 s for a chair), so the
isotropic stiffness is assembled here from the same gradients with batched
matrix products instead; a test checks it against
``skfem.asm(linear_elasticity)`` entry by entry.

Transverse shear is integrated selectively. With every term integrated by
the full 3 x 3 x 3 Gauss rule, a thin quadratic brick is too stiff in
bending (parasitic transverse shear: a clamped plate 8 elements across
deflects 6% too little, 16 across 1.4%). The energy of the two transverse
shear strains (between the thickness direction and the surface, in a frame
per quadrature point) is therefore integrated with 2 x 2 points in the
surface's directions (3 through the thickness), every other term with the
full rule: the standard cure for shear locking of quadratic plate and shell
elements. The stiffness keeps exactly six zero-energy modes, the rigid
motions (a test counts them), and the plate deflects as Timoshenko says at
8 elements across.

Degrees of freedom are numbered ``3 d + c``: component ``c`` (x, y, z) of
scikit-fem's scalar degree of freedom ``d``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from seatkit.constants import GRAVITY
from seatkit.errors import StructureError
from seatkit.structure.materials import Material
from seatkit.structure.mesh import ShellMesh

__all__ = ["Elasticity", "Solution"]

#: Quadrature order of scikit-fem's tensor Gauss rule: 3 points per direction.
INTORDER = 4


def _gauss(points: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(points)
    return 0.5 * (x + 1.0), 0.5 * w


def _shear_rule() -> tuple[np.ndarray, np.ndarray]:
    """2 x 2 Gauss points in the element's surface directions (reference x, y), 3 through its thickness (z)."""
    g2, w2 = _gauss(2)
    g3, w3 = _gauss(3)
    X = np.array(np.meshgrid(g2, g2, g3, indexing="ij")).reshape(3, -1)
    W = np.einsum("i,j,k->ijk", w2, w2, w3).ravel()
    return X, W


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
    """

    displacement: np.ndarray
    reaction: np.ndarray
    load: np.ndarray
    von_mises: np.ndarray
    volume: float


class Elasticity:
    """The stiffness of a :class:`ShellMesh` of one material, ready to solve."""

    def __init__(self, mesh: ShellMesh, material: Material, *, selective: bool = True):
        import skfem

        self.mesh = mesh
        self.material = material
        skmesh = mesh.skfem_mesh()
        self.basis = skfem.Basis(skmesh, skfem.ElementHex2(), intorder=INTORDER)
        self.selective = bool(selective)
        # mesh node -> scalar degree of freedom (MeshHex2 renumbers the nodes)
        self.dof = np.empty(len(mesh.nodes), np.int64)
        self.dof[mesh.elements.ravel()] = self.basis.element_dofs.ravel()
        # basis gradients (E, Q, 27, 3) and quadrature weights times |det J| (E, Q)
        grads = np.stack([self.basis.basis[a][0].grad for a in range(self.basis.Nbfun)])
        self.grads = np.ascontiguousarray(grads.transpose(2, 3, 0, 1))
        self.values = np.stack([self.basis.basis[a][0].value for a in range(self.basis.Nbfun)], axis=-1)  # (E, Q, 27)
        self.dx = np.asarray(self.basis.dx)
        self.volume = float(self.dx.sum())
        self.shear_basis = skfem.Basis(skmesh, skfem.ElementHex2(), quadrature=_shear_rule()) if selective else None
        self.element_stiffness = self._element_stiffness()  # (E, 81, 81)

    @property
    def n_dofs(self) -> int:
        return 3 * self.basis.N

    def _vector_dofs(self) -> np.ndarray:
        d = self.basis.element_dofs.T  # (E, 27)
        return (3 * d[:, :, None] + np.arange(3)).reshape(len(d), -1)  # (E, 81): node-major, then component

    @functools.cached_property
    def stiffness(self) -> sp.csr_matrix:
        """The global stiffness (every degree of freedom); :meth:`solve` assembles only the free ones."""
        return self._assemble(np.ones(self.basis.N, bool))

    def _element_stiffness(self) -> np.ndarray:
        """(E, 81, 81) element stiffness matrices, rows and columns numbered node-major then component."""
        lam, mu = self.material.lame
        g = self.grads  # (E, Q, a, i)
        n_el, n_q, n_b, _ = g.shape
        flat = g.reshape(n_el, n_q, n_b * 3)
        # H[e, a, i, b, j] = sum_q dx g[a, i] g[b, j]
        H = np.matmul((flat * self.dx[:, :, None]).transpose(0, 2, 1), flat).reshape(n_el, n_b, 3, n_b, 3)
        trace = np.einsum("eakbk->eab", H)
        if self.shear_basis is not None:
            # transverse shear: take out its fully integrated energy and put in the reduced one, in one product
            gs = np.stack([self.shear_basis.basis[a][0].grad for a in range(n_b)]).transpose(2, 3, 0, 1)
            full, w_full = self._shear_strains(self.basis, g, self.dx)
            reduced, w_reduced = self._shear_strains(self.shear_basis, gs, np.asarray(self.shear_basis.dx))
            S = np.concatenate([full, reduced], axis=1)  # (E, R, 81)
            W = mu * np.concatenate([-w_full, w_reduced], axis=1)  # (E, R)
            K = np.matmul((S * W[:, :, None]).transpose(0, 2, 1), S)
            del S
        else:
            K = np.zeros((n_el, 3 * n_b, 3 * n_b))
        # K[a i, b j] += lam g_ai g_bj + mu g_aj g_bi + mu delta_ij (g_a . g_b), in place (each temporary is 65 MB for a chair)
        K5 = K.reshape(H.shape)
        H *= mu
        K5 += H.transpose(0, 1, 4, 3, 2)
        H *= lam / mu
        K5 += H
        del H
        for i in range(3):
            K5[:, :, i, :, i] += mu * trace
        return K

    def _shear_strains(self, basis, g: np.ndarray, dx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The two transverse shear strains per point of ``basis``'s rule as rows (E, 2 Q, 81), and their weights (E, 2 Q).

        At each point the thickness direction ``n`` is the normal of the
        element's reference x-y plane (its surface directions), ``t1`` and
        ``t2`` complete an orthonormal frame; the shear strains are
        ``gamma_k = t_k . grad(u) . n + n . grad(u) . t_k`` and their energy
        density is ``mu / 2 (gamma_1^2 + gamma_2^2)``: the stiffness is
        ``mu sum_q dx_q G_q G_q^T`` over the rows ``G`` returned.
        """
        DF = basis.mapping.DF(basis.X)  # (3, 3, E, Q): d x_i / d X_j
        a1 = np.moveaxis(DF[:, 0], 0, -1)
        a2 = np.moveaxis(DF[:, 1], 0, -1)
        n = np.cross(a1, a2)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        t1 = a1 / np.linalg.norm(a1, axis=-1, keepdims=True)
        t2 = np.cross(n, t1)
        gn = np.einsum("eqai,eqi->eqa", g, n)
        n_el, n_q, n_b, _ = g.shape
        rows = []
        for t in (t1, t2):
            gt = np.einsum("eqai,eqi->eqa", g, t)
            # G[e, q, a, c] = (t . g_a) n_c + (n . g_a) t_c
            G = gt[..., None] * n[:, :, None, :] + gn[..., None] * t[:, :, None, :]
            rows.append(G.reshape(n_el, n_q, n_b * 3))
        return np.concatenate(rows, axis=1), np.concatenate([dx, dx], axis=1)

    def _assemble(self, kept: np.ndarray, element_matrices=None, element_nodes=None) -> sp.csr_matrix:
        """The stiffness of the scalar degrees of freedom ``kept`` ((N,) bool; all 3 components of each).

        ``element_matrices`` (E, 3 m, 3 m) on the scalar degrees of freedom
        ``element_nodes`` (E, m): by default the element stiffness on all 27
        nodes. Assembled in 3 x 3 blocks: the sparsity pattern is found among
        the m x m node pairs of every element (9 times fewer than the entries),
        each block component summed with ``np.bincount``, then converted once
        to CSR. Rows and columns follow the kept degrees of freedom in order,
        3 per node.
        """
        d = self.basis.element_dofs.T if element_nodes is None else element_nodes  # (E, m)
        Ke = self.element_stiffness if element_matrices is None else element_matrices
        n_el, n_b = d.shape
        index = np.full(self.basis.N, -1, np.int64)
        index[kept] = np.arange(int(kept.sum()))
        n = int(kept.sum())
        loc = index[d]
        pair = (loc[:, :, None] >= 0) & (loc[:, None, :] >= 0)  # (E, m, m)
        rows = np.broadcast_to(loc[:, :, None], pair.shape)[pair]
        cols = np.broadcast_to(loc[:, None, :], pair.shape)[pair]
        keys, block = np.unique(rows * n + cols, return_inverse=True)
        K = Ke.reshape(n_el, n_b, 3, n_b, 3).transpose(0, 1, 3, 2, 4)[pair]  # (pairs, 3, 3)
        data = np.empty((len(keys), 3, 3))
        for i in range(3):
            for j in range(3):
                data[:, i, j] = np.bincount(block, weights=K[:, i, j], minlength=len(keys))
        indptr = np.searchsorted(keys // n, np.arange(n + 1)) if n else np.zeros(1, np.int64)
        A = sp.bsr_matrix((data, keys % n if n else keys, indptr), shape=(3 * n, 3 * n))
        return A.tocsr()

    def weight_load(self, g: float = GRAVITY) -> np.ndarray:
        """(N, 3) nodal forces of the shell's own weight (along -Y), N."""
        per_dof = np.zeros(self.basis.N)
        np.add.at(per_dof, self.basis.element_dofs.T, np.einsum("eqa,eq->ea", self.values, self.dx))
        out = np.zeros((len(self.mesh.nodes), 3))
        out[:, 1] = -self.material.density_kg_m3 * g * per_dof[self.dof]
        return out

    def solve(self, load: np.ndarray, held_nodes: np.ndarray) -> Solution:
        """Displacements for nodal forces ``load`` (N, 3) with ``held_nodes`` fixed in every direction.

        The nodes that belong to one element only, at the same place in
        every element (the centre, and with one layer the centres of the
        top and bottom faces: a quarter of the unknowns), are eliminated
        element by element first (static condensation, exact), SuperLU
        factorises what remains, and they are recovered from it.
        """
        import scipy.sparse.linalg as sla

        self._check_held(np.asarray(held_nodes, dtype=np.int64))
        n = self.n_dofs
        f = np.zeros(n)
        f.reshape(-1, 3)[self.dof] = load
        held_node = np.zeros(self.basis.N, bool)
        held_node[self.dof[np.asarray(held_nodes, dtype=np.int64)]] = True
        held = np.repeat(held_node, 3)
        d = self.basis.element_dofs.T  # (E, 27)
        count = np.bincount(d.ravel(), minlength=self.basis.N)
        inner = np.flatnonzero((count[d] == 1).all(axis=0))  # element slots whose node is the element's own
        outer = np.setdiff1d(np.arange(d.shape[1]), inner)
        bi = (3 * inner[:, None] + np.arange(3)).ravel()
        bo = (3 * outer[:, None] + np.arange(3)).ravel()
        Ke = self.element_stiffness
        dofs = self._vector_dofs()
        # a held inner unknown: its row and column replaced by the identity, its force by 0 (so it stays 0)
        fixed = held[dofs[:, bi]]  # (E, 3 k)
        Kii = Ke[:, bi][:, :, bi]
        Kio = Ke[:, bi][:, :, bo]
        Kii[fixed] = 0.0
        Kii.transpose(0, 2, 1)[fixed] = 0.0
        Kii[:, np.arange(len(bi)), np.arange(len(bi))] += fixed
        Kio[fixed] = 0.0
        fi = np.where(fixed, 0.0, f[dofs[:, bi]])
        X = np.linalg.solve(Kii, np.concatenate([Kio, fi[:, :, None]], axis=2))  # Kii^-1 [Kio, fi]
        Koo = Ke[:, bo][:, :, bo] - np.matmul(Kio.transpose(0, 2, 1), X[:, :, :-1])
        fo = f - np.bincount(dofs[:, bo].ravel(), weights=np.matmul(Kio.transpose(0, 2, 1), X[:, :, -1:]).ravel(), minlength=n)
        kept = ~held_node
        kept[d[:, inner].ravel()] = False
        free = np.flatnonzero(np.repeat(kept, 3))
        # the free outer block only, assembled directly (symmetric: its CSR arrays are its CSC arrays)
        Kff = self._assemble(kept, Koo, d[:, outer])
        Kff = sp.csc_matrix((Kff.data, Kff.indices, Kff.indptr), shape=Kff.shape)
        u = np.zeros(n)
        # symmetric positive definite: a symmetric ordering without pivoting
        try:
            lu = sla.splu(Kff, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except (MemoryError, SystemError, RuntimeError) as e:  # SuperLU reports a failed allocation as invalid arguments
            if "singular" in str(e).lower():
                msg = "a part of the shell is not connected to where it is held: nothing holds it (singular stiffness)"
            else:
                msg = f"the sparse solver failed on {len(free)} unknowns ({e}); out of memory? try a lower --level"
            raise StructureError(msg) from None
        u[free] = lu.solve(fo[free])
        # the inner unknowns: Kii u_i = f_i - Kio u_o
        u[dofs[:, bi]] = X[:, :, -1] - np.matmul(X[:, :, :-1], u[dofs[:, bo]][:, :, None])[:, :, 0]
        reaction = self._element_product(u) - f
        reaction[~held] = 0.0
        disp = u.reshape(-1, 3)[self.dof]
        return Solution(disp, reaction.reshape(-1, 3)[self.dof], np.asarray(load, dtype=np.float64), self.von_mises(u), self.volume)

    def _element_product(self, u: np.ndarray) -> np.ndarray:
        """``K @ u`` from the element matrices (3 N_dofs,), without the global matrix."""
        dofs = self._vector_dofs()
        Ku = np.matmul(self.element_stiffness, u[dofs][:, :, None])[:, :, 0]
        return np.bincount(dofs.ravel(), weights=Ku.ravel(), minlength=self.n_dofs)

    def stress_basis(self):
        """The basis whose quadrature points the stresses are evaluated at.

        With selective integration, the 2 x 2 x 3 points of the shear rule:
        there the transverse shear strains are those the stiffness saw (at
        the full rule's points they oscillate, unconstrained) and a
        quadratic element's bending strains are most accurate (Barlow
        points).
        """
        return self.shear_basis if self.shear_basis is not None else self.basis

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
        basis = self.stress_basis()
        grads = np.stack([basis.basis[a][0].grad for a in range(basis.Nbfun)]).transpose(2, 3, 0, 1)
        U = u.reshape(-1, 3)[self.basis.element_dofs.T]  # (E, 27, 3)
        grad = np.einsum("eqai,eaj->eqji", grads, U)  # du_j/dx_i -> [j, i]
        strain = 0.5 * (grad + grad.transpose(0, 1, 3, 2))
        tr = np.trace(strain, axis1=2, axis2=3)
        stress = 2 * mu * strain
        for i in range(3):
            stress[:, :, i, i] += lam * tr
        dev = stress - (np.trace(stress, axis1=2, axis2=3) / 3.0)[:, :, None, None] * np.eye(3)
        return np.sqrt(1.5 * np.einsum("eqij,eqij->eq", dev, dev))
