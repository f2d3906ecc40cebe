"""Explicit solver of the torch backend: agreement with numba, energy, errors, device hygiene."""

import ast
import pathlib

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit import TorchExplicitBackend  # noqa: E402
from cfm_core import post as postprocess  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.errors import NumericalError  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "backends" / "torch_explicit"


@pytest.fixture(scope="module")
def small_drop():
    """10 x 10 mm specimen (quarter model), 2 mm elements, the paper's impactor: 36 hexahedra."""
    return build_model(builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.002))


@pytest.fixture(scope="module")
def torch_small(small_drop):
    return TorchExplicitBackend().run(small_drop, frame_interval=2e-3)


def filtered(result, model):
    _, _, a = postprocess.acceleration_histories(result, model.mass_full)
    return a


def rel_l2(a, b):
    """Relative L2 difference over the common 50 kHz samples (runs may stop one step apart)."""
    n = min(a.size, b.size)
    return postprocess.relative_l2(a[:n], b[:n])


def test_agrees_with_numba_on_small_drop_test(small_drop, torch_small):
    pytest.importorskip("numba")
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    ref = NumbaExplicitBackend().run(small_drop)
    res = torch_small
    assert res.steps == ref.steps and res.info["stop_reason"] == ref.info["stop_reason"]
    assert rel_l2(filtered(res, small_drop), filtered(ref, small_drop)) < 1e-6
    np.testing.assert_allclose(res.t, ref.t, rtol=1e-9, atol=0)
    for key in ("kinetic", "internal", "hourglass", "contact", "external"):
        scale = np.abs(ref.energies["kinetic"]).max()
        assert np.abs(res.energies[key] - ref.energies[key]).max() < 1e-8 * scale, key


def test_result_fields(small_drop, torch_small):
    r = torch_small
    assert r.backend == "torch" and r.steps == len(r.t) and r.wall_time > 0
    for arr in (r.contact_force, r.impulse, r.acceleration, r.impactor_z, r.impactor_v):
        assert arr.shape == r.t.shape and np.isfinite(arr).all()
    assert r.reaction_force is None and 0 < r.dt_min <= r.dt_max
    assert r.energy_error() < 1e-3 and r.hourglass_ratio() < 0.1
    assert r.info["device"] == "cpu" and r.info["dtype"] == "float64"
    assert r.info["host_syncs_per_step"] < 12
    assert len(r.frames) >= 2 and r.frames[1][1].shape == (small_drop.n_nodes, 3)
    # impulse = momentum change of the impactor (kinematic contact: exact to round-off)
    M = small_drop.mass_full
    assert abs(r.impulse[-1] - M * (r.impactor_v[-1] - r.impactor_v[0])) < 1e-12 * M * abs(r.impactor_v[0])  # measured 7.6e-16


def test_newton_block_does_not_change_the_result(small_drop, torch_small):
    other = TorchExplicitBackend().run(small_drop, newton_block=5, frame_interval=2e-3)
    np.testing.assert_array_equal(other.contact_force, torch_small.contact_force)
    assert other.info["host_syncs_per_step"] < torch_small.info["host_syncs_per_step"]


def test_float32_runs_close_to_float64(small_drop, torch_small):
    r32 = TorchExplicitBackend().run(small_drop, dtype="float32")
    assert r32.info["dtype"] == "float32"
    assert rel_l2(filtered(r32, small_drop), filtered(torch_small, small_drop)) < 1e-5


def test_prescribed_motion_agrees_with_numba():
    pytest.importorskip("numba")
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    model = build_model(builtin_scene("single-element").with_overrides(stretch=0.5, rate=200.0))
    a = TorchExplicitBackend().run(model)
    b = NumbaExplicitBackend().run(model)
    assert a.steps == b.steps
    assert np.abs(a.reaction_force - b.reaction_force).max() < 1e-9 * np.abs(b.reaction_force).max()
    assert a.energy_error() < 1e-3


def test_float32_overflow_names_element_time_and_float64():
    scene = builtin_scene("single-element").with_overrides(stretch=0.6, parameters={"k1": 1e-42, "k2": 400.0})
    model = build_model(scene)
    ok = TorchExplicitBackend().run(model)            # float64: exp argument ~ 90 < 709, stress tiny
    assert np.isfinite(ok.reaction_force).all()
    with pytest.raises(NumericalError, match=r"float32.*float64") as info:
        TorchExplicitBackend().run(model, dtype="float32")
    err = info.value
    assert err.element == 0 and 0.0 < err.time < ok.t[-1] and "element 0" in str(err)


def test_element_inversion_is_reported():
    model = build_model(builtin_scene("single-element").with_overrides(stretch=0.5))
    v0 = np.zeros((model.n_nodes, 3))
    v0[model.nodes[:, 0] > 0.5e-3, 0] = -2000.0        # push a face through the opposite one in one step
    with pytest.raises(NumericalError, match="inverted") as info:
        TorchExplicitBackend().run(model, initial_velocity=v0)
    assert info.value.element == 0 and info.value.quantity == "J"


def test_arrays_live_on_the_requested_device(small_drop):
    from cfm_backends.torch_explicit import arrays
    from cfm_backends.torch_explicit.options import TorchOptions

    o = TorchOptions()
    a, uv, k = arrays.build(small_drop, o, torch.device("cpu"), torch.float32)
    tensors = [v for v in vars(a).values() if isinstance(v, torch.Tensor)]
    tensors += [t for v in (a.sphere, a.plane) for t in v]
    assert tensors and all(t.device.type == "cpu" for t in tensors)
    assert all(t.dtype in (torch.float32, torch.int64) for t in tensors) and uv.dtype == torch.float32


def test_step_code_makes_no_numpy_round_trips():
    """The per-step modules never call .numpy() / .item() / .cpu(); host transfers are the solver's
    summary .tolist() calls and the contact Newton's (counted in info['host_syncs_per_step'])."""
    for name in ("element.py", "contact.py", "eigen.py"):
        tree = ast.parse((PACKAGE / name).read_text())
        for fn in (n for n in tree.body if isinstance(n, ast.FunctionDef)):
            calls = {n.func.attr for n in ast.walk(fn) if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)}
            assert not calls & {"numpy", "item", "cpu"}, (name, fn.name)
            if fn.name != "_newton_host":
                assert "tolist" not in calls, (name, fn.name)


@pytest.mark.slow
def test_compiled_element_pass_agrees(small_drop, torch_small):
    """torch.compile'd stages (tens of seconds of compilation the first time) give the same run."""
    res = TorchExplicitBackend().run(small_drop, compile=True, frame_interval=2e-3)
    assert res.steps == torch_small.steps
    assert rel_l2(filtered(res, small_drop), filtered(torch_small, small_drop)) < 1e-10


def test_a_pace_that_cannot_reach_the_end_time_stops_as_on_numba():
    """mu = 1e306 Pa: a stable step of 1.4e-155 s. numba stopped after 4096 steps with the projected number
    of steps; torch ran on towards max_steps = 5e7 (killed after minutes, no word). Both now stop with the
    one guard (cfm_backends.explicit.errors.pace) and the same message."""
    pytest.importorskip("numba")
    from cfm_core.runs.pipeline import run_model

    model = build_model(builtin_scene("single-element").with_overrides(material="neo-hookean",
                                                                       parameters={"mu": 1e306}))
    text = {}
    for backend in ("torch", "numba"):   # max_steps = 20000: without the guard torch stops there (~1 min), not never
        with pytest.raises(NumericalError, match=r"4096 steps reached only t = .* more than option max_steps = 20000") \
                as err:
            run_model(model, backend, max_steps=20_000)
        assert err.value.quantity == "steps" and 0.0 < err.value.time < 1e-140
        text[backend] = str(err.value)
    assert text["torch"] == text["numba"]


def test_the_pace_guard_projects_only_after_4096_steps():
    from types import SimpleNamespace

    from cfm_backends.explicit import errors

    model = SimpleNamespace(name="m", end_time=1.0)
    assert errors.pace(model, 4095, 1e-9, 1000_000) is None            # too early to project
    assert "needs about 4.1e+12 steps" in str(errors.pace(model, 4096, 1e-9, 1000_000))
    assert errors.pace(model, 4096, 0.5, 1000_000) is None             # 8192 steps to go: fine
    assert "steps reached at t = 0.5 s" in str(errors.pace(model, 1000_000, 0.5, 1000_000))


def test_a_batch_stops_a_run_whose_pace_cannot_reach_the_end_time_and_finishes_the_others():
    """In a batch, the run with mu = 1e306 Pa (stable step ~1e-155 s) stops with the single run's
    projection (errors.pace) at the first history read after 4096 steps, instead of holding the
    batch to max_steps; the run beside it finishes as it does alone."""
    from cfm_core.errors import NumericalError

    scene = builtin_scene("drop-test").with_overrides(element_size=0.004, material="neo-hookean", end_time=1e-3)
    bad = build_model(scene.with_overrides(parameters={"mu": 1e306}))
    good = build_model(scene)
    out = TorchExplicitBackend().run_batch([bad, good], raise_errors=False, max_steps=20_000)
    assert isinstance(out[0], NumericalError) and out[0].quantity == "steps"
    assert "more than option max_steps = 20000" in str(out[0])
    alone = TorchExplicitBackend().run(good)
    np.testing.assert_allclose(out[1].contact_force, alone.contact_force, rtol=1e-10, atol=1e-12)


def test_max_steps_stops_numba_and_torch_at_the_same_step():
    """max_steps = 10: numba stopped at 11 steps (it looked between history chunks), torch at 10."""
    pytest.importorskip("numba")
    from cfm_core.runs.pipeline import run_model

    model = build_model(builtin_scene("single-element"))
    text = {}
    for backend in ("torch", "numba"):
        with pytest.raises(NumericalError, match=r"^model 'single-element': 10 steps reached at t = ") as err:
            run_model(model, backend, max_steps=10)
        text[backend] = str(err.value)
    assert text["torch"] == text["numba"]
