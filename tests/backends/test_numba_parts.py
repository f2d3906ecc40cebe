"""Models with several parts on the numba backend (Model.parts: one material, density and Prony
state per part, one generated element pass per material).

Independent truths: the one-material run of the same mesh (parts that all carry the model's
material must give its histories), the energy balance of the run, and the first stable step of
the all-stiff run (the layered step must follow the stiffer part).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("numba")

from cfm_backends.numba_explicit import NumbaExplicitBackend  # noqa: E402
from cfm_core.material.registry import make_material  # noqa: E402
from cfm_core.scene import build_model, builtin_scene  # noqa: E402
from cfm_core.scene.model import Part  # noqa: E402

END = 4e-3            # s: into the impact (first contact ~2 ms after the start)


def drop(**kw):
    return build_model(builtin_scene("drop-test").with_overrides(element_size=2e-3, end_time=END, **kw))


def layers(model, materials, densities):
    """Parts by element centroid z: len(materials) layers of equal element count from the bottom."""
    zc = model.nodes[model.hexes][:, :, 2].mean(axis=1)
    levels = np.unique(np.round(zc, 9))
    groups = np.array_split(levels, len(materials))
    parts = []
    for i, (g, mat, rho) in enumerate(zip(groups, materials, densities)):
        el = np.flatnonzero((np.round(zc, 9) >= g[0]) & (np.round(zc, 9) <= g[-1]))
        parts.append(Part(f"layer{i}", mat, float(rho), el.astype(np.int64)))
    return dataclasses.replace(model, parts=tuple(parts))


def run(model, **kw):
    return NumbaExplicitBackend().run(model, threads=1, **kw)


@pytest.fixture(scope="module")
def one():
    model = drop()
    return model, run(model, frame_interval=1e-3)


def test_parts_of_one_material_equal_the_one_material_run(one):
    model, ref = one
    layered = layers(model, [model.material] * 3, [model.density] * 3)
    assert layered.multi_material and len(layered.parts) == 3
    res = run(layered, frame_interval=1e-3)
    assert res.steps == ref.steps
    for name in ("contact_force", "impulse", "impactor_z", "impactor_v"):
        a, b = getattr(res, name), getattr(ref, name)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), name
    for k, e in ref.energies.items():
        assert np.abs(res.energies[k] - e).max() <= 1e-12 * max(np.abs(e).max(), 1e-30), k
    assert ref.contact_force.max() > 10.0            # the impact has started
    # the frame state: per-part Prony H (part order, part.elements order) equals the one-material one
    for s_ref, s in zip(ref.frame_state, res.frame_state):
        assert "prony_H" not in s and len(s["parts"]) == 3
        scale = max(np.abs(s_ref["prony_H"]).max(), 1e-30)
        scale0 = max(np.abs(s_ref["prony_S0"]).max(), 1e-30)
        for part, entry in zip(layered.parts, s["parts"]):
            assert entry["name"] == part.name and np.array_equal(entry["elements"], part.elements)
            assert entry["prony_H"].shape == (3, part.elements.size, 6)
            assert np.abs(entry["prony_H"] - s_ref["prony_H"][:, part.elements]).max() <= 1e-12 * scale
            assert np.abs(entry["prony_S0"] - s_ref["prony_S0"][part.elements]).max() <= 1e-12 * scale0
        assert s["prony_dt"] == pytest.approx(s_ref["prony_dt"], rel=1e-12)


# a --runslow study: it compiles two more modules (about 2 minutes on a cold cache); the default
# suite checks the stable step per part in test_layer_density_enters_the_stable_step
@pytest.mark.slow
def test_two_parts_of_very_different_stiffness(one):
    model, soft = one
    stiff_mat = make_material("neo-hookean", {"mu": 2.0e5, "kappa": 2.0e7})
    two = layers(model, [stiff_mat, model.material], [1100.0, model.density])   # stiff bottom layer
    res = run(two, frame_interval=1e-3)
    assert res.info["stop_reason"] == "end_time" and res.contact_force.max() > 10.0
    assert res.info["energy_error"] < 2e-3, res.info["energy_error"]
    # the stable step follows the stiffer part: the all-stiff run's first step, far below the soft one's
    stiff = run(dataclasses.replace(model, material=stiff_mat, density=1100.0))
    assert res.info["dt_first"] == pytest.approx(stiff.info["dt_first"], rel=1e-12)
    assert res.info["dt_first"] < 0.5 * soft.info["dt_first"]
    # k differs per part: the stiff part has no Prony state, the CFM part three terms
    s = res.frame_state[-1]
    assert "prony_H" not in s["parts"][0] and "prony_S0" not in s["parts"][0]
    assert s["parts"][1]["prony_H"].shape == (3, two.parts[1].elements.size, 6)
    assert np.abs(s["parts"][1]["prony_H"]).max() > 0.0


def test_layer_density_enters_the_stable_step(one):
    model, soft = one
    light = layers(model, [model.material] * 2, [model.density / 4.0, model.density])
    res = run(dataclasses.replace(light, end_time=1e-4))
    # c = sqrt(M / rho): a quarter of the density doubles the wave speed in the bottom layer, so
    # the first step is half the one-material run's (same elements, same modulus at rest)
    assert res.info["dt_first"] == pytest.approx(0.5 * soft.info["dt_first"], rel=1e-12)
