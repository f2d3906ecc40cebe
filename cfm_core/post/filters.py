"""SAE J211/1 channel-frequency-class (CFC) filter, as defined in the standard's Appendix C.

The filter is a 2-pole Butterworth low-pass (bilinear transform, pre-warped) run forward and then
backward over the data, which gives a phaseless 4-pole filter. For sampling period T (s) and
channel frequency class CFC (Hz)::

    wd = 2 pi CFC 2.0775                      (rad/s, design frequency of the 2-pole stage)
    wa = sin(wd T / 2) / cos(wd T / 2)        (pre-warped, dimensionless)
    D  = 1 + sqrt(2) wa + wa^2
    a0 = wa^2 / D,   a1 = 2 a0,   a2 = a0
    b1 = -2 (wa^2 - 1) / D
    b2 = (-1 + sqrt(2) wa - wa^2) / D
    Y[i] = a0 X[i] + a1 X[i-1] + a2 X[i-2] + b1 Y[i-1] + b2 Y[i-2]                    (C1)

One pass has |H(fd)|^2 = 1/2 at fd = 2.0775 CFC; the forward-backward pair has the magnitude
|H|^2, i.e. -6 dB at fd and -3 dB at about 1.667 CFC (1000 Hz for CFC 600).

Padding: a recursive filter needs a run-in before the first sample and a run-out after the last.
The histories filtered here start and end at zero (before first and after last contact), so the
default pads with zeros (``pad="zero"``); ``pad="edge"`` repeats the end values instead (for
signals that do not start or end at zero). The pad length on each side is ``PAD_PERIODS / CFC``
seconds (5/CFC, 8.3 ms for CFC 600). The stage's poles decay as exp(-wd t / sqrt(2)), i.e. by
exp(-2 pi 2.0775 5 / sqrt(2)) = exp(-46) ~ 1e-20 over the pad, below double round-off, so the
start/end transients do not reach the returned samples.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

#: Pad length on each side of the data, in periods of the CFC (pad duration = PAD_PERIODS / CFC s).
PAD_PERIODS = 5.0
#: Smallest sample rate accepted, as a multiple of the CFC (J211/1 recommends at least ~10x).
MIN_RATE_OVER_CFC = 10.0
#: Ratio of the 2-pole design frequency to the CFC (J211/1 Appendix C).
DESIGN_RATIO = 2.0775


def _positive_finite(name: str, value, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number in {unit}; got {value!r}. Pass a finite positive value.") from None
    if not math.isfinite(v) or v <= 0.0:
        raise InputError(
            f"{name} = {value!r} {unit} is not allowed: it must be finite and > 0. "
            f"Pass a finite positive value."
        )
    return v


def _check_rate(cfc: float, sample_rate: float) -> None:
    if sample_rate < MIN_RATE_OVER_CFC * cfc:
        raise InputError(
            f"sample_rate = {sample_rate:g} Hz is too low for CFC {cfc:g}: SAE J211/1 needs at least "
            f"{MIN_RATE_OVER_CFC:g} x CFC = {MIN_RATE_OVER_CFC * cfc:g} Hz (allowed range: "
            f">= {MIN_RATE_OVER_CFC * cfc:g} Hz). Resample the history faster (e.g. 50 kHz for CFC 600)."
        )


def cfc_coefficients(cfc: float, sample_rate: float) -> tuple[float, float, float, float, float]:
    """Coefficients (a0, a1, a2, b1, b2) (dimensionless) of the J211/1 2-pole stage, equation (C1).

    SAE J211/1 Appendix C (module docstring): bilinear transform with pre-warping at the design
    frequency 2.0775 CFC. In scipy's convention the stage is ``b = [a0, a1, a2]``,
    ``a = [1, -b1, -b2]``.

    Parameters
    ----------
    cfc : float
        Channel frequency class (Hz), e.g. 60, 180, 600, 1000; finite, > 0.
    sample_rate : float
        Samples per second (Hz), finite and at least 10 x CFC.

    Returns
    -------
    a0, a1, a2, b1, b2 : float
        The coefficients of (C1) (-).

    Raises
    ------
    InputError
        ``cfc`` or ``sample_rate`` is not a finite positive number, or ``sample_rate`` < 10 x CFC.
    """
    cfc = _positive_finite("cfc", cfc, "Hz")
    sample_rate = _positive_finite("sample_rate", sample_rate, "Hz")
    _check_rate(cfc, sample_rate)
    T = 1.0 / sample_rate
    wd = 2.0 * math.pi * cfc * DESIGN_RATIO
    wa = math.sin(wd * T / 2.0) / math.cos(wd * T / 2.0)
    s2 = math.sqrt(2.0)
    D = 1.0 + s2 * wa + wa * wa
    a0 = wa * wa / D
    a1 = 2.0 * a0
    a2 = a0
    b1 = -2.0 * (wa * wa - 1.0) / D
    b2 = (-1.0 + s2 * wa - wa * wa) / D
    return a0, a1, a2, b1, b2


def pad_length(cfc: float, sample_rate: float) -> int:
    """Number of padding samples on each side: ceil(PAD_PERIODS / CFC * sample_rate) (-).

    Parameters
    ----------
    cfc : float
        Channel frequency class (Hz), > 0 (not checked here).
    sample_rate : float
        Samples per second (Hz).

    Returns
    -------
    int
        Samples of padding per side (417 for CFC 600 at 50 kHz).
    """
    return int(math.ceil(PAD_PERIODS / cfc * sample_rate))


def cfc_filter(x, sample_rate: float, cfc: float = 600.0, pad: str = "zero") -> np.ndarray:
    """Filter the uniformly sampled history ``x`` with SAE J211/1 CFC ``cfc``; same shape and unit.

    Forward pass of (C1) (SAE J211/1 Appendix C) over the padded data, then the same recursion
    over the reversed output (phaseless, 4-pole), then the padding is cut away.

    Parameters
    ----------
    x : array_like, shape (n,)
        Non-empty, finite history (any unit, e.g. m/s^2) sampled at ``sample_rate``.
    sample_rate : float
        Samples per second (Hz), >= 10 x CFC (50 kHz in the drop test).
    cfc : float
        Channel frequency class (Hz); 600 for the drop test's accelerations.
    pad : {"zero", "edge"}
        "zero" (default: the history is zero before its first and after its last sample) or
        "edge" (the end values are held); ``PAD_PERIODS / cfc`` seconds on each side.

    Returns
    -------
    ndarray, shape (n,)
        New float64 array, filtered, in the unit of ``x``.

    Raises
    ------
    InputError
        ``pad`` is not "zero" or "edge"; ``cfc`` or ``sample_rate`` is not a finite positive
        number or ``sample_rate`` < 10 x CFC; ``x`` is not a non-empty 1-D array or has a
        non-finite sample (the message names the first one).
    """
    if pad not in ("zero", "edge"):
        raise InputError(f"pad = {pad!r} is not allowed: use 'zero' (history starts and ends at 0) or 'edge'.")
    a0, a1, a2, b1, b2 = cfc_coefficients(cfc, sample_rate)
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise InputError(f"x must be a non-empty 1-D array; got shape {x.shape}. Pass one history at a time.")
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            f"x[{i}] = {x[i]!r} is not allowed: the filter input must be finite everywhere "
            f"({int(bad.sum())} non-finite of {x.size} samples). Fix the history before filtering."
        )
    n = pad_length(float(cfc), float(sample_rate))
    xp = np.pad(x, n, mode="constant" if pad == "zero" else "edge")

    y = _recursion(xp, a0, a1, a2, b1, b2)
    y = _recursion(y[::-1], a0, a1, a2, b1, b2)[::-1]
    return np.ascontiguousarray(y[n:n + x.size])


def _recursion(x: np.ndarray, a0, a1, a2, b1, b2) -> np.ndarray:
    """One pass of (C1), starting from rest (a plain loop: histories are a few thousand samples,
    and importing scipy.signal for it would cost about a second per run)."""
    y = [0.0] * len(x)
    xs = x.tolist()
    x1 = x2 = y1 = y2 = 0.0
    for i, xi in enumerate(xs):
        yi = a0 * xi + a1 * x1 + a2 * x2 + b1 * y1 + b2 * y2
        y[i] = yi
        x2, x1, y2, y1 = x1, xi, y1, yi
    return np.array(y)
