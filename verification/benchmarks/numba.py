"""Benchmark of the numba backend on the paper's drop test (8 mm, 1 mm hexahedra, quarter model).

    python -m cfm_verification.benchmarks.numba [--thickness 0.008] [--size 0.001] [--no-cold]
    python -m cfm_verification.benchmarks.numba --scale    (cost against mesh size and threads: .scale)
    python -m cfm_verification.benchmarks.numba --parts    (only the layered row)
    python -m cfm_verification.benchmarks.numba --vector-width   (256- against 512-bit vectors: .vector_width)
    python -m cfm_verification.benchmarks.numba --against REV    (element pass against git revision REV: .against)

Prints the cold time (a fresh process with an empty kernel cache: code generation, compilation,
run), a warm ``cfm drop-test`` end to end in fresh processes with its phases next to the 2 s target
(:mod:`.startup`), the warm time (same process, kernels compiled), steps and elements, nanoseconds per
element-cycle (solver wall time / (elements x steps)) with 1 and 2 threads and the speed-up,
and the number of steps taken against the number the tissue's own stable step at rest allows
(the kinematic contact does not shorten the step; the tissue stiffening under compression does),
and the cost per element-cycle of a layered (3-part) specimen against the one-material one.
Timings on a loaded machine are meaningless: check that the cores are idle first.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

from . import startup


def _block() -> int:
    from cfm_backends.numba_explicit.kernels import layout as K

    return K.BLOCK


def drop_test(thickness: float, size: float):
    """The built-in drop-test scene with the given thickness and element size (m)."""
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    return build_model(builtin_scene("drop-test").with_overrides(thickness=thickness, element_size=size))


def _timed_run(model, **options):
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    start = time.perf_counter()
    res = NumbaExplicitBackend().run(model, **options)
    return time.perf_counter() - start, res


def cold(thickness: float, size: float) -> dict:
    """Run once in a fresh interpreter with an empty kernel cache; timings as a dict."""
    code = ("import json, time; t0 = time.perf_counter(); "
            "from cfm_verification.benchmarks.numba import drop_test, _timed_run; "
            f"m = drop_test({thickness!r}, {size!r}); total, r = _timed_run(m); "
            "print(json.dumps({'total': time.perf_counter() - t0, 'run': total, "
            "'compile': r.info['compile_time'], 'wall': r.wall_time, 'steps': r.steps}))")
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "CFM_CACHE_DIR": cache}
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def split(model, t_state: float = 0.006, repeat: int = 20) -> dict:
    """CPU time per element-cycle (ns, one thread) of the step's parts at the state of t_state (s).

    Runs the compiled loop to t_state (the impactor near its deepest point), then times with
    ``time.process_time`` (CPU time of this process: much less disturbed by other processes than
    wall time) the whole step (``advance`` over a few steps), the parallel parts on their own
    (element pass, gather and update, energies) and each stage of the element blocks alone
    (:data:`STAGES`); the rest of a step is the serial part (contact, step minimum, history row,
    chunk loop).
    """
    import numpy as np

    from cfm_backends.numba_explicit import solver
    from cfm_backends.numba_explicit.kernels import layout as K

    from .scale import element_pass_args, one_thread_run

    with one_thread_run(model, t_state, rows=64) as (mod, prep, _hist):
        ne = model.n_elements
        conn, slot, chunks, mass, free, pmask, hptr, hrow = prep.geo
        p = prep.mat[0]
        x, v, vold, ed, eh, fb, fint, fhg, dvc, bdt, bemin, status, errv = prep.st

        def cpu(fn, n=repeat):
            best = math.inf
            for _ in range(3):
                t0 = time.process_time()
                for _ in range(n):
                    fn()
                best = min(best, (time.process_time() - t0) / n)
            return best / ne * 1e9

        steps0 = prep.sc[K.S_STEPS]
        t0 = time.process_time()
        solver.advance(mod, prep, np.zeros((repeat, K.H_N)), math.inf)
        step = (time.process_time() - t0) / max(prep.sc[K.S_STEPS] - steps0, 1) / ne * 1e9
        xs, vs = x.copy(), v.copy()
        # repeated passes at one state: the Prony and previous-step state they update stay finite
        args = element_pass_args(mod, prep, xs, vs, ed, eh, fb)
        decay, gain = args[9], args[10]
        element = cpu(lambda: mod.element_pass(*args))
        gather = cpu(lambda: mod.gather_update(fb, hptr, hrow, mass, free, fint, fhg, xs, vs, vold, 1e-9, 1e-9))
        energy = cpu(lambda: mod.energy_pass(mass, v, vold, fint, fhg, dvc, pmask, 1e-9))
        out = {"step": step, "element_pass": element, "gather_update": gather, "energy": energy,
               "serial_rest": step - element - gather - energy}
        out.update(_stages(mod, x, v, conn, slot, ed.copy(), eh.copy(), fb.copy(), p, decay, gain,
                           prep.par[K.P_GINF], prep.par[K.P_RHO], prep.par[K.P_HG], cpu))
        return out


STAGES = ("kinematics", "eigen", "eigen_fallback", "material", "stress", "prony", "forces", "corners_scatter")


def _stages(mod, x, v, conn, slot, ed, eh, fb, p, decay, gain, ginf, rho, hg, cpu) -> dict:
    """CPU time per element (ns) of each stage of the element blocks (kernels/element.py), each
    stage run over all blocks by a small compiled driver (compiled here, ~10 s)."""
    import numpy as np
    from numba import njit

    from cfm_backends.numba_explicit.kernels import layout as K

    fns = (mod.kinematics_block, mod.eigen_block, mod.eigen_fallback, mod.material_block, mod.stress_block,
           mod.prony_block, mod.forces_block, mod.corner_forces, mod.scatter_corner)
    kin, eig, fbk, mat, st, pr, fo, cor, sca = fns
    B, EDN, WN = K.BLOCK, K.ED_N, K.W_N

    @njit
    def drive(stage, x, v, conn, slot, ed, eh, fb, wk, p, decay, gain, ginf, rho, hg):
        ne = conn.shape[0]
        k6 = 6 * decay.shape[0] * B
        for b in range((ne + B - 1) // B):
            e0 = b * B
            n = min(B, ne - e0)
            w = wk[b * WN * B:(b + 1) * WN * B]
            edb = ed[b * EDN * B:(b + 1) * EDN * B]
            if stage == 0:
                kin(w, edb, x, v, conn, e0, n)
            elif stage == 1:
                eig(w, n)
            elif stage == 2:
                fbk(w, n)
            elif stage == 3:
                mat(w, p, n)
            elif stage == 4:
                st(w, n)
            elif stage == 5:
                pr(w, edb, eh[b * k6:(b + 1) * k6], decay, gain, ginf, n)
            elif stage == 6:
                fo(w, edb, rho, hg, 0, n)
            else:
                for a in range(8):
                    cor(w, edb, a, n)
                    sca(w, fb, slot, e0, a, n)

    nblk = -(-conn.shape[0] // B)
    wk = np.zeros(nblk * WN * B)
    out = {}
    for i, name in enumerate(STAGES):  # in order: each stage reads what the previous ones wrote
        args = (i, x, v, conn, slot, ed, eh, fb, wk, p, decay, gain, ginf, rho, hg)
        drive(*args)
        out[name] = cpu(lambda: drive(*args))
    return out


def layered(model):
    """The model in three layers of equal element count from the plate up (by element centroid z),
    each the same material (CFM) with its own parameters and density (kappa x 1.2, 1, 0.8;
    density x 1.05, 1, 0.95): the parts layout of a layered specimen at the cost of one material."""
    import dataclasses

    import numpy as np

    from cfm_core.scene.model import Part

    zc = np.round(model.nodes[model.hexes][:, :, 2].mean(axis=1), 9)
    levels = np.array_split(np.unique(zc), 3)
    mat = model.material
    parts = tuple(Part(f"layer{i}", mat.with_values(kappa=mat.values["kappa"] * f), model.density * d,
                       np.flatnonzero((zc >= lv[0]) & (zc <= lv[-1])).astype(np.int64))
                  for i, (lv, f, d) in enumerate(zip(levels, (1.2, 1.0, 0.8), (1.05, 1.0, 0.95))))
    return dataclasses.replace(model, parts=parts)


def parts_cost(model, repeat: int = 3, threads: int = 1) -> dict:
    """Best solver ns per element-cycle of the one-material model and of :func:`layered` (same
    process, runs interleaved so that both see the same machine load) and their ratio."""
    three = layered(model)
    _timed_run(model, threads=threads)
    _timed_run(three, threads=threads)  # compile or load both in this process
    one_ns, three_ns = [], []
    for _ in range(repeat):
        one_ns.append(_timed_run(model, threads=threads)[1].info["ns_per_element_cycle"])
        three_ns.append(_timed_run(three, threads=threads)[1].info["ns_per_element_cycle"])
    return {"one": min(one_ns), "layered": min(three_ns), "ratio": min(three_ns) / min(one_ns)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--thickness", type=float, default=8e-3, help="specimen thickness (m)")
    ap.add_argument("--size", type=float, default=1e-3, help="element size (m)")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold (fresh cache) run")
    ap.add_argument("--repeat", type=int, default=None, help="warm runs per thread count (best is kept; "
                    "default 2; --scale's per-size rows take one round more, the sizes in turns), or --against's "
                    "rounds (default 15)")
    ap.add_argument("--no-end-to-end", action="store_true", help="skip the warm cfm drop-test phases")
    ap.add_argument("--scale", action="store_true", help="only the cost against mesh size, threads and a busy "
                    "core (module scale)")
    ap.add_argument("--scale-sizes", default="0.001,0.0005,0.00033", help="element sizes of --scale (m)")
    ap.add_argument("--block", type=int, default=100, help="--scale: edge of the synthetic block in elements "
                    "(100: 10^6 hexahedra; 0 skips it)")
    ap.add_argument("--no-torch", action="store_true", help="--scale: skip torch's ratio to numba")
    ap.add_argument("--no-threads", action="store_true", help="--scale: skip 2 threads against 1")
    ap.add_argument("--no-busy", action="store_true", help="--scale: skip the busy-core row")
    ap.add_argument("--parts", action="store_true", help="only the layered (3-part) row against one material")
    ap.add_argument("--vector-width", action="store_true", help="only the element pass at 256- and 512-bit "
                    "vectors (module vector_width; --size, --repeat)")
    ap.add_argument("--against", metavar="REV", help="only the element pass of this tree's kernels against those "
                    "of git revision REV, both in this process, timed in turns (module against; --size, --repeat "
                    "rounds, default 15)")
    args = ap.parse_args(argv)
    if args.repeat is None:
        args.repeat = 15 if args.against else 2
    if args.against:
        from . import against

        from cfm_core.errors import InputError

        try:
            against.report(args.against, args.size, max(args.repeat, 1))
        except InputError as err:
            ap.exit(2, f"error: {err}\n")
        return
    if args.vector_width:
        from . import vector_width

        vector_width.report(args.size, args.repeat)
        return
    if args.scale:
        from . import scale

        scale.report([float(s) for s in args.scale_sizes.split(",")], args.block, max(args.repeat, 1),
                     not args.no_torch, not args.no_threads, not args.no_busy)
        return

    model = drop_test(args.thickness, args.size)
    ne = model.n_elements
    print(f"drop test: thickness {args.thickness * 1e3:g} mm, element {args.size * 1e3:g} mm, "
          f"{ne} hexahedra, {model.n_nodes} nodes, symmetry factor {model.symmetry_factor:g}")
    if args.parts:
        _print_parts(model, args.repeat)
        return
    if not args.no_cold:
        c = cold(args.thickness, args.size)
        print(f"cold (fresh process, empty cache): {c['total']:.2f} s in all, run() {c['run']:.2f} s "
              f"of which code generation + compilation {c['compile']:.2f} s, solver {c['wall']:.2f} s")
    if not args.no_end_to_end:
        print(startup.report(startup.measure(args.thickness, args.size, max(args.repeat, 1))), flush=True)
    sp = split(model)
    print(f"CPU time per element-cycle, one thread, at t = 6 ms: step {sp['step']:.0f} ns = element pass "
          f"{sp['element_pass']:.0f} + gather and update {sp['gather_update']:.0f} + energies {sp['energy']:.0f} + "
          f"serial rest (contact, step minimum, record, chunk loop) {sp['serial_rest']:.0f} ns; element pass by "
          f"stage (each alone, blocks of {_block()} elements): "
          + ", ".join(f"{name.replace('_', ' ')} {sp[name]:.0f}" for name in STAGES) + " ns", flush=True)
    _timed_run(model, threads=1)  # compile or load the kernels in this process
    best = {}
    for threads in (1, 2):
        runs = [_timed_run(model, threads=threads) for _ in range(args.repeat)]
        best[threads] = min(runs, key=lambda tr: tr[1].wall_time)
    total, res = best[2]
    print(f"warm run() with 2 threads: {total:.2f} s (solver {res.wall_time:.2f} s, kernels loaded "
          f"{res.info['compile_time']:.2f} s); {res.steps} steps, stop: {res.info['stop_reason']} at "
          f"t = {res.t[-1] * 1e3:.2f} ms")
    for threads, (total, r) in best.items():
        print(f"  {threads} thread(s): solver {r.wall_time:.3f} s, "
              f"{r.info['ns_per_element_cycle']:.0f} ns per element-cycle")
    print(f"  speed-up 2 threads / 1 thread: {best[1][1].wall_time / best[2][1].wall_time:.2f}")
    print(f"steps: {res.steps} taken (dt {res.dt_min:.3g} .. {res.dt_max:.3g} s); the tissue's stable "
          f"step at rest ({res.info['dt_first']:.3g} s) would allow {res.info['steps_at_first_dt']}")
    print(f"peak acceleration {res.acceleration.max() / 9.81:.1f} g, energy error "
          f"{res.energy_error():.2e}, hourglass / internal {res.hourglass_ratio():.2e}")
    _print_parts(model, args.repeat)


def _print_parts(model, repeat: int) -> None:
    pc = parts_cost(model, max(repeat, 1))
    print(f"layered (3 parts, CFM with per-part kappa and density) against one material, one thread: "
          f"{pc['layered']:.0f} against {pc['one']:.0f} ns per element-cycle, ratio {pc['ratio']:.3f} "
          f"(target <= 1.15)")


if __name__ == "__main__":
    main()
