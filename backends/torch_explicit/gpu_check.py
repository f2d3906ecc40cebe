"""GPU check of the torch backend, sized for a short lease of one large GPU (< 8 minutes).

    python -m cfm_backends.torch_explicit.gpu_check --out DIR [--sizes 64 256] [--budget 420]

On CUDA: the paper's 8 mm drop test (1 mm hexahedra, quarter model) alone and in batches of 64
and 256 (half of each batch with the paper's k2 = 1.66, half with k2 = 2.5, so that runs mixed
up would show; every step free of host synchronisation, ``sync_free``), in float64 and float32;
each run is checked against the CPU float64 result of the same model (relative L2 of the CFC 600
filtered acceleration; limits 1e-10 in float64, 1e-4 in float32), and the script prints per-run
solver time, ns per element-cycle, host syncs per step and device memory per run. Each
configuration runs twice: its step captured as a CUDA graph and replayed (``cuda_graph=True``),
then the same step eagerly (``cuda_graph=False``); the eager row says how many times faster the
graph was (the graph's time includes its three warm-up steps and the capture). Results go to
DIR/gpu_check.json and DIR/gpu_check.txt. Each configuration first runs a probe of 0.5 ms (about
4 % of the steps); one whose time estimated from it (set-up once, the time loop scaled by the
steps) would end the check after ``--budget`` seconds is skipped, and said so; a check that ran
no configuration exits with status 1. Without a usable CUDA device it exits with status 2 and says
why; ``--device cpu`` (with ``--sizes 3 --element-size 0.002``) is a dry run of the script on the
CPU (about a minute: the sync-free step is slow on the CPU).

Measured on an NVIDIA H200 (torch 2.11, 2026-12-04): the CPU references 31 s, then per run
B = 1 graph 7.9 s (eager 53 s), B = 64 graph 0.30 s (eager 1.13 s) in float64; float32 about
12 % faster; that first run, with batches of 64 and 1024, spent 336 s before reaching 1024,
whence the default sizes 64 and 256 and the skipping by estimate. A second run estimated a
batch from the cost per element-cycle of one run and skipped every batch (B = 64 "about 504 s",
which took 19 s before): the estimate now comes from a probe of the configuration itself. A third
run (float64 B = 64: graph 0.306 s, eager 1.18 s per run; float32 graph 0.291 s) scaled the whole
probe and skipped B = 256 (a 4.9 s probe, mostly set-up, said 272 s): the set-up now counts once.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

LIMITS = {"float64": 1e-10, "float32": 1e-4}


def _models(element_size: float):
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    base = builtin_scene("drop-test").with_overrides(element_size=element_size)
    return build_model(base), build_model(base.with_overrides(parameters={"k2": 2.5}))


def _filtered(result, model) -> np.ndarray:
    from cfm_core.post import acceleration_histories

    return acceleration_histories(result, model.mass_full)[2]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    from cfm_core.post import relative_l2

    n = min(a.size, b.size)
    return float(relative_l2(a[:n], b[:n]))


def _check(be, models, refs, b: int, dtype: str, graph: bool, device: str, ne: int, say, records) -> dict:
    """Run one batch configuration (``graph``: as a captured CUDA graph), check it against the CPU
    references and say its times; the record (with the graph's speed-up over the eager step of
    the same configuration when that ran before it)."""
    import torch

    batch = [models[i % 2] for i in range(b)]
    label = f"B = {b:4d} {dtype} {'graph' if graph else 'eager'}"
    if device.startswith("cuda"):
        torch.cuda.reset_peak_memory_stats(device)
    t0 = time.perf_counter()
    try:
        res = be.run_batch(batch, device=device, dtype=dtype, raise_errors=False, sync_free=True, cuda_graph=graph)
    except Exception as exc:  # report and go on: the other configurations still say something
        say(f"  {label}: FAILED {type(exc).__name__}: {exc}")
        return {"batch": b, "dtype": dtype, "cuda_graph": graph, "error": str(exc)}
    total = time.perf_counter() - t0
    errs = [r for r in res if isinstance(r, Exception)]
    ok = [(i, r) for i, r in enumerate(res) if not isinstance(r, Exception)]
    worst = max((_rel(_filtered(r, batch[i]), refs[i % 2]) for i, r in ok), default=float("nan"))
    info = ok[0][1].info if ok else {}
    wall = info.get("batch_wall_time", float("nan"))
    steps = sum(r.steps for _, r in ok)
    rec = {"batch": b, "dtype": dtype, "cuda_graph": bool(info.get("cuda_graph", False)), "per_run_s": wall / b,
           "total_s": total, "ns_per_element_cycle": wall / max(steps * ne, 1) * 1e9,
           "host_syncs_per_step": info.get("host_syncs_per_step"),
           "peak_device_MiB_per_run": (info["peak_device_bytes_per_run"] / 2**20
                                       if "peak_device_bytes_per_run" in info else None),
           "worst_rel_l2_vs_cpu": worst, "limit": LIMITS[dtype], "failed_runs": len(errs),
           "passed": bool(not errs and worst < LIMITS[dtype] and bool(info.get("cuda_graph", False)) == graph)}
    mib = rec["peak_device_MiB_per_run"]
    other = [r for r in records if r.get("batch") == b and r.get("dtype") == dtype and "per_run_s" in r]
    speed = ""
    if other and not graph:                 # the graph ran first: eager time / graph time
        other[0]["speedup_over_eager"] = rec["per_run_s"] / other[0]["per_run_s"]
        speed = f", the graph was {other[0]['speedup_over_eager']:.2f}x faster"
    say(f"  {label}: {rec['per_run_s']:.3f} s per run, {rec['ns_per_element_cycle']:.2f} ns per "
        f"element-cycle, {'n/a' if mib is None else f'{mib:.1f}'} MiB per run (device peak), "
        f"{rec['host_syncs_per_step']:.3f} host syncs per step, worst rel. L2 vs CPU {worst:.1e} "
        f"(limit {LIMITS[dtype]:g}) {'ok' if rec['passed'] else 'FAILED'}{speed}"
        + (f", {len(errs)} failed runs: {errs[0]}" if errs else ""))
    return rec


#: End time of a configuration's probe (s): 0.5 ms of the drop test's ~12 ms, about 4 % of its steps.
PROBE_END_S = 5e-4


def _probe(be, models, b: int, dtype: str, graph: bool, device: str) -> tuple[float, float, int]:
    """A short run of one configuration (the same batch to ``PROBE_END_S``), its results not
    checked: (wall time of the whole call s, of its time loop s (``batch_wall_time``: the steps,
    the graph's warm-up and capture), steps of the loop)."""
    from dataclasses import replace

    batch = [replace(models[i % 2], end_time=PROBE_END_S) for i in range(b)]
    t0 = time.perf_counter()
    res = be.run_batch(batch, device=device, dtype=dtype, raise_errors=False, sync_free=True, cuda_graph=graph)
    total = time.perf_counter() - t0
    info = next((r.info for r in res if not isinstance(r, Exception)), {})
    return total, float(info.get("batch_wall_time", total)), int(info.get("batch_steps", 0))


def _estimate(total_s: float, loop_s: float, probe_steps: int, steps: int) -> float:
    """Seconds the whole configuration will take from its probe: the probe's set-up and results
    (``total_s - loop_s``) once, its time loop scaled by the steps (the graph's capture scaled
    too, so the estimate errs long); infinite when the probe took no step. A batch on a GPU costs
    far less per run than one run (a B = 64 graph on an H200 took 2.5 times one run's time, not
    64 times), and the set-up of a batch of 256 takes seconds: only a run of the configuration
    itself, split so, says what it costs."""
    if probe_steps <= 0:
        return float("inf")
    return max(total_s - loop_s, 0.0) + loop_s * steps / probe_steps


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for gpu_check.json and gpu_check.txt")
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 256], help="batch sizes (default 64 256)")
    ap.add_argument("--budget", type=float, default=420.0,
                    help="seconds, s: no configuration starts that would, by the cost measured so far, end "
                         "after this (default 420)")
    ap.add_argument("--device", default="cuda", help="CUDA device (default 'cuda'; 'cpu' for a dry run of the "
                    "script itself)")
    ap.add_argument("--element-size", type=float, default=0.001, help="hexahedron edge, m (default 0.001)")
    args = ap.parse_args(argv)
    if any(b < 1 for b in args.sizes):
        ap.error(f"--sizes {' '.join(map(str, args.sizes))}: every batch size must be at least 1 run")
    if not args.budget > 0:
        ap.error(f"--budget {args.budget:g}: give the seconds the check may take, more than 0 (default 420)")
    import torch

    if args.device.startswith("cuda") and not torch.cuda.is_available():
        built = getattr(torch.version, "cuda", None)
        print(f"gpu_check: no CUDA device is usable here (torch.cuda.is_available() = False, torch "
              f"{torch.__version__} built {'with CUDA ' + built if built else 'without CUDA'}); this check needs "
              f"an NVIDIA GPU. Nothing was run.", file=sys.stderr)
        return 2
    from . import TorchExplicitBackend

    start = time.perf_counter()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = []

    def say(text: str) -> None:
        print(text, flush=True)
        lines.append(text)

    be = TorchExplicitBackend()
    models = _models(args.element_size)
    ne = models[0].n_elements
    cuda = args.device.startswith("cuda")
    name = torch.cuda.get_device_name(args.device) if cuda else "CPU (dry run)"
    say(f"gpu_check: {name}, torch {torch.__version__}; 8 mm drop test, "
        f"{ne} hexahedra (quarter model)")
    refs = []
    steps = 0
    for m in models:
        r = be.run(m, device="cpu", dtype="float64")
        steps = max(steps, r.steps)
        refs.append(_filtered(r, m))
        say(f"  CPU float64 reference (k2 = {m.material.values['k2']:g}): {r.steps} steps, {r.wall_time:.1f} s")
    records = []
    # the single run in float64 first, the batches next, the single float32 run (the least news) last
    configs = ([(1, "float64")] + [(b, dt) for b in args.sizes for dt in ("float64", "float32")]
               + [(1, "float32")])
    modes = (True, False) if cuda else (False,)      # the captured CUDA graph, then the eager sync-free step
    for b, dtype in configs:
        for graph in modes:
            elapsed = time.perf_counter() - start
            label = f"B = {b:4d} {dtype} {'graph' if graph else 'eager'}"
            if elapsed >= args.budget:
                say(f"  {label}: skipped ({elapsed:.0f} s elapsed >= budget {args.budget:g} s)")
                records.append({"batch": b, "dtype": dtype, "cuda_graph": graph, "skipped": True})
                continue
            try:
                probe_s, loop_s, probe_steps = _probe(be, models, b, dtype, graph, args.device)
            except Exception:  # the full run would fail alike: it reports the error
                probe_s, loop_s, probe_steps = 0.0, 0.0, 1
            guess = _estimate(probe_s, loop_s, probe_steps, steps)
            elapsed = time.perf_counter() - start
            if elapsed + guess > args.budget:
                say(f"  {label}: skipped ({elapsed:.0f} s elapsed + about {guess:.0f} s estimated by a "
                    f"{1e3 * PROBE_END_S:g} ms probe of {probe_s:.1f} s > budget {args.budget:g} s)")
                records.append({"batch": b, "dtype": dtype, "cuda_graph": graph, "skipped": True,
                                "estimate_s": guess})
                continue
            records.append({**_check(be, models, refs, b, dtype, graph, args.device, ne, say, records),
                            "estimate_s": guess})
    say(f"gpu_check took {time.perf_counter() - start:.0f} s")
    ran = [r for r in records if not r.get("skipped")]
    if not ran:
        say(f"gpu_check: no configuration ran within the budget of {args.budget:g} s: nothing was checked "
            f"(give a larger --budget)")
    (out / "gpu_check.json").write_text(json.dumps({"device": name,
                                                    "elements": ne, "records": records}, indent=2))
    (out / "gpu_check.txt").write_text("\n".join(lines) + "\n")
    return 0 if ran and all(r.get("passed", False) for r in ran) else 1


if __name__ == "__main__":
    sys.exit(main())
