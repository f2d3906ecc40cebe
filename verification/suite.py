"""The verification suite: ``cfm verify [--quick | --full] [--backends A,B] --out DIR``.

:func:`run_suite` runs every installed backend through agreement (:mod:`.agreement`), error against
run time (:mod:`.workprecision`), stability (:mod:`.stability`, :mod:`.drucker`) and the paper
comparison (:mod:`.paper_compare`), then writes DIR/report.md, DIR/report.json and PNG figures
(:mod:`.report`). The suite passes when every agreement and stability check is within its
tolerance and nothing was skipped: the verdict is PASSED (exit 0), FAILED (exit 1) or INCOMPLETE
(exit 4; a backend missing, a run skipped by the budget), see :mod:`.verdict`.

Quick mode (CI; 5.5 minutes measured on a shared 2-core machine at load ~8, two thirds of it the
implicit backend's stability cases): a 1 mm single element, one
small drop test (20 x 20 x 6 mm, 2 mm elements), work-precision at 2 and 1 mm (torch and skfem at
2 mm only, skfem at one step size: :data:`MODES` ``wp_plan``), stability cases on the small drop test cut at 5 ms
(through the loading phase to the peak). Full mode: the
full-size drop tests at 5, 6, 7 and 8 mm (1 mm elements), work-precision at 2, 1 and 0.5 mm.
"""

from __future__ import annotations

import time
from pathlib import Path

#: Per mode. wp_plan: {backend: (element sizes from the coarsest, step options)} of the
#: work-precision runs (absent: all); the skfem entries are the ones to change when the implicit
#: backend gets faster. Budgets in s of solver time per backend (cfm verify --budget overrides).
MODES = {
    "quick": {"small_drop": {"width": 0.02, "thickness": 0.006, "element_size": 0.002},
              "drop_thicknesses": None, "wp_sizes": (2e-3, 1e-3), "wp_budget": 60.0, "scene_budget": 600.0,
              "wp_plan": {"torch": (1, None), "skfem": (1, 1)},
              "stability_end": 5e-3, "thin_element": 2e-3},
    "full": {"small_drop": None, "drop_thicknesses": (0.005, 0.006, 0.007, 0.008),
             "wp_sizes": (2e-3, 1e-3, 5e-4), "wp_budget": 3600.0, "scene_budget": 3600.0,
             "wp_plan": {"skfem": (2, 2)},  # skfem at 2 and 1 mm (0.5 mm: ~10 min a run on 2 cores)
             "stability_end": None, "thin_element": 1e-3},
}


def _scenes(mode: str):
    from cfm_core.scene.scene import builtin_scene

    cfg = MODES[mode]
    single = builtin_scene("single-element")
    drop = builtin_scene("drop-test")
    layered, flat = builtin_scene("layered-tissue"), builtin_scene("flat-impactor")
    if cfg["small_drop"]:
        small = drop.with_overrides(name="drop-test-small", **cfg["small_drop"])
        drops = [("drop test 20x20x6 mm, 2 mm elements", small)]
        wp = [("single element", single), ("small drop test 20x20x6 mm", small)]
        base = small.with_overrides(end_time=cfg["stability_end"])
    else:
        drops = [(f"drop test {1e3 * h:g} mm", drop.with_overrides(thickness=h, element_size=1e-3))
                 for h in cfg["drop_thicknesses"]]
        # the scenes beyond the paper (issue 21), on their built-in 1 mm meshes; with 2 mm elements they are
        # tests (tests/test_impacts_beyond_paper.py, skfem with --runslow); a 20 mm wide block folds under them
        drops += [("layered tissue (built-in scene)", layered), ("flat impactor (built-in scene)", flat)]
        wp = [("single element", single), ("drop test 8 mm", drop.with_overrides(thickness=0.008))]
        base = drop.with_overrides(thickness=0.008, element_size=1e-3)
    return single, drops, wp, base


#: Sections of the suite, in order; ``sections=`` / ``--only`` runs a subset (the verdict is then
#: INCOMPLETE at best).
SECTIONS = ("point", "scenes", "workprecision", "stability", "drucker", "paper")


def run_suite(mode: str = "quick", backends=None, out="verify-out", progress=print, budget: float | None = None,
              require=None, sections=None, cache=None) -> dict:
    """Run the suite and write the report; returns the report dict (``report["verdict"]``:
    "PASSED", "FAILED" or "INCOMPLETE", see :mod:`.verdict`; ``report["passed"]`` is True only for
    PASSED).

    budget (s): solver time per backend for the scene runs (agreement and stability cases) and,
    separately, for the work-precision runs (default: the mode's, 20 s quick, 3600 s full); runs
    estimated to exceed it are listed as skipped with the estimate and make the run INCOMPLETE.
    require: backend names that must be available (default: $CFM_VERIFY_REQUIRE), else FAILED.
    sections: subset of :data:`SECTIONS` (default all). cache: a :class:`.runs.RunCache` to share.

    Raises InputError on an unknown mode, section or backend, or a budget that is not > 0."""
    from cfm_core.errors import InputError

    from . import agreement, calculix, inventory, paper_compare, report, stability, verdict, workprecision
    from .machine import git_commit, machine_info
    from .runs import RunCache

    if mode not in MODES:
        raise InputError(f"verification mode {mode!r}; use 'quick' or 'full'.")
    sections = tuple(SECTIONS if not sections else sections)
    unknown = sorted(set(sections) - set(SECTIONS))
    if unknown:
        raise InputError(f"--only names unknown section(s) {', '.join(unknown)}; sections: {', '.join(SECTIONS)}.")
    if budget is not None and not (isinstance(budget, (int, float)) and budget > 0):
        raise InputError(f"--budget {budget!r} s must be a number > 0.")
    required = list(require) if require is not None else verdict.required_from_env()
    say = progress or (lambda *a: None)
    t_start = time.perf_counter()
    selected = None if not backends else [b.strip() for b in backends if b.strip()]
    inv = inventory.discover(selected)
    unknown = sorted(set(required) - {b["name"] for b in inv})
    if unknown:
        raise InputError(f"--require names unknown backend(s) {', '.join(unknown)}; known: "
                         f"{', '.join(b['name'] for b in inv)}.")
    # an experimental backend (calculix) is checked in its own rows (verification.calculix), not in
    # every pair, work-precision and stability case
    general = [b for b in inv if not getattr(type(b["instance"]), "experimental", False)]
    pointers = inventory.usable(general, "point")
    runners = inventory.usable(general, "run")
    cache = cache or RunCache()
    wp_budget = float(budget) if budget is not None else MODES[mode]["wp_budget"]
    scene_budget = agreement.Budget(float(budget) if budget is not None else MODES[mode]["scene_budget"])
    single, drops, wp_scenes, base = _scenes(mode)
    timings = {}

    def timed(name, section, fn, empty):
        if section not in sections:
            return empty
        t0 = time.perf_counter()
        say(f"verify: {name} ...")
        v = fn()
        timings[name] = time.perf_counter() - t0
        return v

    agree = timed("material-point agreement", "point", lambda: agreement.point_agreement(pointers), [])
    scene_runs = {}

    def scenes():
        rows = []
        for label, scene in [("single element", single)] + drops:
            r, runs = agreement.scene_agreement(label, scene, runners, cache, scene_budget)
            rows += r
            scene_runs[label] = runs
        return rows

    agree += timed("scene agreement", "scenes", scenes, [])
    agree += timed("calculix agreement", "scenes", lambda: calculix.rows(inv, cache, say), [])
    wp = timed("work-precision", "workprecision",
               lambda: [workprecision.study(label, sc, MODES[mode]["wp_sizes"], inv, cache, wp_budget,
                                                   MODES[mode]["wp_plan"])
                        for label, sc in wp_scenes], [])
    stab = timed("stability", "stability",
                 lambda: stability.run_point_cases(inv) + stability.run_scene_cases(base, inv, cache,
                                                                                    MODES[mode]["thin_element"],
                                                                                    scene_budget), [])
    drucker_maps, drucker_rows = timed("Drucker stability map", "drucker", _drucker_all, ({}, []))
    ref_backend = next((n for n in workprecision.REFERENCE_ORDER if any(b["name"] == n for b in runners)),
                       runners[0]["name"] if runners else None)
    extra = None
    label0 = drops[0][0]
    run0 = scene_runs.get(label0, {}).get(ref_backend)
    if run0 and run0["ok"]:
        extra = (label0, run0["t"], run0["y"])
    paper = timed("paper comparison", "paper", lambda: paper_compare.compare(mode, ref_backend, cache, extra,
                                                                [b["name"] for b in runners]),
                  {"source": "section not run", "rows": [], "facts": [], "curves": [], "checks": []})
    wp_rows = [r for s in wp for r in s.get("checks", [])]
    v = verdict.decide({"agreement": agree, "stability": stab, "drucker": drucker_rows,
                        "work-precision": wp_rows, "paper": paper.get("checks", [])}, inv, required,
                       [s for s in SECTIONS if s not in sections])
    rep = {"mode": mode, "verdict": v["verdict"], "passed": v["verdict"] == "PASSED", "exit_code": v["exit_code"],
           "failed": v["failed"], "incomplete": v["incomplete"], "checks": v["checks"], "required": required,
           "sections": list(sections), "commit": git_commit(), "machine": machine_info(),
           "provenance": provenance_record(inv),
           "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "backends_requested": selected,
           "inventory": [{k: val for k, val in b.items() if k != "instance"} for b in inv],
           "agreement": agree, "work_precision": wp, "stability": stab, "drucker": drucker_maps,
           "drucker_checks": drucker_rows, "paper": paper, "timings": timings,
           "runtime": time.perf_counter() - t_start,
           "tolerances": {k: {"rel_l2": t[0], "peak": t[1], "t_peak": t[2], "duration": t[3], "why": t[4]}
                          for k, t in agreement.TOLERANCES.items()}}
    from cfm_core.post.staging import staged_folder

    with staged_folder(out, "--out") as stage:  # published whole: an earlier report's figures do not stay behind
        report.write(stage, rep, scene_runs)
    say(f"verify: {v['verdict']} in {rep['runtime']:.1f} s ({v['checks']} checks, {len(v['failed'])} failed, "
        f"{len(v['incomplete'])} not run); report in {Path(out) / 'report.md'}")
    for msg in v["failed"][:20]:
        say(f"verify: FAILED {msg}")
    for msg in v["incomplete"][:20]:
        say(f"verify: NOT RUN {msg}")
    return rep


def provenance_record(inv) -> dict:
    """What a verification report was made with: the code, the plugins and the gold inputs.

    Parameters
    ----------
    inv : list of dict
        The backend inventory (:func:`.inventory.discover`).

    Returns
    -------
    dict
        :func:`cfm_core.runs.provenance.provenance` (code state: version, commit, dirty, source
        digest; Python, platform, cores) with ``backends`` (name -> distribution, version, entry
        point of each backend in the inventory, or the error of one that cannot be placed),
        ``materials`` (the same for every registered material, with its definition digest) and
        ``gold`` (case -> digests of its definition and material, :func:`.gold.store.inputs`).
    """
    import warnings

    from cfm_core import plugins
    from cfm_core.material.cache import spec_fingerprint
    from cfm_core.runs.provenance import provenance

    from .gold.store import case_names, inputs

    def origin(kind, name):
        try:
            where = plugins.origin(kind, name)
        except Exception as exc:  # an ambiguous or broken plugin: recorded, not fatal to the report
            return {"error": str(exc)}
        return {"distribution": where["distribution"], "version": where["version"], "entry_point": where["value"]}

    backends = {b["name"]: origin("backends", b["name"]) for b in inv}
    materials = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        entries = plugins.entries("materials")
    for name, (spec, err) in entries.items():
        materials[name] = origin("materials", name)
        if spec is not None:
            materials[name]["definition_digest"] = spec_fingerprint(spec)
    return provenance(backends=backends, materials=materials, gold={n: inputs(n) for n in case_names()})


def _drucker_all() -> tuple[dict, list]:
    """Stability maps of every registered material, and the checks on them (:func:`.drucker.checks`)."""
    import warnings

    from cfm_core import plugins as registry
    from cfm_core.material.registry import make_material

    from .drucker import checks, stability_map

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
        except Exception as exc:  # listed, and failed in checks()
            out[name] = {"error": f"{type(exc).__name__}: {exc}"}
    return out, checks(out)


def cli(args) -> int:
    """Handler of ``cfm verify``: 0 PASSED, 1 FAILED, 4 INCOMPLETE (see :mod:`.verdict`)."""
    mode = "full" if getattr(args, "full", False) else "quick"
    names = args.backends.split(",") if getattr(args, "backends", None) else None
    req = getattr(args, "require", None)
    require = [s.strip() for s in req.split(",") if s.strip()] if req is not None else None
    only = getattr(args, "only", None)
    sections = [s.strip() for s in only.split(",") if s.strip()] if only else None
    from cfm_core.post.staging import check_folder_target

    check_folder_target(args.out, "--out")  # before minutes of runs: a file, an unwritable folder -> exit 2
    rep = run_suite(mode, names, args.out, budget=getattr(args, "budget", None), require=require, sections=sections)
    return rep["exit_code"]
