"""Backend-neutral post-processing of a :class:`cfm_core.results.Result` (drop-test histories).

Flow: result -> :func:`resample_acceleration` (uniform grid, no aliasing) -> SAE J211/1 CFC 600
(:func:`cfm_core.filters.cfc_filter`) -> :func:`drop_test_metrics` -> :func:`summarize`.
Acceleration is in m/s^2, positive when the impactor decelerates; times in s.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError, NumericalError
from .filters import cfc_filter

#: Standard gravity (m/s^2), used to express accelerations in g.
G0 = 9.80665
#: Raw acceleration above this fraction of the raw peak counts as contact (round-off guard).
CONTACT_FRACTION_RAW = 1e-9
#: Without a raw signal, filtered acceleration above this fraction of its peak counts as contact.
CONTACT_FRACTION_FILTERED = 0.01
#: Level (fraction of the filtered peak) defining the pulse width, loading and unloading times.
PULSE_FRACTION = 0.05


def _finite(name: str, a) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad.ravel()))
        raise NumericalError(f"{name} has {int(bad.sum())} non-finite value(s), first at index {i} "
                             f"({a.ravel()[i]!r}); refusing to post-process it.", quantity=name)
    return a


def _positive(name: str, value, unit: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise InputError(f"{name} = {value!r} {unit} is not allowed: it must be finite and > 0.")
    return v


def resample_acceleration(result, mass: float, rate: float = 50_000.0) -> tuple[np.ndarray, np.ndarray]:
    """Impactor acceleration on a uniform grid, box-averaged from the impulse (no aliasing).

    mass: impactor mass (kg, full model); rate: samples per second (Hz). Returns (t, a_raw):
    t_k = k h (s), h = 1/rate, k = 0 .. floor(t_end / h), t_end the last recorded time; and::

        a_raw(t_k) = [I(t_k + h/2) - I(t_k - h/2)] / (h mass)        (m/s^2)

    the mean contact force over [t_k - h/2, t_k + h/2] divided by the mass. I (N s) is
    ``result.impulse`` linearly interpolated in ``result.t``, 0 for t < 0, held after t_end (and
    ramped linearly from (0, 0) if the record starts after t = 0). If ``result.impulse`` is None,
    I is the trapezoid-rule integral of ``result.contact_force`` (N). Summing a_raw h mass gives
    back the total impulse. Raises InputError (bad mass, rate, times or missing histories) or
    NumericalError (non-finite histories).
    """
    mass = _positive("mass", mass, "kg")
    rate = _positive("rate", rate, "Hz")
    t = _finite("result.t", result.t)
    if t.ndim != 1 or t.size < 2:
        raise InputError(f"result.t must be 1-D with at least 2 times (s); got shape {t.shape}.")
    if t[0] < 0.0 or np.any(np.diff(t) < 0.0):
        raise InputError(f"result.t must start at t >= 0 s and never decrease; got t[0] = {t[0]!r} s.")
    if result.impulse is not None:
        impulse = _finite("result.impulse", result.impulse)
    elif result.contact_force is not None:
        force = _finite("result.contact_force", result.contact_force)
        if force.shape != t.shape:
            raise InputError(f"result.contact_force has shape {force.shape}, result.t {t.shape}; they must match.")
        impulse = np.concatenate(([0.0], np.cumsum(0.5 * (force[1:] + force[:-1]) * np.diff(t))))
    else:
        raise InputError("result has neither impulse nor contact_force: the backend must record one "
                         "of them for a drop test.")
    if impulse.shape != t.shape:
        raise InputError(f"result.impulse has shape {impulse.shape}, result.t {t.shape}; they must match.")
    if t[0] > 0.0:
        t = np.concatenate(([0.0], t))
        impulse = np.concatenate(([0.0], impulse))
    h = 1.0 / rate
    n = int(math.floor(t[-1] * rate * (1.0 + 1e-12))) + 1
    grid = np.arange(n) * h

    def I(tq):
        return np.interp(tq, t, impulse, left=0.0, right=impulse[-1])

    a_raw = (I(grid + 0.5 * h) - I(grid - 0.5 * h)) / (h * mass)
    return grid, a_raw


def acceleration_histories(result, mass: float, rate: float = 50_000.0, cfc: float = 600.0):
    """(t (s), a_raw (m/s^2), a_cfc (m/s^2)): :func:`resample_acceleration` then CFC filtering.

    mass (kg); rate (Hz); cfc (Hz). The filter pads with zeros (history zero outside the record).
    """
    t, a_raw = resample_acceleration(result, mass, rate)
    return t, a_raw, cfc_filter(a_raw, rate, cfc=cfc, pad="zero")


def _first_crossing(t: np.ndarray, a: np.ndarray, level: float) -> float:
    """Earliest time (s) at which a rises to ``level``, linearly interpolated between samples."""
    i = int(np.argmax(a >= level))
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - a[i - 1]) * (t[i] - t[i - 1]) / (a[i] - a[i - 1]))


def _last_crossing(t: np.ndarray, a: np.ndarray, level: float) -> float:
    """Latest time (s) at which a falls to ``level``, linearly interpolated between samples."""
    j = a.size - 1 - int(np.argmax(a[::-1] >= level))
    if j == a.size - 1:
        return float(t[-1])
    return float(t[j] + (a[j] - level) * (t[j + 1] - t[j]) / (a[j] - a[j + 1]))


def drop_test_metrics(t, a_filtered, a_raw=None) -> dict:
    """Pulse metrics of a filtered impactor acceleration history (m/s^2, positive decelerating).

    t (s), a_filtered (m/s^2), optional a_raw (m/s^2) on the same times. Returns (floats):

    - peak_g = max(a_filtered) / 9.80665 (g), at the sample of the maximum; t_peak (s) its time;
    - t5_start, t5_end (s): first rising and last falling crossing of 5 % of the peak
      (linear interpolation); pulse_width = t5_end - t5_start (s);
      loading_time = t_peak - t5_start (s); unloading_time = t5_end - t_peak (s);
    - duration (s), the contact time. With a_raw: t[k1] - t[k0], k0 and k1 the first and last
      samples with a_raw > 1e-9 max(a_raw) (box averages are exactly 0 without contact; the factor
      only rejects round-off), exact to within one sample spacing h. Without a_raw: time between
      the first and last crossings of 1 % of the filtered peak (interpolated); the filter's
      spread makes this only an estimate.
    """
    t = _finite("t", t)
    a = _finite("a_filtered", a_filtered)
    if t.ndim != 1 or a.shape != t.shape or t.size < 2:
        raise InputError(f"t and a_filtered must be 1-D of equal length >= 2; got {t.shape} and {a.shape}.")
    k = int(np.argmax(a))
    peak = float(a[k])
    if peak <= 0.0:
        raise InputError(f"a_filtered has no positive peak (max = {peak!r} m/s^2): there was no impact to measure.")
    t_peak = float(t[k])
    lo = PULSE_FRACTION * peak
    t5_start = _first_crossing(t, a, lo)
    t5_end = _last_crossing(t, a, lo)
    if a_raw is not None:
        r = _finite("a_raw", a_raw)
        if r.shape != t.shape:
            raise InputError(f"a_raw has shape {r.shape}, t {t.shape}; they must match.")
        on = np.flatnonzero(r > CONTACT_FRACTION_RAW * float(np.max(r)))
        if on.size == 0:
            raise InputError("a_raw is never positive: no contact to time (max a_raw <= 0 m/s^2).")
        duration = float(t[on[-1]] - t[on[0]])
    else:
        c = CONTACT_FRACTION_FILTERED * peak
        duration = _last_crossing(t, a, c) - _first_crossing(t, a, c)
    return {
        "peak_g": peak / G0,
        "t_peak": t_peak,
        "duration": float(duration),
        "pulse_width": t5_end - t5_start,
        "loading_time": t_peak - t5_start,
        "unloading_time": t5_end - t_peak,
        "t5_start": t5_start,
        "t5_end": t5_end,
    }


def relative_l2(a, b) -> float:
    """||a - b||_2 / ||b||_2 (-) for two arrays sampled at the same times (b is the reference)."""
    a = _finite("a", a)
    b = _finite("b", b)
    if a.shape != b.shape:
        raise InputError(f"relative_l2 needs arrays on common samples; got shapes {a.shape} and {b.shape}. "
                         "Use compare_histories for different time grids.")
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        raise InputError("relative_l2: the reference b is identically zero; the relative error is undefined.")
    return float(np.linalg.norm(a - b) / nb)


def compare_histories(t1, a1, t2, a2) -> dict:
    """Compare history (t1, a1) with the reference (t2, a2) (times in s, values in any one unit).

    Both are linearly interpolated onto a uniform grid over the overlap of their time ranges with
    the finer of the two median spacings. Returns rel_l2 (-) = ||a1 - a2|| / ||a2|| on that grid;
    peak_diff (-) = (p1 - p2) / |p2| with p the value of largest magnitude of each history on its
    own samples; t_peak_diff (s) = time of p1 - time of p2.
    """
    t1, a1, t2, a2 = (_finite(n, v) for n, v in (("t1", t1), ("a1", a1), ("t2", t2), ("a2", a2)))
    for name, t, a in (("1", t1, a1), ("2", t2, a2)):
        if t.ndim != 1 or a.shape != t.shape or t.size < 2 or np.any(np.diff(t) <= 0):
            raise InputError(f"history {name}: t{name} must be increasing, 1-D, length >= 2 and match a{name}.")
    start, end = max(t1[0], t2[0]), min(t1[-1], t2[-1])
    if end <= start:
        raise InputError(f"the histories do not overlap in time: [{t1[0]}, {t1[-1]}] s and [{t2[0]}, {t2[-1]}] s.")
    dt = min(float(np.median(np.diff(t1))), float(np.median(np.diff(t2))))
    n = int(math.ceil((end - start) / dt)) + 1
    grid = np.linspace(start, end, n)
    i1, i2 = int(np.argmax(np.abs(a1))), int(np.argmax(np.abs(a2)))
    if a2[i2] == 0.0:
        raise InputError("compare_histories: the reference history a2 is identically zero.")
    return {
        "rel_l2": relative_l2(np.interp(grid, t1, a1), np.interp(grid, t2, a2)),
        "peak_diff": float((a1[i1] - a2[i2]) / abs(a2[i2])),
        "t_peak_diff": float(t1[i1] - t2[i2]),
    }


#: Units of the keys :func:`summarize` writes (stored in summary.json under "units").
SUMMARY_UNITS = {
    "peak_g": "g (9.80665 m/s^2)", "t_peak": "s", "duration": "s", "pulse_width": "s",
    "loading_time": "s", "unloading_time": "s", "t5_start": "s", "t5_end": "s", "steps": "-",
    "elements": "-", "wall_time": "s", "energy_error": "-", "hourglass_ratio": "-", "dt_min": "s",
    "dt_max": "s", "sample_rate": "Hz", "cfc": "Hz", "impactor_mass": "kg", "thickness": "m",
    "element_size": "m", "velocity": "m/s", "peak_force": "N", "t_peak_force": "s", "final_force": "N",
    "final_over_peak": "-", "compile_time": "s", "hourglass_coefficient": "-", "newton_iterations": "-",
    "rejected_steps": "-", "penetration_ratio": "- (largest penetration / element size)", "size": "m", "stretch": "-", "load_time": "s", "hold": "s", "rate": "1/s",
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


def summarize(result, model_info: dict) -> dict:
    """Summary of a drop-test run for summary.json (plain JSON types, never NaN or inf).

    model_info must hold ``impactor_mass`` (kg, full impactor); optional ``sample_rate`` (Hz,
    default 50 000), ``cfc`` (Hz, default 600) and ``elements`` (count; else result.info's);
    every other entry (e.g. thickness in m, element_size in m, velocity in m/s) is copied as is
    (a ``units`` dict in model_info is merged into the summary's).
    Keys: the :func:`drop_test_metrics` of the CFC-filtered acceleration (duration from the raw
    signal), steps, elements, wall_time (s), energy_error and hourglass_ratio (-, left out when
    the backend recorded no energies), dt_min/dt_max (s, when finite), backend, model_info, and
    "units". Non-finite histories raise NumericalError.
    """
    if "impactor_mass" not in model_info:
        raise InputError("model_info needs 'impactor_mass' (kg, full impactor mass, e.g. 0.220).")
    rate = float(model_info.get("sample_rate", 50_000.0))
    cfc = float(model_info.get("cfc", 600.0))
    t, a_raw, a_cfc = acceleration_histories(result, model_info["impactor_mass"], rate, cfc)
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
        out["hourglass_ratio"] = result.hourglass_ratio()
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


def reaction_histories(result, model) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Histories of a prescribed-motion scene (single element, relaxation), at the result's times.

    Returns t (s), stretch (-) = 1 + u(t) / size of the prescribed face, reaction force (N, the
    z force on the prescribed face, negative in compression) and nominal stress (Pa) = force /
    size^2 (the undeformed face area). NumericalError on a non-finite history.
    """
    if result.reaction_force is None or model.prescribed is None:
        raise InputError(f"scene '{model.name}' has no prescribed motion, so no reaction force; "
                         f"reaction histories are for single-element and relaxation scenes.")
    t = _finite("result.t", result.t)
    force = _finite("result.reaction_force", result.reaction_force)
    size = float(model.meta["size"])
    u = np.interp(t, model.prescribed.times, model.prescribed.values)
    return t, 1.0 + u / size, force, force / size**2


def reaction_metrics(t, force) -> dict:
    """Figures of a reaction-force history t (s), force (N): the largest |force| (N, signed) and
    when (s), the final force (N), and final / largest (-), the relaxed fraction of a hold."""
    k = int(np.argmax(np.abs(force)))
    peak = float(force[k])
    return {"peak_force": peak, "t_peak_force": float(t[k]), "final_force": float(force[-1]),
            "final_over_peak": float(force[-1] / peak) if peak != 0.0 else 0.0}


def summarize_reaction(result, t, force, model_info: dict | None = None) -> dict:
    """Summary of a prescribed-motion run for summary.json: :func:`reaction_metrics` of t (s) and
    force (N) from :func:`reaction_histories`, the run's figures as in :func:`summarize` and
    model_info (copied; a ``units`` dict is merged)."""
    return _finish_summary(result, reaction_metrics(t, force), dict(model_info or {}))
