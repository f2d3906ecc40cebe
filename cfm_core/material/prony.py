"""Normalised Prony series on the isochoric stress (docs/conventions.md section 2).

    g(t) = gamma_inf + sum_i gamma_i exp(-t / tau_i),   gamma_inf = 1 - sum_i gamma_i

Finite-strain form (Simo 1987, Holzapfel 2000), on the isochoric second Piola-Kirchhoff stress
S0 = 2 d psi_iso / d C, with the exact exponential recurrence per step dt (s):

    H_i <- exp(-dt/tau_i) H_i + gamma_i (tau_i/dt)(1 - exp(-dt/tau_i)) (S0_new - S0_old)
    S_iso = gamma_inf S0 + sum_i H_i

stable for any dt/tau_i. The paper's Eq. 8 prints a product instead of a sum; with it g(0) != 1,
so the standard sum is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .parameters import Parameter


@dataclass(frozen=True)
class PronySeries:
    """Declaration of an n-term Prony series with default (gamma_i, tau_i) pairs.

    Parameters ``g1, tau1, g2, tau2, ...`` are added to the material: g_i dimensionless in
    [0, 1), tau_i in s, > 0. Their sum must stay below 1 (gamma_inf > 0). Normalised series of
    docs/conventions.md section 2 (the paper's Eq. 8 prints a product; Simo 1987, Holzapfel 2000).

    Parameters
    ----------
    defaults : tuple of (float, float)
        Default ``(gamma_i (-), tau_i (s))`` per term, e.g. Table 1:
        ``((0.45, 1e-3), (0.435, 0.1), (0.094, 10.0))``.
    """

    defaults: tuple[tuple[float, float], ...]

    @property
    def parameters(self) -> tuple[Parameter, ...]:
        """Declarations ``g1, tau1, g2, tau2, ...``: g_i (-) in [0, 1), tau_i (s) in (0, inf)."""
        out = []
        for i, (g, tau) in enumerate(self.defaults, start=1):
            out.append(Parameter(f"g{i}", "-", g, low=0.0, high=1.0, high_open=True,
                                 description=f"normalised shear relaxation coefficient of Prony term {i}"))
            out.append(Parameter(f"tau{i}", "s", tau, low=0.0, low_open=True,
                                 description=f"relaxation time of Prony term {i}"))
        return tuple(out)

    def arrays(self, values: dict) -> tuple[np.ndarray, np.ndarray]:
        """(gammas, taus) from bound parameter values; checks sum(gammas) < 1.

        Parameters
        ----------
        values : dict of str to float
            Bound values containing ``g1 .. gn`` (-) and ``tau1 .. taun`` (s).

        Returns
        -------
        gammas : ndarray, shape (n,)
            g_i (-).
        taus : ndarray, shape (n,)
            tau_i (s).

        Raises
        ------
        InputError
            sum(g_i) >= 1, which would make gamma_inf = 1 - sum(g_i) zero or negative.
        """
        n = len(self.defaults)
        gammas = np.array([values[f"g{i}"] for i in range(1, n + 1)], dtype=float)
        taus = np.array([values[f"tau{i}"] for i in range(1, n + 1)], dtype=float)
        total = float(gammas.sum())
        if not total < 1.0:
            names = " + ".join(f"g{i}" for i in range(1, n + 1))
            raise InputError(
                f"Prony series: {names} = {total:g} (-) must be below 1 so that the long-term "
                f"coefficient gamma_inf = 1 - sum is positive; lower one of the g_i."
            )
        return gammas, taus


def relaxation_function(t, gammas, taus):
    """Relaxation function g(t) = gamma_inf + sum_i gamma_i exp(-t/tau_i), gamma_inf = 1 - sum_i gamma_i.

    Parameters
    ----------
    t : array_like
        Times (s), any shape.
    gammas : array_like, shape (k,)
        g_i (-).
    taus : array_like, shape (k,)
        tau_i (s), > 0.

    Returns
    -------
    ndarray
        g(t) (-), the shape of ``t``; g(0) = 1 (docs/conventions.md section 2).
    """
    t = np.asarray(t, dtype=float)
    g = (1.0 - float(np.sum(gammas))) * np.ones_like(t)
    for gam, tau in zip(gammas, taus):
        g = g + gam * np.exp(-t / tau)
    return g


def step_factors(dt: float, gammas, taus):
    """(decay_i, gain_i) of the recurrence for a step dt (s): exp(-dt/tau), gamma (tau/dt)(1-exp(-dt/tau)).

    dt = 0 gives the instantaneous jump: decay 1, gain gamma. The exact exponential recurrence
    of docs/conventions.md section 2 (Simo 1987; Holzapfel 2000); (1 - exp(-x)) / x
    is evaluated without cancellation for small x = dt / tau.

    Parameters
    ----------
    dt : float
        Step (s); <= 0 is treated as 0.
    gammas : array_like, shape (k,)
        g_i (-).
    taus : array_like, shape (k,)
        tau_i (s), > 0.

    Returns
    -------
    decay : ndarray, shape (k,)
        exp(-dt / tau_i) (-).
    gain : ndarray, shape (k,)
        gamma_i tau_i / dt (1 - exp(-dt / tau_i)) (-).
    """
    gammas = np.asarray(gammas, dtype=float)
    taus = np.asarray(taus, dtype=float)
    if dt <= 0.0:
        return np.ones_like(taus), gammas.copy()
    x = dt / taus
    decay = np.exp(-x)
    # (1 - exp(-x)) / x computed without cancellation for small x
    gain = gammas * np.where(x > 1e-8, -np.expm1(-x) / np.maximum(x, 1e-300), 1.0 - 0.5 * x)
    return decay, gain


def effective_factor(dt: float, gammas, taus) -> float:
    """d S_iso / d S0 over one step: gamma_inf + sum gain_i (consistent tangent factor, -).

    Parameters
    ----------
    dt : float
        Step (s); 0 gives the instantaneous factor 1.
    gammas : array_like, shape (k,)
        g_i (-); empty for an elastic material.
    taus : array_like, shape (k,)
        tau_i (s).

    Returns
    -------
    float
        The factor on the instantaneous isochoric tangent (-); 1 without Prony terms.
    """
    if len(gammas) == 0:
        return 1.0
    _, gain = step_factors(dt, gammas, taus)
    return float(1.0 - np.sum(gammas) + np.sum(gain))


def update(H, S0_old, S0_new, dt, gammas, taus):
    """One step of the exact recurrence (docs/conventions.md section 2)::

        H_i <- decay_i H_i + gain_i (S0_new - S0_old),   S_iso = gamma_inf S0_new + sum_i H_i

    Parameters
    ----------
    H : ndarray, shape (k, ..., 6) or (k, ..., 3, 3)
        History stresses of the k Prony terms (Pa); not modified.
    S0_old, S0_new : ndarray, shape (..., 6) or (..., 3, 3)
        Instantaneous isochoric second Piola-Kirchhoff stress at the start and end of the step (Pa).
    dt : float
        Step (s); 0 = instantaneous jump.
    gammas : array_like, shape (k,)
        g_i (-).
    taus : array_like, shape (k,)
        tau_i (s).

    Returns
    -------
    H_new : ndarray
        Updated history stresses, shape of ``H`` (Pa).
    S_iso : ndarray
        Viscoelastic isochoric stress at the end of the step, shape of ``S0_new`` (Pa).
    """
    decay, gain = step_factors(dt, gammas, taus)
    shape = (-1,) + (1,) * (H.ndim - 1)
    H_new = decay.reshape(shape) * H + gain.reshape(shape) * (S0_new - S0_old)[None]
    S_iso = (1.0 - float(np.sum(gammas))) * S0_new + H_new.sum(axis=0)
    return H_new, S_iso


def gamma_inf(gammas) -> float:
    """Long-term coefficient gamma_inf = 1 - sum(gamma_i) (-), summed with ``math.fsum``.

    Parameters
    ----------
    gammas : iterable of float
        g_i (-).

    Returns
    -------
    float
        gamma_inf (-); 0.021 for Table 1.
    """
    return 1.0 - math.fsum(float(g) for g in gammas)
