"""numba's machine code at the host CPU's full vector width.

LLVM tunes Intel's AVX-512 processors (Skylake-SP to Sapphire Rapids; numba names them e.g.
``skylake-avx512``, ``icelake-server``, ``rocketlake``) to prefer 256-bit vectors (its tuning
feature ``prefer-256-bit``, a guard against the clock drop of early AVX-512 parts): a vectorised
loop then handles 4 doubles per instruction instead of 8. The element blocks of the numba backend
(``numba_explicit/kernels/element.py``) are such loops across elements; with 512-bit vectors their
pass took 263.7 ns per element instead of 346.5 ns on a 2-core Xeon (Sapphire Rapids, 2.0 GHz, best
of 2 alternating processes each; ``python -m cfm_verification.benchmarks.numba --vector-width``),
and the 1 mm drop test 278 instead of 501 ns per element-cycle (docs/user/performance.md).

:func:`configure` therefore asks numba, before its first compilation in the process, for the host's
own features plus ``-prefer-256-bit``. It leaves numba alone where

* the CPU has no AVX-512 (nothing to gain: the tuning flag changes nothing there),
* the user set ``NUMBA_CPU_FEATURES`` or ``NUMBA_CPU_NAME`` (their choice wins),
* ``CFM_NUMBA_VECTOR_WIDTH=256`` is set (this module's switch off), or
* numba has already compiled code in this process (its code generator exists; it keeps the
  features it started with, and so do the kernels, correctly, only at the narrower width).

The width changes how many elements one instruction handles, not the arithmetic of an element,
except for a block's last few elements when a mesh's element count leaves fewer than 8 (or 4) in
the last block: they take LLVM's scalar remainder loop, whose fused multiply-adds may round
differently (histories then agree to round-off; the paper's 1 mm drop test, 5000 elements, is
bit for bit the same at both widths). numba's cache keys machine code on the features, so each
width compiles once.
"""

from __future__ import annotations

import os

#: Environment variable that turns the wide vectors off (value ``256``).
SWITCH = "CFM_NUMBA_VECTOR_WIDTH"

_state = {"width": None}


def configure() -> int:
    """Ask numba for 512-bit vectors on AVX-512 CPUs, before its first compilation.

    Returns
    -------
    int
        The preferred vector width in bits the process's numba code gets: 512 where this call (or
        an earlier one) set it, 256 where it left numba's default (see the module docstring), 0
        where the CPU has no AVX-512 (numba's default width for that CPU applies).

    Raises
    ------
    cfm_core.errors.InputError
        ``CFM_NUMBA_VECTOR_WIDTH`` set to something other than 256 or 512.
    """
    if _state["width"] is not None:
        return _state["width"]
    want = os.environ.get(SWITCH, "").strip()
    if want not in ("", "256", "512"):
        from cfm_core.errors import InputError

        raise InputError(f"environment variable {SWITCH} = {want!r}: use 256 (numba's default vector width) or "
                         f"512 (full AVX-512 vectors, the default on AVX-512 CPUs), or leave it unset.")
    import llvmlite.binding as ll
    from numba.core import config
    from numba.core.registry import cpu_target

    features = ll.get_host_cpu_features()
    if not features.get("avx512f", False):
        width = 0
    elif (want == "256" or config.CPU_FEATURES is not None or config.CPU_NAME is not None
          or "_toplevel_target_context" in vars(cpu_target)):
        width = 256
    else:
        config.CPU_FEATURES = features.flatten() + ",-prefer-256-bit"
        width = 512
    _state["width"] = width
    return width


def source_line() -> str:
    """The line a generated numba module carries to name its vector width (after :func:`configure`):
    the width is part of the module's text, so each width is a module and a cache entry of its own
    (and the cold-run notice's cache check stays right).

    Returns
    -------
    str
        ``"# preferred vector width: 512 (cfm_backends.numba_target)\\n"`` (or 256, or ``default``).

    Raises
    ------
    cfm_core.errors.InputError
        As :func:`configure`.
    """
    return f"# preferred vector width: {configure() or 'default'} (cfm_backends.numba_target)\n"
