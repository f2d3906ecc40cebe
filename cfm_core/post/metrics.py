"""Metrics of histories: peak, time of peak, contact duration, pulse width, loading and unloading
times (drop tests), peak reaction (element tests), and the comparison of two histories
(relative L2, peak and time-of-peak differences). Times in s, accelerations in m/s^2.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .histories import G0, _finite

#: Raw acceleration above this fraction of the raw peak counts as contact (round-off guard).
CONTACT_FRACTION_RAW = 1e-9
#: A record whose last raw sample is above this fraction of its raw peak ends in contact (cut short;
#: the run checks' own threshold on the contact force, cfm_core.simulation.checks.check_result). A
#: viscoelastic specimen still pressing on a 10 ug impactor with 2.5e-9 of the peak counted as cut
#: short at CONTACT_FRACTION_RAW, which hid a one-sample spike of 8 000 g filtered to 444 g.
CUT_SHORT_FRACTION = 1e-6
#: Without a raw signal, filtered acceleration above this fraction of its peak counts as contact.
CONTACT_FRACTION_FILTERED = 0.01
#: Level (fraction of the filtered peak) defining the pulse width, loading and unloading times.
PULSE_FRACTION = 0.05


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


def _contact_time(t: np.ndarray, a_raw: np.ndarray) -> float | None:
    """t[k1] - t[k0] (s), k0 and k1 the first and last samples with a_raw > CONTACT_FRACTION_RAW
    max(a_raw); None when a_raw is never positive."""
    on = np.flatnonzero(a_raw > CONTACT_FRACTION_RAW * float(np.max(a_raw)))
    return float(t[on[-1]] - t[on[0]]) if on.size else None


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
        duration = _contact_time(t, r)
        if duration is None:
            raise InputError("a_raw is never positive: no contact to time (max a_raw <= 0 m/s^2).")
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


#: Filtered / raw peak below which the CFC filter is said to cut the pulse (-): an explicit run's
#: raw peak carries some ringing (the paper's 8 mm drop test: 56.9 g raw, 56.7 g CFC 600).
FILTER_KEEPS = 0.8
#: A raw peak at most this many samples wide at half its height is a spike the sampling does not
#: resolve: its raw height depends on the output rate (each raw sample is a box average over one
#: output interval).
SPIKE_SAMPLES = 2


def _half_height_samples(a: np.ndarray) -> int:
    """The samples of the run around the maximum of ``a`` that stay at or above half of it."""
    k = int(np.argmax(a))
    below = a < 0.5 * a[k]
    before = np.flatnonzero(below[:k])
    after = np.flatnonzero(below[k:])
    first = int(before[-1]) + 1 if before.size else 0
    last = k + int(after[0]) - 1 if after.size else a.size - 1
    return last - first + 1


def filter_warning(t, a_raw, a_filtered, cfc: float) -> str | None:
    """A warning when the channel-class filter removes much of the raw peak, saying what the record
    shows as the cause: the raw peak's width at half its height, measured in samples.

    The filtered peak (peak_g, as SAE J211 and the paper report it) is then well below the raw one
    and says less than the run shows. The cause named is the one measured: a raw peak at most
    :data:`SPIKE_SAMPLES` samples wide at half its height is a spike the sampling does not resolve
    (its raw height depends on the output rate; 20 m/s on the paper's 8 mm specimen: one sample of
    83 000 g at 50 kHz in 0.58 ms of contact); a wider one is a peak too short for the channel
    class (a half-sine pulse of 0.4 ms: 0.27 ms at half height, 13 samples at 50 kHz).

    Parameters
    ----------
    t : array_like, shape (n,)
        Times (s).
    a_raw, a_filtered : array_like, shape (n,)
        Raw and CFC-filtered acceleration (m/s^2, positive decelerating).
    cfc : float
        The channel frequency class (Hz).

    Returns
    -------
    str or None
        The warning (both peaks in g, the raw peak's width at half height in samples and ms, the
        output rate, the contact time), or None when the filtered peak is at least
        :data:`FILTER_KEEPS` of the raw one, or when the record ends in contact (cut short, which
        the run checks say). At 20 m/s on the paper's 8 mm specimen, 83 000 g raw and 9 900 g
        filtered were reported as 9 900 g without a word.
    """
    t, a_raw = np.asarray(t, dtype=np.float64), np.asarray(a_raw, dtype=np.float64)
    raw, filtered = float(np.max(a_raw)), float(np.max(a_filtered))
    if not raw > 0.0 or filtered >= FILTER_KEEPS * raw:
        return None
    if float(a_raw[-1]) > CUT_SHORT_FRACTION * raw:
        return None  # a record ending in contact: cut short, which the run checks say, not a short pulse
    contact = _contact_time(t, a_raw)
    n = _half_height_samples(a_raw)
    h = float(np.median(np.diff(t)))
    head = (f"the CFC {cfc:g} filter keeps {100 * filtered / raw:.0f} % of the raw peak ({filtered / G0:.4g} g of "
            f"{raw / G0:.4g} g): ")
    if n <= SPIKE_SAMPLES:
        return head + (f"the raw peak is a spike {n} sample{'s' if n > 1 else ''} wide at half its height "
                       f"({1e3 * n * h:.3g} ms at the output rate of {1.0 / h:.6g} Hz; {1e3 * contact:.3g} ms of "
                       f"contact), which the sampling does not resolve: its raw height depends on the output rate, "
                       f"and the channel class removes it, so peak_g (filtered, as SAE J211 reports it) leaves it "
                       f"out. A higher [scene] output_rate resolves the spike in the a_raw column (filter it with a "
                       f"higher class, cfm_core.post.filters.cfc_filter, to keep it).")
    return head + (f"the raw peak is {1e3 * n * h:.3g} ms wide at half its height ({n} samples at "
                   f"{1.0 / h:.6g} Hz; {1e3 * contact:.3g} ms of contact), too short for this channel class, so "
                   f"peak_g (filtered, as SAE J211 reports it) understates the impact; read the a_raw column (or "
                   f"filter it with a higher class, cfm_core.post.filters.cfc_filter).")


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


def velocity_change(t, a) -> float:
    """The velocity change int a dt (m/s) of an acceleration history a (m/s^2) at times t (s), trapezoid
    rule; shapes (n,)."""
    trapezoid = getattr(np, "trapezoid", None) or np.trapz  # numpy < 2 names it trapz
    return float(trapezoid(a, t))


def unit_hint(ratio: float) -> str:
    """The likely unit slip behind an acceleration curve whose velocity change int a dt is ``ratio``
    times the expected one (an impact stops the impactor: 1 - 2 x its speed): a in g gives about
    0.1 x (or a curve cut short), t in ms or a in mm/s^2 about 1000 x, a negative ratio a sign slip. A
    sentence or two, or ""
    for a ratio within 0.3 - 3."""
    if 0.3 <= ratio <= 3.0:
        return ""
    if 0.03 <= ratio < 0.3:
        return (" Is a in g? It must be in m/s^2 (multiply by 9.80665). Or does the curve end before the pulse"
                " does (a record cut short, or the impactor's speed in the scene too high)?")
    if ratio > 3.0:
        return " Is t in ms or a in mm/s^2? t must be in s and a in m/s^2."
    return " Is a positive when the impactor decelerates, and in m/s^2?"


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
def reaction_metrics(t, force) -> dict:
    """Figures of a reaction-force history t (s), force (N): the largest |force| (N, signed) and
    when (s), the final force (N), and final / largest (-), the relaxed fraction of a hold."""
    k = int(np.argmax(np.abs(force)))
    peak = float(force[k])
    return {"peak_force": peak, "t_peak_force": float(t[k]), "final_force": float(force[-1]),
            "final_over_peak": float(force[-1] / peak) if peak != 0.0 else 0.0}


