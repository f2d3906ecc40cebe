"""Agreement checks: every backend against the reference and against every other backend.

Material point: each backend's ``point`` against :func:`cfm_core.material.reference.stress_history` along the
histories of :mod:`.histories`, elastic and viscoelastic. Scenes (single element, drop tests): every
pair of backends that can run the scene, plus the single element against the numpy quasi-static
uniaxial-stress solution (:func:`cfm_core.simulation.point.uniaxial`). Metrics (:func:`cfm_core.post.
compare_histories`): relative L2 error over the event, peak difference (relative), time-of-peak
difference (s). Tolerances are per pair of backend kinds (:data:`TOLERANCES`).
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np

from . import histories

#: (rel_l2 limit, peak limit, justification) per kind of pair.
TOLERANCES = {
    "reference-point": (1e-10, 1e-10, "the backend evaluates the same generated float64 formulas and the same "
                        "exact exponential Prony recurrence as the reference, so only round-off (~1e-14) may differ."),
    "explicit-explicit": (1e-6, 1e-6, "same mesh, same algorithm and the same step rule, so the runs may differ "
                          "only by floating-point summation order, amplified by the nonlinear dynamics."),
    "explicit-implicit": (5e-2, 2e-2, "different time integrators (central differences vs Newmark/Newton) and "
                          "elements (one-point + hourglass vs 2x2x2 mean dilatation) agree only to discretisation "
                          "error, a few per cent at these meshes."),
    "implicit-implicit": (5e-2, 2e-2, "independent implicit discretisations agree to discretisation error."),
    "quasistatic-scene": (5e-2, 2e-2, "a 1 mm cube loaded over 5 ms is quasi-static (wave transit ~40 us) and "
                          "homogeneous, so the element's force equals the uniaxial-stress solution up to the "
                          "dynamic start-up ringing and the time step."),
}


def pair_kind(kind_a: str, kind_b: str) -> str:
    kinds = sorted((kind_a, kind_b))
    if "reference" in kinds:
        return "reference-point"
    return "-".join(kinds)


def _metrics(t1, y1, t2, y2) -> dict:
    from cfm_core.post import compare_histories

    return compare_histories(t1, y1, t2, y2)


def _row(check, case, a, b, kind, m=None, error="") -> dict:
    l2, pk, why = TOLERANCES[kind]
    row = {"check": check, "case": case, "a": a, "b": b, "pair": kind, "tol_rel_l2": l2, "tol_peak": pk,
           "justification": why, "rel_l2": None, "peak_diff": None, "t_peak_diff": None, "passed": False,
           "error": error}
    if m is not None:
        row.update(m)
        row["passed"] = bool(m["rel_l2"] <= l2 and abs(m["peak_diff"]) <= pk)
    return row


def point_agreement(point_rows, material_names=("cfm",)) -> list[dict]:
    """Each point-capable backend against the reference, for every history, elastic and viscoelastic."""
    from cfm_core.errors import InputError, NumericalError
    from cfm_core.material.kinematics import to_voigt
    from cfm_core.material.registry import make_material
    from cfm_core.material.reference import stress_history

    rows = []
    for mat_name in material_names:
        for elastic in (True, False):
            mat = make_material(mat_name, elastic=elastic)
            for hname, make in histories.AGREEMENT.items():
                t, F = make()
                ref = to_voigt(stress_history(mat, t, F))
                norm = np.linalg.norm(ref, axis=1)
                case = f"{mat_name}, {hname}, {'elastic' if elastic else 'viscoelastic'}"
                for b in point_rows:
                    if b["kind"] == "reference":
                        continue
                    try:
                        s = np.asarray(b["instance"].point(mat, t, F), dtype=float)
                        if not np.isfinite(s).all():
                            raise NumericalError("non-finite stress returned without an error")
                        # stress tensor norm per instant, its error history: rel L2 and peak of |sigma|
                        m = {"rel_l2": float(np.linalg.norm(s - ref) / np.linalg.norm(ref))}
                        ns = np.linalg.norm(s, axis=1)
                        i, j = int(np.argmax(ns)), int(np.argmax(norm))
                        m["peak_diff"] = float((ns[i] - norm[j]) / norm[j])
                        m["t_peak_diff"] = float(t[i] - t[j])
                        m["max_abs_diff_rel"] = float(np.abs(s - ref).max() / np.abs(ref).max())
                        rows.append(_row("material point", case, "numpy", b["name"], "reference-point", m))
                    except (InputError, NumericalError, Exception) as exc:  # reported as a failed row
                        rows.append(_row("material point", case, "numpy", b["name"], "reference-point",
                                         error=f"{type(exc).__name__}: {exc}"))
    return rows


class Budget:
    """Solver time (s) each backend may spend on the scene checks of one suite, with a cost estimate.

    A drop test's cost scales with its elements times its duration (thickness / velocity, the
    step being set by the element size): a run is estimated from the backend's previous drop test
    as ``total x (elements / previous elements) x (thickness / previous thickness) x (previous
    velocity / velocity)``. The first run of a backend is never skipped (nothing to estimate from).
    """

    def __init__(self, seconds: float = math.inf):
        self.seconds = float(seconds)
        self.spent: dict[str, float] = {}
        self.last: dict[str, tuple] = {}
        self._counted: set[int] = set()
        self._sizes: dict[str, tuple] = {}

    def _size(self, scene):
        """(elements, thickness m, velocity m/s) of a drop-test scene, None otherwise; meshed once
        per scene (allows and record ask for the same scene)."""
        if scene.type != "drop-test":
            return None
        from cfm_core.scene.builder import build_model
        from cfm_core.scene.scene import scene_to_dict

        key = json.dumps(scene_to_dict(scene), sort_keys=True, default=str)
        if key not in self._sizes:
            self._sizes[key] = (build_model(scene).n_elements, scene.specimen.thickness, scene.impactor.velocity)
        return self._sizes[key]

    def estimate(self, backend: str, scene) -> float:
        size, last = self._size(scene), self.last.get(backend)
        if size is None or last is None:
            return 0.0
        (n0, h0, v0), total = last
        n, h, v = size
        return total * (n / n0) * (h / h0) * (v0 / v)

    def allows(self, backend: str, scene) -> tuple[bool, str]:
        guess, spent = self.estimate(backend, scene), self.spent.get(backend, 0.0)
        if spent + guess <= self.seconds:
            return True, ""
        return False, (f"skipped: estimated {guess:.0f} s would exceed the budget of {self.seconds:g} s of "
                       f"scene runs per backend ({spent:.0f} s spent; raise it with cfm verify --budget)")

    def record(self, backend: str, scene, run: dict) -> None:
        if id(run) in self._counted:  # a cached run shared by two checks costs once
            return
        self._counted.add(id(run))
        self.spent[backend] = self.spent.get(backend, 0.0) + float(run["total"])
        size = self._size(scene)
        if size is not None and run["ok"]:
            self.last[backend] = (size, float(run["total"]))


def scene_agreement(label: str, scene, run_rows, cache, budget: Budget | None = None) -> tuple[list[dict], dict]:
    """Every pair of backends on one scene. Returns (rows, runs {backend: run dict}).

    With a :class:`Budget`, a backend whose run would exceed it is listed as skipped (a row with
    verdict n/a naming the estimate), not run and not failed.
    """
    budget = budget or Budget()
    runs, rows = {}, []
    for b in run_rows:
        ok, why = budget.allows(b["name"], scene)
        if not ok:
            rows.append({**_row(label, label, b["name"], b["name"], "explicit-implicit"), "pair": "run",
                         "passed": None, "error": why})
            continue
        runs[b["name"]] = cache.run(scene, b["name"])
        budget.record(b["name"], scene, runs[b["name"]])
    kinds = {b["name"]: b["kind"] for b in run_rows}
    for name, r in runs.items():
        if not r["ok"]:
            rows.append({**_row(label, label, name, name, "explicit-implicit"), "pair": "run",
                         "error": f"run on '{name}' did not complete: {r['message']}"})
    for a, b in itertools.combinations(sorted(runs), 2):
        ra, rb = runs[a], runs[b]
        kind = pair_kind(kinds[a], kinds[b])
        if not (ra["ok"] and rb["ok"]):
            continue
        rows.append(_row(label, label, a, b, kind, _metrics(ra["t"], ra["y"], rb["t"], rb["y"])))
    if scene.type == "single-element":
        rows += _quasistatic_rows(label, scene, runs)
    return rows, runs


def _quasistatic_rows(label, scene, runs) -> list[dict]:
    """Single element against the numpy uniaxial-stress solution: force = nominal stress x face area."""
    from cfm_core.scene.builder import build_model
    from cfm_core.simulation.point import uniaxial

    model = build_model(scene)
    meta = model.meta
    t, lam, P, _ = uniaxial(model.material, meta["rate"], meta["stretch"], steps=400, hold=meta["hold"])
    force = P * meta["size"] ** 2
    rows = []
    for name, r in sorted(runs.items()):
        if r["ok"]:
            m = _metrics(r["t"], r["y"], t, force)
            rows.append(_row(label, label + " vs quasi-static uniaxial", "numpy (uniaxial)", name,
                             "quasistatic-scene", m))
    return rows
