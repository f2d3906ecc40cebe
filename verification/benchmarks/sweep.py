"""Sweep speed-up on Dask: ``python -m cfm_verification.benchmarks.sweep [--element-size 0.001] [--runs 8]``.

Runs the same sweep (``--runs`` impact speeds from 0.8 to 1.2 m/s, drop-test scene, numba) twice
into temporary folders: serially in this process (numba with its default threads; kernels
loaded before timing; ``--serial-threads``) and on a local Dask cluster of ``--workers`` one-thread processes. Prints
both wall times, the cluster's start-up, and the speed-up serial / Dask (with and without the
start-up), and checks that both tables hold the same numbers.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from cfm_core.scene import builtin_scene
from cfm_core.studies import sweep
from cfm_core.studies.dask_runner import SerialRunner, open_runner


def same_tables(path_a, path_b, rtol: float = 0.0) -> bool:
    """Whether two sweep.csv hold the same runs and values (times apart) to ``rtol``
    (relative, absolute below 1; default: exactly).

    A numba run gives the same bits on any thread count, its energy sums included (the element
    pass sums its chunks' stress work in chunk order, the energy pass fixed node ranges), so the
    serial sweep (2 threads per run) and the cluster's (1 thread per worker) must agree exactly.
    """
    a, b = sweep.read_table(path_a), sweep.read_table(path_b)
    if len(a) != len(b):
        return False
    for ra, rb in zip(a, b):
        for k, v in ra.items():
            if k.startswith(("run_time", "wall_time")):
                continue
            w = rb.get(k)
            if isinstance(v, float) and isinstance(w, float):
                if abs(v - w) > rtol * max(abs(v), abs(w), 1.0):
                    return False
            elif v != w:
                return False
    return True


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m cfm_verification.benchmarks.sweep", description=__doc__.splitlines()[0])
    p.add_argument("--element-size", type=float, default=0.001, help="hexahedron edge, m (default 0.001)")
    p.add_argument("--thickness", type=float, default=0.008, help="specimen thickness, m (default 0.008)")
    p.add_argument("--runs", type=int, default=8, help="drop tests in the sweep (default 8)")
    p.add_argument("--workers", type=int, default=2, help="local Dask workers (default 2)")
    p.add_argument("--serial-threads", type=int, default=None,
                   help="numba threads of the serial run (default: numba's, i.e. the cores)")
    args = p.parse_args(argv)
    import numba

    if args.serial_threads is not None:
        numba.set_num_threads(args.serial_threads)
    scene = builtin_scene("drop-test").with_overrides(element_size=args.element_size, thickness=args.thickness)
    speeds = ",".join(f"{v:.6g}" for v in np.linspace(0.8, 1.2, args.runs))
    axes = sweep.parse_vary([f"velocity={speeds}"], scene)
    sweep.run_case((scene, {}, "numba"))  # load (or compile) the kernels in this process first
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        serial = sweep.run_sweep(scene, axes, Path(tmp) / "serial", "numba", SerialRunner())
        t_serial = time.perf_counter() - t0
        t0 = time.perf_counter()
        with open_runner(None, args.workers) as runner:
            t_start = time.perf_counter() - t0
            dask = sweep.run_sweep(scene, axes, Path(tmp) / "dask", "numba", runner)
            t_sweep = time.perf_counter() - t0 - t_start
        t_dask = time.perf_counter() - t0
        same = same_tables(Path(tmp) / "serial" / "sweep.csv", Path(tmp) / "dask" / "sweep.csv")
    per_run = np.mean([r["run_time"] for r in serial.rows])
    print(f"{args.runs} drop tests, {1e3 * args.thickness:g} mm, {1e3 * args.element_size:g} mm hexahedra, "
          f"{serial.rows[0]['elements']} elements, {per_run:.2f} s per run serially; "
          f"{serial.failed + dask.failed} failed")
    print(f"serial (this process, {numba.get_num_threads()} numba thread(s)): {t_serial:.2f} s")
    print(f"local Dask cluster, {args.workers} workers x 1 thread: {t_dask:.2f} s "
          f"(start-up {t_start:.2f} s, sweep {t_sweep:.2f} s, incl. loading kernels in each worker)")
    print(f"speed-up serial / Dask: {t_serial / t_dask:.2f} (whole command), {t_serial / t_sweep:.2f} "
          f"(cluster already running)")
    print(f"tables equal (every value, times apart): {same}")
    return 0 if same else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
