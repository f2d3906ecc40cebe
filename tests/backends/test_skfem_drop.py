"""skfem backend: drop test on a small quarter model (10 x 10 mm quarter, 2 mm elements, 8 mm).

Result format as every backend (post-processing does not know the backend), impulse consistent
with the integrator, energy balance, penetration below 1 % of the element size, insensitivity to
the penalty, and agreement with the explicit numba backend on the same mesh.
"""

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_core import post as postprocess
from cfm_core.scene.builder import build_model
from cfm_core.simulation.registry import get_backend
from cfm_core.scene.scene import builtin_scene

SMALL = dict(width=0.02, element_size=0.002, thickness=0.008)
OPTIONS = dict(dt_max=5e-5)  # 2.5x the output interval: keeps this test short (default: 2e-5)


@pytest.fixture(scope="module")
def run():
    m = build_model(builtin_scene("drop-test").with_overrides(**SMALL))
    return m, get_backend("skfem").run(m, **OPTIONS)


def test_result_format(run):
    m, r = run
    assert r.backend == "skfem" and r.steps == len(r.t) - 1 and r.wall_time > 0
    for name in ("contact_force", "impulse", "acceleration", "impactor_z", "impactor_v"):
        a = getattr(r, name)
        assert a.shape == r.t.shape and np.isfinite(a).all(), name
    assert r.reaction_force is None
    assert set(r.energies) == {"kinetic", "internal", "hourglass", "contact", "external", "numerical_dissipation"}
    assert not r.energies["hourglass"].any()
    np.testing.assert_allclose(r.acceleration, r.contact_force / m.mass_full)
    assert 0 < r.dt_min <= r.dt_max <= OPTIONS["dt_max"] * (1 + 1e-12)
    assert r.info["separated"] and r.t[-1] < m.end_time
    assert r.impactor_v[0] == -1.0 and r.impactor_v[-1] > 0  # rebounds


def test_impulse_is_the_impactor_momentum_change(run):
    m, r = run
    np.testing.assert_allclose(r.impulse, m.mass_full * (r.impactor_v - r.impactor_v[0]), atol=1e-12)
    trapezoid = np.concatenate([[0], np.cumsum(0.5 * (r.contact_force[1:] + r.contact_force[:-1]) * np.diff(r.t))])
    assert abs(trapezoid[-1] - r.impulse[-1]) < 0.02 * r.impulse[-1]


def test_energy_balance_and_penetration(run):
    m, r = run
    print(f"energy error {r.energy_error():.2e}, penetration/h {r.info['penetration_ratio']:.1e}")
    assert r.energy_error() < 0.03  # numerical dissipation of generalized-alpha (rho_inf = 0)
    assert r.info["penetration_ratio"] < 0.01
    assert r.energies["kinetic"][0] == pytest.approx(0.5 * m.mass_full * 1.0 ** 2)


def test_postprocessing_does_not_know_the_backend(run):
    m, r = run
    t, a_raw, a = postprocess.acceleration_histories(r, m.mass_full)
    s = postprocess.summarize(r, {"impactor_mass": m.mass_full})
    print(f"skfem small drop test: peak {s['peak_g']:.2f} g at {s['t_peak'] * 1e3:.2f} ms")
    assert 50 < s["peak_g"] < 110 and s["backend"] == "skfem"


def test_peak_insensitive_to_penalty():
    """Loading phase up to 4 ms: impulse changes < 0.5 % for a 10x stiffer penalty (same steps)."""
    m = build_model(builtin_scene("drop-test").with_overrides(end_time=0.004, **SMALL))
    b = get_backend("skfem")
    r1 = b.run(m, penalty_factor=1e3, dt_max=1e-4)
    r2 = b.run(m, penalty_factor=1e4, dt_max=1e-4)
    assert r1.info["penetration_ratio"] < 0.01 and r2.info["penetration_ratio"] < 0.001
    assert abs(r1.impulse[-1] - r2.impulse[-1]) < 5e-3 * r2.impulse[-1]


def test_agrees_with_numba_on_the_same_mesh(run):
    pytest.importorskip("numba")
    try:
        numba = get_backend("numba")
    except Exception as exc:  # noqa: BLE001 - the numba backend is developed separately
        pytest.skip(f"numba backend not usable: {exc}")
    m, r = run
    rn = numba.run(m)
    t, _, a = postprocess.acceleration_histories(r, m.mass_full)
    tn, _, an = postprocess.acceleration_histories(rn, m.mass_full)
    c = postprocess.compare_histories(t, a, tn, an)
    peak = (a.max() - an.max()) / an.max()
    print(f"skfem vs numba (small mesh): peak {peak:+.2%}, rel L2 {c['rel_l2']:.2%}")
    assert abs(peak) < 0.01 and c["rel_l2"] < 0.02
    assert r.info["newton_iterations"] / r.steps <= 3.0


@pytest.mark.slow
@pytest.mark.parametrize("thickness", [0.005, 0.008])
def test_full_mesh_agrees_with_numba(thickness):
    """The paper's specimen (quarter, 1 mm elements): filtered peak within 1 %, rel. L2 < 2 %,
    at most 3 Newton iterations per step on average (measured: -0.30 % / 1.67 % / 2.6 at 5 mm,
    -0.27 % / 0.25 % / 2.5 at 8 mm)."""
    pytest.importorskip("numba")
    m = build_model(builtin_scene("drop-test").with_overrides(thickness=thickness))
    r = get_backend("skfem").run(m)
    rn = get_backend("numba").run(m)
    t, _, a = postprocess.acceleration_histories(r, m.mass_full)
    tn, _, an = postprocess.acceleration_histories(rn, m.mass_full)
    c = postprocess.compare_histories(t, a, tn, an)
    peak = (a.max() - an.max()) / an.max()
    print(f"{thickness * 1e3:.0f} mm: skfem vs numba peak {peak:+.2%}, rel L2 {c['rel_l2']:.2%}")
    assert abs(peak) < 0.01 and c["rel_l2"] < 0.02
    assert r.info["newton_iterations"] / r.steps <= 3.0
