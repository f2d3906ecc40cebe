"""skfem backend: models with several parts (each its own material, parameters and density).

- parts that all carry the same material give the one-material run (the drop test on a small
  quarter model, every history to 1e-12);
- each part's elements are evaluated with that part's material (against the one-material
  evaluator on the whole mesh), compiled and numpy kernels agree, the lumped mass uses each
  element's density;
- a two-layer neo-Hookean column of very different stiffness, slowly compressed with free lateral
  faces, against the closed form of layers in series in uniaxial stress (finite strain: each
  layer's stretch solved for the common force), force and each layer's energy within 1 %.
"""

import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

pytest.importorskip("skfem")

from cfm_core.material.registry import make_material
from cfm_core.scene.builder import build_model
from cfm_core.scene.model import Part, Prescribed
from cfm_core.scene.scene import builtin_scene
from cfm_core.simulation.registry import get_backend

SMALL = dict(width=0.02, element_size=0.002, thickness=0.008)


def layered(model, z_cut: float, materials, densities, names=("bottom", "top")):
    """``model`` with two parts split at element-centroid height z_cut (m)."""
    zc = model.nodes[model.hexes, 2].mean(axis=1)
    below = np.flatnonzero(zc < z_cut)
    above = np.flatnonzero(zc >= z_cut)
    parts = tuple(Part(n, m, float(d), e) for n, m, d, e in zip(names, materials, densities, (below, above)))
    return dataclasses.replace(model, parts=parts, material=materials[0], density=float(densities[0]))


def test_same_material_in_every_part_equals_one_material():
    m = build_model(builtin_scene("drop-test").with_overrides(**SMALL, end_time=3e-3))
    twin = m.material.spec.bind(dict(m.material.values), m.material.moduli, m.material.elastic)  # another object
    m2 = layered(m, 0.004, (m.material, twin), (m.density, m.density))
    assert m2.multi_material
    skfem = get_backend("skfem")
    a = skfem.run(m, dt_max=5e-5)
    b = skfem.run(m2, dt_max=5e-5)
    assert a.steps == b.steps and np.array_equal(a.t, b.t)
    for name in ("contact_force", "impulse", "impactor_z", "impactor_v"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-12, atol=1e-12 * np.abs(
            getattr(a, name)).max(), err_msg=name)
    for k, e in a.energies.items():
        np.testing.assert_allclose(b.energies[k], e, rtol=1e-12, atol=1e-12 * np.abs(e).max() + 1e-300, err_msg=k)


def _two_part_model():
    m = build_model(builtin_scene("drop-test").with_overrides(width=0.008, element_size=0.002, thickness=0.004))
    soft = make_material("neo-hookean", {"mu": 1e3, "kappa": 2e4})
    stiff = make_material("cfm", None, "long-term", False)
    return layered(m, 0.002, (soft, stiff), (900.0, 1100.0))


@pytest.mark.parametrize("kernels", ["numba", "numpy"])
def test_each_part_is_evaluated_with_its_material(kernels):
    """Rows of the part evaluator = the one-material evaluator of the part's material on the whole mesh."""
    from cfm_backends.skfem_implicit import element
    from cfm_backends.skfem_implicit.system import System

    m = _two_part_model()
    sys_ = System(m, kernels=kernels)
    rng = np.random.default_rng(3)
    u = 2e-5 * rng.standard_normal((m.n_nodes, 3))
    ev = sys_.parts.evaluate(u, sys_.relaxed_history(), 1e-4)
    fe, Ke, theta = ev.force.copy(), ev.stiffness.copy(), ev.theta.copy()
    for p in m.part_list():
        one = System(dataclasses.replace(m, parts=(), material=p.material, density=p.density), kernels=kernels)
        if one.compiled is not None:
            ref = one.compiled.evaluate(u, one.relaxed_history(), 1e-4)
        else:
            ref = element.evaluate(one.disc, one.mat, u, one.relaxed_history(), 1e-4)
        np.testing.assert_allclose(fe[p.elements], ref.force[p.elements], rtol=0,
                                   atol=1e-13 * np.abs(ref.force).max())
        np.testing.assert_allclose(Ke[p.elements], ref.stiffness[p.elements], rtol=0,
                                   atol=1e-13 * np.abs(ref.stiffness).max())
        np.testing.assert_array_equal(theta[p.elements], ref.theta[p.elements])
    # lumped mass: every element's density x volume, distributed to its nodes
    total = sys_.mass[: 3 * m.n_nodes].reshape(-1, 3)[:, 0].sum()
    expect = sum(p.density * sys_.disc.volume[p.elements].sum() for p in m.part_list())
    assert total == pytest.approx(expect, rel=1e-13)
    assert sys_.kappa0 == pytest.approx(max(2e4, m.parts[1].material.values["kappa"]), rel=1e-12)


def test_compiled_and_numpy_parts_agree():
    from cfm_backends.skfem_implicit.system import System

    m = _two_part_model()
    rng = np.random.default_rng(5)
    a, b = System(m, kernels="numba"), System(m, kernels="numpy")
    q = np.zeros(a.n)
    q[: 3 * m.n_nodes] = 5e-5 * rng.standard_normal(3 * m.n_nodes)
    ea = a.evaluate(q, a.relaxed_history(), 2e-4)
    eb = b.evaluate(q, b.relaxed_history(), 2e-4)
    scale = np.abs(eb.f_int).max()
    np.testing.assert_allclose(ea.f_int, eb.f_int, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(ea.K, eb.K, rtol=0, atol=1e-10 * np.abs(eb.K).max())
    assert type(ea.history) is tuple and len(ea.history) == 2 and ea.history[0] is None  # neo-Hookean: elastic


# ----------------------------------------------------------------------------- layered column
MU = (1.0e3, 20.0e3)  # Pa, soft bottom and stiff top layer


def _uniaxial_stress_nominal(lam: float, mu: float, kappa: float) -> float:
    """Nominal axial stress (Pa) of the compressible neo-Hookean mu/2 (I1bar - 3) + kappa/2 (J - 1)^2
    in uniaxial stress at axial stretch lam: the lateral stretch t solves sigma_lateral = 0."""

    def sigma(t):  # Cauchy stresses (axial, lateral), b = diag(t^2, t^2, lam^2), J = lam t^2
        J = lam * t * t
        f = mu * J ** (-5.0 / 3.0)
        return (f * 2.0 * (lam * lam - t * t) / 3.0 + kappa * (J - 1.0),
                f * (t * t - lam * lam) / 3.0 + kappa * (J - 1.0))

    t = _lateral(lam, mu, kappa)
    return sigma(t)[0] * t * t


def _lateral(lam: float, mu: float, kappa: float) -> float:
    """Lateral stretch (-) of uniaxial stress: mu J^(-5/3) (t^2 - lam^2) / 3 + kappa (J - 1) = 0, J = lam t^2."""
    def sigma_lateral(t):
        J = lam * t * t
        return mu * J ** (-5.0 / 3.0) * (t * t - lam * lam) / 3.0 + kappa * (J - 1.0)

    return brentq(sigma_lateral, 0.3, 3.0, xtol=1e-15)


def _energy_density(lam: float, t: float, mu: float, kappa: float) -> float:
    """mu/2 (I1bar - 3) + kappa/2 (J - 1)^2 (Pa) at principal stretches (t, t, lam)."""
    J = lam * t * t
    return 0.5 * mu * (J ** (-2.0 / 3.0) * (lam * lam + 2.0 * t * t) - 3.0) + 0.5 * kappa * (J - 1.0) ** 2


def _series_force_per_area(delta: float, heights, mus, kappas) -> float:
    """Nominal stress (Pa) of layers in series shortened by -delta (m, delta < 0), each in uniaxial
    stress at the same nominal stress; stretches on the monotone branch lam > 0.75."""
    def stretch(P, mu, kappa):
        return brentq(lambda lam: _uniaxial_stress_nominal(lam, mu, kappa) - P, 0.75, 1.0, xtol=1e-15)

    def mismatch(P):
        return sum(h * (stretch(P, mu, k) - 1.0) for h, mu, k in zip(heights, mus, kappas)) - delta

    low = max(_uniaxial_stress_nominal(0.75, mu, k) for mu, k in zip(mus, kappas))
    return brentq(mismatch, low, 0.0, xtol=1e-14)


def test_two_layer_column_against_series_closed_form():
    """Quasi-static compression of a slender two-layer column (free lateral faces): force and each
    layer's energy. The tied interface holds the layers' lateral stretches equal where the closed
    form lets them differ; that error decays with the column's slenderness (measured: force 3.2e-3,
    layer energy 8.8e-3 at 20 mm height; 1.6e-3 and 4.4e-3 at 40 mm, the height used)."""
    width, h = 0.004, 0.04
    m = build_model(builtin_scene("drop-test").with_overrides(width=width, element_size=0.002, thickness=h))
    kappas = tuple(2.0 * mu / 3.0 for mu in MU)  # Poisson's ratio 0 at small strain: the layers barely
    # change width, so the tied interface hardly constrains them and the column is in uniaxial stress
    mats = tuple(make_material("neo-hookean", {"mu": mu, "kappa": k}) for mu, k in zip(MU, kappas))
    tol = 1e-9
    top = np.flatnonzero(np.abs(m.nodes[:, 2] - h) < tol)
    bottom = np.flatnonzero(np.abs(m.nodes[:, 2]) < tol)
    delta = -0.1 * h
    fixed = np.concatenate([m.fixed_dofs, np.stack([bottom, np.full(bottom.size, 2)], axis=1)])
    col = dataclasses.replace(m, sphere=None, plane=None, sphere_nodes=np.zeros(0, np.int64),
                              plane_nodes=np.zeros(0, np.int64), fixed_dofs=fixed, end_time=1.0,
                              output_interval=0.05, prescribed=Prescribed(top, 2, np.array([0.0, 1.0]),
                                                                          np.array([0.0, delta])),
                              meta={**m.meta, "quasi_static": True}, stop_after_separation=False)
    col = layered(col, h / 2, mats, (0.0, 0.0))
    r = get_backend("skfem").run(col)
    u = np.interp(r.t, [0.0, 1.0], [0.0, delta])
    sel = r.t >= 0.2
    closed = np.array([_series_force_per_area(d, (h / 2, h / 2), MU, kappas) for d in u[sel]]) * width ** 2
    err = np.abs(r.reaction_force[sel] / closed - 1.0)
    # each layer's energy (hyperelastic: the work of its internal forces) against the closed form
    P = closed[-1] / width ** 2
    energies = r.info["part_energies"]
    worst = 0.0
    for name, mu, k in zip(("bottom", "top"), MU, kappas):
        lam = brentq(lambda x: _uniaxial_stress_nominal(x, mu, k) - P, 0.75, 1.0, xtol=1e-15)
        expect = _energy_density(lam, _lateral(lam, mu, k), mu, k) * width ** 2 * h / 2
        worst = max(worst, abs(energies[name]["internal"] / expect - 1.0))
    total = energies["bottom"]["internal"] + energies["top"]["internal"]
    assert total == pytest.approx(r.energies["internal"][-1], rel=1e-12)
    assert energies["bottom"]["internal"] > 10 * energies["top"]["internal"]  # the soft layer takes the work
    print(f"two-layer column: largest relative force error {err.max():.2e}, layer energy error {worst:.2e}")
    assert err.max() < 0.01 and worst < 0.01


def test_bad_parts_are_input_errors():
    from cfm_core.errors import InputError

    m = _two_part_model()
    skfem = get_backend("skfem")
    a, b = m.parts
    doubled = dataclasses.replace(b, elements=np.concatenate([b.elements, a.elements[:1]]))
    overlap = dataclasses.replace(m, parts=(a, doubled))
    with pytest.raises(InputError, match="belongs to 2 parts"):
        skfem.run(overlap)
    with pytest.raises(InputError, match="part names must differ"):
        skfem.run(dataclasses.replace(m, parts=(a, dataclasses.replace(b, name=a.name))))
    with pytest.raises(InputError, match="part 'top' .*density = 0.0 kg/m\\^3 must be > 0"):
        skfem.run(dataclasses.replace(m, parts=(a, dataclasses.replace(b, density=0.0))))
