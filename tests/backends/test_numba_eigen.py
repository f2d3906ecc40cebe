"""Symmetric 3x3 eigen-solver of the numba backend: accuracy for general and repeated spectra."""

import numpy as np
import pytest

pytest.importorskip("numba")
from cfm_backends.numba_explicit.kernels.eigen import eig3, eig3_jacobi


def _decompose(A, solver=eig3):
    r = solver(A[0, 0], A[0, 1], A[0, 2], A[1, 1], A[1, 2], A[2, 2])
    return np.array(r[:3]), np.array(r[3:]).reshape(3, 3)


def _errors(A, solver=eig3):
    m, Q = _decompose(A, solver)
    scale = np.abs(A).max()
    recon = np.abs(Q @ np.diag(m) @ Q.T - A).max() / scale
    ortho = np.abs(Q.T @ Q - np.eye(3)).max()
    values = np.abs(np.sort(m) - np.linalg.eigvalsh(A)).max() / scale
    return recon, ortho, values


def _rotated(d, rng):
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    A = Q @ np.diag(d) @ Q.T
    return 0.5 * (A + A.T)


@pytest.mark.parametrize("solver", [eig3, eig3_jacobi])
def test_random_spd(solver):
    rng = np.random.default_rng(0)
    for _ in range(3000):
        F = np.eye(3) + 0.4 * rng.normal(size=(3, 3))
        C = F.T @ F
        assert max(_errors(C, solver)) < 1e-13


@pytest.mark.parametrize("solver", [eig3, eig3_jacobi])
def test_exactly_repeated(solver):
    for A in (np.eye(3), 2.5 * np.eye(3), np.diag([2.0, 2.0, 3.0]), np.diag([0.7, 1.3, 1.3]),
              np.diag([1.1, 0.4, 1.1]), np.zeros((3, 3))):
        m, Q = _decompose(A, solver)
        np.testing.assert_allclose(np.sort(m), np.sort(np.diag(A)), rtol=0, atol=1e-15)
        np.testing.assert_allclose(Q @ np.diag(m) @ Q.T, A, rtol=0, atol=1e-15)
    m, Q = _decompose(np.eye(3), solver)
    np.testing.assert_array_equal(Q, np.eye(3))  # the reference state: exact, no rotation


def test_nearly_repeated_and_rotated():
    rng = np.random.default_rng(1)
    for k in range(4000):
        g = 10.0 ** rng.uniform(-16, -3)
        base = 10.0 ** rng.uniform(-3, 2)
        d = base * [np.array([1.0, 1.0, 1.7]), np.array([1.0, 1.0 + g, 0.6]),
                    np.array([1.0, 1.0 + g, 1.0 - g]), np.array([1.0, 1.0 + g, 1.0 + 2.3 * g]),
                    10.0 ** rng.uniform(-6, 0, size=3)][k % 5]
        assert max(_errors(_rotated(d, rng))) < 1e-13


def test_branch_free_path_covers_the_undeformed_state():
    """eig3_hybrid (the vectorised element loop's decomposition) returns an exactly diagonal
    matrix it cannot decompose (the undeformed C = I, any isotropic diagonal) as that diagonal
    with Q = I, flagged ok, so such elements skip the scalar fallback; the values are eig3's to
    the bit. A non-diagonal isotropic-to-round-off matrix is still left to the fallback."""
    from cfm_backends.numba_explicit.kernels.eigen import eig3_hybrid

    for A in (np.eye(3), 2.5 * np.eye(3), np.zeros((3, 3)), np.diag([1.0, 1.0, 1.0 + 1e-18])):
        args = (A[0, 0], A[0, 1], A[0, 2], A[1, 1], A[1, 2], A[2, 2])
        ok, *r = eig3_hybrid(*args)
        assert ok
        np.testing.assert_array_equal(r[:3], np.diag(A))
        np.testing.assert_array_equal(np.reshape(r[3:], (3, 3)), np.eye(3))
        assert tuple(r) == tuple(eig3(*args))
    A = np.eye(3) + 1e-19 * np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    ok, *_ = eig3_hybrid(A[0, 0], A[0, 1], A[0, 2], A[1, 1], A[1, 2], A[2, 2])
    assert not ok
    m, Q = _decompose(A)
    np.testing.assert_allclose(Q @ np.diag(m) @ Q.T, A, rtol=0, atol=1e-15)
