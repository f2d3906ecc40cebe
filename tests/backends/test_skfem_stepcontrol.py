"""skfem backend: step size from the local error estimate, and the energy balance with numerical dissipation.

Small quarter model (10 x 10 mm, 2 mm elements, 8 mm), loading phase (4 ms). The truth for the
time-discretisation error is an skfem run with a 10x tighter tolerance and small steps.
"""

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_core import post as postprocess
from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene
from cfm_core.simulation.registry import get_backend

SMALL = dict(width=0.02, element_size=0.002, thickness=0.008)


@pytest.fixture(scope="module")
def model():
    return build_model(builtin_scene("drop-test").with_overrides(end_time=0.004, **SMALL))


@pytest.fixture(scope="module")
def runs(model):
    b = get_backend("skfem")
    return {tol: b.run(model, error_tol=tol, dt_max=1e-3) for tol in (1e-2, 1e-3)}


def _filtered_error(r, ref, mass):
    """Peak difference and relative L2 of the CFC 600 filtered acceleration against ``ref`` (-)."""
    t, _, a = postprocess.acceleration_histories(r, mass)
    t0, _, a0 = postprocess.acceleration_histories(ref, mass)
    c = postprocess.compare_histories(t, a, t0, a0)
    return (a.max() - a0.max()) / a0.max(), c["rel_l2"]


def test_steps_follow_the_tolerance(runs):
    """A 10x tighter tolerance takes 10^(1/3) ~ 2x more steps (third-order local error); the estimate,
    not dt_max = 1 ms, sets the step; at the tighter one Newton needs about 3 iterations per step
    (at 1e-2 the steps reach 0.4 ms and Newton about 6)."""
    steps = {tol: r.steps for tol, r in runs.items()}
    print("steps:", steps, "largest step (s):", {t: r.dt_max for t, r in runs.items()})
    assert 1.5 * steps[1e-2] < steps[1e-3] < 4.0 * steps[1e-2]
    assert runs[1e-2].dt_max < 1e-3
    assert runs[1e-3].info["error_tol"] == 1e-3
    assert runs[1e-3].info["newton_iterations"] / runs[1e-3].steps < 3.5


@pytest.mark.slow
def test_error_falls_with_the_tolerance():
    """Whole pulse, steps set by the estimate alone (dt_max 1 ms), against numba on the same mesh:
    the filtered history's error falls with the tolerance (measured: rel. L2 8.6 % at 1e-2, 2.3 %
    at 3e-4)."""
    pytest.importorskip("numba")
    m = build_model(builtin_scene("drop-test").with_overrides(**SMALL))
    ref = get_backend("numba").run(m)
    b = get_backend("skfem")
    err = {tol: _filtered_error(b.run(m, error_tol=tol, dt_max=1e-3), ref, m.mass_full) for tol in (1e-2, 3e-4)}
    print("tolerance -> (peak difference, rel. L2) vs numba:", err)
    assert err[3e-4][1] < 0.5 * err[1e-2][1]
    assert abs(err[3e-4][0]) < 0.04 and err[3e-4][1] < 0.04


def test_energy_balance_closes_with_the_numerical_dissipation():
    """Full small drop test, default options: balance error < 1 % with dissipation as its own term."""
    m = build_model(builtin_scene("drop-test").with_overrides(**SMALL))
    r = get_backend("skfem").run(m)
    e = r.energies
    d = e["numerical_dissipation"]
    assert d[-1] > 0.0  # rho_inf = 0 removes energy (per step not sign-definite with nonlinear forces)
    print(f"energy error {r.energy_error():.2e}, numerical dissipation {d[-1] / e['kinetic'][0]:.2%} "
          f"of the initial kinetic energy")
    assert r.energy_error() < 0.01
    # the same balance without the dissipation term misses by about that term
    total = e["kinetic"] + e["internal"] + e["contact"] - e["external"]
    scale = max(np.max(e["kinetic"] + e["internal"]), np.max(np.abs(e["external"])))
    assert abs(np.max(np.abs(total - total[0])) / scale - d[-1] / scale) < 0.01
