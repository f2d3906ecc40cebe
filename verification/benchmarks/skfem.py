"""Measured figures of the skfem backend (printed, not asserted): ``python -m cfm_verification.benchmarks.skfem``.

Sections (default: all; pick some with ``--only newton,point,...``):

- newton:     residual sequences of Newton steps and their convergence orders (-)
- point:      material-point driver against the numpy reference (relative error, -)
- single:     single-element reaction force against cfm_core.simulation.point.uniaxial (relative error)
- relaxation: relaxation scene against the uniaxial driver with hold (relative error)
- speed:      numba and skfem on the same drop tests in one process (8 mm; 1 mm elements, 5000
              hexahedra, and the coarse 2 mm mesh): per Newton iteration the material + element
              time, assembly, factorisation (or preconditioner set-up), solve (ms); steps, Newton
              iterations per step, the skfem / numba solver-time ratio, peak and rel. L2 vs numba,
              energy-balance error and numerical dissipation
- tolerance:  drop test (small mesh): error against the step-error tolerance error_tol (steps,
              peak and rel. L2 against numba), with dt_max 1 ms and with the default dt_max
- penalty:    drop test (small mesh): filtered peak, penetration and Newton iterations against the
              contact stiffness, augmented Lagrangian and plain penalty
- dt:         drop test (small mesh): wall time against accuracy for several dt_max (vs numba)
- drop:       drop test at the numba backend's mesh (quarter, 1 mm elements) for 5 mm and 8 mm:
              filtered peak difference and relative L2 of the filtered history (CFC 600, 50 kHz)

``--renumber`` (alone): the node numbering and the Newton system at 1 mm and 0.5 mm elements
(bandwidth, profile, fill of the direct factorisations, block-Jacobi CG iterations and time,
mat-vec time for the mesh's numbering, RCM, Morton and a random one; :mod:`.skfem_renumber`).

Times are wall-clock seconds on this machine; accelerations in g (9.80665 m/s^2).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

SECTIONS = ("newton", "point", "single", "relaxation", "speed", "tolerance", "penalty", "dt", "drop")
SMALL = dict(width=0.02, element_size=0.002, thickness=0.008)  # 10 x 10 mm quarter, 2 mm elements


def _backend(name="skfem"):
    from cfm_core.simulation.registry import get_backend

    return get_backend(name)


def orders(res, floor=1e-7):
    """Convergence orders log(r_k+1/r_k) / log(r_k/r_k-1) of a residual sequence (-).

    Only while r_k+1 stays above ``floor`` x r_0 (below that, round-off decides).
    """
    r = np.asarray(res, dtype=float)
    r = r[r > floor * r[0]]
    return [math.log(r[k + 1] / r[k]) / math.log(r[k] / r[k - 1]) for k in range(1, r.size - 1)
            if r[k] != r[k - 1]]


def newton():
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    print("== Newton convergence (residual norms in N; order p: r_k+1 ~ r_k^p) ==")
    m = build_model(builtin_scene("single-element").with_overrides(stretch=0.5, rate=100.0))
    r = _backend().run(m, quasi_static=True, record_newton=True, dt=5e-4, dt_max=5e-4, segment_steps=1)
    for t, dt, res in r.info["newton"][:3]:
        print(f"single element, quasi-static, step to t = {t:.4g} s (dt = {dt:.1e} s): "
              + ", ".join(f"{x:.2e}" for x in res) + "  orders " + ", ".join(f"{p:.2f}" for p in orders(res)))
    m = build_model(builtin_scene("drop-test").with_overrides(end_time=0.004, **SMALL))
    r = _backend().run(m, record_newton=True)
    longest = sorted(r.info["newton"], key=lambda row: -len(row[2]))[:3]
    for t, dt, res in longest:
        print(f"drop test (small mesh), step to t = {t:.4g} s (dt = {dt:.1e} s): "
              + ", ".join(f"{x:.2e}" for x in res) + "  orders " + ", ".join(f"{p:.2f}" for p in orders(res)))


def point():
    from cfm_core.material import reference as ref
    from cfm_core.material.kinematics import to_voigt
    from cfm_core.material.registry import make_material

    print("== material point: skfem point() against cfm_core.material.reference.stress_history ==")
    mat = make_material("cfm")
    t = np.linspace(0.0, 0.02, 201)
    lam = 1.0 - 20.0 * t
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = lam
    F[:, 1, 1] = F[:, 2, 2] = lam ** -0.5
    F[:, 0, 1] = 0.1 * t / t[-1]
    s = _backend().point(mat, t, F)
    r = to_voigt(ref.stress_history(mat, t, F))
    print(f"max |sigma - sigma_ref| / max |sigma_ref| = {np.abs(s - r).max() / np.abs(r).max():.2e}")


def single():
    from cfm_core.scene.builder import build_model
    from cfm_core.simulation.point import uniaxial
    from cfm_core.scene.scene import builtin_scene

    print("== single element (free lateral faces) against the uniaxial material-point driver ==")
    sc = builtin_scene("single-element")
    m = build_model(sc)
    el = sc.element
    n = round(el.load_time / m.output_interval)
    tu, _, P, _ = uniaxial(m.material, el.rate, el.stretch, steps=n)
    ref = P * el.size ** 2
    for qs in (True, False):
        start = time.perf_counter()
        r = _backend().run(m, quasi_static=qs)
        err = np.abs(np.interp(tu, r.t, r.reaction_force) - ref).max() / np.abs(ref).max()
        print(f"{'quasi-static' if qs else 'dynamic     '}: {r.steps} steps, max rel. error of the "
              f"reaction force {err:.2e}, wall {time.perf_counter() - start:.2f} s")


def relaxation():
    from cfm_core.scene.builder import build_model
    from cfm_core.simulation.point import uniaxial
    from cfm_core.scene.scene import builtin_scene

    print("== relaxation scene (compress to 0.7 in 1 ms, hold 30 s) against the uniaxial driver ==")
    sc = builtin_scene("relaxation").with_overrides(output_rate=10.0)
    m = build_model(sc)
    rx = sc.relaxation
    for steps in (50, 200):
        start = time.perf_counter()
        r = _backend().run(m, segment_steps=steps)
        wall = time.perf_counter() - start
        tu, _, P, _ = uniaxial(m.material, abs(rx.stretch - 1) / rx.load_time, rx.stretch, steps=steps, hold=rx.hold)
        ref = P * rx.size ** 2
        common = [rx.load_time, rx.load_time + rx.hold]
        errs = [abs(np.interp(tc, r.t, r.reaction_force) - np.interp(tc, tu, ref)) / np.abs(ref).max() for tc in common]
        load = r.t <= rx.load_time * (1 + 1e-9)
        err_load = np.abs(r.reaction_force[load] - np.interp(r.t[load], tu, ref)).max() / np.abs(ref).max()
        print(f"{steps} load steps: {r.steps} steps, wall {wall:.2f} s; rel. error at end of load "
              f"{errs[0]:.1e}, at end of hold {errs[1]:.1e}, over the load {err_load:.1e}; "
              f"force relaxed to {r.reaction_force[-1] / r.reaction_force[load][-1]:.4f} of its peak")


def _drop(backend, options=None, **geometry):
    from cfm_core import post as postprocess
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    m = build_model(builtin_scene("drop-test").with_overrides(**geometry))
    start = time.perf_counter()
    r = _backend(backend).run(m, **(options or {}))
    wall = time.perf_counter() - start
    t, a_raw, a = postprocess.acceleration_histories(r, m.mass_full)
    return r, t, a, wall, postprocess.drop_test_metrics(t, a, a_raw)


def _compare(t, a, t0, a0):
    from cfm_core.post import compare_histories

    c = compare_histories(t, a, t0, a0)
    return (a.max() - a0.max()) / a0.max(), c["rel_l2"]


def penalty():
    print("== contact stiffness (small mesh, 8 mm): filtered peak, penetration, Newton iterations per step ==")
    from cfm_core.errors import NumericalError

    for mode in ("augmented", "penalty"):
        for f in (1e1, 3e1, 1e2, 1e3, 1e4):
            try:
                r, t, a, wall, met = _drop("skfem", {"penalty_factor": f, "contact": mode}, **SMALL)
            except NumericalError as exc:
                print(f"{mode} penalty_factor {f:.0e}: failed: {exc}")
                continue
            print(f"{mode:9s} penalty_factor {f:.0e} (k = {r.info['penalty']:.3g} N/m): peak {met['peak_g']:.3f} g, "
                  f"max penetration / h = {r.info['penetration_ratio']:.1e}, "
                  f"{r.info['newton_iterations'] / r.steps:.2f} Newton iterations per step, wall {wall:.1f} s")


def speed(cases=(("8 mm, 1 mm elements (5000 hexahedra)", dict(thickness=0.008)),
                 ("8 mm, 2 mm elements (676 hexahedra)", dict(thickness=0.008, element_size=0.002)))):
    print("== speed: numba and skfem on the same drop tests, one process (solver times, s) ==")
    for label, geo in cases:
        _drop("numba", **geo)  # compiles or loads numba's kernels outside the timing
        rn, tn, an, _, metn = _drop("numba", **geo)
        _drop("skfem", None, end_time=1e-4, **geo)  # compiles or loads skfem's kernels
        r, t, a, _, met = _drop("skfem", **geo)
        pk, l2 = _compare(t, a, tn, an)
        it = r.info["newton_iterations"]
        tm, cnt = r.info["times"], r.info["counts"]
        per = {k: 1e3 * v / max(cnt["evaluations"] if k in ("element", "assembly") else cnt["solves"], 1)
               for k, v in tm.items()}
        print(f"{label}: {r.info['dofs']} dofs, linear solver {r.info['linear_solver']}")
        print(f"  numba: {rn.steps} steps, solver {rn.wall_time:.2f} s, peak {metn['peak_g']:.2f} g")
        print(f"  skfem: {r.steps} steps, {it} Newton iterations ({it / r.steps:.2f} per step), "
              f"{r.info['rejected_steps']} failed / {r.info['error_rejections']} error-rejected steps, "
              f"{r.info['linear_iterations']} CG iterations, solver {r.wall_time:.1f} s "
              f"(set-up {r.info['setup_time']:.1f} s), peak {met['peak_g']:.2f} g")
        print(f"  skfem per evaluation / solve (ms): material + element {per['element']:.1f}, assembly "
              f"{per['assembly']:.1f}, factorisation {per['factorization']:.1f}, solve {per['solve']:.1f}; "
              f"totals (s): " + ", ".join(f"{k} {v:.1f}" for k, v in tm.items()))
        diss = r.energies["numerical_dissipation"][-1] / r.energies["kinetic"][0]
        print(f"  skfem / numba solver time: {r.wall_time / rn.wall_time:.1f}; peak {pk:+.2%}, rel L2 {l2:.2%}; "
              f"energy-balance error {r.energy_error():.1e}, numerical dissipation {diss:.2%} of the initial "
              f"kinetic energy")


def tolerance():
    print("== step-error tolerance (small mesh, 8 mm): error against error_tol, vs numba ==")
    _, tn, an, walln, metn = _drop("numba", **SMALL)
    for cap in (1e-3, None):
        label = "dt_max 1 ms (the estimate alone)" if cap else "default dt_max (2.5 output intervals)"
        for tol in (1e-2, 3e-3, 1e-3, 3e-4):
            opts = {"error_tol": tol, **({"dt_max": cap} if cap else {})}
            r, t, a, wall, met = _drop("skfem", opts, **SMALL)
            pk, l2 = _compare(t, a, tn, an)
            print(f"{label}: error_tol {tol:.0e}: {r.steps} steps (dt {r.dt_min * 1e6:.1f}-{r.dt_max * 1e6:.0f} us), "
                  f"{r.info['newton_iterations'] / r.steps:.2f} Newton iterations per step, solver {r.wall_time:.1f} s; "
                  f"vs numba: peak {pk:+.2%}, rel L2 {l2:.2%}")


def dt():
    print("== wall time against accuracy (small mesh, 8 mm) ==")
    try:
        _, tn, an, walln, metn = _drop("numba", **SMALL)
        print(f"numba reference: peak {metn['peak_g']:.3f} g, wall {walln:.2f} s")
    except Exception as exc:  # noqa: BLE001 - a missing backend is reported, not fatal
        tn = None
        print(f"numba not available ({exc}); comparing with the finest skfem run")
    runs = []
    for d in (1e-5, 2e-5, 5e-5, 1e-4, 2e-4):
        r, t, a, wall, met = _drop("skfem", {"dt_max": d}, **SMALL)
        runs.append((d, t, a, wall, met, r))
    ref = (tn, an) if tn is not None else (runs[0][1], runs[0][2])
    for d, t, a, wall, met, r in runs:
        pk, l2 = _compare(t, a, *ref)
        print(f"dt_max {d:.0e} s: {r.steps} steps, {r.info['newton_iterations']} Newton iterations, "
              f"wall {wall:.1f} s, peak {met['peak_g']:.3f} g, peak diff {pk:+.2%}, rel L2 {l2:.2%}, "
              f"energy error {r.energy_error():.1e}")


def drop(thicknesses=(0.005, 0.008)):
    print("== drop test, quarter model, 1 mm elements (the numba backend's mesh), CFC 600 ==")
    for h in thicknesses:
        r, t, a, wall, met = _drop("skfem", thickness=h)
        print(f"skfem {h * 1e3:.0f} mm: peak {met['peak_g']:.2f} g, t_peak {met['t_peak'] * 1e3:.2f} ms, "
              f"{r.steps} steps, {r.info['newton_iterations']} Newton iterations, wall {wall:.0f} s, "
              f"penetration/h {r.info['penetration_ratio']:.1e}, energy error {r.energy_error():.1e}")
        try:
            rn, tn, an, walln, metn = _drop("numba", thickness=h)
        except Exception as exc:  # noqa: BLE001
            print(f"numba not available ({exc})")
            continue
        pk, l2 = _compare(t, a, tn, an)
        print(f"numba {h * 1e3:.0f} mm: peak {metn['peak_g']:.2f} g, wall {walln:.1f} s -> skfem - numba: "
              f"peak {pk:+.2%}, rel L2 of the filtered history {l2:.2%}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated sections of {SECTIONS}")
    p.add_argument("--thickness", type=float, action="append",
                   help="drop section: specimen thickness in m (repeatable; default 0.005 and 0.008)")
    p.add_argument("--renumber", action="store_true", help="only the node numberings' Newton systems "
                   "(bandwidth, fill, CG; see cfm_verification.benchmarks.skfem_renumber)")
    p.add_argument("--renumber-sizes", default="0.001,0.0005", help="--renumber: element sizes (m)")
    p.add_argument("--repeat", type=int, default=5, help="--renumber: timed solves per numbering (best kept)")
    args = p.parse_args(argv)
    if args.renumber:
        from . import skfem_renumber

        skfem_renumber.run(tuple(float(x) for x in args.renumber_sizes.split(",")), repeat=args.repeat)
        return
    chosen = [s.strip() for s in args.only.split(",") if s.strip()]
    for s in chosen:
        if s not in SECTIONS:
            p.error(f"unknown section {s!r}; choose from {', '.join(SECTIONS)}")
    for s in chosen:
        start = time.perf_counter()
        if s == "drop" and args.thickness:
            drop(tuple(args.thickness))
        else:
            globals()[s]()
        print(f"   ({s}: {time.perf_counter() - start:.0f} s)\n", flush=True)


if __name__ == "__main__":
    main()
