"""Histories from a backend's :class:`~cfm_core.simulation.Result`: impactor acceleration on a
uniform grid (box average of the contact impulse, no aliasing), filtered with SAE J211/1 CFC
(:func:`cfm_core.post.filters.cfc_filter`), and reaction-force histories of prescribed-motion
scenes. Acceleration in m/s^2, positive when the impactor decelerates; times in s.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, NumericalError
from .filters import _positive_finite, cfc_filter

#: Standard gravity (m/s^2), used to express accelerations in g.
G0 = 9.80665


def _finite(name: str, a, ndim: int | None = None, then: str = "refusing to post-process it") -> np.ndarray:
    """``a`` as a float array; InputError for a wrong number of dimensions, NumericalError (naming
    the first bad index and what is not done, ``then``) for inf or NaN."""
    a = np.asarray(a, dtype=float)
    if ndim is not None and a.ndim != ndim:
        raise InputError(f"{name} must be a {ndim}-D array; got shape {a.shape}.")
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad.ravel()))
        raise NumericalError(f"{name} has {int(bad.sum())} non-finite value(s), first at index {i} "
                             f"({a.ravel()[i]!r}); {then}.", quantity=name)
    return a


def resample_acceleration(result, mass: float, rate: float = 50_000.0) -> tuple[np.ndarray, np.ndarray]:
    """Impactor acceleration on a uniform grid, box-averaged from the impulse (no aliasing).

    With t_k = k h (s), h = 1/rate, k = 0 .. floor(t_end / h), t_end the last recorded time (t_k computed
    as k / rate, the float nearest k h: it prints as people write it, 6e-05 rather than
    6.000000000000001e-05)::

        a_raw(t_k) = [I(t_k + h/2) - I(t_k - h/2)] / (h mass)        (m/s^2)

    the mean contact force over [t_k - h/2, t_k + h/2] divided by the mass. I (N s) is
    ``result.impulse`` linearly interpolated in ``result.t``, 0 for t < 0, held after t_end (and
    ramped linearly from (0, 0) if the record starts after t = 0). If ``result.impulse`` is None,
    I is the trapezoid-rule integral of ``result.contact_force`` (N). Summing a_raw h mass gives
    back the total impulse.

    Parameters
    ----------
    result : Result
        A backend's histories: ``t`` (s) and ``impulse`` (N s) or ``contact_force`` (N), shape
        (m,), full model.
    mass : float
        Impactor mass (kg, full model), > 0.
    rate : float
        Samples per second (Hz), > 0; 50 kHz as in the paper.

    Returns
    -------
    t : ndarray, shape (k,)
        Uniform times (s), from 0.
    a_raw : ndarray, shape (k,)
        Acceleration (m/s^2), positive when the impactor decelerates.

    Raises
    ------
    InputError
        ``mass`` or ``rate`` not finite and > 0; ``result.t`` not 1-D with at least 2 times,
        starting before 0 or decreasing; neither impulse nor contact_force recorded; or a history
        whose shape differs from ``result.t``.
    NumericalError
        A non-finite value in ``result.t``, the impulse or the contact force (names the first).
    """
    mass = _positive_finite("mass", mass, "kg")
    rate = _positive_finite("rate", rate, "Hz")
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
    centre = np.arange(n) * h  # the box centres, computed as ever: the histories' bytes are unchanged

    def I(tq):
        return np.interp(tq, t, impulse, left=0.0, right=impulse[-1])

    a_raw = (I(centre + 0.5 * h) - I(centre - 0.5 * h)) / (h * mass)
    # the times written: k / rate, the float nearest k h (6e-05 s, where k * h gives 6.000000000000001e-05);
    # they differ from the centres by at most one unit in the last place
    return np.arange(n) / rate, a_raw


def acceleration_histories(result, mass: float, rate: float = 50_000.0, cfc: float = 600.0):
    """(t (s), a_raw (m/s^2), a_cfc (m/s^2)): :func:`resample_acceleration` then CFC filtering.

    The filter (SAE J211/1 Appendix C, :func:`cfm_core.post.filters.cfc_filter`) pads with zeros
    (the history is zero outside the record).

    Parameters
    ----------
    result : Result
        A backend's histories (see :func:`resample_acceleration`).
    mass : float
        Impactor mass (kg, full model).
    rate : float
        Samples per second of the uniform grid (Hz), >= 10 x ``cfc``.
    cfc : float
        Channel frequency class (Hz); 600 as in the paper.

    Returns
    -------
    t : ndarray, shape (k,)
        Uniform times (s).
    a_raw : ndarray, shape (k,)
        Box-averaged acceleration (m/s^2), positive when decelerating.
    a_cfc : ndarray, shape (k,)
        ``a_raw`` filtered with CFC ``cfc`` (m/s^2).

    Raises
    ------
    InputError
        Bad mass, rate, cfc or times, or missing histories.
    NumericalError
        Non-finite histories.
    """
    t, a_raw = resample_acceleration(result, mass, rate)
    return t, a_raw, cfc_filter(a_raw, rate, cfc=cfc, pad="zero")


def reaction_histories(result, model) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Histories of a prescribed-motion scene (single element, relaxation), at the result's times.

    Parameters
    ----------
    result : Result
        A backend's histories with ``t`` (s) and ``reaction_force`` (N), shape (m,).
    model : Model
        The model that ran: its ``prescribed`` motion and ``meta["size"]`` (m).

    Returns
    -------
    t : ndarray, shape (m,)
        Times (s).
    stretch : ndarray, shape (m,)
        1 + u(t) / size of the prescribed face (-).
    force : ndarray, shape (m,)
        Reaction force (N): the z force on the prescribed face, negative in compression.
    nominal : ndarray, shape (m,)
        Nominal stress force / size^2 (Pa), on the undeformed face area.

    Raises
    ------
    InputError
        The result has no reaction force or the model no prescribed motion (not a
        single-element or relaxation scene).
    NumericalError
        A non-finite time or reaction force (names the first).
    """
    if result.reaction_force is None or model.prescribed is None:
        raise InputError(f"scene '{model.name}' has no prescribed motion, so no reaction force; "
                         f"reaction histories are for single-element and relaxation scenes.")
    t = _finite("result.t", result.t)
    force = _finite("result.reaction_force", result.reaction_force)
    size = float(model.meta["size"])
    u = np.interp(t, model.prescribed.times, model.prescribed.values)
    return t, 1.0 + u / size, force, force / size**2


