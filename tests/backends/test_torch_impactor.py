"""Impactor shapes and lateral motion on the torch explicit backend."""

from dataclasses import replace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit import TorchExplicitBackend  # noqa: E402
from cfm_backends.torch_explicit.impactor import gap, land  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.scene.impactor import gap as gap_reference  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402

BASE = builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.002)
SHAPES = [("hemisphere", 0.02, 0.0), ("sphere", 0.02, 0.0), ("flat", 0.01, 0.003), ("flat", 0.01, 0.0),
          ("plane", 0.0, 0.0)]


def _points(rng, n=4000):
    """Points around an impactor of radius ~1 cm: inside, outside, near the rim, on the axis."""
    p = rng.uniform(-0.02, 0.02, (n, 3))
    p[:50, 0:2] = 0.0                         # on the axis
    p[50:100, 2] = rng.uniform(-1e-4, 1e-4, 50)  # near the bottom face
    return p


@pytest.mark.parametrize("shape,R,r", SHAPES)
def test_gap_equals_the_numpy_reference(shape, R, r):
    rng = np.random.default_rng(1)
    c = np.array([0.001, -0.002, 0.003])
    x = _points(rng) + c
    g_ref, n_ref = gap_reference(shape, R, r, c, x)
    g, n = gap(shape, R, r, torch.as_tensor((x - c).T))
    g, n = g.numpy(), n.numpy().T
    fin = np.isfinite(g_ref)
    assert np.array_equal(fin, np.isfinite(g))
    np.testing.assert_allclose(g[fin], g_ref[fin], rtol=0, atol=1e-14 * 0.02)
    np.testing.assert_allclose(n, n_ref, rtol=0, atol=1e-14)


@pytest.mark.parametrize("shape,R,r", SHAPES)
def test_landing_is_exact_and_its_derivative_matches_finite_differences(shape, R, r):
    """s lands the point on the surface (gap 0 to round-off); ds/dd equals central differences."""
    rng = np.random.default_rng(2)
    P = _points(rng, 3000).T
    g0, n0 = gap(shape, R, r, torch.as_tensor(P))
    inside = (g0 < 0.0).numpy()
    # push directions: the normal with a random tilt (a fixed dof removed), still pointing outwards
    D = n0.numpy() + 0.3 * rng.uniform(-1.0, 1.0, P.shape) * (rng.uniform(size=P.shape[1]) < 0.5)
    D /= np.linalg.norm(D, axis=0)
    ok = inside & ((D * n0.numpy()).sum(0) > 0.3)
    assert ok.sum() > 200
    P, D = torch.as_tensor(P[:, ok]), torch.as_tensor(D[:, ok])
    s, ds = land(shape, R, r, P, D)
    assert bool((s > 0.0).all())
    # the hemisphere's landing is on its sphere (a tilted push may land above the centre plane)
    g, _ = gap("sphere" if shape == "hemisphere" else shape, R, r, P + s * D)
    assert float(g.abs().max()) < 1e-15
    h = 1e-7
    for axis in range(3):
        e = torch.zeros((3, 1), dtype=P.dtype)
        e[axis] = h
        fd = (land(shape, R, r, P - e, D)[0] - land(shape, R, r, P + e, D)[0]) / (2 * h)
        # the rim of a flat impactor is C1 only: skip points whose landing changes face within +-h
        sp, sm = land(shape, R, r, P + e, D)[1], land(shape, R, r, P - e, D)[1]
        smooth = (sp - sm).abs().amax(0) < 1e-3
        np.testing.assert_allclose(fd[smooth].numpy(), ds[axis][smooth].numpy(), rtol=0, atol=2e-6)


def _full(end=0.004, **sphere):
    m = replace(build_model(BASE.with_overrides(symmetry="none")), end_time=end)
    return replace(m, sphere=replace(m.sphere, **sphere))


@pytest.mark.parametrize("moves", [(False, False, True), (True, True, True)])
def test_centred_full_model_equals_the_quarter_model(moves):
    """A centred impact on the full specimen (symmetry "none") gives the quarter model's force
    history (full-model forces): the mirrored mesh is symmetric, so only round-off separates them
    (measured 1.4e-13 relative); the free impactor (x, y, z: the general contact) stays centred."""
    quarter = replace(build_model(BASE), end_time=0.004)
    ref = TorchExplicitBackend().run(quarter)
    res = TorchExplicitBackend().run(_full(moves=moves))
    assert res.steps == ref.steps
    assert np.max(np.abs(res.contact_force - ref.contact_force)) < 1e-10 * np.max(ref.contact_force)
    if moves[0]:
        assert np.max(np.abs(res.impactor_lateral["x"])) < 1e-15


def _oblique(shape, R, r, mu=0.3, end=0.003):
    """An off-centre, oblique impact of a free impactor on a free-floating block (no plate)."""
    m = _full(end=end)
    top = float(m.nodes[:, 2].max())
    sp = replace(m.sphere, shape=shape, radius=R, edge_radius=r, moves=(True, True, True), velocity_xy=(0.3, -0.2),
                 center=(0.001, -0.0015, top + (R if shape == "sphere" else 0.0) + 1e-4))
    return replace(m, sphere=sp, plane=None, plane_nodes=np.zeros(0, dtype=np.int64), friction=mu)


@pytest.mark.parametrize("shape,R,r", [("sphere", 0.02, 0.0), ("flat", 0.004, 0.002)])
def test_off_centre_oblique_impact_conserves_momentum_and_energy(shape, R, r):
    model = _oblique(shape, R, r)
    res = TorchExplicitBackend().run(model)
    p0 = model.sphere.mass * np.abs(model.sphere.velocity_vector).max()
    lat = res.impactor_lateral
    assert np.max(np.abs(lat["force_x"])) > 1e-3 * np.max(res.contact_force) > 0.0   # friction acts sideways
    for k in ("momentum_x_drift", "momentum_y_drift", "momentum_z_drift"):
        assert res.info[k] < 1e-12 * p0, k
    assert abs(res.info["energy_error"]) < 1e-4
    # nodes land on the surface; the friction correction after the landing moves touching nodes along
    # the tangent, which on the curved parts leaves a penetration of order (v_t dt)^2 / R (as the
    # hemisphere contact does): far below a micrometre
    assert res.info["max_sphere_penetration"] < 1e-9


def test_batch_of_general_impactors_equals_the_runs_alone():
    """Two oblique flat impacts with different speeds and parameters in one batch (synchronising and
    sync-free) equal the runs done alone."""
    a = _oblique("flat", 0.004, 0.002)
    scene = BASE.with_overrides(symmetry="none", parameters={"k2": 2.5})
    b = replace(a, material=build_model(scene).material, sphere=replace(a.sphere, velocity=-1.3))
    alone = [TorchExplicitBackend().run(m) for m in (a, b)]
    for sync_free in (False, True):
        batch = TorchExplicitBackend().run_batch([a, b], sync_free=sync_free)
        for r, ref in zip(batch, alone):
            assert r.steps == ref.steps
            assert np.max(np.abs(r.contact_force - ref.contact_force)) < 1e-10 * np.max(ref.contact_force)
            assert np.max(np.abs(r.impactor_lateral["y"] - ref.impactor_lateral["y"])) < 1e-15
            if sync_free:       # the step reads nothing back (the history and flags once per chunk)
                assert r.info["host_syncs_per_step"] < 0.1
    assert np.max(np.abs(alone[0].contact_force[:50] - alone[1].contact_force[:50])) > 0.0


def test_flat_punch_converges_as_its_rim_sharpens():
    """A centred flat punch whose rim lies over a row of top nodes (radius 10 um beyond them): the
    peak force approaches the sharp punch's (edge_radius = 0.1 nm: an explicit backend refuses 0, a
    stress singularity) as edge_radius -> 0 (measured differences 2.8 %, 1.0 %, 0.02 % for r = 100,
    50, 25 um)."""
    m = replace(build_model(BASE), end_time=0.002)
    top = float(m.nodes[:, 2].max())
    rho0 = float(np.unique(m.nodes[:, 0])[2])
    peaks = []
    for r in (1e-4, 5e-5, 2.5e-5, 1e-10):
        sp = replace(m.sphere, shape="flat", radius=rho0 + 1e-5, edge_radius=r, center=(0.0, 0.0, top + 1e-4))
        peaks.append(float(np.max(TorchExplicitBackend().run(replace(m, sphere=sp)).contact_force)))
    diff = np.abs(np.array(peaks[:-1]) - peaks[-1]) / peaks[-1]
    assert np.all(np.diff(diff) < 0.0) and diff[-1] < 1e-3 < diff[0]
