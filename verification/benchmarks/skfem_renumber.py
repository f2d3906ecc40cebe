"""Node numbering and the skfem backend's Newton system: ``python -m cfm_verification.benchmarks.skfem --renumber``.

The skfem backend solves the Newton system of every implicit step with block-Jacobi CG (the
inverse of each node's 3 x 3 diagonal block, :class:`cfm_backends.skfem_implicit.linear.BlockJacobiCG`).
This benchmark asks whether the explicit backends' renumbering (:func:`cfm_backends.explicit.renumber.plan`:
reverse Cuthill-McKee or a Morton curve over the element centroids, nodes in first-touch order)
would help that solve or a direct factorisation. It

1. runs the skfem backend on the built-in drop test (quarter, 8 mm) to ``capture_time`` and keeps
   the last Newton system it solved: the CSR data of the matrix (the backend's own assembly:
   tangent, mass term, contact, constraints), the right-hand side and the CG tolerance the
   backend asked for (:func:`capture`);
2. permutes that system symmetrically, P A P^T, for each node numbering (:data:`ORDERINGS`),
   node by node (a node's three dofs stay together and in order; the impactor's dof stays last);
3. prints for each numbering: dofs, non-zeros, bandwidth and profile (envelope) of the node-dof
   block, the fill nnz(L) + nnz(U) of SuperLU with the numbering's own order (``permc_spec =
   "NATURAL"``, diagonal pivots) and with its default COLAMD ordering (the backend's SuperLU),
   the factor size PARDISO's METIS analysis predicts (when pypardiso is installed), the backend's
   block-Jacobi CG (iterations, best wall time of ``repeat`` solves, set-up included), the best
   time of one CSR mat-vec, and the largest difference of the CG solution from the mesh
   numbering's (relative to its largest entry).

Block-Jacobi CG is invariant under a node permutation in exact arithmetic (the preconditioner's
blocks are the same blocks, the Krylov space is the permuted one), so any change in its
iterations is round-off; what a numbering can change is the memory traffic of the mat-vec and
the fill of an envelope (banded) factorisation. The two direct solvers order the matrix
themselves (COLAMD, METIS), so their fill depends on the input order only through ties.
The factorisations are skipped above ``direct_dofs`` dofs (COLAMD) or when the envelope work
exceeds ``natural_work`` (NATURAL), which is said in the row.
"""

from __future__ import annotations

import os
import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

#: the node numberings compared: the mesh's own (the structured generator's lexicographic order),
#: first-touch order of the mesh's elements, RCM, Morton, and a random one (a scattered mesh)
ORDERINGS = ("mesh", "none", "rcm", "morton", "random")


@dataclass
class NewtonSystem:
    """One Newton system A dq = b of the skfem backend, as its linear solver received it.

    Attributes
    ----------
    pattern : cfm_backends.skfem_implicit.linear.Pattern
        The CSR pattern (n dofs).
    data : (nnz,) ndarray
        The matrix's CSR data in ``pattern`` (N/m).
    b : (n,) ndarray
        The right-hand side (N).
    rtol : float
        The CG tolerance the backend asked for (-).
    maxiter : int
        The backend's CG iteration limit.
    n_nodes : int
        Mesh nodes; dofs 3 node + axis, then the impactor's.
    nodes, hexes : ndarray
        The mesh (m; connectivity) the numberings are planned on.
    """

    pattern: object
    data: np.ndarray
    b: np.ndarray
    rtol: float
    maxiter: int
    n_nodes: int
    nodes: np.ndarray
    hexes: np.ndarray


def capture(model, **options) -> NewtonSystem:
    """Run the skfem backend on ``model`` (to its end time) and return the last Newton system solved.

    The backend's linear solver is wrapped for the run (its ``solve`` records a copy of the CSR
    data, the right-hand side and the tolerance, then solves as before); nothing else changes.

    Parameters
    ----------
    model : cfm_core.scene.model.Model
        A model the skfem backend runs (its end time sets the system captured).
    **options
        Options of the skfem backend (:class:`cfm_backends.skfem_implicit.options.SkfemOptions`).

    Returns
    -------
    NewtonSystem
        The last system the backend's linear solver received.

    Raises
    ------
    RuntimeError
        The run solved no linear system.
    """
    from cfm_backends.skfem_implicit import solver as driver

    real = driver._linear_solver
    box = {}

    def recording(sys_, o, quasi):
        lin = real(sys_, o, quasi)
        solve = lin.solve

        def record(data, b, rtol=None):
            box.update(data=data.copy(), b=b.copy(), rtol=rtol if rtol is not None else o["cg_rtol"])
            return solve(data, b, rtol)

        lin.solve = record
        box.update(pattern=sys_.pattern, maxiter=o["cg_maxiter"], n_nodes=sys_.n_nodes)
        return lin

    with _replaced(driver, "_linear_solver", recording):
        driver.run_model(model, **options)
    if "data" not in box:
        raise RuntimeError(f"the skfem run of model '{model.name}' solved no Newton system")
    return NewtonSystem(box["pattern"], box["data"], box["b"], float(box["rtol"]), int(box["maxiter"]),
                        int(box["n_nodes"]), np.asarray(model.nodes, dtype=np.float64),
                        np.asarray(model.hexes, dtype=np.int64))


@contextmanager
def _replaced(module, name, value):
    old = getattr(module, name)
    setattr(module, name, value)
    try:
        yield
    finally:
        setattr(module, name, old)


def node_order(ordering: str, nodes: np.ndarray, hexes: np.ndarray, seed: int = 0) -> np.ndarray:
    """(n,) int64: the mesh node at each new position (new -> old) for one of :data:`ORDERINGS`."""
    from cfm_backends.explicit import renumber

    n = nodes.shape[0]
    if ordering == "mesh":
        return np.arange(n, dtype=np.int64)
    if ordering == "random":
        return np.random.default_rng(seed).permutation(n).astype(np.int64)
    if ordering in renumber.METHODS:
        return renumber.plan(nodes, hexes, ordering).nodes
    raise ValueError(f"ordering {ordering!r} is not one of {ORDERINGS}")


def dof_order(nodes_new_to_old: np.ndarray, n_dofs: int) -> np.ndarray:
    """(n_dofs,) int64: the dof at each new position (new -> old) for a node order.

    Node dofs 3 node + axis move with their node, in axis order; the dofs after the nodes' (the
    impactor's) keep their place at the end.
    """
    p = nodes_new_to_old.astype(np.int64)
    d = (3 * p[:, None] + np.arange(3)).ravel()
    return np.concatenate([d, np.arange(d.size, n_dofs, dtype=np.int64)])


def permute(system: NewtonSystem, order: np.ndarray):
    """The system P A P^T, P b in the backend's own CSR form: (Pattern, data, b).

    The pattern is built by the backend's :class:`Pattern` from the renumbered entries, so the
    solver sees what it would see had the mesh been numbered that way.

    Parameters
    ----------
    system : NewtonSystem
        The system in the mesh's numbering.
    order : (n,) ndarray of int64
        New -> old dofs (:func:`dof_order`).

    Returns
    -------
    pattern : Pattern
        The renumbered CSR pattern (same non-zero count).
    data : (nnz,) ndarray
        The CSR data of P A P^T in it (N/m).
    b : (n,) ndarray
        P b (N).
    """
    from cfm_backends.skfem_implicit.linear import Pattern

    pat = system.pattern
    inv = np.empty_like(order)
    inv[order] = np.arange(order.size, dtype=np.int64)
    r, c = inv[pat.row], inv[pat.indices.astype(np.int64)]
    new = Pattern(np.zeros((0, 24), dtype=np.int64), pat.n, (r, c))
    data = np.zeros(new.nnz)
    data[new.position(r, c)] = system.data
    return new, data, system.b[order]


def envelope(pattern, m: int) -> tuple[int, int, float]:
    """(bandwidth, profile, work) of the leading m x m block of a symmetric CSR pattern.

    Row i's envelope starts at its first column f_i <= i: bandwidth = max (i - f_i), profile =
    sum (i - f_i) (the entries below the diagonal a banded / envelope factorisation stores; it
    fills them), work = sum (i - f_i)^2 (the multiply-adds of that factorisation, to leading order).
    """
    first = pattern.indices[pattern.indptr[:m]].astype(np.int64)  # sorted indices: the row's smallest
    width = np.arange(m, dtype=np.int64) - first
    return int(width.max(initial=0)), int(width.sum()), float(np.square(width.astype(np.float64)).sum())


class _NoFallback:
    """The CG's direct fallback, refused: a system CG cannot solve is reported, not factorised."""

    def solve(self, data, b, rtol=None):
        raise RuntimeError("block-Jacobi CG did not converge")


def prepare(system: NewtonSystem, ordering: str, direct_dofs: int = 40_000, natural_work: float = 1e11) -> dict:
    """The structure of one row for ``ordering``: the permuted system, its envelope and fills, its solver.

    Returns a dict with ``ordering``, ``dofs``, ``nnz``, ``bandwidth``, ``profile``, ``work``
    (see :func:`envelope`), ``natural`` / ``colamd`` (SuperLU's nnz(L) + nnz(U), None where
    skipped), ``pardiso`` (PARDISO's predicted factor non-zeros, None without pypardiso), and the
    private ``_order``, ``_data``, ``_b``, ``_A``, ``_cg`` that :func:`time_rows` uses.
    """
    import scipy.sparse as sps
    import scipy.sparse.linalg as sla

    from cfm_backends.skfem_implicit import linear

    order = dof_order(node_order(ordering, system.nodes, system.hexes), system.pattern.n)
    pat, data, b = permute(system, order)
    bw, prof, work = envelope(pat, 3 * system.n_nodes)
    A = sps.csr_matrix((data, pat.indices, pat.indptr), shape=(pat.n, pat.n))
    row = {"ordering": ordering, "dofs": pat.n, "nnz": pat.nnz, "bandwidth": bw, "profile": prof, "work": work,
           "natural": None, "colamd": None, "pardiso": None, "_order": order, "_data": data, "_b": b, "_A": A,
           "_cg": linear.BlockJacobiCG(pat, system.n_nodes, system.rtol, system.maxiter, _NoFallback())}
    if work <= natural_work:
        # the numbering's own order: no column ordering, diagonal pivots, the symmetric etree
        lu = sla.splu(A.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        row["natural"] = lu.L.nnz + lu.U.nnz
        del lu
    if pat.n <= direct_dofs:
        lu = sla.splu(A.tocsc())  # the backend's SuperLU: COLAMD, default pivoting
        row["colamd"] = lu.L.nnz + lu.U.nnz
        del lu
    if linear.pardiso_available():
        p = linear.Pardiso(pat)  # METIS analysis (phase 11) only
        row["pardiso"] = int(p.iparm[17])
        p.release()
    return row


def time_rows(rows: list[dict], rtol: float, repeat: int = 5, matvecs: int = 10) -> None:
    """Time the rows' CG solves and mat-vecs, interleaved (round r times every row once), in place.

    Adds ``cg_iterations``, ``cg_time`` (best CPU time of a solve, preconditioner set-up included,
    s), ``matvec`` (best CPU time of one CSR product, s), ``x`` (the CG solution in the mesh's
    numbering) and ``x_diff`` (max |x - x of the first row| / max |x of the first row|). CPU time
    of this process: the solve is single-threaded, and other processes on the machine disturb it
    less than the wall time.
    """
    if not rows:
        return
    v = np.random.default_rng(1).standard_normal(rows[0]["dofs"])
    for r in rows:
        r["cg_time"] = r["matvec"] = np.inf
    for _ in range(repeat):
        for r in rows:
            tic = time.process_time()
            x, r["cg_iterations"] = r["_cg"].solve(r["_data"], r["_b"], rtol)
            r["cg_time"] = min(r["cg_time"], time.process_time() - tic)
            r["x"] = np.empty_like(x)
            r["x"][r["_order"]] = x  # back to the mesh numbering
            vp = v[r["_order"]]
            for _ in range(matvecs):
                tic = time.process_time()
                r["_A"] @ vp
                r["matvec"] = min(r["matvec"], time.process_time() - tic)
    x0 = rows[0]["x"]
    for r in rows:
        r["x_diff"] = float(np.abs(r["x"] - x0).max() / np.abs(x0).max())


def measure(system: NewtonSystem, orderings=ORDERINGS, repeat: int = 5, direct_dofs: int = 40_000,
            natural_work: float = 1e11) -> list[dict]:
    """The rows of the table for ``orderings`` (:func:`prepare`, then :func:`time_rows`), private keys dropped."""
    rows = [prepare(system, name, direct_dofs, natural_work) for name in orderings]
    time_rows(rows, system.rtol, repeat)
    for r in rows:
        for k in [k for k in r if k.startswith("_")]:
            del r[k]
    return rows


def _fmt(v, missing="skipped"):
    return missing if v is None else f"{v:,}"


def table(rows: list[dict], label: str) -> str:
    """The rows of one mesh as a markdown table."""
    head = ("| " + label + " | dofs | non-zeros | bandwidth | profile | LU fill, own order | LU fill, COLAMD "
            "| PARDISO factor | CG iterations | CG solve (ms) | mat-vec (ms) | CG solution vs mesh order |")
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        lines.append(f"| {r['ordering']} | {r['dofs']:,} | {r['nnz']:,} | {r['bandwidth']:,} | {r['profile']:,} "
                     f"| {_fmt(r['natural'])} | {_fmt(r['colamd'])} | {_fmt(r['pardiso'], 'n/a')} | {r['cg_iterations']} "
                     f"| {r['cg_time'] * 1e3:.1f} | {r['matvec'] * 1e3:.2f} | {r['x_diff']:.1e} |")
    return "\n".join(lines)


def drop_model(size: float, end_time: float, **geometry):
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    return build_model(builtin_scene("drop-test").with_overrides(element_size=size, end_time=end_time, **geometry))


def run(sizes=(1e-3, 5e-4), capture_time: float = 5e-4, repeat: int = 5, direct_dofs: int = 40_000,
        natural_work: float = 1e11, geometry: dict | None = None, orderings=ORDERINGS, out=print) -> list[list[dict]]:
    """The benchmark: one table per element size, printed with ``out``.

    Parameters
    ----------
    sizes : tuple of float
        Element sizes of the drop test (m).
    capture_time : float
        End time of the skfem run whose last Newton system is measured (s).
    repeat : int
        Interleaved timing rounds (the best is kept).
    direct_dofs : int
        Largest system factorised with COLAMD.
    natural_work : float
        Largest envelope work (multiply-adds) factorised in the numbering's own order.
    geometry : dict, optional
        Further overrides of the drop-test scene (``width``, ``thickness``, m).
    orderings : tuple of str
        Numberings of :data:`ORDERINGS`, the first the reference of the solution difference.
    out : callable
        Receives each printed line.

    Returns
    -------
    list of list of dict
        The rows of each table (:func:`measure`).
    """
    out("== skfem: node numbering and the Newton system (drop test, last Newton system before "
        f"t = {capture_time * 1e3:g} ms) ==")
    tables = []
    for h in sizes:
        model = drop_model(h, capture_time, **(geometry or {}))
        tic = time.perf_counter()
        system = capture(model)
        out(f"element size {h * 1e3:g} mm: {len(model.hexes):,} hexahedra; skfem run to t = {capture_time:g} s "
            f"in {time.perf_counter() - tic:.1f} s; CG tolerance {system.rtol:.1e} "
            f"(load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores)")
        rows = measure(system, orderings, repeat, direct_dofs, natural_work)
        out(table(rows, f"{h * 1e3:g} mm"))
        out(f"(load {os.getloadavg()[0]:.2f}; bandwidth and profile of the node-dof block, the impactor's dof "
            f"last; LU fill nnz(L) + nnz(U); own order skipped above {natural_work:.0e} envelope multiply-adds, "
            f"COLAMD above {direct_dofs:,} dofs; PARDISO n/a: pypardiso's MKL not found; CPU times of this process, best of {repeat} interleaved rounds)")
        tables.append(rows)
    return tables
