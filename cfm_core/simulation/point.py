"""Material-point driver (like MFront's MTest): stress along a prescribed F(t) history, and
uniaxial stress (lateral tractions zero, solved each step) at a constant engineering strain rate.

History CSV: header exactly ``t,F11,F12,F13,F21,F22,F23,F31,F32,F33`` (t in s, F dimensionless,
rows in time order; units may be written, ``t [s]``), read by :func:`cfm_core.tables.read_table`. Output CSV: ``t [s],s11 [Pa],...,s13 [Pa]`` (Cauchy stress), or for uniaxial stress
``t [s],stretch [-],nominal_stress [Pa],lateral_stretch [-]``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from ..material import kinematics as kin
from ..material import reference as ref
from ..material.diagnose import describe_nonfinite
from ..errors import InputError, NumericalError
from ..tables import read_table

HISTORY_HEADER = ["t", "F11", "F12", "F13", "F21", "F22", "F23", "F31", "F32", "F33"]
STRESS_HEADER = ["t", "s11", "s22", "s33", "s12", "s23", "s13"]
UNIAXIAL_HEADER = ["t", "stretch", "nominal_stress", "lateral_stretch"]
#: Units of the output columns (the CSV header writes ``name [unit]``).
STRESS_UNITS = {"t": "s", **{c: "Pa" for c in STRESS_HEADER[1:]}}
UNIAXIAL_UNITS = {"t": "s", "stretch": "-", "nominal_stress": "Pa", "lateral_stretch": "-"}


def read_history(path) -> tuple[np.ndarray, np.ndarray]:
    """Deformation history from a CSV file (:func:`cfm_core.tables.read_table` rules: UTF-8 with or
    without BOM, any line ending, ``#`` comments, optional units such as ``t [s]``).

    Parameters
    ----------
    path : str or Path
        CSV with the header ``t,F11,F12,F13,F21,F22,F23,F31,F32,F33`` (t in s, F dimensionless),
        rows in time order.

    Returns
    -------
    t : ndarray, shape (n,)
        Times (s).
    F : ndarray, shape (n, 3, 3)
        Deformation gradients (-).

    Raises
    ------
    InputError
        Naming the file and line: encoding, header, non-finite or non-numeric values, times out
        of order, det F <= 0.
    """
    table = read_table(path, HISTORY_HEADER, {"t": "s", **{c: "-" for c in HISTORY_HEADER[1:]}}, exact=True,
                       strict=False, what="history file")
    t, F = table.data[:, 0], table.data[:, 1:].reshape(-1, 3, 3)
    J = np.linalg.det(F)
    bad = np.flatnonzero(~(J > 0))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"{path}, line {table.lines[k]}: det F = {J[k]:g} <= 0 (inverted or degenerate "
                         f"deformation); det F must be positive.")
    return t, F


def run_history(material, t, F, backend=None) -> np.ndarray:
    """Cauchy stress along a deformation history.

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material.
    t : ndarray, shape (n,)
        Times (s).
    F : ndarray, shape (n, 3, 3)
        Deformation gradients (-).
    backend : Backend, optional
        None for the numpy reference, else a backend whose ``point`` is used.

    Returns
    -------
    ndarray, shape (n, 6)
        Cauchy stress (Pa), order s11, s22, s33, s12, s23, s13.

    Raises
    ------
    NumericalError
        A non-finite stress, naming the row, its time (s) and the material's term that failed
        (:mod:`cfm_core.material.diagnose`); no numpy RuntimeWarning is shown.
    """
    t = np.asarray(t, dtype=np.float64)
    try:
        with np.errstate(all="ignore"):  # failures are reported below, not as numpy RuntimeWarnings
            if backend is None or backend.kind == "reference":
                out = kin.to_voigt(ref.stress_history(material, t, F))
            else:
                out = np.asarray(backend.point(material, t, kin.as_batch(F)))
    except NumericalError as exc:
        row = exc.element if exc.element is not None and 0 <= exc.element < t.size else None
        if row is None or exc.time is not None:
            raise
        raise NumericalError(f"row {row} (t = {t[row]:.6g} s): {exc}", time=float(t[row]), element=row,
                             quantity=exc.quantity) from None
    if not np.isfinite(out).all():
        i = int(np.argmax(~np.isfinite(out).all(axis=1)))
        m = np.linalg.eigvalsh(np.einsum("ki,kj->ij", kin.as_batch(F)[i], kin.as_batch(F)[i]))
        raise NumericalError(f"stress is not finite at row {i} (t = {t[i]:.6g} s): {describe_nonfinite(material, m)}.",
                             time=float(t[i]), element=i, quantity="stress")
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
    with np.errstate(all="ignore"):  # failures are reported as NumericalError, not numpy RuntimeWarnings
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
    bad = ~(np.isfinite(P) & np.isfinite(lat))
    if bad.any():
        k = int(np.argmax(bad))
        raise NumericalError(f"uniaxial: the stress is not finite at step {k} (t = {t[k]:g} s, stretch {lam[k]:g}).",
                             time=float(t[k]), element=k, quantity="stress")
    return t, lam, P, lat
