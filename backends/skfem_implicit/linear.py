"""Fixed sparse pattern, assembly into it, Dirichlet constraints and the linear solvers (project code).

The CSR pattern (element couplings, every diagonal, and the extra couplings of the contact: each
candidate sphere node with the impactor dof) is built once per run; an assembly writes the CSR
data array only (:func:`kernels.scatter_matrix` or ``numpy.bincount``), so a factorisation can
keep its ordering and symbolic analysis for the whole run. Constrained dofs get an identity row
and column (scaled by the mean diagonal; zero increment), so size, pattern and symmetry stay.

Solvers (option ``linear_solver``; chosen by measurement, docs/user/performance.md):

- "pardiso": Intel MKL PARDISO through ctypes (the library that pypardiso installs), real
  symmetric indefinite (mtype -2, Bunch-Kaufman pivoting) on the upper triangle: the tangent of
  the compressed tissue is indefinite (compressive stress against a shear modulus of ~0.5 kPa),
  and only the mass term keeps M / (beta dt^2) + K positive at small steps; METIS ordering and symbolic analysis
  (phase 11) once per run, numerical factorisation (22) and solve (33) per Newton iteration.
- "cg": conjugate gradients with the 3 x 3 nodal block-Jacobi preconditioner (scipy's CSR
  product, numpy blocks; an inexact Newton solve: the stepper asks for just the accuracy the
  Newton tolerance needs); the dynamic drop-test system is dominated by its mass term at the steps the
  accuracy needs, so CG converges in tens of cheap iterations; if it does not converge in
  ``cg_maxiter`` iterations the solve falls back to the direct solver for that system.
- "superlu": scipy.sparse.linalg.splu, the scipy-only fallback (no reuse of the ordering).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import glob
import sys
import time

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as sla


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b without BLAS: numpy's BLAS wakes its thread pool for every call, which on a shared
    2-core machine costs milliseconds per product (measured: 8 ms for 18 000 entries)."""
    return float(np.multiply(a, b).sum())


def norm(a: np.ndarray) -> float:
    """Euclidean norm of a vector, without BLAS (see :func:`dot`)."""
    return float(np.sqrt(np.multiply(a, a).sum()))


class LinearSolveError(Exception):
    """The linear solver failed (singular or indefinite matrix, CG not converged, library error)."""


class Pattern:
    """CSR pattern of the element matrices, the diagonal of all ``n`` dofs and ``extra`` (rows, cols) pairs.

    ``map_el`` (E, 24, 24): position in the CSR data of each element matrix entry; ``diag`` (n,):
    positions of the diagonal; ``upper`` : positions of the upper triangle (row <= col) in CSR
    order, with ``upper_indptr`` / ``upper_indices`` its own CSR structure.
    """

    def __init__(self, edofs: np.ndarray, n: int, extra: tuple[np.ndarray, np.ndarray] | None = None):
        E = edofs.shape[0]
        rows = [np.repeat(edofs, 24, axis=1).ravel(), np.arange(n)]
        cols = [np.tile(edofs, (1, 24)).ravel(), np.arange(n)]
        if extra is not None and len(extra[0]):
            er, ec = (np.asarray(x, dtype=np.int64) for x in extra)
            rows += [er, ec]
            cols += [ec, er]
        key = np.concatenate(rows).astype(np.int64) * n + np.concatenate(cols)
        uniq, inverse = np.unique(key, return_inverse=True)
        self.n = n
        self.keys = uniq  # row * n + col of every stored entry, sorted: what position() searches
        self.indices = (uniq % n).astype(np.int32)
        r = uniq // n
        self.row = r
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=n))]).astype(np.int32)
        self.map_el = np.ascontiguousarray(inverse[: E * 576].reshape(E, 24, 24).astype(np.int64))
        self.nnz = uniq.size
        self.diag = self.position(np.arange(n), np.arange(n))
        up = self.indices >= r
        self.upper = np.flatnonzero(up)
        self.upper_indptr = np.concatenate([[0], np.cumsum(np.bincount(r[up], minlength=n))]).astype(np.int32)
        self.upper_indices = self.indices[up].copy()

    def position(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Positions in the CSR data of the entries (rows, cols) (same shape); KeyError if absent."""
        rows = np.asarray(rows, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64)
        key = rows * self.n + cols
        pos = np.searchsorted(self.keys, key.ravel())
        pos = np.minimum(pos, self.keys.size - 1)
        if not (self.keys[pos] == key.ravel()).all():
            raise KeyError("entry outside the sparse pattern")
        return pos.reshape(key.shape)

    def matrix(self, data: np.ndarray) -> sps.csr_matrix:
        """The CSR matrix of ``data`` (nnz,) in this pattern (shares no memory with data)."""
        return sps.csr_matrix((data.copy(), self.indices.copy(), self.indptr.copy()), shape=(self.n, self.n))


class Constraints:
    """Identity rows and columns at the constrained dofs of a :class:`Pattern` (boolean mask (n,))."""

    def __init__(self, pattern: Pattern, constrained: np.ndarray):
        self.pattern = pattern
        self.mask = np.asarray(constrained, dtype=bool)
        self.kill = self.mask[pattern.row] | self.mask[pattern.indices]
        self.diag_c = pattern.diag[self.mask]
        self.diag_free = pattern.diag[~self.mask]

    def apply(self, data: np.ndarray) -> None:
        """In place: zero the constrained rows and columns, put the mean |free diagonal| on their diagonal."""
        if not self.mask.any():
            return
        scale = float(np.mean(np.abs(data[self.diag_free]))) if self.diag_free.size else 1.0
        data[self.kill] = 0.0
        data[self.diag_c] = scale if scale > 0.0 else 1.0


def _mkl_rt():
    """ctypes handle of MKL's runtime library (installed with pypardiso), or ImportError."""
    import pypardiso  # noqa: F401  - the distribution that brings mkl_rt; fails fast if absent

    name = ctypes.util.find_library("mkl_rt")
    candidates = [name] if name else []
    candidates += sorted(glob.glob(f"{sys.prefix}/lib/libmkl_rt.so*") + glob.glob(f"{sys.prefix}/Library/bin/mkl_rt*.dll")
                         + glob.glob(f"{sys.prefix}/lib/libmkl_rt*.dylib"), key=len)
    for c in candidates:
        try:
            return ctypes.CDLL(c)
        except OSError:
            continue
    raise ImportError("MKL runtime library mkl_rt not found (pip install pypardiso)")


class Pardiso:
    """MKL PARDISO on a fixed :class:`Pattern`: real symmetric indefinite (mtype -2), upper triangle.

    The ordering and symbolic factorisation (phase 11) run once in the constructor; ``factor``
    (phase 22) and ``solve`` (phase 33) reuse them. Times (s) are accumulated in ``times``.
    """

    name = "pardiso"

    def __init__(self, pattern: Pattern, times: dict | None = None, counts: dict | None = None):
        self.times = times if times is not None else {}
        self.counts = counts if counts is not None else {}
        self._lib = _mkl_rt()
        self._f = self._lib.pardiso
        self.pattern = pattern
        self.n = pattern.n
        self.pt = np.zeros(64, dtype=np.int64)
        ip = np.zeros(64, dtype=np.int32)
        ip[0] = 1    # no solver defaults: the values below
        ip[1] = 2    # METIS nested dissection
        ip[7] = 2    # at most two steps of iterative refinement
        ip[9] = 8    # pivot perturbation 1e-8
        ip[17] = -1  # report the number of non-zeros of the factor
        ip[34] = 1   # zero-based indexing
        self.iparm = ip
        self.ia = np.ascontiguousarray(pattern.upper_indptr, dtype=np.int32)
        self.ja = np.ascontiguousarray(pattern.upper_indices, dtype=np.int32)
        self.a = np.zeros(self.ja.size)
        self.a[self.ia[1:] - 1] = 1.0  # a placeholder with a non-zero diagonal for the analysis
        self.perm = np.zeros(self.n, dtype=np.int32)
        self._factored = False
        self._call(11, np.zeros(self.n))

    def _call(self, phase: int, b: np.ndarray) -> np.ndarray:
        b = np.ascontiguousarray(b, dtype=np.float64)
        x = np.zeros_like(b)
        err = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        f64 = ctypes.POINTER(ctypes.c_double)
        one = ctypes.c_int32(1)
        self._f(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one), ctypes.byref(one),
                ctypes.byref(ctypes.c_int32(-2)), ctypes.byref(ctypes.c_int32(phase)),
                ctypes.byref(ctypes.c_int32(self.n)), self.a.ctypes.data_as(f64), self.ia.ctypes.data_as(i32),
                self.ja.ctypes.data_as(i32), self.perm.ctypes.data_as(i32), ctypes.byref(one),
                self.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)), b.ctypes.data_as(f64),
                x.ctypes.data_as(f64), ctypes.byref(err))
        if err.value != 0:
            what = {-4: "zero pivot", -3: "reordering problem", -2: "out of memory"}.get(err.value, "error")
            raise LinearSolveError(f"PARDISO phase {phase}: error {err.value} ({what})")
        return x

    def factor(self, data: np.ndarray) -> None:
        """Numerical factorisation of the matrix with CSR ``data`` in the pattern (reuses the analysis)."""
        tic = time.perf_counter()
        self.a[:] = data[self.pattern.upper]
        self._call(22, np.zeros(self.n))
        self._factored = True
        _count(self.times, self.counts, "factorization", tic)

    def solve(self, data: np.ndarray, b: np.ndarray, rtol: float | None = None) -> tuple[np.ndarray, int]:
        """x with A x = b, A the matrix of CSR ``data``: factorisation, then one solve (with refinement)."""
        self.factor(data)
        tic = time.perf_counter()
        x = self._call(33, b)
        _count(self.times, self.counts, "solve", tic)
        return x, 0

    def release(self) -> None:
        """Free PARDISO's memory (phase -1)."""
        if self._factored or self.pt.any():
            try:
                self._call(-1, np.zeros(self.n))
            except LinearSolveError:
                pass

    def __del__(self):
        try:
            self.release()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


class SuperLU:
    """scipy's SuperLU on the full matrix (the scipy-only fallback; orders every factorisation anew)."""

    name = "superlu"

    def __init__(self, pattern: Pattern, times: dict | None = None, counts: dict | None = None):
        self.pattern = pattern
        self.times = times if times is not None else {}
        self.counts = counts if counts is not None else {}

    def solve(self, data: np.ndarray, b: np.ndarray, rtol: float | None = None) -> tuple[np.ndarray, int]:
        """x with A x = b, A the matrix of CSR ``data`` (ordering and factorisation every call)."""
        tic = time.perf_counter()
        K = self.pattern.matrix(data).tocsc()
        try:
            with np.errstate(all="ignore"):
                lu = sla.splu(K)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise LinearSolveError(str(exc)) from None
        _count(self.times, self.counts, "factorization", tic)
        tic = time.perf_counter()
        x = lu.solve(b)
        _count(self.times, self.counts, "solve", tic)
        return x, 0


class BlockJacobiCG:
    """Preconditioned conjugate gradients (compiled), 3 x 3 nodal block-Jacobi preconditioner.

    Falls back to a direct solver (:func:`direct_solver`, made on first need) for a system on which CG does not reach ``rtol``
    in ``maxiter`` iterations; ``fallbacks`` counts those.
    """

    name = "cg"

    def __init__(self, pattern: Pattern, n_nodes: int, rtol: float, maxiter: int, fallback,
                 times: dict | None = None, counts: dict | None = None):
        self.times = times if times is not None else {}
        self.counts = counts if counts is not None else {}
        self.pattern = pattern
        self.n_nodes = n_nodes
        self.rtol = rtol
        self.maxiter = maxiter
        self.fallback = fallback
        self.fallbacks = 0
        m = 3 * n_nodes
        nodes = np.arange(n_nodes)
        r = (3 * nodes[:, None, None] + np.arange(3)[None, :, None]).repeat(3, axis=2)
        c = (3 * nodes[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1)
        self.block_pos = np.ascontiguousarray(pattern.position(r, c))  # (n_nodes, 3, 3)
        self.rest_pos = pattern.diag[m:]

    def solve(self, data: np.ndarray, b: np.ndarray, rtol: float | None = None) -> tuple[np.ndarray, int]:
        """x with |A x - b| <= rtol |b| (CG; rtol default: the solver's), or from the direct fallback.

        Returns (x, CG iterations). The products use scipy's CSR kernel; the preconditioner is the
        inverse of each node's 3 x 3 diagonal block (and 1 / diagonal for the impactor dof).
        """
        rtol = self.rtol if rtol is None else rtol
        tic = time.perf_counter()
        blocks = data[self.block_pos]
        try:
            inv = np.linalg.inv(blocks)
        except np.linalg.LinAlgError:
            self.fallbacks += 1
            return self._direct().solve(data, b)
        rest = data[self.rest_pos]
        rest_inv = np.where(rest != 0.0, 1.0 / np.where(rest != 0.0, rest, 1.0), 1.0)
        A = sps.csr_matrix((data, self.pattern.indices, self.pattern.indptr), shape=(self.pattern.n,) * 2)
        m = 3 * self.n_nodes

        def precondition(r):
            z = np.empty_like(r)
            z[:m] = np.matmul(inv, r[:m].reshape(-1, 3, 1)).ravel()
            z[m:] = rest_inv * r[m:]
            return z

        _count(self.times, self.counts, "factorization", tic)
        tic = time.perf_counter()
        x = np.zeros_like(b)
        bn = norm(b)
        it, ok = 0, bn == 0.0
        if not ok:
            r = b.copy()
            z = precondition(r)
            d = z.copy()
            rz = dot(r, z)
            for it in range(1, self.maxiter + 1):
                q = A @ d
                dq = dot(d, q)
                if not dq > 0.0:  # not positive definite along d: the direct solver takes over
                    break
                alpha = rz / dq
                x += alpha * d
                r -= alpha * q
                if norm(r) <= rtol * bn:
                    ok = True
                    break
                z = precondition(r)
                rz_new = dot(r, z)
                d *= rz_new / rz
                d += z
                rz = rz_new
        _count(self.times, self.counts, "solve", tic)
        if not ok or not np.isfinite(x).all():
            self.fallbacks += 1
            return self._direct().solve(data, b)
        return x, it

    def _direct(self):
        if self.fallback is None:
            self.fallback = direct_solver(self.pattern, self.times, self.counts)
        return self.fallback


def make_solver(kind: str, pattern: Pattern, n_nodes: int, rtol: float = 1e-8, maxiter: int = 400,
                times: dict | None = None, counts: dict | None = None):
    """A solver by name ("pardiso", "cg", "superlu", "direct"); "pardiso" needs pypardiso (ImportError otherwise).

    times / counts: dicts in which the solver accumulates "factorization" and "solve" seconds / calls.
    """
    if kind == "pardiso":
        return Pardiso(pattern, times, counts)
    if kind == "superlu":
        return SuperLU(pattern, times, counts)
    if kind == "direct":
        return direct_solver(pattern, times, counts)
    if kind == "cg":
        return BlockJacobiCG(pattern, n_nodes, rtol, maxiter, None, times, counts)
    raise ValueError(kind)


def direct_solver(pattern: Pattern, times: dict | None = None, counts: dict | None = None):
    """PARDISO when pypardiso is installed, else SuperLU (scipy only)."""
    try:
        return Pardiso(pattern, times, counts)
    except ImportError:
        return SuperLU(pattern, times, counts)


def _count(times: dict, counts: dict, key: str, tic: float) -> None:
    times[key] = times.get(key, 0.0) + time.perf_counter() - tic
    plural = {"factorization": "factorizations", "solve": "solves"}[key]
    counts[plural] = counts.get(plural, 0) + 1


def pardiso_available() -> bool:
    """True when MKL PARDISO can be loaded (pypardiso installed)."""
    return pardiso_problem() is None


def pardiso_problem() -> str | None:
    """Why MKL PARDISO cannot be loaded here (pypardiso absent, or present but its MKL library
    not found, as in some virtual environments), or None when it can."""
    try:
        _mkl_rt()
    except (ImportError, OSError) as exc:
        return f"{type(exc).__name__}: {exc}"
    return None


def assemble_vector(edofs: np.ndarray, fe: np.ndarray, n: int) -> np.ndarray:
    """Global vector (n,) from element vectors (E, 24)."""
    return np.bincount(edofs.ravel(), weights=fe.ravel(), minlength=n)
