"""Material-point driver (like MFront's MTest): stress along a prescribed F(t) history, and
uniaxial stress (lateral tractions zero, solved each step) at a constant engineering strain rate.

History CSV: header exactly ``t,F11,F12,F13,F21,F22,F23,F31,F32,F33`` (t in s, F dimensionless,
rows in time order; units may be written, ``t [s]``), read by :func:`cfm_core.tables.read_table`. Output CSV: ``t [s],s11 [Pa],...,s13 [Pa]`` (Cauchy stress), or for uniaxial stress
``t [s],stretch [-],nominal_stress [Pa],lateral_stretch [-]``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..material import kinematics as kin
from ..material import reference as ref
from ..material.diagnose import describe_nonfinite
from ..errors import InputError, NumericalError
from ..tables import read_table

HISTORY_HEADER = ["t", "F11", "F12", "F13", "F21", "F22", "F23", "F31", "F32", "F33"]
STRESS_HEADER = ["t", "s11", "s22", "s33", "s12", "s23", "s13"]
UNIAXIAL_HEADER = ["t", "stretch", "nominal_stress", "lateral_stretch"]
#: Units of the output columns (headers ``name [unit]``: :func:`cfm_core.tables.unit_header`).
STRESS_UNITS = {"t": "s", **{c: "Pa" for c in STRESS_HEADER[1:]}}
UNIAXIAL_UNITS = {"t": "s", "stretch": "-", "nominal_stress": "Pa", "lateral_stretch": "-"}
#: Smallest diagonal entry of C = F^T F a history may give (-): the smallest normal float64, 2.2e-308
#: (a stretch of 1.5e-154); below it the squared stretch is subnormal or has underflowed to zero.
C_DIAGONAL_MIN = float(np.finfo(np.float64).tiny)
#: Volume ratio J (-) below which a state is called crushed (:func:`crushed_volume`): half the volume
#: gone. A nearly incompressible tissue (kappa / c ~ 10^3 in Table 1) keeps J near 1 under any
#: load it survives; below this J the Ogden term alone sets the stress (at J = 0.5 its pressure is
#: kappa (2^10 - 2) / 9, 114 kappa), and uniaxial compression to a stretch of 0.05 came out at
#: J = 0.02 and -7e21 Pa with exit 0 and no word.
CRUSHED_J = 0.5


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
        of order, det F <= 0, det F or F^T F beyond the float64 range, C = F^T F not positive
        definite in float64 or with a diagonal entry below :data:`C_DIAGONAL_MIN` (2.2e-308: a
        square that underflowed).
    """
    table = read_table(path, HISTORY_HEADER, {"t": "s", **{c: "-" for c in HISTORY_HEADER[1:]}}, exact=True,
                       strict=False, what="history file")
    t, F = table.data[:, 0], table.data[:, 1:].reshape(-1, 3, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        J = np.linalg.det(F)
        C = np.einsum("nki,nkj->nij", F, F)
    bad = np.flatnonzero(~(J > 0))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"{path}, line {table.lines[k]}: det F = {J[k]:g} <= 0 (inverted or degenerate "
                         f"deformation); det F must be positive.")
    huge = np.flatnonzero(~(np.isfinite(J) & np.isfinite(C).all(axis=(1, 2))))
    if huge.size:  # det F = inf read as "inverted" by two backends and as zero stress by the others
        k = int(huge[0])
        what = "det F = inf" if not np.isfinite(J[k]) else f"C = F^T F overflows (det F = {J[k]:g})"
        raise InputError(f"{path}, line {table.lines[k]}: {what}: beyond the float64 range (largest |F| entry "
                         f"{np.abs(F[k]).max():g}); no material point follows such a deformation. Give "
                         f"stretches (F entries) whose squares and det F are finite numbers.")
    # det F > 0 makes C = F^T F positive definite in exact arithmetic, but a square that underflows
    # (F11 = 1e-170: C11 = 1e-340 -> 0) or round-off in a sheared F leaves a C that is singular or
    # indefinite in float64: J = sqrt(det C) = 0 and every backend divides by it.
    with np.errstate(all="ignore"):
        diag = np.einsum("nii->ni", C)
        m_min = np.linalg.eigvalsh(C)[:, 0]
    small = np.flatnonzero(~((diag >= C_DIAGONAL_MIN).all(axis=1) & (m_min > 0.0)))
    if small.size:
        k = int(small[0])
        i = int(np.argmin(diag[k]))
        cause = (f"C{i + 1}{i + 1} = {diag[k, i]:g}: a squared stretch that underflowed; give F entries whose "
                 f"squares are normal numbers" if diag[k, i] < C_DIAGONAL_MIN else
                 f"its smallest eigenvalue is {m_min[k]:g}: lost to round-off next to the largest, "
                 f"{np.abs(C[k]).max():g} (a shear or stretch ratio beyond what float64 resolves); give a "
                 f"less extreme F")
        raise InputError(f"{path}, line {table.lines[k]}: C = F^T F (det F = {J[k]:g}) must be positive definite with "
                         f"every diagonal entry at least {C_DIAGONAL_MIN:g} (the smallest normal float64; a stretch "
                         f"of at least {math.sqrt(C_DIAGONAL_MIN):.3g} along each axis), but {cause}.")
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

    Warns
    -----
    RuntimeWarning
        A row with det F below :data:`CRUSHED_J` (:func:`crushed_volume`), naming the first.
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
    J = np.linalg.det(kin.as_batch(F))
    if J.min() < CRUSHED_J:
        i = int(np.argmax(J < CRUSHED_J))
        warnings.warn(f"history: row {i} (t = {t[i]:.6g} s) has J = det F below {CRUSHED_J:g} ({J[i]:.4g}); the smallest "
                      f"is {crushed_volume(float(J.min()))}", RuntimeWarning, stacklevel=2)
    return out


def uniaxial_on_backend(material, backend, t, stretch, lateral):
    """Nominal stress (Pa) of a backend along a uniaxial path found with the numpy reference.

    The reference solves the lateral stretch for zero lateral stress (:func:`uniaxial`); the
    backend's ``point`` driver then evaluates the Cauchy stress along F = diag(l, lt, lt), and the
    nominal stress is P11 = J (sigma11 - sigma22) / l (:func:`nominal_uniaxial`: the pressure,
    whose round-off grows with the bulk modulus, cancels). Its lateral stress, relative to the
    axial one, shows how far the backend's material is from the reference's (round-off when they
    agree; near the incompressible limit the pressure's round-off, which the nominal stress does
    not carry).

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
    return nominal_uniaxial(stretch, J * sigma[:, 0], J * sigma[:, 1]), float(np.max(np.abs(sigma[:, 1])) / scale)


def nominal_uniaxial(stretch, tau11, tau22):
    """Nominal stress P11 = (tau11 - tau22) / l (Pa) of a uniaxial-stress state F = diag(l, lt, lt),
    from the Kirchhoff stresses tau = J sigma along and across the axis.

    Where the lateral stress is zero this is P11 = tau11 / l; written as the difference, the
    pressure term of the stress (-p J in every normal component) cancels exactly, and with it
    the pressure's round-off: near the incompressible limit p = U'(J) J is set by J to the last
    bit times the bulk modulus (at kappa = 6.7e17 Pa an error of 1e-15 in the lateral stretch
    moves p by ~10^3 Pa), while the deviatoric difference stays accurate to round-off of the
    stress itself. The same formula serves a lateral stress that is round-off away from zero.

    Parameters
    ----------
    stretch : float or ndarray, shape (n,)
        Axial stretch l (-).
    tau11, tau22 : float or ndarray, shape (n,)
        Kirchhoff stresses J sigma11 and J sigma22 (Pa); for the second Piola-Kirchhoff S of
        F = diag(l, lt, lt): tau11 = l^2 S11, tau22 = lt^2 S22.

    Returns
    -------
    float or ndarray, shape (n,)
        P11 (Pa).
    """
    return (tau11 - tau22) / stretch


def uniaxial(material, rate: float, stretch: float, steps: int = 200, hold: float = 0.0, progress=None):
    """Uniaxial stress at constant engineering strain rate (1/s) to a final stretch (-).

    The lateral stretch solves sigma22 = sigma33 = 0 at each step (F = diag(l, lt, lt), isotropic
    material) with the viscoelastic state carried from step to step. It is continued along the
    path from lt = 1 at stretch 1: each step takes the root nearest to the previous step's lateral
    stretch (:func:`nearest_root`), so the branch that starts at J = 1 is followed. Where that
    branch enters the region in which the volumetric energy is not convex (its pressure falls as J
    grows; J > 10^(1/9) = 1.29 for the paper's Ogden term, e.g. stiff fibres pulled far: k2 = 500
    at stretch 3 gives J ~ 18), no physical lateral stretch exists any more: a RuntimeWarning names
    the first stretch and J there and the largest J reached.

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material (isotropic).
    rate : float
        Engineering strain rate (1/s), > 0.
    stretch : float
        Final stretch (-), 0.05 .. 5, not 1.
    steps : int
        Steps of the loading ramp (>= 2).
    hold : float
        Hold time at the final stretch (s).
    progress : callable, optional
        Called after each step with (steps done, steps in all), e.g. to update a progress bar.

    Returns
    -------
    t : ndarray, shape (n,)
        Times (s).
    stretch : ndarray, shape (n,)
        Axial stretch (-).
    nominal : ndarray, shape (n,)
        Nominal stress P11 (Pa).
    lateral : ndarray, shape (n,)
        Lateral stretch (-).

    Raises
    ------
    InputError
        Rate, stretch, steps or hold out of range.
    NumericalError
        No lateral stretch gives zero lateral stress near the previous one, or a non-finite stress.

    Warns
    -----
    RuntimeWarning
        The continued lateral stretch gives a J where the volumetric energy is not convex, or a J
        below :data:`CRUSHED_J` (:func:`crushed_volume`).
    """
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"rate = {rate!r} 1/s must be a positive engineering strain rate.")
    if not (math.isfinite(stretch) and 0.05 <= stretch <= 5.0 and stretch != 1.0):
        raise InputError(f"stretch = {stretch!r} (-) must lie in [0.05, 5] and differ from 1.")
    if not (isinstance(steps, int) and steps >= 2):
        raise InputError(f"steps = {steps!r} must be an integer >= 2.")
    if not (math.isfinite(hold) and hold >= 0.0):
        raise InputError(f"hold = {hold!r} s must be a finite hold time >= 0 at the final stretch (0: none).")
    from scipy.optimize import brentq  # deferred: ~0.2 s to import, and only this study needs it (not cfm drop-test)

    t_load = abs(stretch - 1.0) / rate
    t = np.linspace(0.0, t_load, steps + 1)
    if hold > 0:
        t = np.concatenate([t, t_load + np.linspace(0.0, hold, steps + 1)[1:]])
    lam = 1.0 + np.sign(stretch - 1.0) * rate * np.minimum(t, t_load)
    unstable = None  # first step whose J lies where the volumetric energy is not convex
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

            if n:
                lo, hi = nearest_root(lateral_stress, lat[n - 1])
                if lo is None:
                    raise NumericalError(f"uniaxial: no lateral stretch near {lat[n - 1]:.6g} gives zero lateral "
                                         f"stress at stretch {lam[n]:.6g} (t = {t[n]:g} s).", time=float(t[n]))
                lt = lo if lo == hi else brentq(lateral_stress, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200)
            else:
                lt = 1.0
            _, S, state = lateral_stress(lt, keep=True)
            lat[n] = lt
            P[n] = nominal_uniaxial(lam[n], lam[n] ** 2 * S[0, 0], lt**2 * S[1, 1])  # P11, pressure-free
            if unstable is None and n and not volumetric_convex(material, lam[n], lt):
                unstable = n
            if progress is not None:
                progress(n + 1, t.size)
    bad = ~(np.isfinite(P) & np.isfinite(lat))
    if bad.any():
        k = int(np.argmax(bad))
        raise NumericalError(f"uniaxial: the stress is not finite at step {k} (t = {t[k]:g} s, stretch {lam[k]:g}).",
                             time=float(t[k]), element=k, quantity="stress")
    J = lam * lat**2
    if J.min() < CRUSHED_J:
        k = int(np.argmax(J < CRUSHED_J))
        warnings.warn(f"uniaxial: from stretch {lam[k]:.4g} (t = {t[k]:.4g} s) on, the lateral stretch that gives zero "
                      f"lateral stress ({lat[k]:.4g}) leaves J below {CRUSHED_J:g} ({J[k]:.4g}), down to "
                      f"{crushed_volume(float(J.min()))}",
                      RuntimeWarning, stacklevel=2)
    if unstable is not None:
        k = int(np.argmax(np.abs(J - 1.0)))
        warnings.warn(f"uniaxial: from stretch {lam[unstable]:.4g} (t = {t[unstable]:.4g} s) on, the lateral stretch "
                      f"{lat[unstable]:.4g} that gives zero lateral stress makes J = {J[unstable]:.4g}, where "
                      f"{nonconvex_volumetric(material)}: the bulk modulus cannot hold the lateral pull, and no "
                      f"physical lateral stretch exists. The curve beyond is not physical (J reaches {J[k]:.4g} at "
                      f"stretch {lam[k]:.4g}); lower the stretch or the fibre stiffness (k1, k2), or raise kappa.",
                      RuntimeWarning, stacklevel=2)
    return t, lam, P, lat


def nearest_root(f, x0: float, factor: float = 1.01, max_steps: int = 700):
    """The bracket of the root of ``f`` nearest to ``x0 > 0`` (continuation: the previous step's value).

    Steps outward from x0 on both sides alternately by the ratio ``factor`` (x0 factor^k and
    x0 / factor^k, k = 1 .. max_steps: x0 x/÷ 1066 for the defaults) and returns the first interval
    over which f changes sign. A side where f cannot be evaluated (NumericalError: e.g. an
    exponential overflows) or is not finite stops there.

    Parameters
    ----------
    f : callable
        f(x) -> float.
    x0 : float
        Start (> 0), e.g. the lateral stretch of the previous step (-).
    factor : float
        Ratio between neighbouring trial points (> 1).
    max_steps : int
        Trial points on each side.

    Returns
    -------
    lo, hi : float or None
        An interval with a sign change of f (lo == hi == x0 when f(x0) = 0), or (None, None).
    """

    def value(x):
        try:
            y = float(f(x))
        except NumericalError:
            return math.nan
        return y

    y0 = value(x0)
    if y0 == 0.0:
        return x0, x0
    if not math.isfinite(y0):
        return None, None
    up = down = (x0, y0)  # the last finite point on each side
    for k in range(1, max_steps + 1):
        for side in (0, 1):
            last = up if side == 0 else down
            if last is None:
                continue
            x = x0 * factor**k if side == 0 else x0 / factor**k
            y = value(x)
            if not math.isfinite(y):
                up, down = (None, down) if side == 0 else (up, None)
                continue
            if (y > 0.0) != (last[1] > 0.0) or y == 0.0:
                return (last[0], x) if side == 0 else (x, last[0])
            up, down = ((x, y), down) if side == 0 else (up, (x, y))
        if up is None and down is None:
            break
    return None, None


def volumetric_convex(material, stretch: float, lateral: float, h: float = 1e-6) -> bool:
    """Whether the material's volumetric energy is convex at J = stretch * lateral^2 (U''(J) >= 0).

    :func:`volumetric_convex_at` at that J (the pressure depends on J alone).

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material.
    stretch, lateral : float
        Axial and lateral stretch (-).
    h : float
        Relative step in J of the difference (-).

    Returns
    -------
    bool
        True where U''(J) >= 0 (or the material has no volumetric term).
    """
    return bool(volumetric_convex_at(material, stretch * lateral**2, h)[0])


def volumetric_convex_at(material, J, h: float = 1e-6) -> np.ndarray:
    """Whether the material's volumetric energy U is convex (U''(J) >= 0) at each volume ratio J.

    The pressure p = U'(J) is read from the volumetric second Piola-Kirchhoff stress
    S_vol = J p C^-1 of :func:`cfm_core.material.reference.pk2_parts` in pure dilatation,
    F = J^(1/3) I (isochoric stretches 1, so no other term can overflow), at J and J (1 + h);
    convex where p does not fall by more than 1e-12 of itself. For the paper's Ogden term
    U = kappa/81 (9 ln J + J^-9 - 1), U'' = kappa/9 (10 J^-11 - J^-2): convex for J <= 10^(1/9) = 1.29
    (in compression too), not beyond.

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material.
    J : float or array_like, shape (n,)
        Volume ratios det F (-), > 0.
    h : float
        Relative step in J of the difference (-).

    Returns
    -------
    ndarray of bool, shape (n,)
        True where U''(J) >= 0 (or the material has no volumetric term); True where J is not a
        positive finite number (nothing to judge).

    Raises
    ------
    NumericalError
        The volumetric term is not finite at a J (e.g. J = 1e-32 for the Ogden term).
    """
    J = np.atleast_1d(np.asarray(J, dtype=np.float64)).reshape(-1)
    ok = np.isfinite(J) & (J > 0.0)
    out = np.ones(J.shape, dtype=bool)
    if not ok.any():
        return out
    Jk = J[ok]
    p = []
    for Jh in (Jk, Jk * (1.0 + h)):
        a = Jh ** (1.0 / 3.0)
        S_vol = ref.pk2_parts(material, a[:, None, None] * np.eye(3))[1]
        p.append(S_vol[:, 1, 1] * a**2 / Jh)   # S_vol = J p C^-1 = J p a^-2 I
    drop = p[1] - p[0]
    out[ok] = ~((drop < 0.0) & (np.abs(drop) > 1e-12 * np.maximum(np.abs(p[0]), 1e-300)))
    return out


def crushed_volume(J: float) -> str:
    """The words every driver uses for a state below :data:`CRUSHED_J`.

    Parameters
    ----------
    J : float
        The smallest volume ratio reached (-).

    Returns
    -------
    str
        "J = ... (... % of the volume gone): ..." saying that the stresses there are the volumetric
        term's, outside what any test of the tissue measured.
    """
    return (f"J = {J:.4g} ({100 * (1 - J):.3g} % of the volume gone): a nearly "
            f"incompressible tissue does not lose that much volume, so the state is crushed beyond the "
            f"model's range; the stresses there come from the volumetric term alone and no test of the tissue "
            f"measured them (check the stretch, the units of the moduli, or a fibre stiffness that holds the "
            f"lateral expansion back).")


def nonconvex_volumetric(material) -> str:
    """The words every driver uses for a J where ``material``'s volumetric energy is not convex.

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material.

    Returns
    -------
    str
        "the volumetric energy of material '...' is not convex (its pressure falls as J grows; ...)".
    """
    return (f"the volumetric energy of material '{material.name}' is not convex (its pressure falls as J grows; "
            f"J > 10^(1/9) = 1.29 for the Ogden term)")
