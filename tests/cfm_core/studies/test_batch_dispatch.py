"""map_cases on a batching backend (torch): each model built once, invalid cases failing alone;
the shared forward-difference Jacobian against an analytic one."""

import numpy as np
import pytest

from cfm_core.runs import pipeline
from cfm_core.scene.scene import builtin_scene
from cfm_core.studies.dask_runner import SerialRunner
from cfm_core.studies.differences import forward_jacobian, forward_steps
from cfm_core.studies.sweep import map_cases, run_all


def test_forward_jacobian_of_a_linear_map_is_its_matrix_and_steps_turn_at_the_bound():
    A = np.array([[1.0, -2.0, 0.5], [3.0, 0.25, -1.0]])
    b = np.array([0.3, -0.7])
    x = np.array([0.1, 0.2, 0.95])
    upper = np.array([1.0, 1.0, 1.0])
    steps = forward_steps(x, upper, [1e-3, 1e-3, 0.1])
    assert steps == [1e-3, 1e-3, -0.1]        # the third step would pass the bound: backwards
    calls = []

    def values(points):
        calls.append(len(points))
        return [A @ p + b for p in points]

    scale = np.array([2.0, 4.0])
    J = forward_jacobian(values, x, A @ x + b, steps, scale=scale)
    np.testing.assert_allclose(J, A / scale[:, None], rtol=1e-11)
    assert calls == [3]                        # all perturbed points in one call (one set of drop tests)


def test_run_all_raises_the_failure_of_a_failed_task():
    scene = builtin_scene("drop-test")
    with pytest.raises(RuntimeError, match="task 0 failed: InputError: .*thickness"):
        run_all(SerialRunner(), [(scene, {"thickness": -1.0}, "numba")],
                lambda i, error: RuntimeError(f"task {i} failed: {error}"))


def test_map_cases_builds_each_model_once_in_process(monkeypatch):
    pytest.importorskip("torch")
    built = []
    real = pipeline.build_model

    def counting(scene):
        built.append(scene)
        return real(scene)

    monkeypatch.setattr(pipeline, "build_model", counting)
    scene = builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.005, thickness=0.005)
    cases = [{"k2": 1.66}, {"thickness": -0.005}, {"k2": 2.5}]
    done = {d.index: d for d in map_cases(SerialRunner(), [(scene, c, "torch") for c in cases])}
    assert sorted(done) == [0, 1, 2]
    assert not done[1].ok and "thickness" in done[1].error     # the invalid case fails alone
    assert done[0].ok and done[2].ok, (done[0].error, done[2].error)
    assert done[2].value["summary"]["peak_g"] > done[0].value["summary"]["peak_g"]  # stiffer fibres
    assert len(built) == 2                                    # once each (the invalid one is not built)
