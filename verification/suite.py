"""The verification suite: ``cfm verify [--quick | --full] [--backends A,B] --out DIR``.

:func:`run_suite` runs every installed backend through agreement (:mod:`.agreement`), error against
run time (:mod:`.workprecision`), stability (:mod:`.stability`, :mod:`.drucker`) and the paper
comparison (:mod:`.paper_compare`), then writes DIR/report.md, DIR/report.json and PNG figures
(:mod:`.report`). The suite passes when every agreement and stability check is within its
tolerance; the CLI exits 1 otherwise.

Quick mode (CI, a few tens of seconds with numba's cached kernels): a 1 mm single element, one
small drop test (20 x 20 x 6 mm, 2 mm elements), work-precision at 2 and 1 mm (runs estimated to exceed
20 s per backend are listed as skipped), stability cases on the small drop test cut at 5 ms
(through the loading phase to the peak). Full mode: the
full-size drop tests at 5, 6, 7 and 8 mm (1 mm elements), work-precision at 2, 1 and 0.5 mm.
"""

from __future__ import annotations

import time
from pathlib import Path

MODES = {
    "quick": {"small_drop": {"width": 0.02, "thickness": 0.006, "element_size": 0.002},
              "drop_thicknesses": None, "wp_sizes": (2e-3, 1e-3), "wp_budget": 20.0, "scene_budget": 600.0, "stability_end": 5e-3, "thin_element": 2e-3},
    "full": {"small_drop": None, "drop_thicknesses": (0.005, 0.006, 0.007, 0.008),
             "wp_sizes": (2e-3, 1e-3, 5e-4), "wp_budget": 3600.0, "scene_budget": 3600.0, "stability_end": None, "thin_element": 1e-3},
}


def _scenes(mode: str):
    from cfm_core.scene.scene import builtin_scene

    cfg = MODES[mode]
    single = builtin_scene("single-element")
    drop = builtin_scene("drop-test")
    if cfg["small_drop"]:
        small = drop.with_overrides(name="drop-test-small", **cfg["small_drop"])
        drops = [("drop test 20x20x6 mm, 2 mm elements", small)]
        wp = [("single element", single), ("small drop test 20x20x6 mm", small)]
        base = small.with_overrides(end_time=cfg["stability_end"])
    else:
        drops = [(f"drop test {1e3 * h:g} mm", drop.with_overrides(thickness=h, element_size=1e-3))
                 for h in cfg["drop_thicknesses"]]
        wp = [("single element", single), ("drop test 8 mm", drop.with_overrides(thickness=0.008))]
        base = drop.with_overrides(thickness=0.008, element_size=1e-3)
    return single, drops, wp, base


def run_suite(mode: str = "quick", backends=None, out="verify-out", progress=print, budget: float | None = None) -> dict:
    """Run the suite and write the report; returns the report dict (``report["passed"]``).

    budget (s): solver time per backend for the scene runs (agreement and stability cases) and,
    separately, for the work-precision runs (default: the mode's, 20 s quick, 3600 s full); runs estimated to exceed
    it are listed as skipped with the estimate."""
    from cfm_core.errors import InputError

    from . import agreement, inventory, paper_compare, report, stability, workprecision
    from .drucker import stability_map
    from .machine import git_commit, machine_info
    from .runs import RunCache

    if mode not in MODES:
        raise InputError(f"verification mode {mode!r}; use 'quick' or 'full'.")
    say = progress or (lambda *a: None)
    t_start = time.perf_counter()
    selected = None if not backends else [b.strip() for b in backends if b.strip()]
    inv = inventory.discover(selected)
    pointers = inventory.usable(inv, "point")
    runners = inventory.usable(inv, "run")
    cache = RunCache()
    if budget is not None and not (isinstance(budget, (int, float)) and budget > 0):
        raise InputError(f"--budget {budget!r} s must be a number > 0.")
    wp_budget = float(budget) if budget is not None else MODES[mode]["wp_budget"]
    scene_budget = agreement.Budget(float(budget) if budget is not None else MODES[mode]["scene_budget"])
    single, drops, wp_scenes, base = _scenes(mode)
    timings = {}

    def timed(name, fn):
        t0 = time.perf_counter()
        say(f"verify: {name} ...")
        v = fn()
        timings[name] = time.perf_counter() - t0
        return v

    agree = timed("material-point agreement", lambda: agreement.point_agreement(pointers))
    scene_runs = {}

    def scenes():
        rows = []
        for label, scene in [("single element", single)] + drops:
            r, runs = agreement.scene_agreement(label, scene, runners, cache, scene_budget)
            rows += r
            scene_runs[label] = runs
        return rows

    agree += timed("scene agreement", scenes)
    wp = timed("work-precision", lambda: [workprecision.study(label, sc, MODES[mode]["wp_sizes"], inv, cache,
                                                              wp_budget) for label, sc in wp_scenes])
    stab = timed("stability", lambda: stability.run_point_cases(inv) + stability.run_scene_cases(base, inv, cache,
                                                                                          MODES[mode]["thin_element"],
                                                                                          scene_budget))
    from cfm_core import plugins as registry

    drucker = timed("Drucker stability map", lambda: _drucker_all(registry, stability_map))
    ref_backend = next((n for n in workprecision.REFERENCE_ORDER if any(b["name"] == n for b in runners)),
                       runners[0]["name"] if runners else None)
    extra = None
    label0 = drops[0][0]
    run0 = scene_runs.get(label0, {}).get(ref_backend)
    if run0 and run0["ok"]:
        extra = (label0, run0["t"], run0["y"])
    paper = timed("paper comparison", lambda: paper_compare.compare(mode, ref_backend, cache, extra))
    checks = [r for r in agree + stab if r.get("passed") is not None]  # None: skipped, listed
    passed = all(bool(r["passed"]) for r in checks)
    rep = {"mode": mode, "passed": passed, "commit": git_commit(), "machine": machine_info(),
           "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "backends_requested": selected,
           "inventory": [{k: v for k, v in b.items() if k != "instance"} for b in inv],
           "agreement": agree, "work_precision": wp, "stability": stab, "drucker": drucker, "paper": paper,
           "timings": timings, "runtime": time.perf_counter() - t_start,
           "tolerances": {k: {"rel_l2": v[0], "peak": v[1], "why": v[2]} for k, v in agreement.TOLERANCES.items()}}
    report.write(Path(out), rep, scene_runs)
    say(f"verify: {'PASSED' if passed else 'FAILED'} in {rep['runtime']:.1f} s; report in {Path(out) / 'report.md'}")
    return rep


def _drucker_all(registry, stability_map) -> dict:
    import warnings

    from cfm_core.material.registry import make_material

    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        entries = registry.entries("materials")
    for name, (spec, err) in entries.items():
        if err:
            out[name] = {"error": f"material plugin is broken: {err}"}
            continue
        try:
            out[name] = stability_map(make_material(name))
        except Exception as exc:  # listed, not hidden
            out[name] = {"error": f"{type(exc).__name__}: {exc}"}
    return out


def cli(args) -> int:
    """Handler of ``cfm verify``: 0 when every check passes, 1 otherwise."""
    mode = "full" if getattr(args, "full", False) else "quick"
    names = args.backends.split(",") if getattr(args, "backends", None) else None
    rep = run_suite(mode, names, args.out, budget=getattr(args, "budget", None))
    return 0 if rep["passed"] else 1
