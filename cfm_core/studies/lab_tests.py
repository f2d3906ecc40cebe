"""Laboratory material tests: reading their curves and simulating them at a material point.

A test is a homogeneous deformation along axis 1 (SI units; stretches and shear dimensionless):

============  ==========================================  ==============================  =========
kind          deformation gradient F                      condition solved per step       stress
============  ==========================================  ==============================  =========
uniaxial      diag(l, q, q)                               S22 = S33 = 0 (q unknown)       P11
relaxation    diag(l, q, q), l ramps then holds           S22 = S33 = 0 (q unknown)       P11
shear         I + gamma e1 (x) e2 (simple shear)          none (F prescribed)             P12
equibiaxial   diag(l, l, q)                               S33 = 0 (q unknown)             P11
confined      diag(l, 1, 1) (lateral strain held at 0)    none (F prescribed)             P11
============  ==========================================  ==============================  =========

P = F S is the nominal (first Piola-Kirchhoff) stress in Pa, S = 2 d psi / d C, with the Prony
series of the material on the isochoric part (recurrence of :mod:`cfm_core.material.prony`). The
material is undeformed and relaxed before the first row; a deformed first row is a jump.

Vectorised over the time steps: for the diagonal kinds the principal stretches are the diagonal of
F, and the generated kernels (``psi_grad``, ``psi_hess``) are evaluated on all steps at once; the
unknown lateral stretch q of every step is found together by Newton iterations with the diagonal
of the (lower-triangular, causal) Jacobian, which converge because the history terms are small
next to the volumetric stiffness; only the Prony recurrence loops over the steps (a few arrays of
3 numbers). Shear evaluates the stresses of all steps with :func:`cfm_core.material.reference.pk2_parts`.

CSV of a test: lines starting with '#' and blank lines are skipped; the first other line is the
header, naming ``t`` (s), ``stretch`` (-, all kinds but shear) or ``shear`` (-, kind shear) and
``stress`` (Pa, the nominal stress of the table above; ``nominal_stress`` is read as ``stress``, so
the output of ``cfm point --uniaxial`` is a valid uniaxial test); a name may carry its unit in brackets
(``t [s]``, ``stress [Pa]``): another unit (e.g. kPa) is an error. Other columns are ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, NumericalError
from ..material import prony
from ..material import reference as ref
from ..simulation.point import nominal_uniaxial
from ..tables import as_float, read_table, shown

#: kind -> (deformation column, what it is)
KINDS = {
    "uniaxial": ("stretch", "uniaxial stress (tension or compression) at a constant engineering strain rate"),
    "relaxation": ("stretch", "uniaxial stress relaxation: ramp at the rate, then hold"),
    "shear": ("shear", "simple shear at a constant shear rate; stress = nominal shear stress P12"),
    "equibiaxial": ("stretch", "equibiaxial tension: equal stretch along 1 and 2, traction-free along 3"),
    "confined": ("stretch", "confined compression: stretch along 1, lateral stretches held at 1"),
}
UNITS = {"t": "s", "stretch": "-", "shear": "-", "stress": "Pa"}


def undeformed(kind: str) -> float:
    """The deformation column's value at the undeformed state of a test.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.

    Returns
    -------
    float
        0 for shear (the shear gamma), 1 for the others (a stretch) (-).
    """
    return 0.0 if kind == "shear" else 1.0
#: Newton on the lateral stretch has converged when no step moves it by more than this fraction (a few
#: units of the last bit), whatever the lateral stress left.
ROUNDOFF_STEP = 8 * np.finfo(float).eps
#: Fewest data rows of a test.
MIN_ROWS = 5
#: Largest relative difference between the stated rate and the file's loading rate.
RATE_TOLERANCE = 0.1
#: Largest change of the deformation (stretch or shear, -) over one step of the simulation. The Prony
#: recurrence is exact for a stress linear in time over a step, and the stress is not linear in the
#: stretch: on a file's own rows (a fit of 6 rows of a uniaxial curve to 0.6: k1 +2.8 % with an
#: interval excluding the truth) the simulation was biased by the rows' spacing. Each interval between
#: rows is cut into equal steps of at most this change (the deformation linear in time between rows).
MAX_STEP = 0.0025
#: Range of the largest |nominal stress| of a test (Pa): outside it the column is not a stress in Pa (a
#: stress scaled by 1e-300 underflowed the fit's residuals to inf).
STRESS_RANGE = (1e-6, 1e12)
#: Measurement noise tolerated in the deformation column, relative to the largest deformation: a value on
#: the other side of the undeformed state, or back below the largest so far, by more is an error.
NOISE = 0.02


@dataclass(frozen=True)
class LabTest:
    """One measured curve.

    Attributes
    ----------
    name : str
        Label of the curve (file stem, made unique).
    path : str
        File it was read from.
    kind : str
        One of :data:`KINDS`.
    rate : float
        Nominal loading rate, engineering strain or shear rate (1/s).
    weight : float
        Weight in the objective (-).
    t : ndarray, shape (n,)
        Times (s), increasing.
    x : ndarray, shape (n,)
        Stretch (-) or, for shear, the shear gamma (-).
    P : ndarray, shape (n,)
        Measured nominal stress (Pa).
    """

    name: str
    path: str
    kind: str
    rate: float
    weight: float
    t: np.ndarray
    x: np.ndarray
    P: np.ndarray

    @property
    def scale(self) -> float:
        """Largest |measured nominal stress| (Pa), the residual scale of this curve."""
        return float(np.max(np.abs(self.P)))


def read_lab_test(path, kind: str, rate: float, weight: float = 1.0, name: str | None = None) -> LabTest:
    """Read and check one test curve (see the module docstring for the CSV).

    Parameters
    ----------
    path : str or Path
        CSV file with columns t (s), stretch or shear (-), stress (Pa).
    kind : str
        One of :data:`KINDS`.
    rate : float
        Nominal engineering strain (or shear) rate of the loading, 1/s, > 0; checked against the file's
        mean rate from 10 % to 90 % of the largest deformation (within :data:`RATE_TOLERANCE`).
    weight : float
        Weight of the curve in the objective (-), > 0.
    name : str, optional
        Label of the curve (default: the file stem).

    Returns
    -------
    LabTest

    Raises
    ------
    InputError
        Naming the file, line, field, value and what is allowed, for any problem.
    """
    p = Path(path)
    if kind not in KINDS:
        raise InputError(f"test '{path}': kind {kind!r} is not known; allowed: {', '.join(KINDS)}.")
    if not (isinstance(rate, (int, float)) and math.isfinite(as_float(rate)) and rate > 0):
        raise InputError(f"test '{path}': rate = {shown(rate)} 1/s is not allowed; give the loading's engineering "
                         f"strain (or shear) rate, a positive number in 1/s.")
    if not (isinstance(weight, (int, float)) and math.isfinite(as_float(weight)) and weight > 0):
        raise InputError(f"test '{path}': weight = {shown(weight)} is not allowed; give a positive number (-).")
    deformation = KINDS[kind][0]
    table = read_table(p, ["t", deformation], {**UNITS, "nominal_stress": "Pa"}, what="test file")
    # the fit compares nominal stress: a column named so wins over a plain "stress" (lab exports often carry
    # the true stress beside the engineering one; cfm point --uniaxial writes nominal_stress)
    stress = next((c for c in ("nominal_stress", "stress") if c in table.columns), None)
    if stress is None:
        raise InputError(f"test file '{p}': the header names the columns {list(table.columns)} but no stress; a "
                         f"{kind} test needs t (s), {deformation} (-) and stress (nominal, Pa), e.g. "
                         f"'t,{deformation},stress'.")
    if table.data.shape[0] < MIN_ROWS:
        raise InputError(f"test file '{p}' has {table.data.shape[0]} data rows; at least {MIN_ROWS} are needed.")
    t, x, P = (table.column(c) for c in ("t", deformation, stress))
    lineno = list(table.lines)
    if t[0] < 0:
        raise InputError(f"test file '{p}', line {lineno[0]}: t = {float(t[0])!r} s is negative; t starts at 0 or later.")
    _check_deformation(p, kind, x, lineno)
    _check_stress(p, kind, x, P, lineno)
    _check_rate(p, kind, rate, t, x)
    return LabTest(name or p.stem, str(p), kind, float(rate), float(weight), t, x, P)


def _check_deformation(p, kind, x, lineno):
    base = undeformed(kind)
    if kind == "shear":
        bad = np.flatnonzero(np.abs(x) > 5.0)
        allowed = "|shear| <= 5"
    else:
        bad = np.flatnonzero((x < 0.05) | (x > 5.0))
        allowed = "0.05 <= stretch <= 5"
    if bad.size:
        k = bad[0]
        strain = (" The column holds a stretch l = 1 + engineering strain (undeformed: 1); a strain column "
                  "(undeformed: 0) must be converted." if kind != "shear" and np.all(np.abs(x) < 1.0) else "")
        raise InputError(f"test file '{p}', line {lineno[k]}: {KINDS[kind][0]} = {float(x[k])!r} is outside "
                         f"{allowed}.{strain}")
    d = x - base
    peak = float(np.abs(d).max())
    if peak == 0.0:
        raise InputError(f"test file '{p}': the {KINDS[kind][0]} never changes; a test must deform the material.")
    sign = np.sign(d[np.argmax(np.abs(d))])
    tol = NOISE * peak
    other = np.flatnonzero(sign * d < -tol)
    if other.size:
        k = int(other[0])
        raise InputError(f"test file '{p}', line {lineno[k]}: {KINDS[kind][0]} = {float(x[k])!r} crosses the undeformed "
                         f"value {base:g} by more than {100 * NOISE:g} % of the largest deformation; one test is "
                         f"either tension or compression (split the file).")
    limits = {"equibiaxial": (1.0, "tension (stretch >= 1)"), "confined": (-1.0, "compression (stretch <= 1)")}
    if kind in limits and sign != limits[kind][0]:
        raise InputError(f"test file '{p}': the largest stretch deviation is {float(x[np.argmax(np.abs(d))])!r}; {_article(kind)} "
                         f"test is {limits[kind][1]}.")
    back = np.flatnonzero(sign * d < np.maximum.accumulate(sign * d) - tol)
    if back.size:
        k = int(back[0])
        raise InputError(f"test file '{p}', line {lineno[k]}: {KINDS[kind][0]} = {float(x[k])!r} moves back towards "
                         f"{base:g} by more than {100 * NOISE:g} % of the largest deformation; a {kind} test loads "
                         f"monotonically (unloading is not supported; cut the file at the largest deformation).")


def _article(kind: str) -> str:
    """'a uniaxial', 'an equibiaxial': the kind with its indefinite article."""
    return f"{'an' if kind[0] in 'aeio' else 'a'} {kind}"


def _check_stress(p, kind, x, P, lineno):
    """A stress column that records a stress, with the sign of the deformation: nominal stress is positive
    in tension (and positive shear), negative in compression, for every kind of :data:`KINDS`."""
    peak = float(np.abs(P).max())
    if not peak > 0.0:
        raise InputError(f"test file '{p}': the stress column is 0 on every line; a test must record the nominal "
                         f"stress (Pa) the deformation caused.")
    lo, hi = STRESS_RANGE
    if not lo <= peak <= hi:
        raise InputError(f"test file '{p}': the largest |stress| is {peak:.3g} Pa, outside {lo:g} - {hi:g} Pa, which no "
                         f"material test records (soft tissue: kPa to MPa); give the nominal stress in Pa.")
    d = x - undeformed(kind)
    k = int(np.argmax(np.abs(d)))
    if P[k] * d[k] < 0.0 and abs(P[k]) > NOISE * peak:
        what = "shear" if kind == "shear" else ("tension" if d[k] > 0 else "compression")
        sign = "positive" if d[k] > 0 else "negative"
        raise InputError(f"test file '{p}', line {lineno[k]}: stress = {float(P[k]):.6g} Pa at the largest "
                         f"deformation ({KINDS[kind][0]} = {float(x[k]):.6g}, {what}); the nominal stress of "
                         f"{_article(kind)} test in {what} is {sign} (tension positive, compression negative). Flip the "
                         f"sign of the stress column.")


def _check_rate(p, kind, rate, t, x):
    """The stated rate against the file's: the mean rate between the first rows at 10 % and 90 % of the
    largest deformation (robust to noise and to a hold)."""
    d = np.abs(x - undeformed(kind))
    i10 = int(np.argmax(d >= 0.1 * d.max()))
    i90 = int(np.argmax(d >= 0.9 * d.max()))
    if i90 <= i10 or t[i90] <= t[i10]:
        return  # a jump to the final deformation: no loading rate to compare
    measured = float((d[i90] - d[i10]) / (t[i90] - t[i10]))
    if abs(measured - rate) > RATE_TOLERANCE * rate:
        raise InputError(f"test '{p}': the stated rate {rate:g} 1/s differs from the file's loading rate "
                         f"{measured:.4g} 1/s (from 10 % to 90 % of the largest deformation) by more than "
                         f"{100 * RATE_TOLERANCE:g} %; give the rate of the test (engineering strain or shear rate, "
                         f"1/s) or check the t column (s).")


# ----------------------------------------------------------------------------- simulation
def _hess3(h):
    """(n, 6) Hessian entries (11, 22, 33, 12, 23, 13) -> (n, 3, 3)."""
    out = np.empty((h.shape[0], 3, 3))
    for k, (a, b) in enumerate(((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))):
        out[:, a, b] = out[:, b, a] = h[:, k]
    return out


def _principal(material, m):
    """Instantaneous principal PK2 parts S0_iso, S_vol (n, 3) and their d/dm (n, 3, 3) at eigenvalues m (n, 3)."""
    k = material.kernels("numpy")
    p = material.param_array()
    with np.errstate(over="ignore", invalid="ignore"):
        g = np.stack(k.psi_grad(m[:, 0], m[:, 1], m[:, 2], p), axis=1)
        h = np.stack(k.psi_hess(m[:, 0], m[:, 1], m[:, 2], p), axis=1)
    if not (np.isfinite(g).all() and np.isfinite(h).all()):
        i = int(np.argmax(~(np.isfinite(g).all(axis=1) & np.isfinite(h).all(axis=1))))
        raise NumericalError(f"material '{material.name}': stress not finite at stretches^2 {m[i].tolist()} "
                             f"(exponential overflow?).", quantity="stress")
    return 2 * g[:, :3], 2 * g[:, 3:], 2 * _hess3(h[:, :6]), 2 * _hess3(h[:, 6:])


def _segments(t):
    """(start, stop, dt) of the runs of equal step dt (s); the first row is its own run with dt = 0."""
    dt = np.diff(t)
    if dt.size == 0:
        return [(0, 1, 0.0)]
    change = np.flatnonzero(np.abs(np.diff(dt)) > 1e-9 * dt[:-1]) + 1  # dt[k] differs from dt[k - 1]
    starts = np.concatenate([[0], change])
    stops = np.concatenate([change, [dt.size]])
    return [(0, 1, 0.0)] + [(int(a) + 1, int(b) + 1, float(dt[a])) for a, b in zip(starts, stops)]


def _viscous(material, t, S0):
    """Isochoric stress with the Prony recurrence, and the per-step factor d S_iso / d S0 (n,).

    The recurrence H_n = decay H_(n-1) + gain (S0_n - S0_(n-1)) (:func:`cfm_core.material.prony.step_factors`,
    S0 = 0 before the first row) is a first-order linear filter with constant coefficients on each run of
    equal steps: ``scipy.signal.lfilter`` per run and Prony term, the state carried between runs.
    """
    from scipy.signal import lfilter

    gammas, taus = material.prony_arrays()
    if gammas.size == 0:
        return S0, np.ones(t.size)
    g_inf = prony.gamma_inf(gammas)
    dS = np.diff(S0, axis=0, prepend=np.zeros_like(S0[:1]))
    H = np.zeros_like(S0)
    eff = np.full(t.size, g_inf)
    state = np.zeros((gammas.size,) + S0.shape[1:])
    for a, b, dt in _segments(t):
        decay, gain = prony.step_factors(dt, gammas, taus)
        eff[a:b] += gain.sum()
        for i in range(gammas.size):
            y, _ = lfilter([gain[i]], [1.0, -decay[i]], dS[a:b], axis=0, zi=decay[i] * state[i][None])
            H[a:b] += y
            state[i] = y[-1]
    return g_inf * S0 + H, eff


def _diagonal(material, t, axis1, free, guess=None, iterations=100):
    """Principal PK2 (n, 3) along stretches (axis1, ...) with the ``free`` axes' common stretch q solving S = 0.

    axis1: (n, 3) fixed stretches (the free entries are ignored); free: tuple of free axes (may be empty);
    guess: (n,) starting q (e.g. the previous solution for nearby parameters). Returns (S (n, 3), stretches (n, 3)).
    """
    lam = axis1.copy()
    if free and guess is not None and guess.shape == (t.size,):
        lam[:, list(free)] = guess[:, None]
    elif free:  # start from the volume-preserving lateral stretch
        fixed = [a for a in range(3) if a not in free]
        lam[:, list(free)] = (np.prod(lam[:, fixed], axis=1) ** (-1.0 / len(free)))[:, None]
    a0 = free[0] if free else None
    for _ in range(iterations):
        with np.errstate(over="ignore"):
            m = lam**2
        if not np.isfinite(m).all():  # a Newton step out of the float range (a guess far from the solution)
            k = int(np.argmax(~np.isfinite(m).all(axis=1)))
            raise NumericalError(f"material '{material.name}': the lateral stretch diverged (to {lam[k, a0]:.6g} at "
                                 f"t = {t[k]:.6g} s, axial stretch {lam[k, 0]:.6g}): no lateral stretch with zero "
                                 f"lateral stress was found there.", quantity="lateral stretch")
        S0, Sv, dS0, dSv = _principal(material, m)
        S_iso, eff = _viscous(material, t, S0)
        S = S_iso + Sv
        if not free:
            return S, lam
        r = S[:, a0]
        scale = max(float(np.abs(S).max()), 1e-30)
        q = lam[:, a0]
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # a step out of range: said above
            d = sum(eff * dS0[:, a0, b] + dSv[:, a0, b] for b in free) * 2 * q
            step = r / d
        # converged: the lateral stress is ~0 next to the stresses, or the lateral stretch moves by no more
        # than its last bits (near the incompressible limit the lateral stress cannot fall below
        # kappa times the round-off of J: at kappa = 6.7e8 Pa that is above 1e-11 of the stresses)
        if np.abs(r).max() <= 1e-11 * scale or np.all(np.abs(step) <= ROUNDOFF_STEP * np.abs(q)):
            return S, lam
        lam[:, list(free)] = np.maximum(q - step, 0.5 * q)[:, None]
    k = int(np.argmax(np.abs(r)))
    raise NumericalError(f"material '{material.name}': the lateral stretch did not converge in {iterations} "
                         f"iterations (largest lateral stress {np.abs(r).max():.3g} Pa, at t = {t[k]:.6g} s, axial "
                         f"stretch {lam[k, 0]:.6g}, lateral {lam[k, a0]:.6g}): the stresses grow too steeply with the "
                         f"stretch there for the simultaneous Newton iterations (e.g. a very large fibre exponent k2).",
                         quantity="lateral stretch")


def simulate(material, test: LabTest, memory: dict | None = None) -> np.ndarray:
    """Nominal stress of ``material`` along the test's deformation history (table above).

    Parameters
    ----------
    material : Material
        Bound material (its moduli convention and Prony series apply).
    test : LabTest
        The test (kind, t in s, x stretch or shear).
    memory : dict, optional
        Kept between calls for the same test (a fit): the simulation's time rows (:func:`_grid`) and
        the last lateral stretches, reused as the next starting guess, which saves most Newton
        iterations. Where Newton fails from that guess it is tried again from the volume-preserving
        lateral stretch (what a call without memory starts from), so a memory never makes a
        simulation fail that succeeds without one; the result agrees with a call without memory to
        the Newton tolerance (about 1e-11 of the largest stress), not to the bit.

    Returns
    -------
    ndarray, shape (n,)
        Nominal stress P11 (P12 for shear) in Pa at the test's rows, simulated on the rows cut into
        steps of at most :data:`MAX_STEP` change of the deformation (:func:`_grid`).

    Raises
    ------
    NumericalError
        Non-finite stress (exponential overflow) or a lateral stretch that does not converge.
    """
    if memory is None:
        memory = {}
    if "grid" not in memory:
        memory["grid"] = _grid(test)
    t, x, rows = memory["grid"]
    n = t.size
    if test.kind == "shear":
        F = np.tile(np.eye(3), (n, 1, 1))
        F[:, 0, 1] = x
        S0, Sv = ref.pk2_parts(material, F)
        S_iso, _ = _viscous(material, t, S0)
        S = S_iso + Sv
        return (S[:, 0, 1] + x * S[:, 1, 1])[rows]
    stretches = np.ones((n, 3))
    stretches[:, 0] = x
    free = {"uniaxial": (1, 2), "relaxation": (1, 2), "equibiaxial": (2,), "confined": ()}[test.kind]
    if test.kind == "equibiaxial":
        stretches[:, 1] = x
    guess = memory.get("lateral")
    try:
        S, lam = _diagonal(material, t, stretches, free, guess)
    except NumericalError:
        if guess is None:
            raise
        # the remembered stretches belong to other parameters (another start of a fit, far away): where the
        # volumetric energy is not convex they lead Newton away; the volume-preserving start decides
        memory.pop("lateral", None)
        S, lam = _diagonal(material, t, stretches, free)
    if free:
        memory["lateral"] = lam[:, free[0]].copy()
    if not free:
        return (lam[:, 0] * S[:, 0])[rows]
    a = free[0]  # traction-free axis: P11 = (tau11 - tau_aa) / l1, in which the pressure's round-off cancels
    return nominal_uniaxial(lam[:, 0], lam[:, 0] ** 2 * S[:, 0], lam[:, a] ** 2 * S[:, a])[rows]


def _grid(test: LabTest):
    """The simulation's time rows: (t (s), deformation (-), index of each data row in them), shapes (m,),
    (m,), (n,).

    Each interval between data rows is cut into equal steps of at most :data:`MAX_STEP` change of the
    deformation, linear in time. In a relaxation test an interval whose deformation changes slower than
    the stated rate (by more than :data:`RATE_TOLERANCE`; a ramp recorded by its end points only) is the
    ramp at the stated rate from the interval's start, then the hold: the test's definition (ramp at the
    rate, then hold), where the straight line between the rows would be a slower ramp."""
    t, x = test.t, test.x
    ts, xs, rows = [t[:1]], [x[:1]], [0]
    count = 1
    for k in range(1, t.size):
        t0, t1, x0, x1 = float(t[k - 1]), float(t[k]), float(x[k - 1]), float(x[k])
        dx = abs(x1 - x0)
        m = max(1, math.ceil(dx / MAX_STEP))
        f = np.arange(1, m + 1) / m
        if test.kind == "relaxation" and dx > 0.0 and dx < (1.0 - RATE_TOLERANCE) * test.rate * (t1 - t0):
            seg_t = np.append(t0 + f * (dx / test.rate), t1)
            seg_x = np.append(x0 + f * (x1 - x0), x1)
        else:
            seg_t = t0 + f * (t1 - t0)
            seg_x = x0 + f * (x1 - x0)
        seg_t[-1], seg_x[-1] = t1, x1          # the data row itself, to the bit
        ts.append(seg_t)
        xs.append(seg_x)
        count += seg_t.size
        rows.append(count - 1)
    return np.concatenate(ts), np.concatenate(xs), np.asarray(rows)
