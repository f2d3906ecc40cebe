"""Deformation histories F(t) for the material-point checks (times in s, F dimensionless).

Each function returns (t (n,), F (n, 3, 3)); the material is undeformed at t[0]. Rates are those
of the drop tests (about 100-200 1/s), so the 1 ms Prony term is active.
"""

from __future__ import annotations

import numpy as np


def _ramp(n: int, end: float):
    return np.linspace(0.0, end, n)


def uniaxial_compression(n: int = 201, stretch: float = 0.5, duration: float = 5e-3):
    """F = diag(l, l^-1/2, l^-1/2), l from 1 to ``stretch`` linearly in time, then held as long."""
    t = _ramp(2 * n - 1, 2 * duration)
    lam = 1.0 + (stretch - 1.0) * np.minimum(t / duration, 1.0)
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = lam, lam ** -0.5, lam ** -0.5
    return t, F


def simple_shear(n: int = 201, gamma: float = 1.0, duration: float = 5e-3):
    """F = I + g e1 (x) e2, g rising to ``gamma`` and back to 0 (a triangle in time)."""
    t = _ramp(n, duration)
    g = gamma * (1.0 - np.abs(2.0 * t / duration - 1.0))
    F = np.tile(np.eye(3), (n, 1, 1))
    F[:, 0, 1] = g
    return t, F


def random_smooth(n: int = 301, amplitude: float = 0.25, duration: float = 1e-2, seed: int = 7):
    """F = I + sum_k A_k sin(pi k t / T) with random (seeded) 3x3 amplitudes: a smooth general history."""
    rng = np.random.default_rng(seed)
    t = _ramp(n, duration)
    F = np.tile(np.eye(3), (n, 1, 1))
    for k in (1, 2, 3):
        A = rng.uniform(-1.0, 1.0, (3, 3)) * amplitude / k
        F += np.sin(np.pi * k * t / duration)[:, None, None] * A
    return t, F


def repeated_stretches(n: int = 301, stretch: float = 0.6, cycles: int = 3, duration: float = 1.2e-2):
    """Load-unload cycles with two equal principal stretches at every instant (repeated eigenvalues):
    F = diag(l, l^-1/2, l^-1/2) between 1 and ``stretch``, ``cycles`` times."""
    t = _ramp(n, duration)
    phase = (t / duration * cycles) % 1.0
    lam = 1.0 + (stretch - 1.0) * (1.0 - np.abs(2.0 * phase - 1.0))
    F = np.zeros((n, 3, 3))
    F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = lam, lam ** -0.5, lam ** -0.5
    return t, F


def equal_stretches(n: int = 101, stretch: float = 0.8, duration: float = 2e-3):
    """Three equal principal stretches (F = l I): every eigenvalue repeated, from 1 to ``stretch``."""
    t = _ramp(n, duration)
    lam = 1.0 + (stretch - 1.0) * t / duration
    return t, lam[:, None, None] * np.eye(3)


def hydrostatic(n: int = 101, J_end: float = 1.5, duration: float = 2e-3):
    """F = J^(1/3) I with J from 1 to ``J_end`` (hydrostatic tension past J = 1.29 when J_end > 1.29)."""
    return equal_stretches(n, J_end ** (1.0 / 3.0), duration)


#: The agreement suite's histories: name -> (t, F).
AGREEMENT = {
    "uniaxial compression": uniaxial_compression,
    "simple shear": simple_shear,
    "random smooth": random_smooth,
    "repeated stretches": repeated_stretches,
}
