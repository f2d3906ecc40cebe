"""The numba element pass at 256-bit and 512-bit vectors (AVX-512 CPUs; ``cfm_backends.numba_target``).

    python -m cfm_verification.benchmarks.numba --vector-width [--size 0.001] [--repeat 3]

The width is fixed when numba first compiles in a process, so each width runs in a process of
its own (``CFM_NUMBA_VECTOR_WIDTH=256`` or ``512``), the two alternating ``repeat`` times. Each
process advances the drop test (8 mm, one thread) to the impact (t = 6 ms at 1 mm elements,
1 ms on finer meshes) and times the element pass alone at that state with the process's CPU
time (best of 15 stretches of 0.2 s; the first run of a width compiles its kernels, 1-2 min).
Prints ns per element for both widths, their ratio, and whether the histories of a short run
agree (the width changes how many elements an instruction handles, not an element's
arithmetic, except in a block's scalar remainder loop).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time


def element_pass_ns(size: float, stretches: int = 15, seconds: float = 0.2) -> dict:
    """CPU ns per element of the element pass at the drop test's impact, one thread, in this process.

    Parameters
    ----------
    size : float
        Element size (m) of the built-in drop test (8 mm specimen).
    stretches, seconds : int, float
        Timed stretches of ``seconds`` (s) of repeated passes; the best is kept.

    Returns
    -------
    dict
        ns (best CPU time per element and pass, ns), width (the process's preferred vector width,
        bits; 0: no AVX-512), peak (peak acceleration of the run to t = 2 ms, m/s^2).
    """
    from cfm_backends.numba_explicit import NumbaExplicitBackend
    from cfm_backends.numba_target import configure

    from .scale import drop_model, element_pass_args, one_thread_run

    model = drop_model(size)
    with one_thread_run(model, 6e-3 if size >= 1e-3 else 1e-3) as (mod, prep, _hist):
        x, v, _vold, ed, eh, fb = prep.st[:6]
        args = element_pass_args(mod, prep, x.copy(), v.copy(), ed, eh, fb)

        def one():
            mod.element_pass(*args)

        one()
        best = math.inf
        for _ in range(stretches):
            t0 = time.process_time()
            n = 0
            while time.process_time() - t0 < seconds:
                one()
                n += 1
            best = min(best, (time.process_time() - t0) / n / model.n_elements * 1e9)
    from dataclasses import replace

    r = NumbaExplicitBackend().run(replace(model, end_time=2e-3), threads=1)
    return {"ns": best, "width": configure(), "accel": r.acceleration.tolist()}


def _child(size: float, width: int) -> dict:
    code = ("import json; from cfm_verification.benchmarks.vector_width import element_pass_ns; "
            f"print(json.dumps(element_pass_ns({size!r})))")
    env = {**os.environ, "CFM_NUMBA_VECTOR_WIDTH": str(width)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"vector-width benchmark: the {width}-bit process failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def report(size: float, repeat: int, say=print) -> None:
    """Print the element pass at both widths (best of ``repeat`` alternating processes)."""
    import numpy as np

    from .scale import load

    best: dict = {}
    runs: dict = {}
    say(f"element pass, drop test {size * 1e3:g} mm elements, one thread, CPU ns per element "
        f"(the first process of each width compiles its kernels)")
    for _ in range(max(repeat, 1)):
        for width in (256, 512):
            r = runs[width] = _child(size, width)
            best[width] = min(best.get(width, math.inf), r["ns"])
            say(f"  {width}-bit request: {r['ns']:.1f} ns (width used: {r['width'] or 'no AVX-512'})  ({load()})")
    if runs[512]["width"] != 512:
        say("  this CPU (or the environment) gives no 512-bit vectors: both processes ran the same code")
    a, b = np.asarray(runs[256]["accel"]), np.asarray(runs[512]["accel"])
    same = "bit for bit" if a.shape == b.shape and np.array_equal(a, b) else (
        f"to {np.abs(a - b).max() / np.abs(a).max():.1e} of the peak" if a.shape == b.shape
        else f"in {a.size} and {b.size} steps")
    say(f"  best: 256-bit {best[256]:.1f} ns, 512-bit {best[512]:.1f} ns, 256 / 512 = {best[256] / best[512]:.2f}; "
        f"acceleration histories to 2 ms agree {same}")
