"""Summaries of finished runs (summary.json): metrics, run statistics and units for every key."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, NumericalError
from .histories import _finite, acceleration_histories
from .metrics import drop_test_metrics, reaction_metrics


SUMMARY_UNITS = {
    "peak_g": "g (9.80665 m/s^2)", "t_peak": "s", "duration": "s", "pulse_width": "s",
    "loading_time": "s", "unloading_time": "s", "t5_start": "s", "t5_end": "s", "steps": "-",
    "elements": "-", "wall_time": "s", "energy_error": "-", "hourglass_ratio": "- (null: n/a, see hourglass_ratio_note)",
    "hourglass_ratio_note": "text",
    "energy_error_note": "text (what the energy balance leaves out, or why there is none)", "dt_min": "s",
    "dt_max": "s", "sample_rate": "Hz", "cfc": "Hz", "impactor_mass": "kg", "thickness": "m",
    "element_size": "m", "velocity": "m/s", "peak_force": "N", "t_peak_force": "s", "final_force": "N",
    "final_over_peak": "-", "compile_time": "s", "hourglass_coefficient": "-", "newton_iterations": "-",
    "rejected_steps": "-", "threads": "- (threads the run used)",
    "vector_width": "bit (numba's preferred SIMD width; 0: no AVX-512 on the CPU)", "penetration_ratio": "- (largest penetration / element size)",
    "warnings": "text (run checks that passed with a warning: hourglass, energy balance, contact at the end, inertia)", "size": "m", "stretch": "-", "load_time": "s", "hold": "s", "rate": "1/s",
}


def _jsonable(key: str, v):
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        if not math.isfinite(float(v)):
            raise NumericalError(f"summary value {key!r} = {v!r} is not finite; refusing to report it.", quantity=key)
        return float(v)
    if isinstance(v, str) or v is None:
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_jsonable(key, x) for x in (v.tolist() if isinstance(v, np.ndarray) else v)]
    if isinstance(v, dict):
        return {str(k): _jsonable(f"{key}.{k}", x) for k, x in v.items()}
    raise InputError(f"model_info[{key!r}] = {v!r} is not JSON-serialisable; use numbers, strings, lists or dicts.")


def summarize(result, model_info: dict, histories: tuple | None = None) -> dict:
    """Summary of a drop-test run for summary.json (plain JSON types, never NaN or inf).

    model_info must hold ``impactor_mass`` (kg, full impactor); optional ``sample_rate`` (Hz,
    default 50 000), ``cfc`` (Hz, default 600) and ``elements`` (count; else result.info's);
    every other entry (e.g. thickness in m, element_size in m, velocity in m/s) is copied as is
    (a ``units`` dict in model_info is merged into the summary's).
    Keys: the :func:`drop_test_metrics` of the CFC-filtered acceleration (duration from the raw
    signal), steps, elements, wall_time (s), energy_error and hourglass_ratio (-, left out when
    the backend recorded no energies, then ``energy_error_note`` says why (``result.info["energy_note"]``,
    which otherwise says what the balance leaves out); hourglass_ratio None with a ``hourglass_ratio_note``
    when ``result.info["hourglass_control"]`` is False: a backend without hourglass modes, or
    ``result.info["hourglass_note"]`` (that text): a backend that reports no hourglass energy),
    dt_min/dt_max (s, when finite), backend, model_info (among
    it "warnings": the run checks' warnings, :mod:`cfm_core.simulation.checks`, text) and "units".
    Non-finite histories raise NumericalError. ``histories``: (t, a_raw, a_cfc) already computed
    by :func:`cfm_core.post.acceleration_histories` with the same mass, rate and CFC (not
    recomputed); None computes them.
    """
    if "impactor_mass" not in model_info:
        raise InputError("model_info needs 'impactor_mass' (kg, full impactor mass, e.g. 0.220).")
    rate = float(model_info.get("sample_rate", 50_000.0))
    cfc = float(model_info.get("cfc", 600.0))
    t, a_raw, a_cfc = histories or acceleration_histories(result, model_info["impactor_mass"], rate, cfc)
    out = drop_test_metrics(t, a_cfc, a_raw)
    out.update(sample_rate=rate, cfc=cfc)
    return _finish_summary(result, out, model_info)


def _finish_summary(result, out: dict, model_info: dict) -> dict:
    """Add the run's figures (steps, wall time, energies, step sizes, backend) and model_info to
    ``out``; JSON-able values with their units (the one place both summaries share)."""
    for name, e in result.energies.items():
        _finite(f"result.energies[{name!r}]", e)
    out.update(steps=int(result.steps), wall_time=float(result.wall_time), backend=str(result.backend))
    elements = model_info.get("elements", result.info.get("elements"))
    if elements is not None:
        out["elements"] = int(elements)
    if result.energies:
        out["energy_error"] = result.energy_error()
        if result.info.get("energy_note"):
            out["energy_error_note"] = str(result.info["energy_note"])
        if result.info.get("hourglass_note"):  # a backend with hourglass modes that reports no hourglass energy
            out["hourglass_ratio"] = None
            out["hourglass_ratio_note"] = str(result.info["hourglass_note"])
        elif result.info.get("hourglass_control", True):
            out["hourglass_ratio"] = result.hourglass_ratio()
        else:  # fully integrated elements: no hourglass modes, so no hourglass energy to compare
            out["hourglass_ratio"] = None
            out["hourglass_ratio_note"] = (f"n/a: backend '{result.backend}' has no hourglass control (its elements "
                                           f"are fully integrated, without hourglass modes), so it has no hourglass "
                                           f"energy")
    else:
        out["energy_error_note"] = ("n/a: " + str(result.info.get("energy_note") or f"backend '{result.backend}' "
                                    f"recorded no energies"))
    for name in ("dt_min", "dt_max"):
        v = float(getattr(result, name))
        if math.isfinite(v):
            out[name] = v
    for k, v in model_info.items():
        if k not in out:
            out[k] = v
    out = {k: _jsonable(k, v) for k, v in out.items()}
    units = {k: u for k, u in SUMMARY_UNITS.items() if k in out}
    units.update(out.get("units") or {})  # units given in model_info win
    out["units"] = units
    return out


def summarize_reaction(result, t, force, model_info: dict | None = None) -> dict:
    """Summary of a prescribed-motion run for summary.json: :func:`reaction_metrics` of t (s) and
    force (N) from :func:`reaction_histories`, the run's figures as in :func:`summarize` and
    model_info (copied; a ``units`` dict is merged)."""
    return _finish_summary(result, reaction_metrics(t, force), dict(model_info or {}))
