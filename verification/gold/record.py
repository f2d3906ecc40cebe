"""Run a gold case and reduce it to its stored values; compare two records.

A record (JSON-able dict): ``kind`` ("point" or the scene type), ``steps`` (time steps, or rows of
a point history), ``dt_min``/``dt_max`` (s), ``energies`` (J, final value and largest magnitude of
each energy), ``energy_error`` (-), ``peak``/``t_peak``/``final`` of the signal (Pa for points:
the largest stress-tensor norm; N reaction force; m/s^2 CFC 600 acceleration), ``samples``
(the signal at 12 evenly spaced times), and for drop tests the summary's peak_g (g), t_peak,
duration, loading and unloading times (s) and hourglass ratio (-).
"""

from __future__ import annotations

import math

import numpy as np

from cfm_core.errors import InputError

from .. import histories

N_SAMPLES = 12
SUMMARY_KEYS = ("peak_g", "t_peak", "duration", "loading_time", "unloading_time", "hourglass_ratio")


def point_inputs(case):
    """(material, t (s), F) of a point case."""
    from cfm_core.material.registry import make_material

    o = case.overrides
    mat = make_material(o["material"], elastic=o["elastic"], moduli=o["moduli"])
    t, F = histories.AGREEMENT[o["history"]]()
    return mat, t, F


def scene_of(case):
    from cfm_core.scene.scene import builtin_scene

    return builtin_scene(case.scene).with_overrides(**case.overrides) if case.overrides else builtin_scene(case.scene)


def run_case(case) -> tuple[dict, dict]:
    """(record, raw) of one case; raw keeps what the independent checks need (histories, Result)."""
    from cfm_core.simulation.registry import get_backend

    if case.scene == "point":
        mat, t, F = point_inputs(case)
        s = np.asarray(get_backend(case.backend).point(mat, t, F), dtype=float)
        norm = np.linalg.norm(s, axis=1)
        k = int(np.argmax(norm))
        idx = np.linspace(0, t.size - 1, N_SAMPLES).astype(int)
        rec = {"kind": "point", "steps": int(t.size - 1), "dt_min": float(np.diff(t).min()),
               "dt_max": float(np.diff(t).max()), "peak": float(norm[k]), "t_peak": float(t[k]),
               "final": s[-1].tolist(), "samples": s[idx].tolist()}
        return rec, {"material": mat, "t": t, "F": F, "stress": s}
    from ..runs import run_scene

    scene = scene_of(case)
    run = run_scene(scene, case.backend, **case.options)
    if not run["ok"]:
        raise InputError(f"gold case {case.name}: the run did not complete ({run['status']}): {run['message']}")
    res = run["result"]
    t, y = np.asarray(run["t"], float), np.asarray(run["y"], float)
    k = int(np.argmax(np.abs(y)))
    ts = np.linspace(t[0], t[-1], N_SAMPLES)
    rec = {"kind": scene.type, "steps": int(res.steps), "dt_min": float(res.dt_min), "dt_max": float(res.dt_max),
           "energies": {n: {"final": float(e[-1]), "max_abs": float(np.max(np.abs(e)))}
                        for n, e in sorted((res.energies or {}).items())},
           "energy_error": float(run["energy_error"]), "peak": float(y[k]), "t_peak": float(t[k]),
           "final": float(y[-1]), "t_end": float(t[-1]), "samples": np.interp(ts, t, y).tolist()}
    if run["summary"]:
        rec["summary"] = {key: float(run["summary"][key]) for key in SUMMARY_KEYS
                          if run["summary"].get(key) is not None}  # None: n/a (no hourglass on skfem)
    return rec, {"scene": scene, "run": run}


def _num(a):
    return np.asarray(a, dtype=float)


def compare(new: dict, old: dict, rtol: float) -> list[str]:
    """Differences beyond ``rtol`` between two records, one line each (empty: equal).

    Scalars: |new - old| <= rtol |old|; arrays (samples, final stress): relative to the array's
    largest |old|; energies: relative to the case's largest energy; energy_error: relative to
    max(|stored|, 1e-3) (it is itself a relative error near round-off); step counts: rtol x old, at least
    exact; time steps and times: rtol relative."""
    out = []
    if new.get("kind") != old.get("kind"):
        return [f"kind {new.get('kind')} != stored {old.get('kind')}"]

    def scalar(key, a, b, scale=None):
        if a is None or b is None:
            if a is not b:
                out.append(f"{key}: {a!r} (stored {b!r})")
            return
        if isinstance(b, float) and not math.isfinite(b):
            if math.isfinite(a):
                out.append(f"{key}: {a!r} (stored {b!r})")
            return
        s = abs(b) if scale is None else scale
        if not abs(a - b) <= rtol * s:
            out.append(f"{key}: {a:.6g} (stored {b:.6g}, relative difference {(a - b) / (s or 1):+.2e})")

    for key in ("steps", "dt_min", "dt_max", "peak", "t_peak", "t_end"):
        if key in old or key in new:
            scalar(key, new.get(key), old.get(key))
    for key in ("final", "samples"):
        a, b = _num(new[key]), _num(old[key])
        if a.shape != b.shape:
            out.append(f"{key}: shape {a.shape} (stored {b.shape})")
            continue
        scale = float(np.abs(b).max()) or 1.0
        worst = float(np.abs(a - b).max()) / scale
        if not worst <= rtol:
            out.append(f"{key}: differs by {worst:.2e} of its largest value (limit {rtol:g})")
    if "energies" in old:
        scale = max([v["max_abs"] for v in old["energies"].values()] + [1e-300])
        for n, v in old["energies"].items():
            nv = new.get("energies", {}).get(n)
            if nv is None:
                out.append(f"energies[{n}]: missing")
                continue
            for key in ("final", "max_abs"):
                scalar(f"energies[{n}].{key}", nv[key], v[key], scale)
        scalar("energy_error", new.get("energy_error"), old.get("energy_error"), max(abs(old.get("energy_error") or 0.0), 1e-3))
    for key, b in old.get("summary", {}).items():
        scalar(f"summary.{key}", new.get("summary", {}).get(key), b)
    return out
