"""Measured drop-test curves: reading, checking and putting them on the simulation's grid.

A curve is a CSV with a header naming columns ``t`` (s, from first contact: samples before t = 0
are ignored) and ``a`` (m/s^2, positive when the impactor decelerates), any sampling, rows in
time order, the whole pulse until separation. It is put on the simulation's grid exactly as a
simulated history: box average on the 50 kHz grid (:func:`cfm_core.post.acceleration_histories`),
then SAE J211 CFC 600 (:func:`cfm_core.post.cfc_filter`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..errors import InputError
from ..post import acceleration_histories
from ..post.metrics import unit_hint, velocity_change
from ..tables import read_table

#: Fewest samples a measured curve must have (rows after t >= 0).
MIN_POINTS = 10
#: Channel frequency class of the filter applied to measured and simulated curves (SAE J211/1).
CFC = 600.0


@dataclass(frozen=True)
class Curve:
    """A measured history on the simulation grid: t (s), a (m/s^2, CFC-filtered), the file."""

    name: str
    path: str
    thickness: float
    t: np.ndarray
    a: np.ndarray
    notes: tuple = ()  # warnings about the file (e.g. sampled below 10 x CFC), carried into the fit's
    samples: float = 0.0  # independent samples of the record (independent_samples); 0: unknown, every grid point
    late: str = ""  # the record starts after contact began (:func:`starts_in_contact`): the fit's intervals are withheld

    @property
    def peak(self) -> float:
        """Largest filtered measured acceleration (m/s^2), the residual scale."""
        return float(np.max(self.a))


# ----------------------------------------------------------------------------- measured data
def parse_data_spec(spec: str, default_thickness: float | None) -> tuple[str, float]:
    """``file.csv:0.005`` -> (file, thickness in m); without ``:thickness`` the default is used.

    default_thickness: the --scene file's thickness (m), or None (then a thickness is required).
    """
    path, sep, tail = str(spec).rpartition(":")
    thickness = None
    if sep and path:
        try:
            thickness = float(tail)
        except ValueError:
            path = spec  # a ':' that is part of the path, or a malformed thickness after the file
            _refuse_malformed_suffix(spec)
    else:
        path = spec
    if thickness is None:
        if default_thickness is None:
            raise InputError(f"--data {spec}: no specimen thickness; give it as {path}:THICKNESS in m "
                             f"(e.g. {path}:0.005 for 5 mm), or give a --scene whose thickness applies.")
        thickness = default_thickness
    if not (math.isfinite(thickness) and 1e-4 <= thickness <= 0.1):
        hint = f" (in m: {thickness:g} mm is {thickness / 1e3:g} m)" if 1.0 <= thickness <= 100.0 else ""
        raise InputError(f"--data {spec}: thickness {thickness!r} m is not allowed; it must be a number "
                         f"with 1e-4 <= thickness <= 0.1 m, the specimen's thickness{hint}.")
    return path, thickness


def _refuse_malformed_suffix(spec: str) -> None:
    """InputError when ``spec`` is no file but begins with one followed by ':' and something that is
    not one thickness (``d8.csv:abc``, ``d8.csv:``, ``d8.csv:0.008:x``): the file exists, the
    thickness is what is wrong, and "the file does not exist" would send the user the wrong way."""
    if Path(spec).exists():
        return
    head = spec
    while ":" in head:
        head = head.rpartition(":")[0]
        if head and Path(head).is_file():
            raise InputError(f"--data {spec}: after the file {head} comes {spec[len(head):]!r}, which is not "
                             f"':THICKNESS' (one number in m, e.g. {head}:0.005 for 5 mm); or leave it out for the "
                             f"--scene file's thickness.")


def read_measured(path) -> tuple[np.ndarray, np.ndarray]:
    """A measured curve from a CSV file (:func:`cfm_core.tables.read_table` rules).

    Parameters
    ----------
    path : str or Path
        CSV with columns t (s, from first contact) and a (m/s^2, positive decelerating), other
        columns ignored; units may be written (``t [s],a [m/s^2]``); UTF-8 with or without BOM;
        lines starting with '#' and blank lines skipped.

    Returns
    -------
    t : ndarray, shape (n,)
        Times (s) at t >= 0.
    a : ndarray, shape (n,)
        Accelerations (m/s^2).

    Raises
    ------
    InputError
        Naming the file and line: encoding, header, non-finite values, t not increasing, or
        fewer than MIN_POINTS rows at t >= 0.
    """
    table = read_table(path, ("t", "a"), {"t": "s", "a": "m/s^2"}, what="data file")
    t, a = table.column("t"), table.column("a")
    keep = t >= 0.0
    if keep.sum() < MIN_POINTS:
        raise InputError(f"data file '{path}' has {int(keep.sum())} rows at t >= 0 s; at least {MIN_POINTS} are "
                         f"needed (t is the time from first contact, s).")
    return t[keep], a[keep]


#: A step between samples above this many times the median (and above 1 / (10 CFC)) is a gap.
GAP = 4.0
#: Velocity change int a dt of a measured curve over the scene's impact speed allowed: an impact stops the
#: impactor and at most throws it back (1 - 2); below 0.7 the curve is cut short or the speed is not in m/s
#: (3.6 for 1 m/s, written in km/h, read 0.44 and the fit failed at k1 = 1.6e-20 Pa without naming it).
DV_LOW = 0.7
DV_HIGH = 3.0
#: A measured curve below this fraction of its peak for more than LEAD_FRACTION of the time to its
#: peak starts before contact (warned): the Table 1 drop test reaches 1 % of its peak at 3 % of that time.
LEAD_LEVEL = 0.01
LEAD_FRACTION = 0.15


def check_plausible(path, t: np.ndarray, a: np.ndarray, velocity: float, end_time: float, cfc: float = CFC) -> list[str]:
    """InputError when a measured curve cannot be a drop test of the scene (units, sampling); the
    warnings for one that can but biases a fit.

    Parameters
    ----------
    path : str
        The file (for messages).
    t, a : ndarray, shape (n,)
        Times (s) and accelerations (m/s^2) at t >= 0, as read.
    velocity : float
        The scene's impact speed (m/s).
    end_time : float
        The scene's end time (s): a bound on the duration of the pulse.
    cfc : float
        Channel frequency class (Hz) of the filter applied to the curve.

    Returns
    -------
    list of str
        A warning when the curve stays below LEAD_LEVEL of its peak for more than LEAD_FRACTION of
        the time to its peak (recorded from before contact); a warning when the samples are coarser
        than SAE J211/1's 1 / (10 CFC) but within the
        refusal limit: the linear interpolation before the filter then biases a fit (a noise-free twin
        of the Table 1 drop test, fitted from the truth: k1 +1.8 % at 5 kHz, +7.8 % at 2.5 kHz, +30 %
        at 1.26 kHz, with intervals that exclude the truth).

    Raises
    ------
    InputError
        - duration: the curve lasts longer than 10 x the scene's end time (t in ms?);
        - sampling: the median step is coarser than 1 / (2 CFC) (t in ms, or too coarse for the filter);
        - gap: a step between samples above GAP x the median and 1 / (10 CFC) (missing samples);
        - peak: the velocity change int a dt is not within DV_LOW - DV_HIGH (0.7 - 3) x the impact speed (an impact
          stops the impactor and at most throws it back: 1 - 2 x; a in g gives about 0.1 x, t in ms 1000 x).

    Notes
    -----
    The momentum balance of the impactor: int a dt over the pulse equals its change of speed,
    v (1 + e) with the coefficient of restitution 0 <= e <= 1.
    """
    span = float(t[-1] - t[0])
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    ms = (" Is t in ms? The time column must be in s (divide it by 1000, or write the header 't [ms]' "
          "to be told so).")
    if span > 10.0 * end_time:
        raise InputError(f"data file '{path}': the curve lasts {span:g} s, but this drop test ends by {end_time:g} s "
                         f"(an impact lasts milliseconds).{ms}")
    if step > 0.5 / cfc:
        raise InputError(f"data file '{path}': the samples are {step:g} s apart (median), too coarse for the CFC "
                         f"{cfc:g} filter (at most {0.5 / cfc:g} s; SAE J211/1 asks for at least 10 x CFC = "
                         f"{10 * cfc:g} samples per s).{ms}")
    gaps = np.flatnonzero(np.diff(t) > max(GAP * step, 0.1 / cfc))
    if gaps.size:
        k = int(gaps[0])
        raise InputError(f"data file '{path}': no samples between t = {float(t[k]):.6g} s and {float(t[k + 1]):.6g} s "
                         f"({gaps.size} such gap{'s' if gaps.size > 1 else ''} in the file), "
                         f"{float(t[k + 1] - t[k]) / step:.3g} x the median step {step:g} s and more than SAE "
                         f"J211/1's 1 / (10 CFC) = {0.1 / cfc:g} s: the curve would be joined by a straight line "
                         f"there, which cuts a peak (a 1.2 ms gap at the peak of a drop test: 116 g read as 68 g). "
                         f"Give the curve without gaps.")
    dv = velocity_change(t, a)
    ratio = dv / velocity if velocity > 0 else float("nan")
    if not (DV_LOW <= ratio <= DV_HIGH):
        hint = unit_hint(ratio) or (f" Does the curve end before the impactor stopped (a record cut short), or is the "
                                    f"scene's speed too high (in km/h? {velocity:g} km/h is {velocity / 3.6:.4g} m/s)?")
        raise InputError(f"data file '{path}': the curve's velocity change int a dt = {dv:.4g} m/s is {ratio:.3g} times "
                         f"the scene's impact speed {velocity:g} m/s; an impact that stops the impactor gives 1 to 2 "
                         f"times ({DV_LOW:g} to {DV_HIGH:g} allowed).{hint}")
    notes = []
    k_peak = int(np.argmax(a))
    rise = np.flatnonzero(a[:k_peak + 1] > LEAD_LEVEL * a[k_peak])
    lead = float(t[rise[0]] - t[0]) if rise.size else 0.0
    if lead > LEAD_FRACTION * float(t[k_peak] - t[0]):
        notes.append(f"data file '{path}': the curve stays below {100 * LEAD_LEVEL:g} % of its peak until t = "
                     f"{float(t[rise[0]]):.4g} s, {100 * lead / float(t[k_peak] - t[0]):.3g} % of the time to its "
                     f"peak; the simulation starts at first contact (t = 0), where a drop test reaches "
                     f"{100 * LEAD_LEVEL:g} % of its peak within a few per cent of that time. If the recording "
                     f"starts before contact, shift its t column so that t = 0 is the contact: a late curve biases "
                     f"the fit.")
    if step > 0.1 / cfc:
        return notes + [f"data file '{path}': the samples are {step:g} s apart (median, {1.0 / step:.4g} per s), below SAE "
                f"J211/1's 10 x CFC = {10 * cfc:g} per s: the curve is interpolated linearly before the CFC {cfc:g} "
                f"filter, which flattens its peak and biases the fitted parameters beyond their intervals (a "
                f"noise-free 1.26 kHz copy of the Table 1 drop test fitted k1 30 % high). Record or export the "
                f"curve at {10 * cfc:g} samples per s or more."]
    return notes


#: A record whose first START_SAMPLES samples average above START_LEVEL of its peak, and that rises
#: by more than START_LEVEL of its peak over the next RISE_SAMPLES, starts after contact began.
START_LEVEL = 0.01
START_SAMPLES = 3
RISE_SAMPLES = 8


def starts_in_contact(path, t: np.ndarray, a: np.ndarray) -> str:
    """A warning when a measured record starts after the impact began (its first samples already
    above :data:`START_LEVEL` of the peak and rising), else "".

    The simulation starts at first contact (t = 0), where the Table 1 drop test's deceleration is 0
    and reaches 1 % of its peak only at 3 % of the time to it. A record cut 0.2 ms after contact
    misses under 2 % of the peak, yet the fit shifted k1 by 21 % and k2 by 26 % with intervals that
    excluded the truth. A constant offset before contact is level, not rising, and is not named here.

    Parameters
    ----------
    path : str
        The file (for the message).
    t, a : ndarray, shape (n,)
        Times (s) and accelerations (m/s^2), as read.

    Returns
    -------
    str
        The warning, or "".
    """
    peak = float(np.max(a)) if a.size else 0.0
    if not peak > 0.0 or a.size < START_SAMPLES + RISE_SAMPLES:
        return ""
    first = float(np.mean(a[:START_SAMPLES]))
    then = float(np.mean(a[START_SAMPLES:START_SAMPLES + RISE_SAMPLES]))
    if first > START_LEVEL * peak and then > first + START_LEVEL * peak:
        return (f"data file '{path}': the record starts in contact: its first samples are already at "
                f"{100 * first / peak:.2g} % of the peak and rising (t = {float(t[0]):.4g} s), while the "
                f"simulation starts at first contact with zero acceleration; the missing start shifts the fitted "
                f"parameters (0.2 ms missing: k1 +21 %), so no interval is given. Give the record from before "
                f"contact, with t = 0 at the contact.")
    return ""


@functools.lru_cache(maxsize=8)
def independent_rate(cfc: float = CFC) -> float:
    """Independent samples per second of white noise after the SAE J211 CFC ``cfc`` filter: rate / k, k =
    (sum h)^2 / sum h^2 the sum of the filtered noise's autocorrelation coefficients in samples (h the
    filter's impulse response at a rate well above the filter's band; the result does not depend on it).
    CFC 600: about 2 077 per s (about 24 of the 50 kHz grid's samples carry one sample's information)."""
    from ..post.filters import cfc_filter

    rate = 50.0 * cfc * 5.0 / 3.0
    x = np.zeros(int(rate * 0.2) | 1)
    x[x.size // 2] = 1.0
    h = cfc_filter(x, rate, cfc)
    return float(rate * np.sum(h ** 2) / np.sum(h) ** 2)


def independent_samples(t: np.ndarray, duration: float, cfc: float = CFC) -> float:
    """Independent samples of a measured record over [0, duration] (s) once filtered: its rows there, or
    duration x :func:`independent_rate` where that is fewer (a record sampled above the filter's band).
    The fit's intervals count these, not the grid's points (:func:`cfm_core.studies.calibrate.confidence`)."""
    rows = int(np.count_nonzero((t >= 0.0) & (t <= duration)))
    return float(min(rows, independent_rate(cfc) * duration))


def read_curve(spec: str, default_thickness: float | None, rate: float = 50_000.0, cfc: float = CFC,
               scene=None) -> Curve:
    """A measured curve from ``file.csv[:thickness]`` on the grid k / rate, CFC-filtered; with a drop-test
    ``scene``, checked for plausibility against it (:func:`check_plausible`)."""

    path, thickness = parse_data_spec(spec, default_thickness)
    t, a = read_measured(path)
    notes, late = [], starts_in_contact(path, t, a)
    if scene is not None:
        notes = check_plausible(path, t, a, scene.impactor.speed, float(scene.end_time), cfc)  # |v| of a vector too
    if late:
        notes.append(late)
    # Box average of the (linearly interpolated) signal on the grid: the same resampling as a
    # simulated contact force, with mass 1 kg and the signal as the "force".
    grid, _, a_cfc = acceleration_histories(SimpleNamespace(t=t, impulse=None, contact_force=a), 1.0, rate, cfc)
    if not np.max(a_cfc) > 0.0:
        raise InputError(f"data file '{path}': the filtered acceleration is never positive; a is positive "
                         f"when the impactor decelerates (m/s^2): flip its sign.")
    samples = independent_samples(t, float(grid[-1] - grid[0]) + 1.0 / rate, cfc)
    return Curve(Path(path).stem, path, thickness, grid, a_cfc, tuple(notes), samples, late)


def read_curves(specs, scene, scene_given: bool) -> list[Curve]:
    """The curves of ``--data`` specs; names made unique; the same (file, thickness) twice is an error."""
    if not specs:
        raise InputError("give at least one --data FILE.csv[:THICKNESS] (t in s, a in m/s^2).")
    if scene.type != "drop-test":
        raise InputError(f"the scene is a '{scene.type}' scene; measured acceleration curves are fitted with drop "
                         f"tests: give a drop-test scene (--scene; the built-in 'drop-test' by default). Stress-strain "
                         f"and relaxation curves are fitted with 'cfm fit'.")
    default = scene.specimen.thickness if scene_given else None
    rate = float(scene.settings.output_rate)
    curves, seen, names = [], set(), {}
    for spec in specs:
        c = read_curve(spec, default, rate, scene=scene)
        key = (str(Path(c.path).resolve()), c.thickness)
        if key in seen:
            raise InputError(f"--data {spec}: this file is given twice with thickness {c.thickness:g} m; "
                             f"give each measurement once.")
        seen.add(key)
        names[c.name] = names.get(c.name, 0) + 1
        name = c.name if names[c.name] == 1 else f"{c.name}-{names[c.name]}"
        curves.append(Curve(name, c.path, c.thickness, c.t, c.a, c.notes, c.samples, c.late))
    return curves
