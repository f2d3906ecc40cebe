"""Kinematic contact of the numba backend: symmetry, momentum, penetration, energy balance."""

import numpy as np
import pytest

pytest.importorskip("numba")
from cfm_backends.numba_explicit import NumbaExplicitBackend
from fixtures.hand_derived import NeoHookeanStandIn, drop_test_model

MAT = NeoHookeanStandIn(mu=50.0e3, kappa=1.0e6)
SMALL = dict(width=12e-3, thickness=4e-3, h=2e-3, mass=0.05, velocity=1.0, end_time=20e-3)


@pytest.fixture(scope="module")
def quarter():
    return NumbaExplicitBackend().run(drop_test_model(MAT, quarter=True, **SMALL))


def test_quarter_equals_full(quarter):
    full = NumbaExplicitBackend().run(drop_test_model(MAT, quarter=False, **SMALL))
    assert quarter.steps == full.steps
    scale = np.abs(full.acceleration).max()
    np.testing.assert_allclose(quarter.t, full.t, rtol=1e-12, atol=0)
    np.testing.assert_allclose(quarter.acceleration, full.acceleration, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(quarter.impulse, full.impulse, rtol=0, atol=1e-8 * np.abs(full.impulse).max())
    for key, e in full.energies.items():
        np.testing.assert_allclose(quarter.energies[key], e, rtol=0, atol=1e-8 * full.energies["kinetic"][0])


def test_elastic_impact(quarter):
    r = quarter
    assert r.info["stop_reason"] == "separated" and r.impactor_v[-1] > 0.9  # elastic rebound
    assert r.energy_error() < 5e-3
    assert r.hourglass_ratio() < 0.1
    assert r.info["max_sphere_penetration"] < 1e-14
    assert 0.0 <= r.energies["contact"][-1] < 0.02 * r.energies["kinetic"][0]
    assert np.all(r.contact_force >= 0.0) and r.acceleration.max() > 10 * 9.81
    # the impulse is the integral of the contact force and the impactor's momentum change
    np.testing.assert_allclose(r.impulse[-1], 0.05 * (r.impactor_v[-1] - r.impactor_v[0]), rtol=1e-9)
    assert np.all(np.isfinite(r.acceleration)) and r.dt_min > 0.2 * r.dt_max


def test_momentum_and_penetration_without_supports():
    model = drop_test_model(MAT, quarter=False, plane=False, stop_after_separation=False,
                            **{**SMALL, "end_time": 3e-3})
    r = NumbaExplicitBackend().run(model)
    p0 = 0.05 * 1.0
    assert r.info["momentum_z_drift"] < 1e-12 * p0
    assert r.info["max_sphere_penetration"] < 1e-14
    assert r.contact_force.max() > 0.0


def test_friction_dissipates_and_balances(quarter):
    r = NumbaExplicitBackend().run(drop_test_model(MAT, quarter=True, friction=0.5, **SMALL))
    assert r.energy_error() < 1e-2
    assert r.energies["contact"][-1] > quarter.energies["contact"][-1]
    assert r.acceleration.max() != pytest.approx(quarter.acceleration.max(), rel=1e-6)


def test_threads_give_identical_histories():
    """Every history, the energies included, is the same bits with one thread and two: the
    element pass sums its chunks' work in chunk order, the energy pass its fixed node ranges.
    The model is large enough for several chunks and node ranges (with one of each both sums
    would be serial anyway)."""
    model = drop_test_model(MAT, quarter=True, **{**SMALL, "width": 48e-3, "thickness": 8e-3, "h": 1e-3,
                                                  "end_time": 0.5e-3})
    assert model.n_elements >= 4 * 32 * 32 and model.nodes.shape[0] > 4096
    one = NumbaExplicitBackend().run(model, threads=1)
    two = NumbaExplicitBackend().run(model, threads=2)
    assert one.info["threads"] == 1 and two.info["threads"] == 2
    for name in ("t", "contact_force", "impulse", "acceleration", "impactor_z", "impactor_v", "reaction_force"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name), err_msg=name)
    assert set(one.energies) == set(two.energies) and len(one.energies) >= 4
    for name in one.energies:
        np.testing.assert_array_equal(one.energies[name], two.energies[name], err_msg=name)
    assert one.energies["internal"][-1] > 0.0


def test_gravity_free_fall():
    model = drop_test_model(MAT, quarter=True, gravity=9.81, **{**SMALL, "end_time": 2e-3})
    model = type(model)(**{**model.__dict__, "sphere": type(model.sphere)(
        model.sphere.radius, model.sphere.mass, (0.0, 0.0, 0.1), -1.0)})   # far above: no contact
    r = NumbaExplicitBackend().run(model)
    t = r.t
    np.testing.assert_allclose(r.impactor_v, -1.0 - 9.81 * t, rtol=1e-12)
    np.testing.assert_allclose(r.impactor_z, 0.1 - t - 0.5 * 9.81 * t ** 2, rtol=1e-9)
    assert np.all(r.contact_force == 0.0)
    assert r.energy_error() < 1e-9 and r.energies["external"][-1] > 0


def test_time_step_collapse_and_options():
    from cfm_core.errors import NumericalError

    model = drop_test_model(MAT, quarter=True, **SMALL)
    with pytest.raises(NumericalError, match=r"time-step collapse at t = .* element \d+") as info:
        NumbaExplicitBackend().run(model, collapse=0.97)     # any stiffening "collapses" the step
    assert info.value.quantity == "time step" and info.value.element is not None
    r = NumbaExplicitBackend().run(model, dt_max=1e-6, hourglass=0.05, hourglass_wave="longitudinal")
    assert r.dt_max <= 1e-6 and r.info["hourglass_wave"] == "longitudinal" and r.energy_error() < 5e-3
