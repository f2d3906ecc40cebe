"""torch: a drop test on CUDA goes to the batch engine with the options it parsed (not re-parsed);
checked without a GPU by standing in for the engine, and the engine's parsed entry against run_batch."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cfm_backends.torch_explicit import batch, solver  # noqa: E402
from cfm_backends.torch_explicit.options import TorchOptions  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402

SCENE = builtin_scene("drop-test").with_overrides(width=0.01, element_size=0.005, thickness=0.005)


def test_cuda_drop_test_hands_its_parsed_options_to_the_batch_engine(monkeypatch):
    seen = {}

    def engine(models, o, progress=None, raise_errors=True, sync_free=None, device=None, dtype=None):
        seen.update(models=models, o=o, raise_errors=raise_errors, sync_free=sync_free, device=device, dtype=dtype)
        return ["result"]

    def from_mapping(options):
        seen["parsed"] = seen.get("parsed", 0) + 1
        return real(options)

    real = TorchOptions.from_mapping
    monkeypatch.setattr(batch, "run_parsed", engine)
    monkeypatch.setattr(TorchOptions, "from_mapping", staticmethod(from_mapping))
    monkeypatch.setattr(solver, "resolve_device", lambda name: torch.device("cuda"))
    model = build_model(SCENE)
    assert solver.run_model(model, device="cuda", safety=0.5) == "result"
    assert seen["parsed"] == 1 and seen["o"].safety == 0.5 and seen["models"] == [model]
    assert seen["device"] == torch.device("cuda") and seen["dtype"] == torch.float64
    assert seen["raise_errors"] is True and seen["sync_free"] is True


def test_parsed_entry_equals_run_batch():
    model = build_model(SCENE)
    a = batch.run_batch([model], None, True, False)[0]
    b = batch.run_parsed([model], TorchOptions.from_mapping({}), None, True, False,
                         torch.device("cpu"), torch.float64)[0]
    assert np.array_equal(a.t, b.t) and np.array_equal(a.impulse, b.impulse)
