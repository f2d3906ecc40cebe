"""Cost per element-cycle of the numba backend against mesh size, threads, and a busy core.

    python -m cfm_verification.benchmarks.numba --scale [--scale-sizes 0.001,0.0005,0.00033]
        [--block 100] [--repeat 3] [--no-torch] [--no-threads] [--no-busy]

One process, one machine; the load average is printed with every row (timings on a loaded
machine are not meaningful: compare rows of one run, not runs of different days).

1. ns per element-cycle, one thread: the built-in drop test (quarter, 8 mm) at each element
   size, run to t = 0.8 ms (set-up, compilation and the start of the impact drop out), then
   ``segments`` stretches of steps timed with the process's CPU time (much less disturbed by
   other processes than wall time), the best kept; and a synthetic block of ``block``^3
   hexahedra (1 000 000 for 100) under a homogeneous finite strain with a velocity field (every
   element deformed, so every element takes the vectorised eigen path), a few steps. Then the
   largest / smallest ratio and the solver's memory per element (float64; every array of the
   run, nodes included, divided by the elements). Each round's rows are printed too, with the
   machine's memory copy rate measured at the start of that round (:func:`copy_rate`): the
   larger meshes stream their element state from memory, so a round in which another tenant of
   a shared host holds the memory bandwidth is slower at 40 000 elements and up and not at
   5 000, and the copy rate says so.
2. torch (eager float64, one thread) / numba at each drop-test size, both run end to end for
   the same short end time (few steps: torch eager is slow), wall time per element-cycle, the
   run monitor's periodic scans left out on both sides (:func:`without_periodic_checks`).
3. Threads at the largest drop-test size: 2 threads against 1 (wall time, alternating, best of
   ``repeat``); then with one core kept busy by a second process this benchmark starts (a
   bounded busy loop, killed at the end), the default thread count (``threads=None``) against
   one thread and two: numba at the largest drop-test size, torch (eager float64) as a single
   run and as a batch of 4 on the 1 mm drop test to 0.4 ms.
"""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
import time

import numpy as np


def load() -> str:
    """The 1-minute load average and the core count, for a row."""
    return f"load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores"


def drop_model(size: float, end_time: float = 0.03):
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    return build_model(builtin_scene("drop-test").with_overrides(element_size=size, end_time=end_time))


def block_model(n: int):
    """A cube of n^3 hexahedra (edge 1 mm each), the CFM material, no contact."""
    from cfm_core.material.registry import make_material
    from cfm_core.scene.mesh import structured_hex_mesh
    from cfm_core.scene.model import Model

    h = 1e-3
    nodes, hexes = structured_hex_mesh(n * h, n * h, n * h, n, n, n)
    return Model(name="block", nodes=nodes, hexes=hexes, density=950.0, material=make_material("cfm"),
                 end_time=1.0, output_interval=1.0)


def memory_per_element(prep, ne: int) -> float:
    """Bytes per element of every array a run keeps (float64 state, index arrays, nodes)."""
    total = 0
    for group in (prep.geo, prep.mat, prep.st, prep.cnt, prep.presc, (prep.par, prep.ipar, prep.sc, prep.nodes)):
        total += sum(a.nbytes for a in group if isinstance(a, np.ndarray))
    return total / ne


@contextlib.contextmanager
def one_thread_run(model, t_state: float | None, deform=None, rows: int = 4096):
    """The compiled module, a prepared run of ``model`` advanced to ``t_state`` (s) and a history
    buffer of ``rows`` rows, on one numba thread (the caller's count restored afterwards).
    ``deform(prep)`` may change the prepared state before the advance."""
    import numba

    from cfm_backends.numba_explicit import codegen, solver
    from cfm_backends.numba_explicit.kernels import layout as K
    from cfm_backends.numba_explicit.options import NumbaOptions

    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        mod = codegen.load(model.material)
        solver.warm_up(mod, model.material)
        prep = solver.prepare(model, NumbaOptions())
        if deform is not None:
            deform(prep)
        hist = np.zeros((rows, K.H_N))
        if t_state:
            while prep.sc[K.S_T] < t_state:
                solver.advance(mod, prep, hist, t_state)
        yield mod, prep, hist
    finally:
        numba.set_num_threads(old)


def element_pass_args(mod, prep, x, v, ed, eh, fb) -> tuple:
    """The arguments of ``mod.element_pass`` for the first part of a prepared run (the whole mesh of
    a one-material model): positions x (m), velocities v (m/s), block state ed, eh and force
    buffer fb as given (the run's own arrays or the caller's copies), the rest the part's, with the
    Prony factors of the run's last step (computed into fresh arrays, so the run's stay as they are)."""
    from cfm_backends.numba_explicit.kernels import layout as K

    pt = prep.parts[0]
    decay, gain = np.zeros(pt[K.PT_GAM].size), np.zeros(pt[K.PT_GAM].size)
    mod.prony_step(float(prep.sc[K.S_DTPREV]), pt[K.PT_GAM], pt[K.PT_TAU], decay, gain)
    return (x, v, pt[K.PT_CONN], pt[K.PT_SLOT], pt[K.PT_CHUNKS], ed, eh, fb, pt[K.PT_P], decay, gain,
            pt[K.PT_PAR][K.PP_GINF], pt[K.PT_BDT], pt[K.PT_BEMIN], pt[K.PT_STATUS], pt[K.PT_ERRV],
            pt[K.PT_PAR][K.PP_RHO], prep.par[K.P_HG], 0)


def per_cycle(model, t_state: float | None, segments: int = 3, budget: float = 0.4, deform=None) -> dict:
    """ns per element-cycle (CPU time, one thread) of the compiled loop after t_state (s)."""
    return per_cycle_rounds([(model, t_state, deform)], rounds=1, segments=segments, budget=budget)[0]


def per_cycle_rounds(cases, rounds: int = 3, segments: int = 2, budget: float = 0.3, on_round=None) -> list[dict]:
    """ns per element-cycle (CPU time, one thread) of several models' compiled loops, measured in
    turns: every model prepared (and advanced to its t_state) first, then ``rounds`` rounds in
    which each model runs ``segments`` timed segments of about ``budget`` s; the best segment of
    each model is kept. On a shared host whose speed moves for minutes at a time (+-25 %), rows
    measured one after the other can land in different spells; in turns, each row's best comes
    from the same spells as the others'. The segments of one model add up to at most 0.7 s of CPU
    time (``budget`` shrinks with more rounds), so that a drop test measured from 0.8 ms is still
    in contact at its last segment (the 1 mm mesh: about 1 100 steps, to about 7.5 ms). Two
    untimed steps of each model set its segment length first, so that the first round's
    segments are as long as the others' (each round's best is reported too).

    Parameters
    ----------
    cases : list of (model, t_state (s) or None, deform hook or None)
        As for :func:`one_thread_run`.

    on_round : callable, optional
        Called with no argument at the start of each round (a probe of the machine, e.g.
        :func:`copy_rate`); its results are returned under ``probe``.

    Returns
    -------
    list of dict
        Per case: ``ns`` (best ns per element-cycle), ``bytes`` (per element), ``ne``,
        ``rounds`` (the best of each round, ns per element-cycle) and ``probe`` (the results of
        ``on_round`` per round; empty without it).

    Raises
    ------
    RuntimeError
        A run failed (inverted elements, non-finite state) or took no step.
    """
    from cfm_backends.numba_explicit import solver
    from cfm_backends.numba_explicit.kernels import layout as K

    budget = min(budget, 0.7 / max(rounds * segments, 1))
    with contextlib.ExitStack() as stack:
        runs = [stack.enter_context(one_thread_run(m, t, deform)) for m, t, deform in cases]
        counts = [m.n_elements for m, _, _ in cases]
        each = [[] for _ in runs]
        probe = []

        def segment(per_step: float) -> int:   # steps of about ``budget`` s of CPU time, 1 to 4000
            return int(max(1, min(4000, budget / max(per_step, 1e-9))))

        steps = []
        for mod, prep, hist in runs:   # the segment length from 2 untimed steps
            s0, c0 = prep.sc[K.S_STEPS], time.process_time()
            solver.advance(mod, prep, hist[:2], math.inf)
            steps.append(segment((time.process_time() - c0) / max(prep.sc[K.S_STEPS] - s0, 1)))
        for _ in range(rounds):
            if on_round is not None:
                probe.append(on_round())
            for i, (mod, prep, hist) in enumerate(runs):
                each[i].append(math.inf)
                ne = counts[i]
                for _ in range(segments):
                    s0 = prep.sc[K.S_STEPS]
                    c0 = time.process_time()
                    rows, code = solver.advance(mod, prep, hist[:steps[i]], math.inf)
                    dt = time.process_time() - c0
                    n = prep.sc[K.S_STEPS] - s0
                    if code >= K.R_INVERTED or n < 1:
                        raise RuntimeError(f"scale benchmark: the run failed (code {code})")
                    each[i][-1] = min(each[i][-1], dt / n / ne * 1e9)
                    steps[i] = segment(dt / n)
        return [{"ns": min(r), "bytes": memory_per_element(prep, ne), "ne": ne, "rounds": r, "probe": probe}
                for (_, prep, _), ne, r in zip(runs, counts, each)]


def copy_rate(megabytes: int = 64, repeat: int = 3) -> float:
    """The machine's memory copy rate now (GB/s, one thread): bytes read plus bytes written per
    second of ``numpy.copyto`` between two arrays of ``megabytes`` MB each (far larger than the
    caches), the best of ``repeat``. A probe of the memory bandwidth this process gets at the
    moment, for rows that stream their state from memory; not a peak figure (the write-allocate
    traffic of the destination is not counted)."""
    n = megabytes * (1 << 20) // 8
    a = np.ones(n)
    b = np.empty(n)
    np.copyto(b, a)                  # the pages touched before the timing
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        np.copyto(b, a)
        best = min(best, time.perf_counter() - t0)
    return 2 * n * 8 / best / 1e9


def prestrain(model):
    """A deform hook for :func:`per_cycle`: positions F0 X, velocities L0 X (every element deformed)."""
    F0 = np.array([[1.05, 0.03, 0.01], [-0.02, 0.97, 0.02], [0.01, 0.03, 0.98]])
    L0 = np.array([[3.0, -1.0, 2.0], [0.5, 1.0, -2.0], [1.0, 0.0, -4.0]])

    def hook(prep):
        x = prep.st[0]
        x[:] = prep.nodes @ F0.T
        prep.st[1][:] = prep.nodes @ L0.T
    return hook


@contextlib.contextmanager
def without_periodic_checks():
    """Runs inside skip the run monitor's periodic physics scans (``Monitor.due`` is False; the
    final check still runs). A run checks about 100 times whatever its length; in the few steps
    a short benchmark run takes that is nearly every step, and torch's scan (numpy) then costs
    more than its step, so a per-step ratio would measure the scans (numba's per-cycle figures,
    timed on the compiled loop alone, exclude them too)."""
    from cfm_core.simulation.checks import Monitor

    due = Monitor.due
    Monitor.due = lambda self, t: False
    try:
        yield
    finally:
        Monitor.due = due


def torch_ratio(model, end_time: float) -> tuple[float, float]:
    """(numba, torch eager float64) wall ns per element-cycle, one thread, run to ``end_time``,
    both without the periodic physics scans (:func:`without_periodic_checks`)."""
    from dataclasses import replace

    from cfm_backends.numba_explicit import NumbaExplicitBackend
    from cfm_backends.torch_explicit import TorchExplicitBackend

    m = replace(model, end_time=end_time)
    with without_periodic_checks():
        n = min(NumbaExplicitBackend().run(m, threads=1).info["ns_per_element_cycle"] for _ in range(2))
        t = TorchExplicitBackend().run(m, threads=1, dtype="float64").info["ns_per_element_cycle"]
    return n, t


def busy_core(seconds: float) -> subprocess.Popen:
    """A second process keeping one core busy for ``seconds`` (a bounded busy loop)."""
    code = f"import time\nend = time.perf_counter() + {seconds!r}\nwhile time.perf_counter() < end:\n    pass\n"
    return subprocess.Popen([sys.executable, "-c", code])


def best_of(run, threads, repeat: int) -> dict:
    """Best wall time (s) of ``run(th) -> (seconds, threads used)`` over ``repeat`` rounds of the
    thread settings ``threads`` (alternating), with the threads each setting used."""
    best: dict = {}
    used: dict = {}
    for _ in range(repeat):
        for th in threads:
            seconds, used[th] = run(th)
            best[th] = min(best.get(th, math.inf), seconds)
    return {"best": best, "used": used}


def wall(model, threads, repeat: int) -> dict:
    """Best solver wall time (s) of numba runs of ``model`` per thread setting (:func:`best_of`)."""
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    be = NumbaExplicitBackend()

    def run(th):
        r = be.run(model, threads=th)
        return r.wall_time, r.info["threads"]

    return best_of(run, threads, repeat)


def torch_wall(models, threads, repeat: int) -> dict:
    """Best wall time (s) of a torch run (one model) or batch (a list), eager float64 on the CPU,
    per thread setting (:func:`best_of`), after one untimed run (imports, allocator)."""
    from cfm_backends.torch_explicit import TorchExplicitBackend

    be = TorchExplicitBackend()

    def run(th):
        t0 = time.perf_counter()
        r = (be.run_batch(models, threads=th, dtype="float64")[0] if isinstance(models, list)
             else be.run(models, threads=th, dtype="float64"))
        return time.perf_counter() - t0, r.info["threads"]

    run(1)
    return best_of(run, threads, repeat)


def busy_verdict(w: dict) -> str:
    """The text of one busy-core row from :func:`best_of` over (None, 1, 2): the times, the ratio
    of one thread to the default and whether the target (the default never slower) is met. Where
    the default chose one thread, the two settings are the same run and their ratio only shows
    the machine's noise: met by construction, and said so."""
    b, used = w["best"], w["used"]
    ratio = b[1] / b[None]
    if used[None] == 1:
        verdict = (f"met: the default chose one thread, the same run as '1 thread' (their ratio is this machine's "
                   f"noise, {100 * abs(ratio - 1):.0f} %)")
    else:
        verdict = "met" if ratio >= 1.0 else f"not met: the default's {used[None]} threads are slower than one"
    return (f"default ({used[None]} thread{'s' if used[None] != 1 else ''}) {b[None]:.2f} s, 1 thread {b[1]:.2f} s, "
            f"2 threads {b[2]:.2f} s; 1 thread / default {ratio:.2f} (target >= 1, never slower: {verdict})")


def busy_rows(big, repeat: int, torch: bool, say=print, small=None) -> None:
    """Default thread count against 1 and 2 threads with one core kept busy by a second process:
    numba on ``big``; torch (single run and a batch of 4) on ``small`` (default: the 1 mm drop
    test to 0.4 ms)."""
    from dataclasses import replace

    proc = busy_core(3600.0)
    try:
        time.sleep(1.0)
        cases = [("numba", lambda th: wall(big, th, repeat))]
        if torch:
            small = small if small is not None else drop_model(1e-3, end_time=0.4e-3)
            batch = [replace(small) for _ in range(4)]
            short = max(repeat, 3)  # runs of under a second: more rounds against the noise
            cases += [("torch single run", lambda th: torch_wall(small, th, short)),
                      ("torch batch of 4", lambda th: torch_wall(batch, th, short))]
        for name, timed in cases:
            w = timed((None, 1, 2))
            say(f"  one core busy (second process), {name}: {busy_verdict(w)}  ({load()})")
    finally:
        proc.kill()
        proc.wait()


def ceiling(seconds: float = 1.0) -> float:
    """Speed-up of 2 threads over 1 on a compute-bound numba loop (what the machine's two cores
    give, with nothing of the solver in it): best of 3 of each, alternating."""
    import numba
    from numba import njit, prange

    @njit(parallel=True, cache=False)
    def spin(n, m):
        out = np.empty(n)
        for i in prange(n):
            x = 0.0
            for k in range(m):
                x += math.sqrt(x + i + k) * 1e-9
            out[i] = x
        return out

    old = numba.get_num_threads()
    spin(64, 10)
    m = 1000
    while True:                       # about ``seconds`` on one thread
        t0 = time.perf_counter()
        spin(64, m)
        if time.perf_counter() - t0 > 0.1:
            break
        m *= 4
    m = int(m * seconds / max(time.perf_counter() - t0, 1e-3))
    best = {1: math.inf, 2: math.inf}
    try:
        for _ in range(3):
            for th in (1, 2):
                numba.set_num_threads(min(th, numba.config.NUMBA_NUM_THREADS))
                t0 = time.perf_counter()
                spin(64, m)
                best[th] = min(best[th], time.perf_counter() - t0)
    finally:
        numba.set_num_threads(old)
    return best[1] / best[2]


def round_lines(rows: list[dict]) -> str:
    """The rows of each round of :func:`per_cycle_rounds` (ns per element-cycle, the cases in
    order) with that round's memory copy rate (:func:`copy_rate`, GB/s), one line per round."""
    out = ["  per round, ns per element-cycle in the order above, and the memory copy rate at the round's start "
           "(GB/s, one thread, read + written):"]
    for k, rate in enumerate(rows[0]["probe"]):
        ns = "  ".join(f"{r['rounds'][k]:5.0f}" for r in rows)
        out.append(f"    round {k + 1}: {ns}   copy {rate:5.1f} GB/s")
    return "\n".join(out)


def report(sizes, block: int, repeat: int, torch: bool, threads: bool, busy: bool, say=print) -> None:
    rounds = repeat + 1
    say(f"numba, one thread, CPU time per element-cycle, best of {rounds} rounds with the sizes in turns ({load()}):")
    cases = [(drop_model(h), 0.8e-3, None) for h in sizes]
    labels = [f"drop test {h * 1e3:g} mm:" for h in sizes]
    if block:
        cases.append((block_model(block), None, prestrain(None)))
        labels.append(f"block {block}^3:     ")
    rows = {}
    got = per_cycle_rounds(cases, rounds=rounds, on_round=copy_rate)
    for label, r in zip(labels, got):
        rows[r["ne"]] = r
        say(f"  {label} {r['ne']:>8} hexahedra  {r['ns']:6.0f} ns  {r['bytes']:6.0f} B/element")
    say(f"  ({load()} after the rounds)")
    say(round_lines(got))
    ns = [r["ns"] for r in rows.values()]
    say(f"  largest / smallest: {max(ns) / min(ns):.2f} (target <= 1.3); at most {max(ns):.0f} ns (target <= 150); "
        f"memory at most {max(r['bytes'] for r in rows.values()):.0f} B/element (target <= 1000)")
    if torch:
        for h in sizes:
            n, t = torch_ratio(drop_model(h), 0.2e-3)
            say(f"  torch eager float64 / numba, one thread, {h * 1e3:g} mm: {t:.0f} / {n:.0f} ns = {t / n:.2f}  ({load()})")
    big = drop_model(min(sizes), end_time=1.6e-3)
    if threads:
        w = wall(big, (1, 2), max(repeat, 3))   # 2 threads wait for the slower core at every barrier: more rounds
        b = w["best"]
        say(f"  threads, {big.n_elements} hexahedra to 1.6 ms (best of {max(repeat, 3)} alternating): 1 thread "
            f"{b[1]:.2f} s, 2 threads {b[2]:.2f} s, "
            f"speed-up {b[1] / b[2]:.2f} (target >= 1.8 on an idle 2-core machine); the machine's own 2-thread "
            f"speed-up on a compute-bound loop {ceiling():.2f}  ({load()})")
    if busy:
        busy_rows(big, repeat, torch, say)
