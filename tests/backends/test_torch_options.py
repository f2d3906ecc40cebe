"""torch backend: registration, lazy import, options, device and dtype errors."""

import subprocess
import sys

import pytest

from cfm_core.errors import InputError


def test_package_import_does_not_import_torch():
    code = ("import sys; import cfm_backends.torch_explicit as m; from cfm_core.simulation.registry import get_backend; "
            "b = get_backend('torch'); assert b.name == 'torch'; print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_capabilities():
    from cfm_backends.torch_explicit import TorchExplicitBackend as B

    assert (B.name, B.kind, B.requires) == ("torch", "explicit", ("torch",))
    assert B.devices == ("cpu", "cuda") and B.dtypes == ("float64", "float32")


def test_registered_through_entry_point():
    from cfm_core.simulation.registry import get_backend

    assert type(get_backend("torch")).__name__ == "TorchExplicitBackend"


def test_bad_options():
    from cfm_backends.torch_explicit.options import TorchOptions

    with pytest.raises(InputError, match="unknown option"):
        TorchOptions.from_mapping({"thread": 2})
    with pytest.raises(InputError, match="dtype"):
        TorchOptions.from_mapping({"dtype": "float16"})
    with pytest.raises(InputError, match="device"):
        TorchOptions.from_mapping({"device": "tpu"})
    with pytest.raises(InputError, match=r"torch backend: option safety = 1.5 is not allowed.*\(0, 1\]"):
        TorchOptions.from_mapping({"safety": 1.5})
    with pytest.raises(InputError, match="compile"):
        TorchOptions.from_mapping({"compile": 3})
    o = TorchOptions.from_mapping({"dtype": "float32", "device": "cuda:1"})
    assert (o.dtype, o.device, o.hourglass) == ("float32", "cuda:1", 0.1)
    torch = pytest.importorskip("torch")
    assert TorchOptions(dtype=torch.float32).dtype == "float32"


def test_options_are_declared_once_and_shared_with_numba():
    """The explicit options have the same names and defaults on both backends (one declaration),
    the run docstrings and ``cfm backends --options`` list them, torch adds its own."""
    from cfm_backends.explicit.options import ExplicitOptions
    from cfm_backends.numba_explicit import NumbaExplicitBackend
    from cfm_backends.torch_explicit import TorchExplicitBackend

    shared = ExplicitOptions.specs()
    t, n = TorchExplicitBackend.options_class, NumbaExplicitBackend.options_class
    assert set(shared) < set(t.specs()) and set(shared) < set(n.specs())
    assert {"device", "dtype", "newton_block"} <= set(t.specs()) - set(n.specs())
    for name in shared:
        assert getattr(t(), name) == getattr(n(), name) == getattr(ExplicitOptions(), name)
    assert "hourglass_wave" in TorchExplicitBackend.run.__doc__ and "newton_block" in TorchExplicitBackend.run.__doc__
    out = subprocess.run([sys.executable, "-m", "cfm_core.cli", "backends", "--options"],
                         capture_output=True, text=True, check=True).stdout
    assert "newton_block" in out and "separation_time" in out and "0.0002" in out


def test_cuda_not_available_names_what_was_found(monkeypatch):
    torch = pytest.importorskip("torch")
    from cfm_backends.torch_explicit.options import resolve_device

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(InputError, match=r"torch.cuda.is_available\(\) = False.*device_count\(\) = 0"):
        resolve_device("cuda")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    with pytest.raises(InputError, match=r"'cuda:3'.*device_count\(\) = 1"):
        resolve_device("cuda:3")
    assert str(resolve_device("cpu")) == "cpu"


def test_run_and_point_on_missing_cuda_are_input_errors():
    torch = pytest.importorskip("torch")
    if torch.cuda.is_available():
        pytest.skip("a CUDA device is available here")
    from cfm_backends.torch_explicit import TorchExplicitBackend
    from cfm_core.scene.builder import build_model
    from cfm_core.material.registry import make_material
    from cfm_core.scene.scene import builtin_scene

    model = build_model(builtin_scene("single-element"))
    with pytest.raises(InputError, match="is_available"):
        TorchExplicitBackend().run(model, device="cuda")
    with pytest.raises(InputError, match="is_available"):
        TorchExplicitBackend().point(make_material("cfm"), [0.0], [[[1, 0, 0], [0, 1, 0], [0, 0, 1]]], device="cuda")


def test_cli_device_error_exit_status(tmp_path):
    pytest.importorskip("torch")
    import torch

    if torch.cuda.is_available():
        pytest.skip("a CUDA device is available here")
    out = subprocess.run([sys.executable, "-m", "cfm_core.cli", "drop-test", "--backend", "torch", "--device",
                          "cuda", "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    assert "torch.cuda.is_available() = False" in out.stderr


def test_gpu_check_without_cuda_exits_2_and_says_why(tmp_path):
    torch = pytest.importorskip("torch")
    if torch.cuda.is_available():
        pytest.skip("a CUDA device is available here")
    out = subprocess.run([sys.executable, "-m", "cfm_backends.torch_explicit.gpu_check", "--out", str(tmp_path)],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "no CUDA device" in out.stderr and "Nothing was run" in out.stderr


def test_gpu_check_dry_run_on_the_cpu(tmp_path):
    """The GPU check's own logic (batches, CPU references, limits, files) on a coarse mesh."""
    import json

    pytest.importorskip("torch")
    out = subprocess.run([sys.executable, "-m", "cfm_backends.torch_explicit.gpu_check", "--out", str(tmp_path),
                          "--device", "cpu", "--sizes", "2", "--element-size", "0.004"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    records = json.loads((tmp_path / "gpu_check.json").read_text())["records"]
    assert [(r["batch"], r["dtype"]) for r in records] == [(1, "float64"), (2, "float64"), (2, "float32"),
                                                           (1, "float32")]
    assert all(r["passed"] and r["host_syncs_per_step"] < 0.1 for r in records)
    assert all(r["estimate_s"] > 0 for r in records)   # the probe's estimate, beside what the run took


def test_gpu_check_that_checked_nothing_fails(tmp_path):
    """A budget spent before any configuration ran is no success (exit 1, said so); a batch of 0
    runs is refused before any work (exit 2)."""
    pytest.importorskip("torch")
    command = [sys.executable, "-m", "cfm_backends.torch_explicit.gpu_check", "--out", str(tmp_path),
               "--device", "cpu", "--element-size", "0.004"]
    out = subprocess.run([*command, "--sizes", "2", "--budget", "0.001"], capture_output=True, text=True)
    assert out.returncode == 1 and "nothing was checked" in out.stdout, out.stdout + out.stderr
    out = subprocess.run([*command, "--sizes", "2", "0"], capture_output=True, text=True)
    assert out.returncode == 2 and "--sizes 2 0: every batch size must be at least 1 run" in out.stderr


def test_gpu_check_estimate_scales_the_probes_loop_by_the_steps():
    """The budget's estimate: a configuration's own 0.5 ms probe, its set-up once and its time loop
    scaled to the whole run's steps (an H200's B = 256 graph probe: 4.9 s, most of it set-up; the
    whole probe scaled said 272 s); a probe that took no step estimates infinity (skipped)."""
    from cfm_backends.torch_explicit.gpu_check import _estimate

    assert _estimate(4.9, 1.2, 75, 1787) == pytest.approx(3.7 + 1.2 * 1787 / 75)
    assert _estimate(0.8, 0.8, 75, 1787) == pytest.approx(0.8 * 1787 / 75)
    assert _estimate(0.8, 0.5, 0, 1787) == float("inf")


def test_gpu_check_probe_runs_the_configuration_briefly():
    """The probe runs the batch to PROBE_END_S on the given device and reports its steps."""
    pytest.importorskip("torch")
    from cfm_backends.torch_explicit import TorchExplicitBackend
    from cfm_backends.torch_explicit.gpu_check import _models, _probe

    models = _models(0.004)
    seconds, loop, steps = _probe(TorchExplicitBackend(), models, 2, "float64", False, "cpu")
    full = TorchExplicitBackend().run(models[0], device="cpu", dtype="float64")
    assert 0 < loop <= seconds and 0 < steps < full.steps / 4   # 0.5 ms of a contact lasting ~10 ms