"""Agreement and speed of the torch backend next to the numba backend (figures, not timed tests).

    python -m cfm_verification.benchmarks.torch [--compile] [--refined-time 0.004] [--repeat 2]
                                                     [--skip-refined] [--threads N ...]

1. Material point: ``point`` (float64) against the core reference ``cfm_core.material.reference.stress_history``
   along a drop-test-like history (compression with shear at about 150 1/s, then a hold): largest
   stress difference relative to the largest stress.
2. Agreement: the built-in drop test (8 mm and 5 mm, 1 mm elements, quarter model) on numba and
   on torch (float64, and float32 for information) with the same mesh and step rule: relative L2
   difference of the CFC 600 filtered impactor acceleration over the common 50 kHz samples, peaks,
   step counts.
4. Batches (``--batch``, or only them with ``--batch-only``): B = 1, 4, 16, 64 drop tests of the
   default mesh with different fibre stiffness k2 and impact velocity in one batched torch run
   (float64, CPU, one thread), simulated for ``--batch-time`` seconds; per-run solver time (batch
   time / B) against numba on one thread in the same process (the mean over the same runs), host
   synchronisations per step, and memory per run (persistent tensors, and the growth of the
   process's peak resident memory over the batch, sizes in increasing order).
3. Speed: solver wall time (compilation excluded, reported apart) and nanoseconds per
   element-cycle (wall / (elements x steps)) of numba and of torch on the CPU (eager float64 and
   float32; compiled with ``--compile``) with the same thread count (``--threads``, default 1),
   best of ``--repeat`` runs, as ratios torch / numba; also the process CPU time of the run call
   (``time.process_time``, set-up included: much less disturbed than wall time by other processes
   on a shared machine) and its ratio; on the default drop test, on a coarse one (2 mm elements,
   ``--coarse``, where torch's per-op overhead dominates) and on a refined one (0.5 mm elements, 8x
   the elements) simulated for ``--refined-time`` seconds of the impact. The torch eager float64
   step is described by its aten ops per step (counted with a dispatch mode over the first 4 ms of
   the impact, views included) and host synchronisations per step.

Timings on a loaded machine are not meaningful: the load average is printed first.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import numpy as np


def scene_model(thickness: float = 0.008, element_size: float = 0.001, end_time: float | None = None):
    """The built-in drop test with a thickness and element size (m); optional end time (s)."""
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    model = build_model(builtin_scene("drop-test").with_overrides(thickness=thickness, element_size=element_size))
    return replace(model, end_time=end_time) if end_time else model


def filtered_acceleration(result, model) -> np.ndarray:
    from cfm_core.post import acceleration_histories

    return acceleration_histories(result, model.mass_full)[2]


def rel_l2(a: np.ndarray, ref: np.ndarray) -> float:
    """Relative L2 difference over the common samples (two runs may stop a step apart)."""
    from cfm_core.post import relative_l2

    n = min(a.size, ref.size)
    return relative_l2(a[:n], ref[:n])


def point_agreement() -> dict:
    """Max |sigma_torch - sigma_ref| / max |sigma_ref| along a drop-test-like history (float64, float32)."""
    from cfm_core.material import kinematics as kin
    from cfm_core.material import reference
    from cfm_core.material.registry import make_material

    from cfm_backends.torch_explicit import TorchExplicitBackend

    material = make_material("cfm")
    t = np.linspace(0.0, 0.01, 401)
    s = np.minimum(t / 0.004, 1.0)                       # 0.6 compression in 4 ms (150 1/s), then hold
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = F[:, 1, 1] = (1.0 - 0.6 * s) ** -0.4
    F[:, 2, 2] = 1.0 - 0.6 * s
    F[:, 0, 2] = 0.2 * s
    ref = kin.to_voigt(reference.stress_history(material, t, F))
    out = {}
    for dtype in ("float64", "float32"):
        sig = TorchExplicitBackend().point(material, t, F, dtype=dtype)
        out[dtype] = float(np.abs(sig - ref).max() / np.abs(ref).max())
    return out


def timed(backend: str, model, repeat: int, **options):
    """Best (smallest solver wall time) of ``repeat`` runs: the Result, with ``info['cpu_time']`` the
    smallest process CPU time (s) of a run call (``time.process_time``, set-up included)."""
    from cfm_core.simulation.registry import get_backend

    best, first, cpu = None, None, float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        r = get_backend(backend).run(model, **options)
        cpu = min(cpu, time.process_time() - c0)
        first = r.info.get("compile_time") if first is None else first
        if best is None or r.wall_time < best.wall_time:
            best = r
    best.info["first_compile_time"] = first
    best.info["cpu_time"] = cpu
    return best


def ops_per_step(model, end_time: float = 0.004) -> float:
    """aten ops per step of the torch eager float64 run (one thread) over the first ``end_time`` s,
    counted with a ``TorchDispatchMode`` (every op the step dispatches, views included)."""
    from torch.utils._python_dispatch import TorchDispatchMode

    from cfm_backends.torch_explicit import TorchExplicitBackend

    class _Count(TorchDispatchMode):
        n = 0

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            _Count.n += 1
            return func(*args, **(kwargs or {}))

    with _Count():
        r = TorchExplicitBackend().run(replace(model, end_time=end_time), threads=1, warm_up=False)
    return _Count.n / r.steps


def agreement(thickness: float) -> None:
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    from cfm_backends.torch_explicit import TorchExplicitBackend

    model = scene_model(thickness)
    ref = NumbaExplicitBackend().run(model)
    a_ref = filtered_acceleration(ref, model)
    for dtype in ("float64", "float32"):
        res = TorchExplicitBackend().run(model, dtype=dtype)
        a = filtered_acceleration(res, model)
        print(f"  {1e3 * thickness:.0f} mm, {model.n_elements} elements, torch {dtype}: rel. L2 of filtered "
              f"acceleration {rel_l2(a, a_ref):.2e}; peak {a.max() / 9.80665:.4f} g (numba "
              f"{a_ref.max() / 9.80665:.4f} g); steps {res.steps} (numba {ref.steps}); energy error "
              f"{res.energy_error():.2e} (numba {ref.energy_error():.2e})", flush=True)


def speed(label: str, model, repeat: int, compile_: bool, threads: list[int]) -> None:
    ne = model.n_elements
    print(f"\n{label}: {ne} hexahedra, {model.n_nodes} nodes, end time {1e3 * model.end_time:g} ms", flush=True)
    timed("numba", model, 1, threads=1)                 # compile / load the numba kernels
    rows = []
    for th in threads:
        rows.append((f"numba, {th} thread(s)", timed("numba", model, repeat, threads=th)))
        rows.append((f"torch eager cpu float64, {th} thread(s)", timed("torch", model, repeat, threads=th)))
        rows.append((f"torch eager cpu float32, {th} thread(s)",
                     timed("torch", model, repeat, threads=th, dtype="float32")))
        if compile_:
            rows.append((f"torch compiled cpu float64, {th} thread(s)",
                         timed("torch", model, repeat, threads=th, compile=True)))
    ref = {r.info["threads"]: r for name, r in rows if name.startswith("numba")}
    for name, r in rows:
        extra = (f", compilation {r.info['first_compile_time']:.1f} s apart (first run)"
                 if r.info.get("compile") else "")
        nb = ref.get(r.info["threads"])
        ratio = r.wall_time / nb.wall_time if nb else float("nan")
        cpu_ratio = r.info["cpu_time"] / nb.info["cpu_time"] if nb else float("nan")
        print(f"  {name:<40} {r.wall_time:8.3f} s {r.info['ns_per_element_cycle']:7.0f} ns/element-cycle "
              f"{r.steps:6d} steps  {ratio:5.2f} x numba; CPU {r.info['cpu_time']:7.3f} s, {cpu_ratio:5.2f} x "
              f"numba{extra}", flush=True)
    r64 = next(r for name, r in rows if name.startswith("torch eager cpu float64"))
    print(f"  torch eager float64 step: {ops_per_step(model):.0f} aten ops, "
          f"{r64.info['host_syncs_per_step']:.2f} host synchronisations", flush=True)


def batch_models(b: int, end_time: float, element_size: float = 0.001):
    """b drop tests on the default mesh: k2 from 1.4 to 2.0, impact velocity from 0.9 to 1.1 m/s."""
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    base = builtin_scene("drop-test").with_overrides(element_size=element_size)
    out = []
    for i in range(b):
        f = i / max(b - 1, 1)
        scene = base.with_overrides(parameters={"k2": 1.4 + 0.6 * f}, velocity=0.9 + 0.2 * ((7 * i) % b) / max(b - 1, 1))
        out.append(replace(build_model(scene), end_time=end_time))
    return out


def batches(sizes: list[int], end_time: float, numba_runs: int = 4) -> None:
    """Per-run solver time of torch batches against numba (one thread each), memory per run."""
    from cfm_backends.numba_explicit import NumbaExplicitBackend
    from cfm_backends.torch_explicit import TorchExplicitBackend

    models = batch_models(max(sizes), end_time)
    ne = models[0].n_elements
    nb = NumbaExplicitBackend()
    nb.run(models[0], threads=1)                                       # compile / load
    ref = [nb.run(m, threads=1) for m in models[:numba_runs]]
    per_numba = sum(r.wall_time for r in ref) / len(ref)
    steps = sum(r.steps for r in ref) / len(ref)
    print(f"  numba, 1 thread: {per_numba:.3f} s per run ({steps:.0f} steps, {ne} hexahedra, "
          f"{per_numba / (steps * ne) * 1e9:.0f} ns per element-cycle; mean of {len(ref)} runs)", flush=True)
    import resource

    tb = TorchExplicitBackend()
    for b in sorted(sizes):
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0      # MiB (Linux: KiB)
        res = tb.run_batch(models[:b], threads=1)
        grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0 - before
        r0 = res[0]
        per = r0.info["batch_wall_time"] / b
        ns = r0.info["batch_wall_time"] / (sum(r.steps for r in res) * ne) * 1e9
        print(f"  torch batch B = {b:3d}: {per:.3f} s per run ({per / per_numba:5.2f} x numba), {ns:.0f} ns per "
              f"element-cycle, {r0.info['host_syncs_per_step']:.2f} host syncs per step, "
              f"{r0.info['tensor_bytes_per_run'] / 2**20:.1f} MiB of state and geometry tensors per run, process "
              f"peak memory grew {grown:.0f} MiB ({grown / b:.1f} MiB per run)", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="runs per configuration (the fastest is kept)")
    ap.add_argument("--compile", action="store_true", help="also time torch.compile'd element passes")
    ap.add_argument("--refined-time", type=float, default=0.004,
                    help="simulated time of the refined (0.5 mm) drop test, s (default 0.004)")
    ap.add_argument("--skip-refined", action="store_true", help="skip the refined drop test")
    ap.add_argument("--coarse", action="store_true", help="also time the coarse drop test (8 mm, 2 mm elements)")
    ap.add_argument("--speed-only", action="store_true", help="only the speed section (3)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1],
                    help="thread counts to time, the same for both backends (default: 1)")
    ap.add_argument("--batch", action="store_true", help="also time batched torch runs (section 4)")
    ap.add_argument("--batch-only", action="store_true", help="only the batched runs (section 4)")
    ap.add_argument("--batch-sizes", type=int, nargs="+", default=[1, 4, 16, 64], help="batch sizes B")
    ap.add_argument("--batch-time", type=float, default=0.004,
                    help="simulated time of the batched drop tests, s (default 0.004: through the peak)")
    args = ap.parse_args(argv)

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs "
          f"(timings are only meaningful on an idle machine)", flush=True)
    t0 = time.perf_counter()
    if args.batch or args.batch_only:
        print(f"\n4. batched drop tests (8 mm, 1 mm elements, first {1e3 * args.batch_time:g} ms), per run:")
        batches(args.batch_sizes, args.batch_time)
        if args.batch_only:
            print(f"\nbenchmark took {time.perf_counter() - t0:.0f} s")
            return
    if not args.speed_only:
        print("\n1. material point vs cfm_core.material.reference.stress_history (max |d sigma| / max |sigma|):")
        pa = point_agreement()
        print(f"  float64 {pa['float64']:.2e}, float32 {pa['float32']:.2e}", flush=True)
        print("\n2. drop test agreement with numba (same mesh, same step rule):")
        for thickness in (0.008, 0.005):
            agreement(thickness)
    print("\n3. speed (solver wall time, compilation excluded):")
    speed("default drop test (8 mm, 1 mm elements)", scene_model(), args.repeat, args.compile, args.threads)
    if args.coarse:
        speed("coarse drop test (8 mm, 2 mm elements)", scene_model(0.008, 0.002), args.repeat, args.compile,
              args.threads)
    if not args.skip_refined:
        speed(f"refined drop test (8 mm, 0.5 mm elements, first {1e3 * args.refined_time:g} ms)",
              scene_model(0.008, 0.0005, args.refined_time), args.repeat, args.compile, args.threads)
    print(f"\nbenchmark took {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
