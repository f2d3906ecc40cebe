"""Sparse assembly into a fixed pattern, Dirichlet constraints and the linear solve.

The element pattern (E x 24 x 24 COO entries summed into CSR) is built once; each assembly is a
``numpy.bincount`` into the CSR data. Small extra blocks (contact, impactor, mass) are added as
sparse matrices. Constrained dofs get an identity row and column (zero increment), so the
system keeps its size and symmetry. Solvers: "direct" (SuperLU via scipy.sparse.linalg.splu)
and "cg" (conjugate gradients with a 3 x 3 nodal block-Jacobi preconditioner, for the large
dynamic systems, where the mass term dominates and a factorisation fills in badly in 3-D).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as sla


class Pattern:
    """CSR pattern of the element matrices plus the diagonal of all ``n`` dofs."""

    def __init__(self, edofs: np.ndarray, n: int):
        E = edofs.shape[0]
        rows = np.concatenate([np.repeat(edofs, 24, axis=1).ravel(), np.arange(n)])
        cols = np.concatenate([np.tile(edofs, (1, 24)).ravel(), np.arange(n)])
        key = rows.astype(np.int64) * n + cols
        uniq, inverse = np.unique(key, return_inverse=True)
        self.n = n
        self.indices = (uniq % n).astype(np.int32)
        r = uniq // n
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=n))]).astype(np.int32)
        self.map_el = inverse[: E * 576]
        self.nnz = uniq.size

    def matrix(self, Ke: np.ndarray) -> sps.csr_matrix:
        """CSR matrix from element matrices (E, 24, 24) (the diagonal of every dof is present)."""
        data = np.bincount(self.map_el, weights=Ke.ravel(), minlength=self.nnz)
        return sps.csr_matrix((data, self.indices.copy(), self.indptr.copy()), shape=(self.n, self.n))


def assemble_vector(edofs: np.ndarray, fe: np.ndarray, n: int) -> np.ndarray:
    """Global vector (n,) from element vectors (E, 24)."""
    return np.bincount(edofs.ravel(), weights=fe.ravel(), minlength=n)


def constrain(K: sps.csr_matrix, constrained: np.ndarray) -> sps.csr_matrix:
    """K with identity rows/columns at the constrained dofs (boolean mask (n,)), scaled by mean |diag|."""
    K = K.tocsr()
    if not constrained.any():
        return K
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    kill = constrained[rows] | constrained[K.indices]
    K.data[kill] = 0.0
    d = K.diagonal()
    scale = float(np.mean(np.abs(d[~constrained]))) if (~constrained).any() else 1.0
    idx = np.flatnonzero(constrained)
    K = K + sps.csr_matrix((np.full(idx.size, scale if scale > 0 else 1.0), (idx, idx)), shape=K.shape)
    return K


def _block_jacobi(K: sps.csr_matrix, n_nodes: int):
    """Preconditioner: inverse of the 3 x 3 diagonal block of each node (and 1/diag for the rest)."""
    m = 3 * n_nodes
    coo = K.tocoo()
    sel = (coo.row < m) & (coo.col < m) & (coo.row // 3 == coo.col // 3)
    blocks = np.zeros((n_nodes, 3, 3))
    np.add.at(blocks, (coo.row[sel] // 3, coo.row[sel] % 3, coo.col[sel] % 3), coo.data[sel])
    inv = np.linalg.inv(blocks)
    rest = K.diagonal()[m:]
    rest = np.where(rest != 0.0, 1.0 / np.where(rest != 0.0, rest, 1.0), 1.0)

    def apply(x):
        y = np.empty_like(x)
        y[:m] = np.einsum("nij,nj->ni", inv, x[:m].reshape(-1, 3)).ravel()
        y[m:] = rest * x[m:]
        return y

    return sla.LinearOperator(K.shape, matvec=apply)


class LinearSolveError(Exception):
    """The linear solver failed (singular matrix, CG not converged)."""


def solve(K: sps.csr_matrix, b: np.ndarray, method: str, n_nodes: int, rtol: float = 1e-12) -> tuple[np.ndarray, int]:
    """x with K x = b; returns (x, iterations (0 for direct))."""
    if method == "direct":
        try:
            with np.errstate(all="ignore"):
                x = sla.splu(K.tocsc()).solve(b)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise LinearSolveError(str(exc)) from None
        if not np.isfinite(x).all():
            raise LinearSolveError("non-finite solution")
        return x, 0
    count = [0]

    def cb(_):
        count[0] += 1

    x, info = sla.cg(K, b, rtol=rtol, atol=0.0, M=_block_jacobi(K, n_nodes), maxiter=20 * int(np.sqrt(K.shape[0])) + 500,
                     callback=cb)
    if info != 0 or not np.isfinite(x).all():
        raise LinearSolveError(f"CG did not converge (info {info}, {count[0]} iterations)")
    return x, count[0]
