"""skfem backend: rigid impactors of every shape, moving along their free axes.

- the contact force is the gradient of the augmented-Lagrangian energy built on the reference gap
  (:func:`cfm_core.scene.impactor.impactor_gap`), and its tangent the derivative of that force
  (finite differences), for each shape, with the impactor free in x, y, z and with shares < 1;
- a centred impact on the full specimen (symmetry "none", impactor free in x, y, z) equals the
  quarter model with the same contact law;
- a flat punch (a "plane", or a "flat" covering the top) pressed slowly into a thin frictionless
  neo-Hookean layer whose lateral motion is held follows the closed-form uniaxial-strain response;
- an off-centre, oblique impact conserves the lateral momentum and balances the energy, the
  integrator's numerical dissipation included;
- bad impactor input is an InputError; a sharp-rimmed flat runs with a warning.
"""

import dataclasses

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_backends.skfem_implicit import impactor
from cfm_core.errors import InputError
from cfm_core.material.registry import make_material
from cfm_core.scene.builder import build_model
from cfm_core.scene.impactor import impactor_gap
from cfm_core.scene.model import RigidSphere
from cfm_core.scene.scene import builtin_scene
from cfm_core.simulation.registry import get_backend

BLOCK = dict(width=0.012, element_size=0.002, thickness=0.006)  # 108 elements on the full specimen


# ----------------------------------------------------------------------------- contact law
def _points(imp: RigidSphere, rng) -> np.ndarray:
    """Points 0-30 um inside the impactor, away from the regions' borders (m)."""
    c = np.asarray(imp.center)
    if imp.shape in ("sphere", "hemisphere"):
        d = rng.standard_normal((12, 3))
        d[:, 2] = -np.abs(d[:, 2]) - 0.3  # lower half
        d /= np.linalg.norm(d, axis=1)[:, None]
        return c + d * (imp.radius - rng.uniform(0, 3e-5, (12, 1)))
    if imp.shape == "plane":
        return c + np.column_stack([rng.uniform(-1e-2, 1e-2, (8, 2)), rng.uniform(0, 3e-5, 8)])
    a, r = imp.radius - imp.edge_radius, imp.edge_radius
    phi = rng.uniform(0, 2 * np.pi, 12)
    er = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(12)])
    depth = rng.uniform(1e-6, 3e-5, 12)
    rho = np.concatenate([rng.uniform(0.1, 0.8, 4) * a,                                      # bottom face
                          np.full(4, imp.radius), a + r * np.sin(rng.uniform(0.3, 1.2, 4))])  # side, rim
    z = np.concatenate([np.zeros(4), rng.uniform(2 * r, 3 * r, 4), np.zeros(4)])
    ang = np.arcsin(np.clip((rho[8:] - a) / r, -1, 1)) if r > 0 else np.zeros(4)
    z[8:] = r - r * np.cos(ang)
    p = c + rho[:, None] * er + z[:, None] * np.array([0, 0, 1.0])
    _, n = impactor_gap(imp, c, p)
    return p - depth[:, None] * n  # push inside along the outward normal


def _energy(imp, x, W, lam, k, share):
    g, _ = impactor_gap(imp, np.asarray(imp.center) + W, x)
    trial = np.maximum(lam - k * g, 0.0)
    return float(np.sum(share * trial ** 2) / (2 * k))


SHAPES = [RigidSphere(0.01, 1.0, (0.0, 0.0, 0.02), -1.0, shape="sphere"),
          RigidSphere(0.01, 1.0, (0.0, 0.0, 0.02), -1.0, shape="hemisphere", moves=(True, True, True)),
          RigidSphere(0.01, 1.0, (0.001, 0.0, 0.02), -1.0, shape="flat", edge_radius=0.002),
          RigidSphere(0.01, 1.0, (0.0, 0.0, 0.02), -1.0, shape="flat", edge_radius=0.0),
          RigidSphere(0.01, 1.0, (0.0, 0.0, 0.02), -1.0, shape="plane")]


@pytest.mark.parametrize("imp", SHAPES, ids=lambda s: f"{s.shape}-{s.edge_radius:g}")
@pytest.mark.parametrize("moves", [(False, False, True), (True, True, True), (True, False, True)])
def test_contact_force_and_tangent_against_the_reference_gap(imp, moves):
    imp = dataclasses.replace(imp, moves=moves)
    rng = np.random.default_rng(11)
    x = _points(imp, rng)
    n = x.shape[0]
    axes = np.flatnonzero(moves)
    dofs = 3 * n + np.arange(axes.size)
    nodes = np.arange(n)
    lam = rng.uniform(0.0, 0.02, n)
    k = 1e3
    share = np.where(rng.uniform(size=n) < 0.3, 0.5, 1.0)

    def split(y):
        W = np.zeros(3)
        W[axes] = y[3 * n:]
        return y[:3 * n].reshape(n, 3), W

    def force(y, tangent=False):
        xx, W = split(y)
        cs = impactor.evaluate(xx, W, imp, nodes, None, np.zeros(0, np.int64), k, dofs, axes, lam,
                               np.zeros(0), tangent=tangent, share_imp=share)
        f = np.zeros(y.size)
        for d, v in cs.grad:
            np.add.at(f, d, v)
        K = np.zeros((y.size, y.size))
        for r, c, v in cs.hess:
            np.add.at(K, (r, c), v)
        return f, K, cs

    y0 = np.concatenate([x.ravel(), np.zeros(axes.size)])
    f, K, cs = force(y0, tangent=True)
    assert cs.n_active == n
    eps = 1e-9
    grad = np.array([(_energy(imp, *split(y0 + eps * e), lam, k, share) - _energy(imp, *split(y0 - eps * e), lam, k,
                                                                                  share)) / (2 * eps)
                     for e in np.eye(y0.size)])
    np.testing.assert_allclose(f, grad, rtol=0, atol=1e-6 * np.abs(f).max())
    fd = np.column_stack([(force(y0 + eps * e)[0] - force(y0 - eps * e)[0]) / (2 * eps) for e in np.eye(y0.size)])
    np.testing.assert_allclose(K, fd, rtol=0, atol=1e-5 * np.abs(K).max())
    np.testing.assert_allclose(K, K.T, rtol=0, atol=1e-12 * np.abs(K).max())
    # the force on the impactor is minus the sum of the nodes' (Newton's third law)
    np.testing.assert_allclose(cs.force_vector, f[:3 * n].reshape(n, 3).sum(axis=0), atol=1e-14)


def test_bad_impactor_input_is_refused_and_a_sharp_rim_warns():
    base = RigidSphere(0.01, 1.0, (0.0, 0.0, 0.02), -1.0, shape="flat", edge_radius=0.001)
    assert impactor.check(base, "m") == []
    assert "singular" in impactor.check(dataclasses.replace(base, edge_radius=0.0), "m")[0]
    for bad, word in ((dict(edge_radius=0.01), "edge_radius"), (dict(shape="cone"), "shape"),
                      (dict(moves=(True, True, False)), "moves"), (dict(velocity_xy=(0.1, 0.0)), "velocity along x"),
                      (dict(mass=0.0), "mass"), (dict(radius=-1.0), "radius")):
        with pytest.raises(InputError, match=word):
            impactor.check(dataclasses.replace(base, **bad), "m")


# ----------------------------------------------------------------------------- symmetry
def test_centred_impact_full_specimen_equals_quarter_model():
    """Fixed steps and Newton to its round-off floor, so both runs take the same steps.

    The quarter model with the same contact law (shape "sphere": the contact of every shape,
    symmetry-plane nodes counted by their share) is compared; the contact force, k x penetration
    with k ~ 1e5 N/m, carries the displacement round-off of Newton's floor (~1e-15 m) as ~1e-10
    relative, so it and the energies (differences of such forces' work) are compared to 2e-9,
    positions and velocities to 1e-12. The paper's hemisphere path (each node with the full
    penalty even on a symmetry plane) differs from the full model by the penetration it leaves,
    0.4 % of the force on this coarse mesh (checked below 1 %).
    """
    end = dict(end_time=2e-3)
    quarter = build_model(builtin_scene("drop-test").with_overrides(**BLOCK, **end))
    full = build_model(builtin_scene("drop-test").with_overrides(**BLOCK, **end, symmetry="none"))
    full = dataclasses.replace(full, sphere=dataclasses.replace(full.sphere, moves=(True, True, True)))
    same_law = dataclasses.replace(quarter, sphere=dataclasses.replace(quarter.sphere, shape="sphere"))
    opts = dict(error_tol=None, dt=5e-5, dt_max=5e-5, rtol=1e-13, linear_solver="cg", cg_rtol=1e-12)
    skfem = get_backend("skfem")
    a, b = skfem.run(same_law, **opts), skfem.run(full, **opts)
    assert a.steps == b.steps and np.array_equal(a.t, b.t)

    def rel(x, y):
        return np.abs(x - y).max() / np.abs(x).max()

    assert rel(a.impactor_z, b.impactor_z) < 1e-12 and rel(a.impactor_v, b.impactor_v) < 1e-12
    assert rel(a.contact_force, b.contact_force) < 2e-9 and rel(a.impulse, b.impulse) < 2e-9
    for k in ("kinetic", "internal", "contact", "numerical_dissipation"):
        assert rel(a.energies[k], b.energies[k]) < 2e-9, k
    lat = b.impactor_lateral
    assert np.abs(lat["x"]).max() < 1e-15 and np.abs(lat["force_x"]).max() < 1e-10 * b.contact_force.max()
    paper = skfem.run(quarter, **opts)
    print(f"quarter (same law) vs full: force {rel(a.contact_force, b.contact_force):.1e}; paper's quarter "
          f"hemisphere vs full: {rel(paper.contact_force, b.contact_force):.1e}")
    assert rel(paper.contact_force, b.contact_force) < 0.01


# ----------------------------------------------------------------------------- uniaxial strain
@pytest.mark.parametrize("shape,edge", [("plane", 0.0), ("flat", 1e-3), ("flat", 0.0)])
def test_flat_punch_on_a_thin_layer_in_uniaxial_strain(shape, edge):
    """Neo-Hookean mu/2 (I1bar - 3) + kappa/2 (J - 1)^2 at F = diag(1, 1, lam): the axial Cauchy stress
    sigma = 2 mu / 3 lam^(-5/3) (lam^2 - 1) + kappa (lam - 1) on the undeformed area (Pa)."""
    w, h, v, mu, kappa = 0.004, 0.004, 0.05, 1e3, 1e4
    m = build_model(builtin_scene("drop-test").with_overrides(width=w, element_size=0.002, thickness=h))
    n = np.arange(m.n_nodes)
    fixed = np.concatenate([np.column_stack([n, np.zeros_like(n)]), np.column_stack([n, np.ones_like(n)])])
    punch = dataclasses.replace(m.sphere, shape=shape, radius=0.01, edge_radius=edge, center=(0.0, 0.0, h),
                                velocity=-v, mass=0.25)  # covers the whole top; heavy: slow, steady
    end = 0.15 * h / v
    m = dataclasses.replace(m, material=make_material("neo-hookean", {"mu": mu, "kappa": kappa}), density=0.1,
                            fixed_dofs=fixed, sphere=punch, mass_full=1.0, end_time=end, output_interval=end / 100)
    r = get_backend("skfem").run(m, frame_interval=end / 10)  # density 0.1 kg/m^3: inertia negligible
    top, bottom = np.abs(m.nodes[:, 2] - h) < 1e-9, np.abs(m.nodes[:, 2]) < 1e-9
    errors = []
    for t, u in r.frames[1:]:
        lam = 1.0 + (u[top, 2].mean() - u[bottom, 2].mean()) / h  # the layer's stretch from the mesh
        sigma = 2.0 * mu / 3.0 * lam ** (-5.0 / 3.0) * (lam * lam - 1.0) + kappa * (lam - 1.0)
        errors.append(r.contact_force[np.searchsorted(r.t, t)] / (-sigma * w * w) - 1.0)
    assert lam < 0.86
    sharp = [w for w in r.info["solver_warnings"] if "sharp rim" in w]
    assert len(sharp) == (shape == "flat" and edge == 0.0)
    print(f"{shape}: largest relative force error {np.abs(errors).max():.1e}")
    assert np.abs(errors).max() < 1e-3


# ----------------------------------------------------------------------------- oblique impact
def test_off_centre_oblique_impact_conserves_momentum_and_balances_energy():
    m = build_model(builtin_scene("drop-test").with_overrides(**BLOCK, end_time=4e-3, symmetry="none"))
    s = dataclasses.replace(m.sphere, shape="sphere", radius=0.01, center=(0.002, 0.001, 0.016),
                            velocity_xy=(0.3, -0.2), moves=(True, True, True))
    m = dataclasses.replace(m, sphere=s)
    r = get_backend("skfem").run(m)
    lat = r.impactor_lateral
    assert set(lat) == {"force_x", "force_y", "x", "y", "vx", "vy"} and all(a.shape == r.t.shape for a in lat.values())
    assert lat["vx"][0] == 0.3 and lat["vy"][0] == -0.2 and lat["x"][0] == 0.002
    assert r.contact_force.max() > 10.0 and np.abs(lat["force_x"]).max() > 0.01 * r.contact_force.max()
    # nothing holds the specimen laterally (frictionless plate): the total momentum along x and y is kept
    p0 = s.mass * np.hypot(*s.velocity_xy)
    print(f"momentum drift x {r.info['momentum_x_drift']:.1e}, y {r.info['momentum_y_drift']:.1e} kg m/s "
          f"(p0 {p0:.3g}); energy error {r.energy_error():.1e}, dissipation "
          f"{r.energies['numerical_dissipation'][-1]:.2e} J of {r.energies['kinetic'][0]:.3g} J")
    assert r.info["momentum_x_drift"] < 1e-7 * p0 and r.info["momentum_y_drift"] < 1e-7 * p0
    # energy: kinetic + internal + contact + the integrator's dissipation = the initial kinetic energy
    assert r.energy_error() < 1e-6
    d = r.energies["numerical_dissipation"]
    assert d[-1] >= 0.0 and d[-1] < 0.01 * r.energies["kinetic"][0]
