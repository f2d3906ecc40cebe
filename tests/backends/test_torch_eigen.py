"""Batched symmetric 3x3 eigen-solver of the torch backend (the numba backend's algorithm)."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit.eigen import eig3, eig3_full, eig3_jacobi  # noqa: E402


def batch(matrices, dtype=torch.float64):
    return torch.as_tensor(np.stack(matrices, axis=-1), dtype=dtype)


def rotated(d, rng):
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    A = Q @ np.diag(d) @ Q.T
    return 0.5 * (A + A.T)


def errors(A, m, Q):
    A, m, Q = (x.double().numpy() for x in (A, m, Q))
    out = []
    for e in range(A.shape[-1]):
        a, q = A[:, :, e], Q[:, :, e]
        scale = np.abs(a).max()
        out.append((np.abs(q @ np.diag(m[:, e]) @ q.T - a).max() / scale, np.abs(q.T @ q - np.eye(3)).max(),
                    np.abs(np.sort(m[:, e]) - np.linalg.eigvalsh(a)).max() / scale))
    return np.array(out)


def spectra():
    rng = np.random.default_rng(1)
    mats = [rotated(d, rng) for d in ([1.3, 0.8, 1.1], [2.0, 1.0, 1.0], [0.5, 0.5, 1.7], [1.0, 1.0 + 1e-9, 0.3],
                                      [4.0, 1e-3, 0.2], [1.0, 1.0, 1.0])]
    mats += [np.eye(3), np.diag([2.0, 1.0, 1.0]), np.diag([0.2, 3.0, 0.2])]
    F = np.eye(3) + 0.3 * rng.normal(size=(40, 3, 3))
    mats += [f.T @ f for f in F]
    return mats


def test_accuracy_general_and_repeated_spectra():
    A = batch(spectra())
    m, Q = eig3_full(A)
    err = errors(A, m, Q)
    assert err.max() < 1e-14


def test_exact_for_diagonal_and_isotropic_matrices():
    A = batch([np.eye(3), np.diag([2.0, 1.0, 1.0]), 3.0 * np.eye(3)])
    m, Q, fallback = eig3(A)
    assert not fallback.any()
    assert torch.equal(Q[:, :, 0], torch.eye(3, dtype=torch.float64))
    np.testing.assert_array_equal(np.sort(m[:, 1].numpy()), [1.0, 1.0, 2.0])


def test_round_off_isotropic_matrix_goes_to_jacobi():
    A = np.eye(3)
    A[0, 1] = A[1, 0] = 1e-30
    m, Q, fallback = eig3(batch([A, np.diag([2.0, 1.0, 1.5])]))
    assert fallback.tolist() == [True, False]
    m, Q = eig3_full(batch([A]))
    assert errors(batch([A]), m, Q).max() < 1e-15


def test_jacobi_alone():
    A = batch(spectra())
    m, Q = eig3_jacobi(A)
    assert errors(A, m, Q).max() < 1e-14


def test_same_as_numba_eig3():
    """Same eigenvalues and eigenvectors as the numba kernel to round-off (vectors up to sign and the
    order of the remaining pair, which depend on the basis the last rotation starts from)."""
    pytest.importorskip("numba")
    from cfm_backends.numba_explicit.kernels import eigen as nb

    A = batch(spectra())
    m, Q = eig3_full(A)
    for e in range(A.shape[-1]):
        a = A[:, :, e].numpy()
        r = nb.eig3(a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2])
        mn, Qn = np.array(r[:3]), np.array(r[3:]).reshape(3, 3)
        mt, Qt = m[:, e].numpy(), Q[:, :, e].numpy()
        assert mt[0] == pytest.approx(mn[0], rel=0, abs=1e-14 * np.abs(a).max())   # the isolated one
        i, j = np.argsort(mt), np.argsort(mn)
        np.testing.assert_allclose(mt[i], mn[j], rtol=0, atol=1e-14 * np.abs(a).max())
        gaps = np.abs(np.diff(np.sort(mn)))
        if gaps.min() > 1e-6 * np.abs(a).max():   # eigenvectors are unique (up to sign) only then
            for k in range(3):
                pt, pn = np.outer(Qt[:, i[k]], Qt[:, i[k]]), np.outer(Qn[:, j[k]], Qn[:, j[k]])
                np.testing.assert_allclose(pt, pn, rtol=0, atol=1e-12)


def test_float32():
    A = batch(spectra(), torch.float32)
    m, Q = eig3_full(A)
    assert m.dtype == torch.float32 and Q.dtype == torch.float32
    assert errors(A, m, Q).max() < 1e-5
