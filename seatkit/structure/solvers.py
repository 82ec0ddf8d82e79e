"""The sparse factorisation of the condensed stiffness: CHOLMOD where cvxopt is installed, SuperLU otherwise.

The condensed stiffness of a held shell is symmetric positive definite.
CHOLMOD's supernodal Cholesky factorisation (SuiteSparse, through cvxopt,
whose wheels bundle it with OpenBLAS: the extra ``seatkit[cholmod]``)
factorises the default chair's in 0.45 s where scipy's SuperLU takes 0.75 s
(docs/performance.md, "Will it hold? The structural analysis"); without cvxopt, SuperLU with a
symmetric minimum-degree ordering and no pivoting, as before; and SuperLU
too where CHOLMOD finds the matrix not positive definite to working
precision (a nearly singular stiffness: the equilibrium check of
:meth:`Elasticity.solve` then judges SuperLU's answer, as before). Both
solve the same matrix: its upper triangle is what CHOLMOD reads, and the
element matrices it is assembled from are symmetrised first.

The matrix comes in 3 x 3 blocks (``rows``, ``cols``: block indices sorted
by row then column; ``blocks`` (B, 3, 3)), the way :class:`Elasticity`
assembles it; each solver takes the layout it needs from them directly.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from seatkit.errors import StructureError

__all__ = ["SOLVER", "Factor", "blocks_to_csr", "factorise", "factorise_name"]

#: Which factorisation :func:`factorise` uses: "auto" (CHOLMOD if cvxopt imports, else SuperLU),
#: "cholmod" or "superlu" (the tests and ``benchmarks/bench_structure.py --solver`` pick one).
SOLVER = "auto"


def blocks_to_csr(rows: np.ndarray, cols: np.ndarray, blocks: np.ndarray, n: int) -> sp.csr_matrix:
    """The (3 n, 3 n) CSR matrix of 3 x 3 ``blocks`` at block positions (``rows``, ``cols``), sorted by row then column."""
    indptr = np.searchsorted(rows, np.arange(n + 1))
    return sp.bsr_matrix((blocks, cols, indptr), shape=(3 * n, 3 * n)).tocsr()


class Factor:
    """A factorised symmetric positive definite matrix: :meth:`solve` and the factorisation's name."""

    def __init__(self, name: str, solve):
        self.name = name
        self._solve = solve

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self._solve(np.ascontiguousarray(rhs, dtype=np.float64))


def _cholmod_module():
    if SOLVER == "superlu":
        return None
    try:
        from cvxopt import cholmod
    except ImportError:
        if SOLVER == "cholmod":
            raise
        return None
    return cholmod


def factorise_name() -> str:
    """The factorisation :func:`factorise` uses now (:data:`SOLVER`, and whether cvxopt imports)."""
    return "CHOLMOD (cvxopt)" if _cholmod_module() is not None else "SuperLU (scipy)"


def factorise(rows: np.ndarray, cols: np.ndarray, blocks: np.ndarray, n: int) -> Factor:
    """Factorise the symmetric positive definite (3 n, 3 n) matrix of 3 x 3 ``blocks`` (see the module's docstring).

    Raises
    ------
    StructureError
        The matrix is singular (a part of the shell nothing holds) or the
        factorisation ran out of memory.
    """
    cholmod = _cholmod_module()
    try:
        if cholmod is not None:
            try:
                return _cholmod_factor(cholmod, rows, cols, blocks, n)
            except ArithmeticError:
                # not positive definite to working precision (a nearly singular stiffness): SuperLU without
                # pivoting factorises it all the same, and the equilibrium check judges its answer
                pass
        return _superlu_factor(rows, cols, blocks, n)
    except (MemoryError, SystemError, RuntimeError) as e:  # SuperLU reports a failed allocation as invalid arguments
        if "singular" in str(e).lower():
            raise StructureError(_SINGULAR) from None
        msg = f"the sparse solver failed on {3 * n} unknowns ({e}); out of memory? try a lower --level"
        raise StructureError(msg) from None


_SINGULAR = "a part of the shell is not connected to where it is held: nothing holds it (singular stiffness)"


def _cholmod_factor(cholmod, rows, cols, blocks, n) -> Factor:
    """CHOLMOD's supernodal Cholesky factorisation (its own fill-reducing ordering) of the upper triangle."""
    from cvxopt import matrix, spmatrix

    # the lower triangle's CSR arrays are the upper triangle's CSC arrays: CHOLMOD's input, column by column
    # (the upper triangle: cvxopt builds its matrix in a time that grows as the squares of the
    # columns' lengths, 25% less this way round in scikit-fem's numbering)
    lower = rows >= cols
    L = blocks_to_csr(rows[lower], cols[lower], blocks[lower], n)
    row = np.repeat(np.arange(3 * n), np.diff(L.indptr))
    keep = L.indices <= row  # a diagonal block's upper entries are left out
    A = spmatrix(L.data[keep], L.indices[keep].astype(np.int64), row[keep], (3 * n, 3 * n))
    del L, row, keep  # before the factor is allocated
    try:
        F = cholmod.symbolic(A, uplo="U")
        cholmod.numeric(A, F)
    except ValueError as e:  # cvxopt: "symbolic factorization failed" (CHOLMOD's status other than out of memory)
        raise RuntimeError(str(e)) from None

    def solve(rhs: np.ndarray) -> np.ndarray:
        x = matrix(rhs)
        cholmod.solve(F, x)
        return np.array(x).ravel()

    return Factor("CHOLMOD (cvxopt)", solve)


def _superlu_factor(rows, cols, blocks, n) -> Factor:
    """SuperLU with a symmetric minimum-degree ordering and no pivoting (the matrix is symmetric positive definite)."""
    import scipy.sparse.linalg as sla

    K = blocks_to_csr(rows, cols, blocks, n)
    # symmetric: its CSR arrays are its CSC arrays
    K = sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)
    lu = sla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return Factor("SuperLU (scipy)", lu.solve)
