"""Run one scene on one backend and reduce it to a signal: the single place the suite calls solvers.

Signals: drop test -> impactor acceleration (m/s^2), 50 kHz box average filtered with SAE J211
CFC 600 (:func:`cfm_core.runs.drop_test`); single element -> reaction force (N) at the output
times. Runs are cached per (scene, backend, options) within one suite, so agreement, work-precision
and paper comparison share them. Errors are caught and returned, never raised: InputError and
NumericalError are "clear diagnostics"; anything else is a raw exception (a failure).
"""

from __future__ import annotations

import json
import math
import time
import traceback

import numpy as np

from cfm_core.errors import InputError, NumericalError


class RunCache:
    """Memo of finished runs keyed by (scene dict, backend, options)."""

    def __init__(self):
        self._runs: dict[str, dict] = {}

    def run(self, scene, backend: str, **options) -> dict:
        from cfm_core.scene.scene import scene_to_dict

        key = json.dumps([scene_to_dict(scene), backend, options], sort_keys=True, default=str)
        if key not in self._runs:
            self._runs[key] = run_scene(scene, backend, **options)
        return self._runs[key]


def _finite_outputs(result) -> str:
    """'' when every history of a Result is finite, else the name of the first that is not."""
    for name in ("t", "contact_force", "impulse", "acceleration", "impactor_z", "impactor_v", "reaction_force"):
        a = getattr(result, name, None)
        if a is not None and not np.isfinite(np.asarray(a, dtype=float)).all():
            return name
    for name, e in (result.energies or {}).items():
        if not np.isfinite(np.asarray(e, dtype=float)).all():
            return f"energies[{name}]"
    return ""


def run_scene(scene, backend: str, **options) -> dict:
    """Run and reduce; returns a dict: ok, status ("completed" | "diagnostic" | "exception" |
    "non-finite"), message, t (s), y (signal), unit, wall (s, solver only, else total), total (s),
    steps, energy_error (-), summary (drop test), result (the Result or None)."""
    from cfm_core.scene.builder import build_model
    from cfm_core.runs.pipeline import drop_test, run_model

    out = {"backend": backend, "options": options, "scene": scene.type, "ok": False, "status": "", "message": "",
           "t": None, "y": None, "unit": "", "wall": math.nan, "total": math.nan, "steps": 0,
           "energy_error": math.nan, "summary": None, "result": None}
    t0 = time.perf_counter()
    try:
        if scene.type == "drop-test":
            res = drop_test(scene, backend, **options)
            result, out["summary"] = res.result, res.summary
            out.update(t=res.t, y=res.a_cfc, unit="m/s^2")
        else:
            result = run_model(build_model(scene), backend, **options)
            if result.reaction_force is None:
                raise InputError(f"backend '{backend}' recorded no reaction force for a {scene.type} scene.")
            out.update(t=np.asarray(result.t, float), y=np.asarray(result.reaction_force, float), unit="N")
        bad = _finite_outputs(result)
        out.update(result=result, steps=int(result.steps), wall=float(result.wall_time),
                   energy_error=float(result.energy_error()))
        if bad or not np.isfinite(out["y"]).all():
            out.update(status="non-finite", message=f"non-finite values in {bad or 'the signal'} of a run "
                       f"that did not raise")
        else:
            out.update(ok=True, status="completed")
    except (InputError, NumericalError) as exc:
        out.update(status="diagnostic", message=f"{type(exc).__name__}: {exc}")
    except Exception as exc:  # a raw exception is a finding, reported with its origin
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        out.update(status="exception", message=f"{type(exc).__name__}: {exc} (at {tb.filename}:{tb.lineno})")
    out["total"] = time.perf_counter() - t0
    if not math.isfinite(out["wall"]):
        out["wall"] = out["total"]
    return out
