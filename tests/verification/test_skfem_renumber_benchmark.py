"""The skfem renumbering benchmark (benchmarks/skfem_renumber.py): the permuted Newton system is
P A P^T exactly, the envelope measures agree with a dense count, block-Jacobi CG gives the same
solution in every numbering, and the table runs on a tiny mesh."""

import numpy as np
import pytest
import scipy.sparse as sps

from cfm_verification.benchmarks import skfem_renumber as sr

pytest.importorskip("skfem")

TINY = dict(width=0.012, thickness=0.004)  # 6 x 6 mm quarter, 2 mm elements: 3 x 3 x 2 hexahedra


@pytest.fixture(scope="module")
def system():
    return sr.capture(sr.drop_model(2e-3, 1e-4, **TINY), kernels="numpy")


def _dense(pattern, data):
    return sps.csr_matrix((data, pattern.indices, pattern.indptr), shape=(pattern.n,) * 2).toarray()


@pytest.mark.parametrize("ordering", sr.ORDERINGS)
def test_permuted_system_is_p_a_pt_and_round_trips(system, ordering):
    order = sr.dof_order(sr.node_order(ordering, system.nodes, system.hexes), system.pattern.n)
    assert np.array_equal(np.sort(order), np.arange(system.pattern.n))
    assert order[-1] == system.pattern.n - 1  # the impactor's dof stays last
    pat, data, b = sr.permute(system, order)
    A = _dense(system.pattern, system.data)
    assert np.array_equal(_dense(pat, data), A[np.ix_(order, order)])
    assert np.array_equal(b, system.b[order])
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    there = sr.NewtonSystem(pat, data, b, system.rtol, system.maxiter, system.n_nodes, system.nodes, system.hexes)
    pat2, data2, b2 = sr.permute(there, back)
    assert np.array_equal(pat2.keys, system.pattern.keys) and np.array_equal(data2, system.data)
    assert np.array_equal(b2, system.b)


def test_envelope_against_a_dense_count():
    rng = np.random.default_rng(3)
    n = 40
    M = (rng.random((n, n)) < 0.08).astype(float)
    M = M + M.T + np.eye(n)
    S = sps.csr_matrix(M)
    S.sort_indices()
    bw = prof = 0
    work = 0.0
    for i in range(n):
        f = min(j for j in range(n) if M[i, j] != 0)
        bw, prof, work = max(bw, i - f), prof + (i - f), work + (i - f) ** 2
    class P:  # noqa: E306 - the two arrays envelope reads
        indices, indptr = S.indices, S.indptr
    assert sr.envelope(P, n) == (bw, prof, work)


def test_cg_solution_is_the_same_in_every_numbering(system):
    rows = sr.measure(system, ("mesh", "rcm", "random"), repeat=1)
    A = sps.csr_matrix((system.data, system.pattern.indices, system.pattern.indptr), shape=(system.pattern.n,) * 2)
    for r in rows:  # each solves the mesh-numbered system to the backend's tolerance
        assert np.linalg.norm(A @ r["x"] - system.b) <= system.rtol * np.linalg.norm(system.b)
        assert abs(r["cg_iterations"] - rows[0]["cg_iterations"]) <= 1
        assert r["x_diff"] < 1e-10
        # the fill of a factorisation in the numbering's own order stays within the envelope
        # (L and U: the profile each, the diagonal, and the impactor's border row and column)
        assert r["natural"] <= 2 * r["profile"] + 4 * r["dofs"]
        assert r["nnz"] == system.pattern.nnz
    assert rows[1]["bandwidth"] < rows[2]["bandwidth"]  # RCM against a scattered numbering


def test_table_runs_on_a_tiny_mesh():
    lines = []
    tables = sr.run(sizes=(2e-3,), capture_time=1e-4, repeat=1, geometry=TINY, out=lines.append)
    text = "\n".join(lines)
    assert [r["ordering"] for r in tables[0]] == list(sr.ORDERINGS)
    for name in sr.ORDERINGS:
        assert f"| {name} |" in text
    assert "load" in text
    assert all(r["natural"] is not None and r["colamd"] is not None for r in tables[0])
