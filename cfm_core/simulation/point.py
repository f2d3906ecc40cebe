"""Material-point driver (like MFront's MTest): stress along a prescribed F(t) history, and
uniaxial stress (lateral tractions zero, solved each step) at a constant engineering strain rate.

History CSV: header exactly ``t,F11,F12,F13,F21,F22,F23,F31,F32,F33`` (t in s, F dimensionless,
rows in time order). Output CSV: ``t,s11,s22,s33,s12,s23,s13`` (Cauchy stress in Pa).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from ..material import kinematics as kin
from ..material import reference as ref
from ..errors import InputError, NumericalError

HISTORY_HEADER = ["t", "F11", "F12", "F13", "F21", "F22", "F23", "F31", "F32", "F33"]
STRESS_HEADER = ["t", "s11", "s22", "s33", "s12", "s23", "s13"]
UNIAXIAL_HEADER = ["t", "stretch", "nominal_stress", "lateral_stretch"]


def read_history(path) -> tuple[np.ndarray, np.ndarray]:
    """(t (n,) in s, F (n, 3, 3)) from a history CSV; InputError naming the line on any problem."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"history file '{path}' does not exist (expected a CSV with header {','.join(HISTORY_HEADER)}).")
    rows = []
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None or [h.strip() for h in header] != HISTORY_HEADER:
            raise InputError(
                f"{path}, line 1: header must be exactly '{','.join(HISTORY_HEADER)}', got "
                f"'{','.join(header) if header else '(empty file)'}'.")
        for lineno, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != 10:
                raise InputError(f"{path}, line {lineno}: expected 10 comma-separated numbers (t and 9 components of F), got {len(row)}.")
            try:
                vals = [float(c) for c in row]
            except ValueError:
                raise InputError(f"{path}, line {lineno}: not a number in {row!r}.") from None
            if not all(math.isfinite(v) for v in vals):
                raise InputError(f"{path}, line {lineno}: NaN or infinite value in {row!r}.")
            rows.append((lineno, vals))
    if not rows:
        raise InputError(f"{path}: no data rows after the header.")
    data = np.array([v for _, v in rows])
    t, F = data[:, 0], data[:, 1:].reshape(-1, 3, 3)
    for k in range(1, len(rows)):
        if t[k] < t[k - 1]:
            raise InputError(f"{path}, line {rows[k][0]}: time {t[k]:g} s is earlier than the previous row's {t[k-1]:g} s; rows must be in time order.")
    J = np.linalg.det(F)
    for k in range(len(rows)):
        if not J[k] > 0:
            raise InputError(f"{path}, line {rows[k][0]}: det F = {J[k]:g} <= 0 (inverted or degenerate deformation); det F must be positive.")
    return t, F


def run_history(material, t, F, backend=None) -> np.ndarray:
    """Cauchy stress (n, 6) in Pa (order s11, s22, s33, s12, s23, s13) along the history.

    backend: None for the numpy reference, else a Backend instance whose ``point`` is used.
    """
    if backend is None or backend.kind == "reference":
        sigma = ref.stress_history(material, t, F)
        out = kin.to_voigt(sigma)
    else:
        out = np.asarray(backend.point(material, np.asarray(t, float), kin.as_batch(F)))
    if not np.isfinite(out).all():
        i = int(np.argmax(~np.isfinite(out).all(axis=1)))
        raise NumericalError(f"stress is not finite at row {i} (t = {t[i]:g} s).", time=float(t[i]), quantity="stress")
    return out


def uniaxial_on_backend(material, backend, t, stretch, lateral):
    """Nominal stress (Pa) of a backend along a uniaxial path found with the numpy reference.

    The reference solves the lateral stretch for zero lateral stress (:func:`uniaxial`); the
    backend's ``point`` driver then evaluates the Cauchy stress along F = diag(l, lt, lt), and the
    nominal stress is P11 = J sigma11 / l. Its lateral stress, relative to the axial one, shows
    how far the backend's material is from the reference's (round-off when they agree).

    Returns
    -------
    nominal : ndarray, shape (n,)
        P11 of the backend, Pa.
    lateral_residual : float
        max |sigma22| / max |sigma11| of the backend along the path (-).
    """
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = stretch, lateral, lateral
    sigma = run_history(material, t, F, backend)
    J = stretch * lateral**2
    scale = max(float(np.max(np.abs(sigma[:, 0]))), 1e-300)
    return J * sigma[:, 0] / stretch, float(np.max(np.abs(sigma[:, 1])) / scale)


def uniaxial(material, rate: float, stretch: float, steps: int = 200, hold: float = 0.0):
    """Uniaxial stress at constant engineering strain rate (1/s) to a final stretch (-).

    Returns (t (s), stretch (-), nominal stress P11 (Pa), lateral stretch (-)). The lateral
    stretch solves sigma22 = sigma33 = 0 at each step (F = diag(l, lt, lt), isotropic material)
    with the viscoelastic state carried from step to step; ``hold`` (s) keeps the final stretch.
    """
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"rate = {rate!r} 1/s must be a positive engineering strain rate.")
    if not (math.isfinite(stretch) and 0.05 <= stretch <= 5.0 and stretch != 1.0):
        raise InputError(f"stretch = {stretch!r} (-) must lie in [0.05, 5] and differ from 1.")
    if not (isinstance(steps, int) and steps >= 2):
        raise InputError(f"steps = {steps!r} must be an integer >= 2.")
    t_load = abs(stretch - 1.0) / rate
    t = np.linspace(0.0, t_load, steps + 1)
    if hold > 0:
        t = np.concatenate([t, t_load + np.linspace(0.0, hold, steps + 1)[1:]])
    lam = 1.0 + np.sign(stretch - 1.0) * rate * np.minimum(t, t_load)
    state = None
    lat = np.ones_like(t)
    P = np.zeros_like(t)
    for n in range(t.size):
        dt = 0.0 if n == 0 else t[n] - t[n - 1]

        def lateral_stress(lt, n=n, dt=dt, keep=False):
            F = np.diag([lam[n], lt, lt])[None]
            S_iso, S_vol = ref.pk2_parts(material, F)
            S, new_state = ref.viscous_step(material, state, dt, S_iso[0], S_vol[0])
            return (S[1, 1], S, new_state) if keep else S[1, 1]

        guess = lat[n - 1] if n else 1.0
        lo, hi = guess, guess
        for _ in range(200):  # bracket the root: S22 grows with the lateral stretch
            lo, hi = lo / 1.05, hi * 1.05
            if lateral_stress(lo) <= 0.0 <= lateral_stress(hi):
                break
        else:
            raise NumericalError(f"uniaxial: no lateral stretch gives zero lateral stress at t = {t[n]:g} s.", time=float(t[n]))
        lt = brentq(lateral_stress, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200) if n else 1.0
        _, S, state = lateral_stress(lt, keep=True)
        lat[n] = lt
        P[n] = lam[n] * S[0, 0]  # P = F S, first component
    return t, lam, P, lat
