"""Stability on stiff and extreme cases: each completes with finite results or stops with a clear
diagnostic (:class:`cfm_core.errors.InputError` / :class:`~cfm_core.errors.NumericalError`).

A raw Python exception of any other type, or NaN/inf in an output, fails the check; so does a
completed scene run whose energy-balance error exceeds :data:`ENERGY_LIMIT`, and a completed
material-point run that deviates from the numpy reference by more than :data:`POINT_LIMIT`.
"""

from __future__ import annotations

import numpy as np

from . import histories
from .drucker import drucker_warnings

#: Largest energy-balance error (-) of a completed scene run that still counts as correct, per kind:
#: implicit runs get more, because generalized-alpha (rho_inf = 0.5) dissipates high-frequency energy
#: by design and the balance counts that as error.
ENERGY_LIMIT = {"explicit": 0.05, "implicit": 0.10}
#: Largest relative deviation (-) of a completed point run from the numpy reference.
POINT_LIMIT = 1e-6


def scene_cases(base, thin_element: float = 1e-3) -> list[tuple[str, object, dict, str | None]]:
    """(name, scene, options, only_backend) for the scene cases, built on the drop-test ``base``;
    thin_element (m): element size of the 2 mm specimen (quick mode: 2 mm, one layer)."""
    return [
        ("k2 = 20", base.with_overrides(parameters={"k2": 20.0}), {}, None),
        ("k2 = 50", base.with_overrides(parameters={"k2": 50.0}), {}, None),
        ("kappa x 100 (nearly incompressible)", base.with_overrides(parameters={"kappa": 666.1e3 * 100}), {}, None),
        ("2 mm specimen", base.with_overrides(thickness=0.002, element_size=thin_element), {}, None),
        ("impact at 5 m/s", base.with_overrides(velocity=5.0), {}, None),
        ("tau1 = 1e-7 s (much smaller than the step)", base.with_overrides(parameters={"tau1": 1e-7}), {}, None),
        ("float32 on torch (dtype='float32')", base, {"dtype": "float32"}, "torch"),
    ]


def point_cases() -> list[tuple[str, list]]:
    """(name, [(t, F), ...]) for the material-point cases."""
    return [
        ("material-point compression to stretch 0.2", [histories.uniaxial_compression(stretch=0.2)]),
        ("repeated principal stretches (l, l, l) and (l, l^-1/2, l^-1/2)",
         [histories.equal_stretches(), histories.repeated_stretches()]),
        ("hydrostatic tension to J = 1.5 (past J = 1.29)", [histories.hydrostatic(J_end=1.5)]),
    ]


def _scene_verdict(run, kind) -> tuple[str, bool]:
    if run["status"] == "completed":
        err, limit = run["energy_error"], ENERGY_LIMIT.get(kind, 0.05)
        text = f"completed: finite results, energy error {100 * err:.3g} %"
        if not (err <= limit):
            return text + f" (above the {100 * limit:g} % limit for {kind} backends)", False
        return text, True
    if run["status"] == "diagnostic":
        return f"stopped with a clear diagnostic: {run['message']}", True
    return f"FAILURE ({run['status']}): {run['message']}", False


def run_scene_cases(base, inventory, cache, thin_element: float = 1e-3, budget=None) -> list[dict]:
    """Every scene case on every backend that can run scenes; with an :class:`.agreement.Budget`
    (shared with the agreement runs), a run estimated to exceed it is listed as skipped (n/a)."""
    from .agreement import Budget

    budget = budget or Budget()
    rows = []
    by_name = {b["name"]: b for b in inventory}
    runners = [b for b in inventory if b["status"] == "available" and b["can_run"]]
    for name, scene, options, only in scene_cases(base, thin_element):
        targets = runners if only is None else [by_name.get(only) or {"name": only, "status": "not registered",
                                                                      "reason": "", "can_run": False}]
        for b in targets:
            row = {"case": name, "kind": "scene", "backend": b["name"], "options": options}
            usable = b["status"] == "available" and b.get("can_run")
            allowed, why = budget.allows(b["name"], scene) if usable else (False, "")
            if not usable:
                row.update(verdict=f"not run: backend '{b['name']}' is {b['status']}"
                           f"{': ' + b['reason'] if b['reason'] else ''}", passed=None)
            elif not allowed:
                row.update(verdict=why, passed=None)
            else:
                run = cache.run(scene, b["name"], **options)
                budget.record(b["name"], scene, run)
                row["verdict"], row["passed"] = _scene_verdict(run, b["kind"])
                row.update(wall=run["total"], energy_error=run["energy_error"] if run["ok"] else None,
                           peak_g=(run["summary"] or {}).get("peak_g"))
            rows.append(row)
    return rows


def run_point_cases(inventory, material_name: str = "cfm") -> list[dict]:
    from cfm_core.errors import InputError, NumericalError
    from cfm_core.material.kinematics import to_voigt
    from cfm_core.material.registry import make_material
    from cfm_core.material.reference import stress_history

    mat = make_material(material_name)
    rows = []
    for name, hist in point_cases():
        warn = []
        for t, F in hist:
            warn += drucker_warnings(mat, F, emit=False)
        for b in [r for r in inventory if r["status"] == "available" and r["can_point"]]:
            row = {"case": name, "kind": "point", "backend": b["name"], "options": {}}
            try:
                dev = 0.0
                for t, F in hist:
                    s = np.asarray(b["instance"].point(mat, t, F), dtype=float)
                    if not np.isfinite(s).all():
                        raise FloatingPointError("non-finite stress returned without an error")
                    ref = to_voigt(stress_history(mat, t, F))
                    dev = max(dev, float(np.linalg.norm(s - ref) / max(np.linalg.norm(ref), 1e-300)))
                row["verdict"] = (f"completed: finite results, energy error n/a (material point); deviation "
                                  f"from the numpy reference {dev:.2g}")
                row["passed"] = dev <= POINT_LIMIT
                row["deviation"] = dev
            except (InputError, NumericalError) as exc:
                row.update(verdict=f"stopped with a clear diagnostic: {type(exc).__name__}: {exc}", passed=True)
            except Exception as exc:
                row.update(verdict=f"FAILURE (raw exception): {type(exc).__name__}: {exc}", passed=False)
            if warn:
                row["verdict"] += f"; Drucker warning: {warn[0]}"
                row["drucker_warnings"] = warn
            rows.append(row)
    return rows
