"""The Prony state numba stores at a frame gives back, through cfm_core.post.fields, exactly the
stress of the solver's next element pass at the frame's positions (viscoelastic CFM, drop test)."""

import numpy as np
import pytest

pytest.importorskip("numba")

from cfm_backends.numba_explicit import codegen, solver
from cfm_backends.numba_explicit.frames import frame_state
from cfm_backends.numba_explicit.kernels import layout as K
from cfm_backends.numba_explicit.options import NumbaOptions
from cfm_core.material import kinematics as kin
from cfm_core.post.fields import deformation_gradients, element_stress, mean_gradients
from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene


def test_frame_stress_is_the_stress_of_the_solvers_next_pass():
    scene = builtin_scene("drop-test").with_overrides(thickness=0.004, element_size=0.002, width=0.012)
    model = build_model(scene)
    mod = codegen.load(model.material)
    prep = solver.prepare(model, NumbaOptions())
    hist = np.zeros((200_000, K.H_N))
    _, code = solver.advance(mod, prep, hist, 2.5e-3)          # well into the impact
    assert code == K.R_CHUNK
    ne, k = model.n_elements, prep.mat[1].shape[0]
    assert k == 3
    state = frame_state(prep, ne, k)
    internal = prep.ren.model(model)  # the solver's own (renumbered) mesh: prep holds its arrays
    F = deformation_gradients(mean_gradients(internal.nodes, internal.hexes), internal.hexes, prep.st[0].copy())
    sigma, exact = element_stress(model.material, F, state)
    assert exact
    solver.advance(mod, prep, hist[:1], 1.0)                   # one more step: its element pass
    S_solver = kin.from_voigt(solver.per_element(prep.st[3], K.ED_N, K.ED_SO, 6, ne))
    Finv = np.linalg.inv(F)
    S_post = np.linalg.det(F)[:, None, None] * np.einsum("eij,ejk,elk->eil", Finv, sigma, Finv)
    scale = np.abs(S_solver).max()
    assert scale > 1e3                                          # a loaded specimen (Pa)
    assert np.abs(S_post - S_solver).max() / scale < 1e-10
    # the viscous part matters: the instantaneous stress differs by far more than round-off
    inst, exact = element_stress(model.material, F, None)
    assert not exact and np.abs(inst - sigma).max() / np.abs(sigma).max() > 1e-3


def test_torch_frames_give_the_same_stress_and_velocity_as_numba():
    pytest.importorskip("torch")
    from cfm_core.simulation.registry import backend_for

    model = build_model(builtin_scene("drop-test").with_overrides(thickness=0.004, element_size=0.002, width=0.012))
    B = mean_gradients(model.nodes, model.hexes)
    runs = [backend_for(b).run(model, frame_interval=1e-3) for b in ("numba", "torch")]
    assert len(runs[0].frames) == len(runs[1].frames) == len(runs[1].frame_state) >= 4
    for (t1, u1), s1, (t2, u2), s2 in zip(runs[0].frames, runs[0].frame_state, runs[1].frames, runs[1].frame_state):
        assert t1 == pytest.approx(t2, rel=1e-12)
        a, exact_a = element_stress(model.material, deformation_gradients(B, model.hexes, model.nodes + u1), s1)
        b, exact_b = element_stress(model.material, deformation_gradients(B, model.hexes, model.nodes + u2), s2)
        assert exact_a and exact_b
        assert np.abs(a - b).max() <= 1e-11 * max(np.abs(a).max(), 1.0)
        assert np.abs(s1["velocity"] - s2["velocity"]).max() < 1e-10
