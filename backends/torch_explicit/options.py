"""Options of the torch backend (declared once), device and dtype resolution.

:class:`TorchOptions` extends the shared explicit-solver options (``cfm_backends.explicit.options``:
the same names, defaults and meaning on numba and torch, so that both run the same algorithm with
the same numbers) with the device, the dtype, threads, ``torch.compile`` and the contact Newton
block. torch itself is imported only by :func:`resolve_device` / :func:`resolve_dtype` (at run time).
"""

from __future__ import annotations

from dataclasses import dataclass

from cfm_backends.explicit.options import ExplicitOptions
from cfm_core.errors import InputError
from cfm_core.simulation.options import document, option

DEVICES = ("cpu", "cuda")
DTYPES = ("float64", "float32")

# Below this many elements the CPU run uses one torch thread unless told otherwise: the tensors are
# then rows of ~1e4-1e5 numbers, where intra-op threads gain little when the cores are free and,
# on a machine whose cores are shared, made a 5000-element drop test 40 times slower.
PARALLEL_MIN = 20_000


@document
@dataclass(frozen=True)
class TorchOptions(ExplicitOptions):
    """Options of the torch backend (``TorchExplicitBackend.run(model, **options)``)."""

    owner = "torch backend"
    device: str = option("cpu", "-", "'cpu', 'cuda' or 'cuda:N' (N the GPU index)", kind="any")
    dtype: str = option("float64", "-", "floating point type of state, stresses and forces ('float64' or "
                        "'float32'; torch dtypes accepted)", kind="any")
    threads: int = option(None, "-", "torch intra-op threads for the run", kind="int", low=1,
                          none=f"1 below {PARALLEL_MIN} elements on the CPU, else the cores free now (at most torch's "
                               f"setting)")
    compile: object = option(False, "-", "torch.compile the pointwise part of the element pass: False, True or "
                             "a mode name ('default', 'reduce-overhead', 'max-autotune'); tens of seconds once",
                             kind="any", choices=(False, True, "default", "reduce-overhead", "max-autotune",
                                                  "max-autotune-no-cudagraphs"))
    newton_block: int = option(None, "-", "contact Newton iterations between host checks (the result does not "
                               "depend on it)", kind="int", low=1, none="1 on the CPU, 4 on CUDA")
    cuda_graph: bool = option(None, "-", "run the drop-test step as a captured CUDA graph (needs device='cuda' "
                              "and the sync-free step)", kind="bool",
                                none="on for a sync-free drop test on CUDA without compile, else off")

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "dtype", check_dtype_name(self.dtype))
        object.__setattr__(self, "device", check_device_name(self.device))
        if not isinstance(self.compile, (bool, str)):
            raise InputError(f"torch backend: option compile = {self.compile!r} is not allowed; use False, True or "
                             f"a torch.compile mode name ('default', 'reduce-overhead', 'max-autotune').")
        check_cuda_graph(self.cuda_graph, self.device, self.compile)


def check_cuda_graph(value, device: str, compile_mode) -> None:
    """InputError unless ``cuda_graph`` (None, True or False: checked by its declaration) is True
    only with a CUDA device and without 'reduce-overhead' compile (which captures graphs of its own)."""
    if value and not device.startswith("cuda"):
        raise InputError(f"torch backend: option cuda_graph = True is not allowed with device = '{device}'; CUDA "
                         f"graphs need device='cuda' (or 'cuda:N'); on the CPU use cuda_graph=None or False.")
    if value and compile_mode == "reduce-overhead":
        raise InputError("torch backend: option cuda_graph = True is not allowed with compile = 'reduce-overhead' "
                         "(that mode captures CUDA graphs of its own); use one or the other.")


def check_dtype_name(dtype) -> str:
    """The dtype name ("float64" / "float32"); accepts torch dtypes too. InputError otherwise."""
    name = str(dtype).replace("torch.", "")
    if name == "double":
        name = "float64"
    if name == "float":
        name = "float32"
    if name not in DTYPES:
        raise InputError(f"torch backend: dtype = {dtype!r} is not supported; use one of {', '.join(DTYPES)} "
                         f"(float64 is the default and the one to use for stiff scenes).")
    return name


def check_device_name(device) -> str:
    """'cpu', 'cuda' or 'cuda:N' (accepts torch.device); InputError otherwise."""
    name = str(device)
    kind, _, index = name.partition(":")
    if kind not in DEVICES or (index and not (index.isdigit() and kind == "cuda")):
        raise InputError(f"torch backend: device = {device!r} is not supported; use 'cpu', 'cuda' or "
                         f"'cuda:N' (N the GPU index).")
    return name


def resolve_dtype(dtype):
    """The torch dtype of a name ("float64" / "float32")."""
    import torch

    return {"float64": torch.float64, "float32": torch.float32}[check_dtype_name(dtype)]


def resolve_device(device):
    """A torch.device; asking for CUDA where there is none is an InputError naming what was found."""
    import torch

    name = check_device_name(device)
    if name == "cpu":
        return torch.device("cpu")
    available = bool(torch.cuda.is_available())
    count = int(torch.cuda.device_count()) if available else 0
    index = int(name.partition(":")[2] or 0)
    if not available or index >= count:
        built = getattr(torch.version, "cuda", None)
        build = f"with CUDA {built}" if built else "without CUDA (CPU-only build)"
        found = (f"torch.cuda.is_available() = {available}, torch.cuda.device_count() = {count}, "
                 f"torch {torch.__version__} built {build}")
        raise InputError(f"torch backend: device = '{name}' was requested but no such CUDA device is usable here "
                         f"({found}); run with device='cpu' (CLI: --device cpu), or install a CUDA build of "
                         f"torch on a machine with an NVIDIA GPU and driver.")
    return torch.device(name)
