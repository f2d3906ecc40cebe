"""torch batch: the sync-free step is capture-safe (a CUDA graph of it replays the run), checked on the CPU.

A CUDA graph records the kernels of one step with the addresses of their tensors and replays them:
Python runs once, no value may be read back to the host, and every tensor carried from one step to
the next must keep its address. On the CPU this is checked by (a) watching every torch op of a
step (a dispatch mode): no host read, no data-dependent shape, no host data copied in, and every
tensor written is one of the carried buffers or a temporary of the step; the carried tensors keep
their objects and addresses; (b) replaying a recorded step: the ops of one step are recorded with
their tensors, and later steps re-run the recorded ops on the recorded tensors with no Python of
the step, as a graph replays; the histories equal the eager step's bit for bit.
"""

from dataclasses import replace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from torch.utils._python_dispatch import TorchDispatchMode  # noqa: E402

from cfm_backends.torch_explicit import TorchExplicitBackend, batch, batch_step  # noqa: E402
from cfm_backends.torch_explicit.options import TorchOptions  # noqa: E402
from cfm_core import post  # noqa: E402
from cfm_core.errors import InputError  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402

BASE = builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.002)
# host reads, data-dependent shapes, host data copied to the device: none may run inside a graph
FORBIDDEN = {"_local_scalar_dense", "item", "is_nonzero", "equal", "nonzero", "masked_select", "_unique",
             "_unique2", "unique_dim", "unique_consecutive", "repeat_interleave.Tensor", "lift_fresh",
             "lift_fresh_copy", "bincount", "histc"}
MASKED = {"index", "index_put", "index_put_", "_index_put_impl_"}     # with a bool mask: a nonzero inside


def _name(func) -> str:
    return str(func).removeprefix("aten.")


def _tensors(x):
    if isinstance(x, torch.Tensor):
        return [x]
    if isinstance(x, (list, tuple)):
        return [t for y in x for t in _tensors(y)]
    return []


def _storage(t) -> int:
    return t.untyped_storage().data_ptr()


class Watch(TorchDispatchMode):
    """Every op (composite ones decomposed): forbidden ones, tensors written, storages created."""

    def __init__(self):
        super().__init__()
        self.bad, self.written, self.created = [], set(), set()

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        name = _name(func)
        if name in FORBIDDEN or name.split(".")[0] in FORBIDDEN or (
                name.split(".")[0] in MASKED and any(t.dtype == torch.bool for t in _tensors(args[1]))) or (
                name.startswith("_to_copy") and "device" in kwargs):
            self.bad.append(name)
        for a, v in zip(func._schema.arguments, list(args) + [kwargs.get(a.name) for a in
                                                              func._schema.arguments[len(args):]]):
            if a.alias_info is not None and a.alias_info.is_write:
                self.written.update(_storage(t) for t in _tensors(v))
        with self:
            out = func.decompose(*args, **kwargs)
        if out is NotImplemented:
            out = func(*args, **kwargs)
        self.created.update(_storage(t) for t in _tensors(out))
        return out


def _batch(models, sync_free=True, graph=False):
    return batch._Batch(models, TorchOptions(), torch.device("cpu"), torch.float64, None, sync_free, graph)


def _general():
    """Two oblique flat-punch impacts (any shape, lateral motion: the impactor_contact step)."""
    m = replace(build_model(BASE.with_overrides(symmetry="none")), end_time=0.002)
    top = float(m.nodes[:, 2].max())
    sp = replace(m.sphere, shape="flat", radius=0.004, edge_radius=0.002, moves=(True, True, True),
                 velocity_xy=(0.3, -0.2), center=(0.001, -0.0015, top + 1e-4))
    a = replace(m, sphere=sp, plane=None, plane_nodes=np.zeros(0, dtype=np.int64), friction=0.3)
    return [a, replace(a, sphere=replace(sp, velocity=-1.3))]


@pytest.fixture(scope="module")
def pair():
    """The paper's drop test (2 mm, narrow block) and one with a stiffer fibre term."""
    return [build_model(BASE), build_model(BASE.with_overrides(parameters={"k2": 2.5}))]


@pytest.mark.parametrize("kind", ["hemisphere", "general"])
def test_the_sync_free_step_is_capture_safe(pair, kind):
    models = pair if kind == "hemisphere" else _general()
    with torch.inference_mode():
        bt = _batch(models)
        s = batch_step.carry(bt, batch.CHUNK)
        batch_step.step(bt, s)                       # warm-up (cached constants), as before a capture
        before = batch_step.tensors(bt, s)
        ptrs = {k: v.data_ptr() for k, v in before.items()}
        ids = {k: id(v) for k, v in vars(s).items()}
        watch = Watch()
        with watch:
            for _ in range(4):
                batch_step.step(bt, s)
        after = batch_step.tensors(bt, s)
    assert watch.bad == [] and bt.syncs == 0
    assert {k: id(v) for k, v in vars(s).items()} == ids           # no attribute of the carry reassigned
    assert all(after[k] is before[k] for k in before) and {k: v.data_ptr() for k, v in after.items()} == ptrs
    carried = {_storage(t) for t in after.values()}
    assert watch.written and watch.written <= carried | watch.created   # writes: carried buffers or temporaries
    assert int(s.pos) == 5 and bool(s.alive.all()) and float(s.t.min()) > 0.0     # five rows, all runs on


def test_the_watch_sees_the_synchronising_step(pair):
    """The same check fails on the CPU's synchronising step (eigen fallback test, Newton checks)."""
    with torch.inference_mode():
        bt = _batch(pair, sync_free=False)
        s = batch_step.carry(bt, batch.CHUNK)
        batch_step.step(bt, s)
        watch = Watch()
        with watch:
            batch_step.step(bt, s)
    assert "_local_scalar_dense.default" in watch.bad and bt.syncs > 0


class Tape(TorchDispatchMode):
    """Records the ops of a step with their tensors (a CUDA graph's capture, but executing)."""

    def __init__(self):
        super().__init__()
        self.ops = []

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        out = func(*args, **kwargs)
        inplace = any(a.alias_info is not None and a.alias_info.is_write for a in func._schema.arguments)
        inputs = {_storage(t) for t in _tensors(list(args) + list(kwargs.values()))}
        fresh = [t for t in _tensors(out) if _storage(t) not in inputs]     # not views of an input
        self.ops.append((func, args, kwargs, None if inplace else (out, fresh)))
        return out

    def replay(self):
        for func, args, kwargs, result in self.ops:
            new = func(*args, **kwargs)
            if result is not None and result[1]:
                old, fresh = result
                for o, n in zip(_tensors(old), _tensors(new)):
                    if any(o is f for f in fresh):
                        o.copy_(n)


class CpuGraph:
    """:class:`batch_step.CudaGraph`'s protocol on the CPU: warm-up calls, one recorded, then replays."""

    def __init__(self, device):
        self.tape, self.calls = None, 0

    @property
    def used(self):
        return self.tape is not None

    def __call__(self, fn):
        if self.tape is not None:
            self.tape.replay()
        elif self.calls >= batch_step.WARM_STEPS:
            self.tape = Tape()
            with self.tape:
                fn()
        else:
            fn()
        self.calls += 1


def _histories(r):
    return np.column_stack([r.t, r.contact_force, r.impulse, r.impactor_z, r.impactor_v,
                            *[r.energies[k] for k in sorted(r.energies)]])


@pytest.mark.parametrize("kind", ["hemisphere", pytest.param("general", marks=pytest.mark.slow)])
def test_a_replayed_step_gives_the_eager_histories_bit_for_bit(pair, kind, monkeypatch):
    # different end times: the run that stops first keeps being computed, its rows masked
    models = [replace(m, end_time=e) for m, e in zip(pair if kind == "hemisphere" else _general(), (0.003, 0.0022))]
    eager = TorchExplicitBackend().run_batch(models, sync_free=True)
    monkeypatch.setattr(batch_step, "CudaGraph", CpuGraph)
    with torch.inference_mode():
        replayed = _batch(models, graph=True).loop()
    for a, b in zip(replayed, eager):
        assert a.info["cuda_graph"] and not b.info["cuda_graph"] and a.steps == b.steps > batch.CHUNK
        assert np.array_equal(_histories(a), _histories(b))
        if kind == "general":
            assert all(np.array_equal(a.impactor_lateral[k], b.impactor_lateral[k]) for k in b.impactor_lateral)
    assert not np.array_equal(_histories(eager[0]), _histories(eager[1]))   # the runs differ


def test_the_sync_free_batch_equals_the_runs_alone(pair):
    """The sync-free batch of two 2 mm drop tests against each run alone (the single-run solver)."""
    models = [replace(m, end_time=0.004) for m in pair]
    out = TorchExplicitBackend().run_batch(models, sync_free=True)
    for m, r in zip(models, out):
        ref = TorchExplicitBackend().run(m)
        a = post.acceleration_histories(r, m.mass_full)[2]
        b = post.acceleration_histories(ref, m.mass_full)[2]
        assert r.steps == ref.steps and post.relative_l2(a, b) < 1e-12
        assert r.info["host_syncs_per_step"] < 0.1 and r.info["cuda_graph"] is False


def test_cuda_graph_on_the_cpu_is_an_input_error(pair, monkeypatch):
    with pytest.raises(InputError, match=r"cuda_graph = True.*device = 'cpu'.*device='cuda'"):
        TorchExplicitBackend().run(pair[0], cuda_graph=True)
    with pytest.raises(InputError, match=r"cuda_graph = 'yes' is not allowed; expected True or False, or None"):
        TorchOptions(cuda_graph="yes")
    with pytest.raises(InputError, match="reduce-overhead"):
        TorchOptions(device="cuda", cuda_graph=True, compile="reduce-overhead")
    with pytest.raises(InputError, match="sync_free=False"):
        batch.cuda_graph(TorchOptions(device="cuda", cuda_graph=True), torch.device("cuda"), False)
    # on CUDA only drop tests without frames run through the graph (the device stood in for, as in
    # test_torch_cuda_route: the error comes before anything runs)
    from cfm_backends.torch_explicit import solver

    monkeypatch.setattr(solver, "resolve_device", lambda name: torch.device("cuda"))
    with pytest.raises(InputError, match="cuda_graph = True is not allowed for model 'drop-test'.*frame_interval"):
        solver.run_model(pair[0], device="cuda", cuda_graph=True, frame_interval=1e-4)
    # the defaults: on for the sync-free step on CUDA, off on the CPU and with torch.compile
    assert batch.cuda_graph(TorchOptions(device="cuda"), torch.device("cuda"), True)
    assert not batch.cuda_graph(TorchOptions(device="cuda", compile=True), torch.device("cuda"), True)
    assert not batch.cuda_graph(TorchOptions(), torch.device("cpu"), True)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_captured_step_on_cuda_equals_the_eager_step(pair):
    models = [replace(m, end_time=0.003) for m in pair]
    be = TorchExplicitBackend()
    graph = be.run_batch(models, device="cuda", cuda_graph=True)
    eager = be.run_batch(models, device="cuda", cuda_graph=False)
    for m, a, b in zip(models, graph, eager):
        assert a.info["cuda_graph"] and not b.info["cuda_graph"] and a.steps == b.steps
        x = post.acceleration_histories(a, m.mass_full)[2]
        y = post.acceleration_histories(b, m.mass_full)[2]
        assert post.relative_l2(x, y) < 1e-10        # index_add_'s atomics: summation order differs
