"""torch's branch-free eigen-decomposition when the rotation's denominator underflows.

With C = diag(0.9999, 1, 1) plus an off-diagonal 1e-24 (float32) or 1e-170 (float64) in the equal pair,
dd = 0 and 4 buw^2 underflow to 0: the rotation's t was 2 buw / 0 = inf, the eigenvalues (0.9999, -inf,
inf), not flagged for the fallback, and a float32 run with kappa = 1e9 stopped blaming the lipid term.
"""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit.eigen import eig3  # noqa: E402


@pytest.mark.parametrize("dtype, off", [(torch.float32, 1e-24), (torch.float64, 1e-170)])
def test_an_underflowing_rotation_leaves_the_pair_unrotated(dtype, off):
    A = torch.tensor([[0.9999, 0.0, 0.0], [0.0, 1.0, off], [0.0, off, 1.0]], dtype=dtype)
    m, Q, fallback = eig3(A[:, :, None])
    assert not bool(fallback[0]) and bool(torch.isfinite(m).all()) and bool(torch.isfinite(Q).all())
    truth = np.linalg.eigvalsh(A.double().numpy())
    assert np.sort(m[:, 0].double().numpy()) == pytest.approx(truth, rel=1e-6)
    Qn = Q[:, :, 0].double().numpy()
    assert Qn.T @ Qn == pytest.approx(np.eye(3), abs=1e-6)
