"""Options of the torch backend: defaults, validation, device and dtype resolution.

The explicit-solver options (``hourglass``, ``safety``, ...) have the numba backend's names,
defaults and meaning, so that both backends run the same algorithm with the same numbers.
torch itself is imported only by :func:`resolve_device` / :func:`resolve_dtype` (at run time).
"""

from __future__ import annotations


from cfm_core.errors import InputError

DEVICES = ("cpu", "cuda")
DTYPES = ("float64", "float32")

def _explicit_defaults() -> dict:
    from cfm_backends.numba_explicit.solver import DEFAULTS as explicit

    return explicit


DEFAULTS = {
    **_explicit_defaults(),      # hourglass, safety, dt_max, collapse, ...: the numba backend's, shared
    "device": "cpu",             # "cpu", "cuda" or "cuda:N"
    "dtype": "float64",          # "float64" or "float32" (state, stresses, forces)
    "threads": None,             # torch intra-op threads (None: 1 below 20000 elements on the CPU, else torch's)
    "warm_up": True,             # one element pass before the clock starts (and torch.compile)
    "compile": False,            # False, True or a torch.compile mode ("default", "reduce-overhead", ...)
    "newton_block": None,        # contact Newton iterations between host checks (None: 1 cpu, 4 cuda)
}


def check_options(options: dict) -> dict:
    """Options merged over DEFAULTS; unknown names and bad values raise InputError."""
    from cfm_backends.numba_explicit.solver import check_options as check_explicit

    o = check_explicit(options, DEFAULTS, "torch")
    if o["threads"] is not None and not (isinstance(o["threads"], int) and o["threads"] >= 1):
        raise InputError(f"torch backend: threads = {o['threads']!r} must be a positive integer or None.")
    if o["newton_block"] is not None and not (isinstance(o["newton_block"], int) and o["newton_block"] >= 1):
        raise InputError(f"torch backend: newton_block = {o['newton_block']!r} must be a positive integer or None.")
    if not (isinstance(o["compile"], (bool, str))):
        raise InputError(f"torch backend: compile = {o['compile']!r}; use False, True or a torch.compile "
                         f"mode name ('default', 'reduce-overhead', 'max-autotune').")
    check_dtype_name(o["dtype"])
    check_device_name(o["device"])
    return o


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
