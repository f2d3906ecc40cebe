"""Batched drop tests on torch: each run of a batch equals the same run done alone."""

from dataclasses import replace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit import TorchExplicitBackend  # noqa: E402
from cfm_core import post  # noqa: E402
from cfm_core.errors import InputError, NumericalError  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402

BASE = builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.002)


def rel_l2(res, ref, model):
    """Relative L2 difference of the CFC 600 filtered accelerations (common 50 kHz samples)."""
    a = post.acceleration_histories(res, model.mass_full)[2]
    b = post.acceleration_histories(ref, model.mass_full)[2]
    n = min(a.size, b.size)
    return post.relative_l2(a[:n], b[:n])


@pytest.fixture(scope="module")
def models():
    """Three drop tests on one mesh: paper defaults, a stiffer fibre term, a faster, lighter impactor."""
    scenes = [BASE, BASE.with_overrides(parameters={"k2": 2.5}), BASE.with_overrides(velocity=1.5, mass=0.15)]
    return [build_model(s) for s in scenes]


@pytest.fixture(scope="module")
def alone(models):
    return [TorchExplicitBackend().run(m) for m in models]


def test_each_run_of_a_batch_equals_the_run_alone(models, alone):
    batch = TorchExplicitBackend().run_batch(models)
    assert len(batch) == 3
    for m, r, ref in zip(models, batch, alone):
        assert r.steps == ref.steps and r.info["stop_reason"] == ref.info["stop_reason"]
        assert rel_l2(r, ref, m) < 1e-10
        np.testing.assert_allclose(r.energies["internal"], ref.energies["internal"], rtol=0,
                                   atol=1e-9 * np.abs(ref.energies["kinetic"]).max())
        assert r.info["batch_size"] == 3
    # the runs really differ (a test that mixed them up would fail)
    assert rel_l2(alone[1], alone[0], models[0]) > 1e-3 and rel_l2(alone[2], alone[0], models[0]) > 1e-3


def test_sync_free_step_gives_the_same_runs(models):
    """The step without host synchronisation (CUDA's default; fixed Newton iterations, masked eigen
    fallback, flags read per chunk) gives the runs of the synchronising one (through the peak)."""
    short = [replace(m, end_time=0.004) for m in models]
    sync = TorchExplicitBackend().run_batch(short)
    free = TorchExplicitBackend().run_batch(short, sync_free=True)
    for m, a, b in zip(short, free, sync):
        assert a.steps == b.steps and rel_l2(a, b, m) < 1e-10
    assert free[0].info["host_syncs_per_step"] < 0.1 < sync[0].info["host_syncs_per_step"]


def test_batch_refuses_models_on_different_meshes(models):
    other = build_model(BASE.with_overrides(element_size=0.0025))
    with pytest.raises(InputError, match="differs from model 0.*nodes"):
        TorchExplicitBackend().run_batch([models[0], other])


def test_a_failing_run_does_not_stop_the_others(models):
    crushing = build_model(BASE.with_overrides(velocity=400.0))
    out = TorchExplicitBackend().run_batch([replace(models[0], end_time=0.002), crushing], raise_errors=False)
    assert isinstance(out[1], NumericalError) and "batch run 1" in str(out[1]) and out[1].time is not None
    assert not isinstance(out[0], Exception) and out[0].steps > 0


def test_sweep_dispatch_groups_runs_sharing_a_mesh_into_batches():
    """map_cases (used by cfm sweep and cfm calibrate) sends one batch per mesh, and each run's
    filtered history equals the run alone."""
    from cfm_core.studies.dask_runner import SerialRunner
    from cfm_core.studies.sweep import map_cases, run_case

    class Counting(SerialRunner):
        items = []

        def map(self, fn, items):
            items = list(items)
            Counting.items.append((fn.__name__, len(items)))
            return super().map(fn, items)

    scene = BASE.with_overrides(element_size=0.0025)
    cases = [{"k2": 1.66}, {"k2": 2.5}, {"k2": 1.66, "thickness": 0.006}]
    tasks = [(scene, c, "torch") for c in cases]
    done = {d.index: d for d in map_cases(Counting(), tasks)}
    assert Counting.items == [("run_cases", 2)]          # two meshes: two batches
    for i, task in enumerate(tasks):
        assert done[i].ok, done[i].error
    for i in (1, 2):                                       # one run of each batch
        alone = run_case(tasks[i])
        a, b = done[i].value["a_cfc"], alone["a_cfc"]
        n = min(a.size, b.size)
        assert post.relative_l2(a[:n], b[:n]) < 1e-10


def test_float32_batch_keeps_the_run_scalars_in_float64():
    """Time, impactor and energy sums stay float64 in a float32 batch (as the single run's host
    arithmetic): the batch equals the float32 run alone far below float32's own error (~1e-5)."""
    models = [replace(build_model(BASE.with_overrides(element_size=0.0025, parameters={"k2": k2})), end_time=0.004)
              for k2 in (1.66, 2.2)]
    batch = TorchExplicitBackend().run_batch(models, dtype="float32")
    free = TorchExplicitBackend().run_batch(models, dtype="float32", sync_free=True)   # CUDA's step
    for m, r, f in zip(models, batch, free):
        alone = TorchExplicitBackend().run(m, dtype="float32")
        assert r.steps == alone.steps and rel_l2(r, alone, m) < 5e-6
        assert f.steps == alone.steps and rel_l2(f, alone, m) < 5e-6


@pytest.mark.slow  # ~100 s; the run checks of single runs are tested on every backend by default
def test_batch_runs_get_the_physics_checks_each_on_its_own(models):
    """A 220 kg impactor (grams written as kg) in a batch stops with the penetration check, naming
    node and time, like the run alone; the other run of the batch completes with its check report."""
    heavy = build_model(BASE.with_overrides(mass=220.0))
    with pytest.raises(NumericalError) as alone_err:
        TorchExplicitBackend().run(heavy)
    out = TorchExplicitBackend().run_batch([models[0], heavy], raise_errors=False)
    assert isinstance(out[1], NumericalError)
    # same check on the same node, or on its mirror image across the quarter model's x = y plane
    # (the two are equally deep to round-off); the depth and time differ a little (the batch checks
    # at its chunk reads)
    def node_position(err):
        text = str(err)
        assert " mm behind the rigid plate" in text, text
        x, y, z = text.split("reference position (")[1].split(")")[0].split(", ")
        return {(x, y, z), (y, x, z)}

    assert node_position(out[1]) == node_position(alone_err.value)
    assert out[1].quantity == alone_err.value.quantity and abs(out[1].time - alone_err.value.time) < 1e-3
    assert out[0].info["checks"]["monitor_calls"] > 10 and out[0].info["checks"]["worst_plate"] < 1e-4


def test_runs_differing_in_prony_series_and_moduli_each_get_their_own_result():
    """Runs of one batch with their own Prony series (g_i, tau_i: another long-term fraction) and
    moduli (c, k1, kappa): each equals its run alone and the numba run (a batch reading run 0's
    long-term fraction or Prony terms, or another run's moduli, fails here; the other batch tests
    vary only k2, speed, mass and thickness). 2 mm mesh, first 3 ms (through the peak)."""
    pytest.importorskip("numba")
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    variants = [{},
                {"g1": 0.30, "g2": 0.50, "g3": 0.15, "tau1": 2e-3, "c": 20.0},        # g_inf 0.05
                {"g1": 0.60, "g2": 0.20, "g3": 0.05, "tau2": 0.05, "k1": 2000.0, "kappa": 1.0e6}]  # 0.15
    models = [replace(build_model(BASE.with_overrides(parameters=p)), end_time=0.003) for p in variants]
    ginf = [1.0 - sum(m.material.prony_arrays()[0]) for m in models]
    assert ginf == pytest.approx([0.021, 0.05, 0.15])
    batch = TorchExplicitBackend().run_batch(models)
    for i, (m, r) in enumerate(zip(models, batch)):
        alone = TorchExplicitBackend().run(m)
        numba = NumbaExplicitBackend().run(m)
        assert r.steps == alone.steps, i
        assert rel_l2(r, alone, m) < 1e-10, i
        assert rel_l2(r, numba, m) < 1e-6, i
        np.testing.assert_allclose(r.energies["internal"], alone.energies["internal"], rtol=0,
                                   atol=1e-9 * np.abs(alone.energies["kinetic"]).max())
    for i in (1, 2):  # the variants really differ from run 0 (and from each other)
        assert rel_l2(batch[i], batch[0], models[0]) > 1e-3
    assert rel_l2(batch[2], batch[1], models[0]) > 1e-3
