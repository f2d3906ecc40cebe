"""skfem backend: hex8 forces and consistent tangent, patch test, volumetric locking."""

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_core.material.registry import make_material
from cfm_core.scene.mesh import structured_hex_mesh
from cfm_core.scene.model import Model, Prescribed
from cfm_core.simulation.registry import get_backend
from cfm_backends.skfem_implicit import element
from cfm_backends.skfem_implicit.constitutive import Constitutive, History
from cfm_backends.skfem_implicit.discretization import discretize


def _mesh(distort=True):
    nodes, hexes = structured_hex_mesh(1e-3, 1e-3, 1e-3, 2, 1, 1)
    if distort:
        rng = np.random.default_rng(3)
        nodes = nodes + 0.08e-3 * rng.standard_normal(nodes.shape)
    return nodes, hexes


def _fd_tangent(disc, mat, u, hist, dt, vol):
    K = element.evaluate(disc, mat, u, hist, dt, volumetric=vol).stiffness
    h = 1e-10
    worst = 0.0
    for e in range(disc.n_elements):
        for k in range(24):
            a, i = divmod(k, 3)
            up, um = u.copy(), u.copy()
            up[disc.conn[e, a], i] += h
            um[disc.conn[e, a], i] -= h
            fp = element.evaluate(disc, mat, up, hist, dt, tangent=False, volumetric=vol).force[e]
            fm = element.evaluate(disc, mat, um, hist, dt, tangent=False, volumetric=vol).force[e]
            worst = max(worst, np.abs((fp - fm) / (2 * h) - K[e, :, k]).max())
    return worst / np.abs(K).max(), np.abs(K - K.transpose(0, 2, 1)).max() / np.abs(K).max()


@pytest.mark.parametrize("vol", ["mean-dilatation", "full"])
@pytest.mark.parametrize("state", ["random", "undeformed", "uniaxial"])
def test_tangent_matches_finite_differences(vol, state):
    """Exact at repeated principal stretches too (undeformed and uniaxial states), with Prony.

    At the undeformed state the CFM fibre switch (x = 1) makes second derivatives jump (docs/conventions.md
    section 2), so central differences there are checked on the smooth Neo-Hookean material.
    """
    mat = Constitutive(make_material("neo-hookean" if state == "undeformed" else "cfm"))
    nodes, hexes = _mesh(distort=state == "random")
    disc = discretize(nodes, hexes, 950.0)
    if state == "random":
        u = 1e-4 * np.random.default_rng(0).standard_normal(nodes.shape)
    elif state == "undeformed":
        u = np.zeros_like(nodes)
    else:  # homogeneous uniaxial: lateral eigenvalues equal at every Gauss point
        u = nodes * np.array([0.2, 0.2, -0.3])
    hist = History.relaxed(mat.k, disc.w.size)
    err, asym = _fd_tangent(disc, mat, u, hist, 1e-3, vol)
    assert err < 1e-5 and asym < 1e-12


def test_forces_are_the_gradient_of_the_discrete_energy():
    """Elastic: f = dPi/du with Pi = sum_q w psi_iso(F) + V U(theta) (mean dilatation)."""
    mat = Constitutive(make_material("cfm", elastic=True))
    nodes, hexes = _mesh()
    disc = discretize(nodes, hexes, 950.0)
    u = 1e-4 * np.random.default_rng(5).standard_normal(nodes.shape)

    def energy(u):
        F = element.deformation_gradient(disc, u)
        J = np.linalg.det(F)
        theta = (disc.w * J).sum(axis=1) / disc.volume
        U, _, _ = mat.volumetric(theta)
        return float((disc.w.ravel() * mat.energy_iso(F.reshape(-1, 3, 3))).sum() + (disc.volume * U).sum())

    f = np.zeros_like(nodes)
    np.add.at(f, disc.conn, element.evaluate(disc, mat, u, None, 0.0, tangent=False).force.reshape(-1, 8, 3))
    h = 1e-9
    for n, i in [(0, 0), (4, 2), (7, 1), (11, 2)]:
        up, um = u.copy(), u.copy()
        up[n, i] += h
        um[n, i] -= h
        assert (energy(up) - energy(um)) / (2 * h) == pytest.approx(f[n, i], rel=1e-5, abs=1e-9 * np.abs(f).max())


def test_patch_homogeneous_deformation_on_distorted_mesh():
    mat = Constitutive(make_material("cfm", elastic=True))
    nodes, hexes = _mesh()
    disc = discretize(nodes, hexes, 950.0)
    G = np.array([[-0.2, 0.05, 0.0], [0.01, 0.1, 0.02], [0.0, -0.03, 0.15]])
    u = nodes @ G.T
    F = element.deformation_gradient(disc, u)
    np.testing.assert_allclose(F, np.broadcast_to(np.eye(3) + G, F.shape), atol=1e-13)
    ev = element.evaluate(disc, mat, u, None, 0.0, tangent=False)
    np.testing.assert_allclose(ev.theta, np.linalg.det(np.eye(3) + G), rtol=1e-13)
    f = np.zeros_like(nodes)
    np.add.at(f, disc.conn, ev.force.reshape(-1, 8, 3))
    assert np.abs(f.sum(axis=0)).max() < 1e-12 * np.abs(f).max()  # self-equilibrated
    # a diagonal F on the regular mesh: the nodes of the shared plane x = 0.5 mm carry no x force
    nodes, hexes = _mesh(distort=False)
    disc = discretize(nodes, hexes, 950.0)
    u = nodes * np.array([-0.2, 0.1, 0.15])
    f = np.zeros_like(nodes)
    np.add.at(f, disc.conn, element.evaluate(disc, mat, u, None, 0.0, tangent=False).force.reshape(-1, 8, 3))
    assert np.abs(f[[1, 4, 7, 10], 0]).max() < 1e-10 * np.abs(f).max()


def test_inverted_element_is_reported():
    mat = Constitutive(make_material("cfm"))
    nodes, hexes = _mesh(distort=False)
    disc = discretize(nodes, hexes, 950.0)
    u = np.zeros_like(nodes)
    u[nodes[:, 2] > 0.5e-3, 2] = -1.5e-3  # top below bottom
    with pytest.raises(element.Inverted) as err:
        element.evaluate(disc, mat, u, None, 0.0)
    assert err.value.element in (0, 1) and err.value.value <= 0


def _bonded_block_force(kappa, volumetric):
    """Bonded block (top and bottom clamped), top pressed down 1 %: reaction force (N)."""
    mat = make_material("neo-hookean", {"mu": 1e3, "kappa": kappa})
    nodes, hexes = structured_hex_mesh(1e-3, 1e-3, 1e-3, 2, 2, 2)
    top = np.flatnonzero(nodes[:, 2] > 1e-3 - 1e-12)
    bottom = np.flatnonzero(nodes[:, 2] < 1e-12)
    fixed = np.array([(n, d) for n in bottom for d in range(3)] + [(n, d) for n in top for d in (0, 1)])
    model = Model(name="bonded", nodes=nodes, hexes=hexes, density=0.0, material=mat, end_time=1e-3,
                  output_interval=1e-3, fixed_dofs=fixed,
                  prescribed=Prescribed(top, 2, np.array([0.0, 1e-3]), np.array([0.0, -1e-5])),
                  stop_after_separation=False, meta={"quasi_static": True})
    r = get_backend("skfem").run(model, volumetric=volumetric, segment_steps=1)
    return -r.reaction_force[-1]


def test_mean_dilatation_is_free_of_volumetric_locking():
    """kappa/mu from 1e3 to 1e5: the locking-free force saturates, the fully integrated one grows ~kappa."""
    md = [_bonded_block_force(k, "mean-dilatation") for k in (1e6, 1e8)]
    full = [_bonded_block_force(k, "full") for k in (1e6, 1e8)]
    print(f"bonded block force (N): mean dilatation {md}, full integration {full}")
    assert md[1] / md[0] < 1.5
    assert full[1] / full[0] > 20.0
    assert full[0] > 2.0 * md[0]
