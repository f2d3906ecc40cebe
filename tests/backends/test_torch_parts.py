"""Parts (per-region material, parameters, density) on the torch explicit backend."""

from dataclasses import replace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit import TorchExplicitBackend  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.scene.model import Part  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402

BASE = builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.002)
END = 0.004


def _model(scene=BASE, end=END):
    return replace(build_model(scene), end_time=end)


def split(model, materials, densities, z_cut=0.004):
    """The model with two parts by element centroid z: below z_cut, then above (user order)."""
    zc = model.nodes[model.hexes].mean(axis=1)[:, 2]
    low, high = np.flatnonzero(zc < z_cut), np.flatnonzero(zc >= z_cut)
    parts = (Part("low", materials[0], densities[0], low), Part("high", materials[1], densities[1], high))
    return replace(model, parts=parts, material=materials[0], density=densities[0])


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.fixture(scope="module")
def one():
    model = _model()
    return model, TorchExplicitBackend().run(model, frame_interval=1e-3)


def test_parts_with_one_material_equal_the_one_material_run(one):
    """Two parts carrying the model's material and density give the one-material run (round-off:
    the parts reorder the elements, so the nodal sums add in another order)."""
    model, ref = one
    two = split(model, (model.material, model.material), (model.density, model.density))
    res = TorchExplicitBackend().run(two, frame_interval=1e-3)
    assert res.steps == ref.steps
    assert rel(res.contact_force, ref.contact_force) < 1e-12
    assert rel(res.energies["internal"], ref.energies["internal"]) < 1e-12
    # the Prony state per part, in the user's element numbering: part rows = the one-material rows
    for st, st_ref in zip(res.frame_state[1:], ref.frame_state[1:]):
        assert "prony_H" not in st and st["prony_dt"] == pytest.approx(st_ref["prony_dt"], rel=1e-12)
        for p, entry in zip(two.parts, st["parts"]):
            assert entry["name"] == p.name and np.array_equal(entry["elements"], p.elements)
            H, S0 = st_ref["prony_H"][:, p.elements], st_ref["prony_S0"][p.elements]
            assert entry["prony_H"].shape == H.shape == (3, p.elements.size, 6)
            np.testing.assert_allclose(entry["prony_H"], H, rtol=0, atol=1e-10 * np.abs(H).max())
            np.testing.assert_allclose(entry["prony_S0"], S0, rtol=0, atol=1e-10 * np.abs(S0).max())


def test_two_parts_of_very_different_stiffness():
    """A stiff elastic part (neo-Hookean, no Prony terms, denser) under a CFM part: the energy
    balance holds, the first stable step is the stiff part's alone, and the frame state has no
    Prony entries for the elastic part."""
    soft = _model()
    stiff_scene = BASE.with_overrides(material="neo-hookean", density=1100.0, parameters={"mu": 2e5, "kappa": 2e7})
    stiff = _model(stiff_scene)
    two = split(soft, (stiff.material, soft.material), (1100.0, soft.density))
    res = TorchExplicitBackend().run(replace(two, end_time=0.0025), frame_interval=1e-3)
    alone_stiff = TorchExplicitBackend().run(replace(stiff, end_time=2e-5))
    alone_soft = TorchExplicitBackend().run(replace(soft, end_time=2e-5))
    assert alone_stiff.info["dt_first"] < 0.5 * alone_soft.info["dt_first"]
    assert res.info["dt_first"] == pytest.approx(alone_stiff.info["dt_first"], rel=1e-12)
    assert abs(res.info["energy_error"]) < 1e-3
    assert np.max(res.contact_force) > 0.0
    entry_low, entry_high = res.frame_state[-1]["parts"]
    assert "prony_H" not in entry_low and entry_high["prony_H"].shape == (3, two.parts[1].elements.size, 6)


def test_batch_with_parts_equals_the_runs_alone():
    """Two models with the same parts (stiff elastic base, CFM top) but different parameters in both
    parts run as one batch (synchronising and sync-free) equal the two runs done alone (both
    renumber the elements alike; the batch's per-run arithmetic may differ in round-off)."""
    soft, soft2 = _model(end=0.0025), _model(BASE.with_overrides(parameters={"k2": 2.5}), end=0.0025)
    nh = BASE.with_overrides(material="neo-hookean", density=1100.0)
    s1 = _model(nh.with_overrides(parameters={"mu": 2e5, "kappa": 2e7})).material
    s2 = _model(nh.with_overrides(parameters={"mu": 1e5, "kappa": 1e7})).material
    a = split(soft, (s1, soft.material), (1100.0, soft.density))
    b = split(soft, (s2, soft2.material), (1100.0, soft.density))
    alone = [TorchExplicitBackend().run(m) for m in (a, b)]
    assert rel(alone[0].contact_force[:100], alone[1].contact_force[:100]) > 1e-3
    for sync_free in (False, True):
        batch = TorchExplicitBackend().run_batch([a, b], sync_free=sync_free)
        for r, ref in zip(batch, alone):
            assert r.steps == ref.steps
            assert rel(r.contact_force, ref.contact_force) < 1e-10
            assert rel(r.energies["internal"], ref.energies["internal"]) < 1e-10


def test_batch_refuses_a_different_parts_layout():
    from cfm_core.errors import InputError

    m = _model()
    a = split(m, (m.material, m.material), (m.density, m.density))
    b = split(m, (m.material, m.material), (m.density, m.density), z_cut=0.002)
    with pytest.raises(InputError, match="parts"):
        TorchExplicitBackend().run_batch([a, b])
