"""Cost of one physics check (cfm_core.simulation.checks.Monitor) on a large drop test.

    python -m cfm_verification.benchmarks.checks [--size 0.00033] [--repeat 40]

The built-in drop test (quarter, 8 mm) at ``size`` elements (138 624 hexahedra at 0.33 mm),
its nodes squeezed by 1 % in z and the impactor at its reference height over the squeezed top
(a state every check passes, so each check does all its work). Timed, best of ``repeat`` (wall
time; the load average is printed):

* numpy: the monitor with the numpy reference scan (``cfm_core.simulation.scan.Scan``, what the
  torch and skfem backends use), given the positions in the user's numbering after the permuted
  copy from the solver's (what the numba backend did before its own scan);
* numba, 1 and 2 threads: the monitor with the numba backend's parallel scan
  (``cfm_backends.numba_explicit.scan.NumbaScan``) of the positions in the solver's numbering.
"""

from __future__ import annotations

import argparse
import functools
import time

import numpy as np

from .scale import drop_model, load


def best(f, repeat: int) -> float:
    """Best wall time (ms) of ``f()`` over ``repeat`` calls after one warm-up call."""
    f()
    out = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        out = min(out, time.perf_counter() - t)
    return 1e3 * out


def main(argv=None) -> dict:
    """Run the benchmark (module docstring); returns the times (ms) by row."""
    import numba

    from cfm_backends.explicit import renumber
    from cfm_backends.numba_explicit.scan import NumbaScan
    from cfm_core.simulation.checks import Monitor

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.33e-3, help="element size (m)")
    ap.add_argument("--repeat", type=int, default=40, help="timed checks per row")
    a = ap.parse_args(argv)
    m = drop_model(a.size, end_time=1.6e-3)
    ren = renumber.plan(m.nodes, m.hexes, "morton")
    x = m.nodes.copy()
    x[:, 2] *= 0.99
    xi = np.ascontiguousarray(ren.to_internal_nodes(x))
    z = float(x[:, 2].max()) + m.sphere.bottom       # the impactor just touching the squeezed top
    reference = Monitor(m)
    fast = Monitor(m, scan=functools.partial(NumbaScan, ren=ren))
    print(f"drop test at {a.size * 1e3:g} mm: {m.n_elements} hexahedra, {m.n_nodes} nodes; {load()}")
    times = {"numpy": best(lambda: reference.inspect(0.0, ren.to_user_nodes(xi), z), a.repeat)}
    before = numba.get_num_threads()
    try:
        for th in (1, 2):
            numba.set_num_threads(min(th, numba.config.NUMBA_NUM_THREADS))
            times[f"numba, {th} thread{'s' if th > 1 else ''}"] = best(lambda: fast.inspect(0.0, xi, z), a.repeat)
    finally:
        numba.set_num_threads(before)
    for name, ms in times.items():
        print(f"  one check, {name:16s} {ms:7.2f} ms")
    assert reference.report() == fast.report(), (reference.report(), fast.report())
    print(f"  same report: {fast.report()}; {load()}")
    return times


if __name__ == "__main__":
    main()
