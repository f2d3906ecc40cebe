"""Normalised Prony series on the isochoric stress (docs/conventions.md section 2).

    g(t) = gamma_inf + sum_i gamma_i exp(-t / tau_i),   gamma_inf = 1 - sum_i gamma_i

Finite-strain form (Simo 1987, Holzapfel 2000), on the isochoric second Piola-Kirchhoff stress
S0 = 2 d psi_iso / d C, with the exact exponential recurrence per step dt (s):

    H_i <- exp(-dt/tau_i) H_i + gamma_i (tau_i/dt)(1 - exp(-dt/tau_i)) (S0_new - S0_old)
    S_iso = gamma_inf S0 + sum_i H_i

stable for any dt/tau_i. The paper's Eq. 8 prints a product instead of a sum; with it g(0) != 1,
so the standard sum is used.

gamma_inf is computed in one place, :func:`gamma_inf` (``math.fsum``, exactly rounded), and every
check, the material's moduli factor 1 / gamma_inf, the backends and the reference use it, so that
what is checked is what is computed. Limits (:data:`GAMMA_INF_MIN`, :data:`GAMMA_INF_WARN`):

- gamma_inf < 1e-6 is refused (InputError): with long-term moduli the instantaneous isochoric
  moduli are 1 / gamma_inf times the written ones, so 1e6 times Table 1 (GPa stresses, an
  explicit step 1000 times shorter); with instantaneous moduli the tissue relaxes to a
  liquid. No tissue is either; the floor also keeps 1 / gamma_inf far from float rounding
  (a sum that is 1 in decimal arithmetic, 0.471 + 0.435 + 0.094, leaves 0 or 1e-16).
- 1e-6 <= gamma_inf < 1e-3 is warned about (:func:`cfm_core.material.plausible.check_material`):
  pyvisco keeps E_inf / E_0 >= 1e-3 "so numerical difficulties are avoided in structural FEM
  simulations" (NatLabRockies/pyvisco#2); Table 1 has gamma_inf = 0.021.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .parameters import Parameter

#: gamma_inf (-) below this is refused: instantaneous / long-term moduli above 1e6 (see the module text).
GAMMA_INF_MIN = 1e-6
#: gamma_inf (-) below this is warned about (pyvisco's E_inf / E_0 floor; Table 1: 0.021).
GAMMA_INF_WARN = 1e-3


@dataclass(frozen=True)
class PronySeries:
    """Declaration of an n-term Prony series with default (gamma_i, tau_i) pairs.

    Parameters ``g1, tau1, g2, tau2, ...`` are added to the material: g_i dimensionless in
    [0, 1), tau_i in s, > 0. Their sum must leave gamma_inf = 1 - sum >= :data:`GAMMA_INF_MIN`
    (computed by :func:`gamma_inf`). Normalised series of
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
        """(gammas, taus) from bound parameter values; checks gamma_inf >= :data:`GAMMA_INF_MIN`.

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
            gamma_inf = 1 - sum(g_i) (:func:`gamma_inf`) below :data:`GAMMA_INF_MIN`: a sum of 1 or
            more, or one so close to 1 that the moduli factor 1 / gamma_inf is absurd.
        """
        n = len(self.defaults)
        gammas = np.array([values[f"g{i}"] for i in range(1, n + 1)], dtype=float)
        taus = np.array([values[f"tau{i}"] for i in range(1, n + 1)], dtype=float)
        check_gamma_inf(gammas)
        return gammas, taus


def check_gamma_inf(gammas) -> float:
    """gamma_inf (:func:`gamma_inf`) if it is at least :data:`GAMMA_INF_MIN`, else InputError.

    Parameters
    ----------
    gammas : array_like, shape (k,)
        g_i (-), named g1 .. gk in the message.

    Returns
    -------
    float
        gamma_inf (-).

    Raises
    ------
    InputError
        gamma_inf < :data:`GAMMA_INF_MIN` (sum of the g_i at or too close to 1); the message
        names the g_i, their sum, gamma_inf and the limit.
    """
    g_inf = gamma_inf(gammas)
    if not g_inf >= GAMMA_INF_MIN:
        names = " + ".join(f"g{i}" for i in range(1, len(gammas) + 1))
        given = ", ".join(f"g{i} = {float(g)!r}" for i, g in enumerate(gammas, start=1))
        raise InputError(
            f"Prony series: {given} leave the long-term coefficient gamma_inf = 1 - ({names}) = {_shown(g_inf, GAMMA_INF_MIN)} (-), "
            f"summed exactly; it must be at least {GAMMA_INF_MIN:g}: the instantaneous isochoric moduli are "
            f"1 / gamma_inf times the long-term ones (Table 1: gamma_inf = 0.021, a factor 48). Lower one of "
            f"the g_i so that their sum is at most 1 - {GAMMA_INF_MIN:g} (Table 1's sum is 0.979).")
    return g_inf


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
    g = gamma_inf(gammas) * np.ones_like(t)
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
    return float(gamma_inf(gammas) + np.sum(gain))


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
    S_iso = gamma_inf(gammas) * S0_new + H_new.sum(axis=0)
    return H_new, S_iso


def gamma_inf(gammas) -> float:
    """Long-term coefficient gamma_inf = 1 - sum(gamma_i) (-), summed with ``math.fsum``.

    The one place it is computed: the range check (:func:`check_gamma_inf`), the moduli factor
    (:attr:`cfm_core.material.Material.iso_scale`), the reference and the backends use it, so
    a sum that rounds to 1 is refused instead of dividing by zero later.

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


def _shown(value: float, limit: float) -> str:
    """``value`` with enough digits to tell it from ``limit`` (9.99999999e-07 is not shown as the limit 1e-06)."""
    for digits in range(3, 18):
        text = f"{value:.{digits}g}"
        if float(text) != limit or value == limit:
            return text
    return repr(value)
