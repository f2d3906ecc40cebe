"""Material-point driver of the torch backend against the core's numpy reference."""

import numpy as np
import pytest

pytest.importorskip("torch")

from cfm_backends.torch_explicit import TorchExplicitBackend  # noqa: E402
from cfm_core.material import kinematics as kin  # noqa: E402
from cfm_core.material import reference  # noqa: E402
from cfm_core.errors import NumericalError  # noqa: E402
from cfm_core.material.registry import make_material  # noqa: E402


def history(n=121, end=0.02):
    """Mixed shear / compression history starting undeformed; ends with a hold (relaxation)."""
    t = np.linspace(0.0, end, n)
    F = np.empty((n, 3, 3))
    for i, s in enumerate(np.minimum(t / (0.7 * end), 1.0)):
        F[i] = np.array([[1 + 0.3 * s, 0.2 * s, 0.0], [0.05 * s, 1 - 0.35 * s, 0.1 * s], [0.0, 0.0, 1 - 0.2 * s]])
    return t, F


@pytest.mark.parametrize("moduli,elastic", [("long-term", False), ("instantaneous", False), ("long-term", True)])
def test_cfm_history_equals_reference(moduli, elastic):
    material = make_material("cfm", {}, moduli, elastic)
    t, F = history()
    sig = TorchExplicitBackend().point(material, t, F)
    ref = kin.to_voigt(reference.stress_history(material, t, F))
    assert np.abs(sig - ref).max() <= 1e-10 * np.abs(ref).max()


def test_repeated_eigenvalues_and_jump_at_t0():
    material = make_material("cfm")
    t = np.array([0.0, 1e-4, 2e-4, 5e-4])
    F = np.array([np.eye(3), np.diag([0.7, 1.2, 1.2]), np.diag([0.6, 1.3, 1.3]), np.diag([1.4, 0.85, 0.85])])
    sig = TorchExplicitBackend().point(material, t, F)
    ref = kin.to_voigt(reference.stress_history(material, t, F))
    assert np.abs(sig - ref).max() <= 1e-10 * np.abs(ref).max()
    assert np.abs(sig[0]).max() == 0.0


def test_float32_close_to_float64():
    material = make_material("cfm")
    t, F = history()
    a = TorchExplicitBackend().point(material, t, F, dtype="float32")
    b = TorchExplicitBackend().point(material, t, F)
    assert np.abs(a - b).max() <= 1e-4 * np.abs(b).max()


def test_float32_overflow_is_reported_float64_is_correct():
    material = make_material("cfm")
    t = np.array([0.0, 1e-3])
    lam = 5.0                                   # k2 (x - 1)^2 = 1.66 * 11.6^2 = 223: > 88.7, < 709
    F = np.array([np.eye(3), np.diag([lam, lam ** -0.5, lam ** -0.5])])
    with pytest.raises(NumericalError, match="float64") as info:
        TorchExplicitBackend().point(material, t, F, dtype="float32")
    assert info.value.element == 1 and info.value.time == pytest.approx(1e-3)
    sig = TorchExplicitBackend().point(material, t, F)
    ref = kin.to_voigt(reference.stress_history(material, t, F))
    assert np.isfinite(sig).all() and np.abs(sig - ref).max() <= 1e-10 * np.abs(ref).max()


def test_inverted_point():
    material = make_material("cfm")
    F = np.array([np.eye(3), np.diag([-0.5, 1.0, 1.0])])
    with pytest.raises(NumericalError, match="inverted"):
        TorchExplicitBackend().point(material, np.array([0.0, 1e-3]), F)


def test_cli_point_with_torch(tmp_path):
    from cfm_core.cli import main

    t, F = history(11)
    path = tmp_path / "F.csv"
    rows = ["t,F11,F12,F13,F21,F22,F23,F31,F32,F33"] + [",".join(f"{v:.17g}" for v in [ti, *f.ravel()])
                                                      for ti, f in zip(t, F)]
    path.write_text("\n".join(rows) + "\n")
    out = tmp_path / "s.csv"
    assert main(["point", "--history", str(path), "--backend", "torch", "--out", str(out)]) == 0
    sig = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:]
    ref = kin.to_voigt(reference.stress_history(make_material("cfm"), t, F))
    assert np.abs(sig - ref).max() <= 1e-9 * np.abs(ref).max()
