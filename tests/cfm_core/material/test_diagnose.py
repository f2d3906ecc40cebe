"""A non-finite stress names the term that failed, its inputs and the right row and time, on every
backend (shared case volumetric-J-near-zero): at J = 1e-32 (pure dilatation, isochoric stretches 1)
kappa/9 (1/J - J^-10) overflows float64, so the volumetric term is the cause, not the fibres (whose
exponent is 0 there), also for the 'ogden' material, which has no fibres at all."""

from pathlib import Path

import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.errors import NumericalError
from cfm_core.material.diagnose import describe_nonfinite, nonfinite_term
from cfm_core.material.registry import make_material
from cfm_core.simulation import point
from cfm_core.simulation.registry import backend_for

DATA = Path(__file__).resolve().parents[2] / "data"
OVERFLOW = DATA / "F_dilatation_overflow.csv"  # rows t = 0, 1e-3, 2e-3 s; J = 1, 0.5, 1e-32


def test_the_volumetric_term_is_named_at_j_1e_32():
    m = make_material("cfm", {}, "long-term", True)
    J = 1e-32
    term, inputs, what = nonfinite_term(m, np.full(3, J ** (2.0 / 3.0)))
    assert term.name == "ogden-volumetric" and what == "derivative"
    assert inputs["J"] == pytest.approx(J, rel=1e-12) and inputs["kappa"] == 666.1e3
    # at J = 1e-30 every term is finite (kappa/9 J^-10 = 7.4e304 < 1.8e308): nothing to blame
    assert nonfinite_term(m, np.full(3, 1e-20)) is None


def test_the_fibre_term_is_named_when_its_exponential_overflows():
    m = make_material("cfm", {"k2": 500.0}, "long-term", True)
    mvals = np.array([0.04, 1.0, 1.0])  # F = diag(0.2, 1, 1): isochoric stretches 0.34, 1.71, 1.71
    term, inputs, _ = nonfinite_term(m, mvals)
    assert term.name == "circular-fibers" and inputs["k2"] == 500.0
    # k2 (x - 1)^2 with x = l2^2 = 2.92 (pair 2-3): 500 * 3.7 = 1840 > 709
    assert inputs["l2"] == pytest.approx(0.2 ** (-1 / 3), rel=1e-12)
    assert "non-finite" in describe_nonfinite(m, mvals) and "circular-fibers" in describe_nonfinite(m, mvals)


@pytest.mark.parametrize("material", ["cfm", "ogden"])
@pytest.mark.parametrize("backend", ["numpy", "numba", "torch", "skfem"])
def test_every_backend_names_the_volumetric_term_row_2_and_t_2ms(material, backend, tmp_path, capsys):
    if backend != "numpy":
        pytest.importorskip(backend)
    out = tmp_path / "s.csv"
    args = ["point", "--material", material, "--history", str(OVERFLOW), "--out", str(out), "--backend", backend]
    if material == "cfm":
        args.append("--elastic")
    with _no_runtime_warning():
        assert main(args) == 3
    err = capsys.readouterr().err
    assert "volumetric term 'ogden-volumetric'" in err and "J = 1e-32" in err, err
    assert "fibre" not in err and "709" not in err and "k2" not in err, err
    assert ("row 2 (t = 0.002 s)" in err or "point 2 (t = 0.002 s)" in err), err
    assert not out.exists()


def test_run_history_error_carries_row_and_time():
    t, F = point.read_history(OVERFLOW)
    with pytest.raises(NumericalError) as err:
        point.run_history(make_material("ogden"), t, F, backend_for("numpy"))
    assert err.value.element == 2 and err.value.time == pytest.approx(2e-3)


class _no_runtime_warning:
    """No numpy RuntimeWarning (overflow, invalid value) may reach the user: turn them into errors."""

    def __enter__(self):
        import warnings

        self._ctx = warnings.catch_warnings()
        self._ctx.__enter__()
        warnings.simplefilter("error", RuntimeWarning)

    def __exit__(self, *exc):
        return self._ctx.__exit__(*exc)


@pytest.mark.parametrize("mvals", [[0.0, 1.0, 1.0], [-1e-18, 1.0, 1e18]])
def test_j_zero_or_an_indefinite_c_is_described_not_a_zero_division(mvals):
    """An eigenvalue of C that underflowed to 0 made term_inputs raise "ZeroDivisionError: 0.0 cannot be
    raised to a negative power" while describing the failure (a traceback in place of the message)."""
    m = make_material("cfm", {}, "long-term", True)
    assert nonfinite_term(m, mvals) is None
    text = describe_nonfinite(m, mvals)
    assert "crushed to no volume" in text and "material 'cfm'" in text
