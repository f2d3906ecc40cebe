"""skfem backend: fixed sparse pattern, constraints and the linear solvers against scipy's spsolve."""

import numpy as np
import pytest
import scipy.sparse.linalg as sla

pytest.importorskip("skfem")
pytest.importorskip("numba")

from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene
from cfm_backends.skfem_implicit import linear
from cfm_backends.skfem_implicit.stepper import generalized_alpha
from cfm_backends.skfem_implicit.system import System

SMALL = dict(width=0.02, element_size=0.002, thickness=0.008)


@pytest.fixture(scope="module")
def system_matrix():
    """Newton matrix of the small drop test at a compressed state (dt = 50 us), constrained."""
    m = build_model(builtin_scene("drop-test").with_overrides(**SMALL))
    s = System(m)
    q = np.zeros(s.n)
    X = s.disc.nodes
    q[: 3 * s.n_nodes].reshape(-1, 3)[:, 2] = -0.2 * X[:, 2]
    ev = s.evaluate(q, s.relaxed_history(), 5e-5)
    am, af, beta, _ = generalized_alpha(0.0)
    data = (1 - af) * ev.K
    data[s.pattern.diag] += (1 - am) * s.mass / (beta * 5e-5 ** 2)
    linear.Constraints(s.pattern, s.constrained).apply(data)
    b = np.random.default_rng(0).standard_normal(s.n)
    b[s.constrained] = 0.0
    return s, data, b


def test_pattern_holds_the_assembled_matrix(system_matrix):
    s, data, _ = system_matrix
    A = s.pattern.matrix(data)
    assert (abs(A - A.T)).max() <= 1e-12 * abs(A).max()  # symmetric (consistent tangent of an energy)
    d = A.diagonal()
    assert np.all(d[s.constrained] > 0)
    assert not A[np.flatnonzero(s.constrained)[0]].toarray()[0, ~s.constrained].any()


@pytest.mark.parametrize("kind", ["pardiso", "cg", "superlu"])
def test_solvers_agree_with_spsolve(system_matrix, kind):
    if kind == "pardiso" and not linear.pardiso_available():
        pytest.skip("pypardiso not installed")
    s, data, b = system_matrix
    ref = sla.spsolve(s.pattern.matrix(data).tocsc(), b)
    solver = linear.make_solver(kind, s.pattern, s.n_nodes, rtol=1e-12, maxiter=2000)
    x, it = solver.solve(data, b)
    assert np.linalg.norm(x - ref) <= 1e-8 * np.linalg.norm(ref)
    if kind == "cg":
        assert it > 0 and solver.fallbacks == 0


def test_pardiso_analyses_once_and_refactors(system_matrix, monkeypatch):
    """The ordering and symbolic factorisation (phase 11) run once; each solve is phases 22 + 33."""
    if not linear.pardiso_available():
        pytest.skip("pypardiso not installed")
    s, data, b = system_matrix
    phases = []
    orig = linear.Pardiso._call

    def spy(self, phase, rhs):
        phases.append(phase)
        return orig(self, phase, rhs)

    monkeypatch.setattr(linear.Pardiso, "_call", spy)
    p = linear.Pardiso(s.pattern)
    x1, _ = p.solve(data, b)
    x2, _ = p.solve(2.0 * data, b)  # another matrix with the same pattern
    assert phases == [11, 22, 33, 22, 33]
    np.testing.assert_allclose(x2, 0.5 * x1, rtol=1e-9, atol=1e-12 * np.abs(x1).max())


def test_pardiso_solves_an_indefinite_system(system_matrix):
    """The compressed tissue's tangent can be indefinite at large steps: PARDISO (mtype -2) copes."""
    if not linear.pardiso_available():
        pytest.skip("pypardiso not installed")
    s, data, b = system_matrix
    shifted = data.copy()
    shifted[s.pattern.diag] -= 1.5 * np.median(data[s.pattern.diag])  # make it indefinite
    A = s.pattern.matrix(shifted).tocsc()
    x, _ = linear.Pardiso(s.pattern).solve(shifted, b)
    assert np.linalg.norm(A @ x - b) <= 1e-8 * np.linalg.norm(b)


@pytest.mark.parametrize("options", [dict(kernels="numpy"), dict(linear_solver="superlu"),
                                     dict(linear_solver="pardiso"), dict(linear_solver="direct")])
def test_runs_agree_across_kernels_and_solvers(options):
    """1 ms of the small drop test: the numpy reference kernels and every linear solver give the
    compiled / CG run's impulse and contact force to 1e-6 (the Newton tolerance, not the path)."""
    if options.get("linear_solver") == "pardiso" and not linear.pardiso_available():
        pytest.skip("pypardiso not installed")
    from cfm_core.simulation.registry import get_backend

    m = build_model(builtin_scene("drop-test").with_overrides(end_time=1e-3, **SMALL))
    b = get_backend("skfem")
    base = b.run(m, dt_max=2e-5, error_tol=None)
    r = b.run(m, dt_max=2e-5, error_tol=None, **options)
    assert r.steps == base.steps and r.info["kernels"] == options.get("kernels", "numba")
    np.testing.assert_allclose(r.impulse, base.impulse, rtol=1e-6, atol=1e-9 * np.abs(base.impulse).max())
    np.testing.assert_allclose(r.contact_force, base.contact_force, rtol=1e-5, atol=1e-6 * np.abs(base.contact_force).max())


def test_pardiso_that_cannot_load_is_refused_naming_why(monkeypatch):
    """linear_solver = 'pardiso' where MKL cannot be loaded: an InputError that says why (the
    loader's own message), not a claim that pypardiso is missing."""
    from cfm_backends.skfem_implicit import solver
    from cfm_core.errors import InputError

    def broken():
        raise ImportError("Shared library mkl_rt not found")

    monkeypatch.setattr(linear, "_mkl_rt", broken)
    assert linear.pardiso_problem() == "ImportError: Shared library mkl_rt not found"
    with pytest.raises(InputError, match=r"cannot be loaded here \(ImportError: Shared library mkl_rt not found\)"):
        solver._linear_solver(None, {"linear_solver": "pardiso"}, False)
