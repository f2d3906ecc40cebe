"""skfem backend: the compiled element path against the numpy reference path and finite differences.

The compiled kernels (numba, :mod:`cfm_backends.skfem_implicit.kernels`) must give the forces,
stiffness, Prony history and volume ratios of :func:`cfm_backends.skfem_implicit.element.evaluate`
(the numpy reference) to round-off, at general states and at repeated principal stretches (the
reference state, uniaxial states), for both volumetric treatments; the stiffness must be the
derivative of the forces (central differences).
"""

import numpy as np
import pytest

pytest.importorskip("skfem")
pytest.importorskip("numba")

from cfm_core.errors import NumericalError
from cfm_core.material import make_material
from cfm_backends.skfem_implicit import element
from cfm_backends.skfem_implicit.compiled import CompiledElements
from cfm_backends.skfem_implicit.constitutive import Constitutive, History
from cfm_backends.skfem_implicit.discretization import discretize

VOIGT_I = [0, 1, 2, 0, 1, 0]
VOIGT_J = [0, 1, 2, 1, 2, 2]


def _mesh(n=2, h=1e-3, distort=0.15, seed=0):
    """n x n x n hexahedra of edge h (m), inner nodes moved by up to distort x h (VTK order)."""
    g = np.linspace(0.0, n * h, n + 1)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    nodes = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    rng = np.random.default_rng(seed)
    nodes += distort * h * rng.uniform(-1, 1, nodes.shape)
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    hexes = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                hexes.append([idx[i, j, k], idx[i + 1, j, k], idx[i + 1, j + 1, k], idx[i, j + 1, k],
                              idx[i, j, k + 1], idx[i + 1, j, k + 1], idx[i + 1, j + 1, k + 1], idx[i, j + 1, k + 1]])
    return nodes, np.array(hexes)


@pytest.fixture(scope="module")
def setup():
    nodes, hexes = _mesh()
    disc = discretize(nodes, hexes, 950.0)
    mat = make_material("cfm")
    return disc, mat


def _states(disc):
    rng = np.random.default_rng(3)
    X = disc.nodes
    yield "general", 0.08 * 1e-3 * rng.standard_normal(X.shape)
    yield "reference", np.zeros_like(X)
    u = np.zeros_like(X)
    u[:, 2] = -0.3 * X[:, 2]  # uniaxial compression: two equal principal stretches
    yield "uniaxial", u
    u = np.zeros_like(X)
    u[:, 0] = 0.2 * X[:, 0]
    u[:, 1] = 0.2 * X[:, 1]  # equibiaxial tension: fibres active, repeated stretches
    yield "equibiaxial", u


@pytest.mark.parametrize("volumetric", ["mean-dilatation", "full"])
def test_compiled_equals_numpy_reference(setup, volumetric):
    disc, mat = setup
    ce = CompiledElements(disc, mat, volumetric)
    ref_mat = Constitutive(mat)
    P = disc.w.size
    for name, u in _states(disc):
        # two steps with history, so the Prony recurrence is compared too
        h_ref = History.relaxed(ref_mat.k, P)
        h_c = ce.relaxed()
        for dt, scale in ((1e-4, 0.5), (3e-4, 1.0)):
            r = element.evaluate(disc, ref_mat, scale * u, h_ref, dt, volumetric=volumetric)
            c = ce.evaluate(scale * u, h_c, dt)
            fscale = max(np.abs(r.force).max(), 1e-300)
            kscale = np.abs(r.stiffness).max()
            assert np.abs(c.force - r.force).max() <= 1e-11 * fscale + 1e-20, name
            assert np.abs(c.stiffness - r.stiffness).max() <= 1e-11 * kscale, name
            np.testing.assert_allclose(c.theta, r.theta, rtol=1e-13, err_msg=name)
            Hr = r.history.H[..., VOIGT_I, VOIGT_J]
            np.testing.assert_allclose(c.history.H, Hr, atol=1e-11 * max(np.abs(Hr).max(), 1.0), err_msg=name)
            h_ref, h_c = r.history, c.history


def test_stiffness_is_the_derivative_of_the_forces(setup):
    """Central differences of the compiled forces against the compiled stiffness (elastic step)."""
    disc, mat = setup
    ce = CompiledElements(disc, mat)
    rng = np.random.default_rng(5)
    u = 0.1e-3 * rng.standard_normal(disc.nodes.shape)
    u[:, 2] -= 0.15 * disc.nodes[:, 2]
    h = ce.relaxed()
    K = ce.evaluate(u, h, 1e-4).stiffness.copy()
    e, eps = 3, 1e-9
    for dof in (0, 7, 13, 23):
        a, i = divmod(dof, 3)
        node = disc.conn[e, a]
        up, um = u.copy(), u.copy()
        up[node, i] += eps
        um[node, i] -= eps
        fd = (ce.evaluate(up, h, 1e-4).force[e].copy() - ce.evaluate(um, h, 1e-4).force[e].copy()) / (2 * eps)
        np.testing.assert_allclose(K[e, :, dof], fd, rtol=2e-5, atol=2e-5 * np.abs(K[e]).max())


def test_reference_state_is_stress_free_to_the_bit(setup):
    disc, mat = setup
    ce = CompiledElements(disc, mat)
    r = ce.evaluate(np.zeros_like(disc.nodes), None, 1e-4)
    assert not r.force.any()
    np.testing.assert_array_equal(r.theta, 1.0)


def test_overflow_is_reported_with_the_element(setup):
    disc, _ = setup
    mat = make_material("cfm", {"k2": 200.0})
    ce = CompiledElements(disc, mat)
    u = np.zeros_like(disc.nodes)
    u[:, 0] = 4.0 * disc.nodes[:, 0]  # stretch 5 along x: k2 (x - 1)^2 = 2400, above 709
    with pytest.raises(NumericalError, match="element 0"):
        ce.evaluate(u, None, 1e-4)
