"""Error against run time (work-precision): each backend at several element and step sizes.

Step options: explicit backends take ``safety`` (dt = safety x the stable step); implicit backends
take ``dt_max`` (s, the largest adaptive Newmark step; see the skfem backend's docstring). Errors
are measured against a converged reference:

- drop test: the finest run (smallest element, smallest step) of the reference backend (the first
  available of :data:`REFERENCE_ORDER`, the most mature solver), and, for the peak, also against
  the Richardson extrapolation of the reference backend's peaks over element size;
- single element: the numpy quasi-static uniaxial-stress solution (independent of every backend).

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


def study(label, base, element_sizes, inventory, cache, budget: float = math.inf) -> dict:
    """All runs of one scene; ``budget`` (s) per backend: runs beyond it are listed as skipped."""
    from cfm_core.scene.builder import build_model
    from cfm_core.simulation.point import uniaxial
    from cfm_core.post import compare_histories

    runners = [b for b in inventory if b["status"] == "available" and b["can_run"]]
    sizes = sorted(element_sizes, reverse=True) if base.type == "drop-test" else [None]
    runs = []
    for b in runners:
        spent, last = 0.0, {}
        for h in sizes:
            scene = base.with_overrides(element_size=h) if h else base
            for opts in step_options(b["kind"]):
                row = {"backend": b["name"], "kind": b["kind"], "element_size": h, "options": opts}
                # cost estimate from the same step option on the next coarser mesh: elements x (h0/h)^3,
                # steps x (h0/h) (explicit) -> (h0/h)^4
                key = json.dumps(opts, sort_keys=True)
                guess = last[key][1] * (last[key][0] / h) ** 4 if (h and key in last) else 0.0
                if spent + guess > budget:
                    row.update(status="skipped", message=f"estimated {guess:.0f} s would exceed this mode's "
                               f"budget of {budget:g} s per backend ({spent:.0f} s spent)")
                    runs.append(row)
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
        model = build_model(base)
        m = model.meta
        t, _, P, _ = uniaxial(model.material, m["rate"], m["stretch"], steps=400, hold=m["hold"])
        ref = {"t": t, "y": P * m["size"] ** 2}
        ref_text = "numpy quasi-static uniaxial-stress solution (cfm_core.simulation.point.uniaxial), force = P x face area"
    else:
        for name in REFERENCE_ORDER + tuple(sorted({r["backend"] for r in ok})):
            mine = [r for r in ok if r["backend"] == name]
            if mine:
                best = min(mine, key=lambda r: (r["element_size"], _step_size(r["options"])))
                ref = {"t": best["run"]["t"], "y": best["run"]["y"], "row": best}
                best["is_reference"] = True
                ref_text = (f"finest run of backend '{name}' (element {1e3 * best['element_size']:g} mm, "
                            f"{best['options']})")
                finest_step = [r for r in mine if _step_size(r["options"]) == _step_size(best["options"])]
                finest_step.sort(key=lambda r: -r["element_size"])
                rich = richardson([r["element_size"] for r in finest_step], [_peak(r["run"]["y"]) for r in finest_step])
                break
    for r in ok:
        if ref is None:
            break
        c = compare_histories(r["run"]["t"], r["run"]["y"], ref["t"], ref["y"])
        r["rel_l2"], r["peak_error"] = c["rel_l2"], abs(c["peak_diff"])
        if rich:
            r["peak_error_richardson"] = abs(_peak(r["run"]["y"]) - rich["peak"]) / abs(rich["peak"])
    first = {}
    for r in ok:
        if r.get("is_reference") or "peak_error" not in r:
            continue
        if max(r["peak_error"], r["rel_l2"]) <= TARGET and (r["backend"] not in first or r["wall"] < first[r["backend"]]["wall"]):
            first[r["backend"]] = r
    winner = min(first.values(), key=lambda r: r["wall"]) if first else None
    if winner:
        size = "-" if winner["element_size"] is None else f"{1e3 * winner['element_size']:g} mm"
        first_text = f"{winner['backend']} ({winner['wall']:.3g} s, element {size}, {winner['options']})"
    else:
        first_text = "no backend reached 1 % (peak and rel L2) in a run other than the reference"
    for r in runs:
        r.pop("run", None)
    return {"label": label, "scene": base.type, "runs": runs, "reference": ref_text, "richardson": rich,
            "first_to_1pct": first_text}
