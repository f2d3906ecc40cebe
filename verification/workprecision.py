"""Error against run time (work-precision): each backend at several element and step sizes.

Step options: explicit backends take ``safety`` (dt = safety x the stable step); implicit backends
take ``dt_max`` (s, the largest adaptive Newmark step; see the skfem backend's docstring). Errors
are measured against a converged reference:

- drop test: the Richardson extrapolation, history and peak, of the reference backend's (the first
  available of :data:`REFERENCE_ORDER`) two finest element sizes at its smallest step: a converged
  estimate that is none of the candidate runs, so the reference backend's own finest run is judged
  like every other;
- single element: the quasi-static uniaxial-stress truth (:func:`.truths.uniaxial_force`).

Wall time is the solver's own (compilation excluded, as ``Result.wall_time``).
"""

from __future__ import annotations

import json
import math

import numpy as np

REFERENCE_ORDER = ("numba", "torch", "skfem")
EXPLICIT_STEPS = ({"safety": 0.9}, {"safety": 0.45})
IMPLICIT_STEPS = ({"dt_max": 1e-4}, {"dt_max": 2.5e-5})
TARGET = 0.01  # the "1 % error" of the question "which backend gets there first"


def step_options(kind: str):
    return IMPLICIT_STEPS if kind == "implicit" else EXPLICIT_STEPS


def _step_size(opts: dict) -> float:
    return float(opts.get("safety", opts.get("dt_max", 1.0)))


def _peak(y):
    i = int(np.argmax(np.abs(y)))
    return float(y[i])


def richardson(sizes, peaks) -> dict | None:
    """Extrapolated peak from peaks at element sizes h (decreasing, ratio 2): observed order from
    three levels, assumed order 1 from two (first-order hourglass-controlled elements)."""
    if len(peaks) < 2:
        return None
    p1, p2 = peaks[-2], peaks[-1]
    order, note = 1.0, "two levels, assumed order 1"
    if len(peaks) >= 3:
        p0 = peaks[-3]
        if (p0 - p1) * (p1 - p2) > 0 and abs(p1 - p2) > 0:
            order = math.log(abs(p0 - p1) / abs(p1 - p2)) / math.log(sizes[-2] / sizes[-1])
            note = "three levels, observed order"
        else:
            note = "three levels, non-monotone: assumed order 1"
    r = sizes[-2] / sizes[-1]
    if not (order > 0.2):
        order, note = 1.0, note + " (unusable, assumed 1)"
    return {"peak": p2 + (p2 - p1) / (r ** order - 1.0), "order": order, "note": note}


def _extrapolated_history(fine, coarse, r, order) -> tuple[np.ndarray, np.ndarray]:
    """Richardson extrapolation of a whole history: y_R = y_f + (y_f - y_c) / (r^p - 1) on the
    fine run's samples (the coarse run interpolated there, zero outside its range)."""
    t = np.asarray(fine["t"], float)
    yf = np.asarray(fine["y"], float)
    yc = np.interp(t, coarse["t"], coarse["y"], left=0.0, right=0.0)
    return t, yf + (yf - yc) / (r ** order - 1.0)


def study(label, base, element_sizes, inventory, cache, budget: float = math.inf, plan=None) -> dict:
    """All runs of one scene. ``budget`` (s) per backend: runs beyond it are listed as skipped
    (a check row with ``passed`` None: the suite is then INCOMPLETE). ``plan``: {backend name:
    (number of element sizes from the coarsest, number of step options)}, the runs a mode
    includes (quick mode keeps the slow backends to their coarsest runs); absent names run all.

    Errors are measured against a reference that no candidate run is: the Richardson
    extrapolation (history and peak) of the reference backend's two finest element sizes at its
    smallest step for a drop test, the quasi-static truth (:func:`.truths.uniaxial_force`) for the
    single element; the fastest run within 1 % of it wins."""
    from .agreement import quasistatic_truth
    from .compare import compare_union

    plan = plan or {}
    runners = [b for b in inventory if b["status"] == "available" and b["can_run"]]
    sizes = sorted(element_sizes, reverse=True) if base.type == "drop-test" else [None]
    runs, checks = [], []
    for b in runners:
        spent, last = 0.0, {}
        n_sizes, n_steps = plan.get(b["name"], (len(sizes), None))
        for h in sizes[:n_sizes]:
            scene = base.with_overrides(element_size=h) if h else base
            for opts in step_options(b["kind"])[:n_steps]:
                row = {"backend": b["name"], "kind": b["kind"], "element_size": h, "options": opts}
                # cost estimate from the same step option on the next coarser mesh: elements x (h0/h)^3,
                # steps x (h0/h) (explicit) -> (h0/h)^4
                key = json.dumps(opts, sort_keys=True)
                guess = last[key][1] * (last[key][0] / h) ** 4 if (h and key in last) else 0.0
                if spent + guess > budget:
                    row.update(status="skipped", message=f"estimated {guess:.0f} s would exceed the work-precision "
                               f"budget of {budget:g} s per backend ({spent:.0f} s spent; cfm verify --budget)")
                    runs.append(row)
                    checks.append({"check": f"work-precision run {label}", "case": f"{b['name']} "
                                   f"{'' if h is None else f'{1e3 * h:g} mm '}{opts}", "passed": None,
                                   "reason": row["message"]})
                    continue
                r = cache.run(scene, b["name"], **opts)
                spent += r["total"]
                if h:
                    last[key] = (h, r["total"])
                row.update(status=r["status"], message=r["message"], wall=r["wall"], run=r)
                runs.append(row)
    ok = [r for r in runs if r["status"] == "completed"]
    ref, rich, ref_text = None, None, ""
    if base.type == "single-element":
        t, force = quasistatic_truth(base)
        ref = {"t": t, "y": force}
        ref_text = "quasi-static uniaxial-stress truth (cfm_verification.truths.uniaxial_force), force = P x face area"
    else:
        for name in REFERENCE_ORDER + tuple(sorted({r["backend"] for r in ok})):
            mine = [r for r in ok if r["backend"] == name]
            if not mine:
                continue
            step = min(_step_size(r["options"]) for r in mine)
            ladder = sorted([r for r in mine if _step_size(r["options"]) == step], key=lambda r: -r["element_size"])
            if len(ladder) < 2:
                continue
            hs = [r["element_size"] for r in ladder]
            rich = richardson(hs, [_peak(r["run"]["y"]) for r in ladder])
            tr, yr = _extrapolated_history(ladder[-1]["run"], ladder[-2]["run"], hs[-2] / hs[-1], rich["order"])
            ref = {"t": tr, "y": yr}
            fin = ladder[-1]
            rich["finest_error"] = abs(_peak(fin["run"]["y"]) - rich["peak"]) / abs(rich["peak"])
            ref_text = (f"Richardson extrapolation of backend '{name}' at {fin['options']} from element sizes "
                        f"{1e3 * hs[-2]:g} and {1e3 * hs[-1]:g} mm ({rich['note']}); its finest run is "
                        f"{100 * rich['finest_error']:.2g} % from the extrapolated peak")
            break
        if ref is None:
            ref_text = "no backend ran two element sizes: no converged reference, no winner"
    for r in ok:
        if ref is None:
            break
        c = compare_union(r["run"]["t"], r["run"]["y"], ref["t"], ref["y"],
                          fill=0.0 if base.type == "drop-test" else None)
        r["rel_l2"], r["peak_error"] = c["rel_l2"], abs(c["peak_diff"])
    first = {}
    for r in ok:
        if "peak_error" not in r:
            continue
        if max(r["peak_error"], r["rel_l2"]) <= TARGET and (r["backend"] not in first or r["wall"] < first[r["backend"]]["wall"]):
            first[r["backend"]] = r
    winner = min(first.values(), key=lambda r: r["wall"]) if first else None
    if winner:
        size = "-" if winner["element_size"] is None else f"{1e3 * winner['element_size']:g} mm"
        first_text = f"{winner['backend']} ({winner['wall']:.3g} s, element {size}, {winner['options']})"
    else:
        first_text = "no backend reached 1 % (peak and rel L2) of the converged reference"
    for r in runs:
        r.pop("run", None)
    return {"label": label, "scene": base.type, "runs": runs, "reference": ref_text, "richardson": rich,
            "first_to_1pct": first_text, "checks": checks}
