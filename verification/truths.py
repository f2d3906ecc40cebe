"""Independent truths: references that share no code with any backend or with the package's
material evaluation (no generated code, no :mod:`cfm_core.material.reference`, no Prony recurrence).

- :func:`cfm_energy_mp`, :func:`cauchy_mp`: the paper's Eq. 2-7 written out in mpmath, stress by
  high-precision central differences of the energy (40 digits). Slow (~50 ms per F): used on a
  few points per history, to check :func:`cfm_pk2_parts` and the backends.
- :func:`cfm_pk2_parts`: Eq. 2-7 differentiated by hand in numpy (principal form, isochoric and
  volumetric second Piola-Kirchhoff stress, Pa); vectorised, so it serves every point of a history.
- :func:`prony_convolution`: the hereditary integral S_iso(t) = int g(t - s) dS0/ds ds summed
  directly with g(t) = gamma_inf + sum_i gamma_i exp(-t / tau_i) written out here, exact for an
  instantaneous stress S0 that is piecewise linear in time between the rows (what the exact
  exponential recurrence assumes). No recurrence, no decay factors: a removed or wrong decay in
  the package's update shows as a difference.
- :func:`convolution_reference`: the same integral on a fine resampling with F linear in time
  between rows (tests/cfm_core/test_prony.py's reference).
- :func:`stress_history`, :func:`uniaxial_force`: Cauchy stress along a history and the quasi-static
  uniaxial-stress reaction of the single element, both from the two functions above.

Moduli convention (docs/conventions.md section 2) applied here from the material's *named* values:
with ``moduli="long-term"`` and a Prony series the isochoric energy is the written one divided by
gamma_inf = 1 - sum gamma_i; elastic materials or ``moduli="instantaneous"`` use it as written.
Units: stresses in Pa, times in s, forces in N.
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
from scipy.optimize import brentq

#: Parameter names of the CFM (paper Table 1, SI): lipid c (Pa), fibres k1 (Pa), k2 (-), bulk kappa (Pa).
CFM_KEYS = ("c", "k1", "k2", "kappa")


def cfm_energy_mp(C, c=10.0, k1=1320.0, k2=1.66, kappa=666.1e3, s_iso=1.0):
    """Strain energy per reference volume (Pa) of the CFM at right Cauchy-Green tensor C (3x3
    nested lists or mpmath matrix), paper Eq. 2-7 in mpmath; ``s_iso`` scales the isochoric part."""
    Cm = mp.matrix(C)
    ev, _ = mp.eigsy(Cm)
    J = mp.sqrt(mp.det(Cm))
    mb = [ev[i] * J ** (-mp.mpf(2) / 3) for i in range(3)]
    w = c / 2 * (mb[0] + mb[1] + mb[2] - 3)
    for a, b in ((0, 1), (1, 2), (0, 2)):
        x = (mb[a] + mb[b]) / 2
        if x >= 1:
            w += k1 / (2 * k2) * (mp.exp(k2 * (x - 1) ** 2) - 1)
    return s_iso * w + kappa / 81 * (9 * mp.log(J) + J ** -9 - 1)


def cauchy_mp(F, **params) -> np.ndarray:
    """Cauchy stress (3, 3) in Pa at F (3, 3): sigma = J^-1 F (2 dW/dC) F^T with dW/dC by central
    differences of :func:`cfm_energy_mp` at 40 digits (step 1e-15, error ~1e-30 relative)."""
    with mp.workdps(40):
        Fm = mp.matrix(np.asarray(F, dtype=float).tolist())
        C = Fm.T * Fm
        h = mp.mpf("1e-15")
        S = mp.matrix(3, 3)
        for i in range(3):
            for j in range(i, 3):
                Cp, Cm_ = C.copy(), C.copy()
                for (a, b) in {(i, j), (j, i)}:
                    Cp[a, b] += h / 2 if i != j else h
                    Cm_[a, b] -= h / 2 if i != j else h
                d = (cfm_energy_mp(Cp.tolist(), **params) - cfm_energy_mp(Cm_.tolist(), **params)) / (2 * h)
                S[i, j] = S[j, i] = 2 * d
        sig = Fm * S * Fm.T / mp.det(Fm)
        return np.array(sig.tolist(), dtype=float)


def iso_scale(material) -> float:
    """Factor on the written isochoric energy giving the instantaneous one (-), from the
    material's named Prony values (docs/conventions.md section 2)."""
    if material.elastic or material.moduli == "instantaneous":
        return 1.0
    gammas, _ = prony_values(material)
    return 1.0 / (1.0 - math.fsum(gammas))


def prony_values(material) -> tuple[list[float], list[float]]:
    """(gammas (-), taus (s)) read from the named values g1, tau1, g2, ...; empty when elastic."""
    if material.elastic:
        return [], []
    v, gammas, taus, i = material.values, [], [], 1
    while f"g{i}" in v:
        gammas.append(float(v[f"g{i}"]))
        taus.append(float(v[f"tau{i}"]))
        i += 1
    return gammas, taus


def cfm_params(material) -> dict:
    """Keyword arguments of :func:`cfm_energy_mp` for a bound CFM material (SI)."""
    if material.name != "cfm":
        from cfm_core.errors import InputError

        raise InputError(f"the independent truths are written for the 'cfm' material only, not {material.name!r}.")
    return {**{k: float(material.values[k]) for k in CFM_KEYS}, "s_iso": iso_scale(material)}


def cfm_pk2_parts(F, c=10.0, k1=1320.0, k2=1.66, kappa=666.1e3, s_iso=1.0) -> tuple[np.ndarray, np.ndarray]:
    """(S_iso, S_vol), each (n, 3, 3) in Pa, instantaneous isochoric and volumetric second
    Piola-Kirchhoff stress of the CFM at F (n, 3, 3), differentiated by hand (paper Eq. 2-7).

    With m_a the eigenvalues of C, mb_a = J^-2/3 m_a, w_b = dW/dmb_b = s_iso (c/2 + sum over the two
    pairs (b, d) of f'(x_bd) / 2), f'(x) = k1 (x - 1) exp(k2 (x - 1)^2) for x >= 1 (0 below):
    dW_iso/dm_a = J^-2/3 (w_a - sum_b w_b m_b / (3 m_a)), S_iso = 2 sum_a dW_iso/dm_a N_a N_a^T;
    U'(J) = kappa/9 (1/J - J^-10), S_vol = J U'(J) C^-1.
    """
    F = np.asarray(F, dtype=float).reshape(-1, 3, 3)
    C = np.einsum("nki,nkj->nij", F, F)
    m, N = np.linalg.eigh(C)
    J = np.sqrt(np.prod(m, axis=1))
    jm = J ** (-2.0 / 3.0)
    mb = m * jm[:, None]
    w = np.full_like(m, c / 2)
    for a, b in ((0, 1), (1, 2), (0, 2)):
        x = 0.5 * (mb[:, a] + mb[:, b])
        with np.errstate(over="raise"):
            fp = np.where(x >= 1.0, k1 * (x - 1.0) * np.exp(k2 * (x - 1.0) ** 2), 0.0)
        w[:, a] += 0.5 * fp
        w[:, b] += 0.5 * fp
    w *= s_iso
    dWdm = jm[:, None] * (w - np.sum(w * m, axis=1)[:, None] / (3.0 * m))
    S_iso = np.einsum("na,nia,nja->nij", 2.0 * dWdm, N, N)
    dU = kappa / 9.0 * (1.0 / J - J ** -10.0)
    S_vol = (J * dU)[:, None, None] * np.linalg.inv(C)
    return S_iso, S_vol


def relaxation(t, gammas, taus) -> np.ndarray:
    """g(t) = gamma_inf + sum_i gamma_i exp(-t / tau_i) (-), t in s (written out here on purpose)."""
    t = np.asarray(t, dtype=float)
    g = np.full_like(t, 1.0 - math.fsum(gammas))
    for gam, tau in zip(gammas, taus):
        g = g + gam * np.exp(-t / tau)
    return g


def _g_integral(a, b, gammas, taus) -> np.ndarray:
    """int_a^b g(u) du (s) for lags 0 <= a <= b (arrays), in closed form."""
    out = (1.0 - math.fsum(gammas)) * (b - a)
    for gam, tau in zip(gammas, taus):
        out = out + gam * tau * (np.exp(-a / tau) - np.exp(-b / tau))
    return out


def _conv_row(t, S0_first, dS, dt, i, gammas, taus) -> np.ndarray:
    """S_iso (9,) at row i of :func:`prony_convolution` (dS (n-1, 9) increments, dt (n-1,) steps)."""
    a = t[i] - t[1:i + 1]  # lag at the end of each step k = 1..i
    b = t[i] - t[:i]       # lag at its start
    pos = dt[:i] > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        wgt = np.where(pos, _g_integral(a, b, gammas, taus) / np.where(pos, dt[:i], 1.0),
                       relaxation(a, gammas, taus))
    return relaxation(t[i] - t[0], gammas, taus) * S0_first + wgt @ dS[:i]


def prony_convolution(t, S0, gammas, taus, rows=None) -> np.ndarray:
    """Hereditary isochoric stress (n, 3, 3) in Pa at times t (n,) s, for an instantaneous stress
    S0 (n, 3, 3) Pa that jumps from 0 to S0[0] at t[0] and is linear in time between rows:

        S_iso(t_n) = g(t_n - t_0) S0_0 + sum_{k=1..n} (S0_k - S0_{k-1}) / (t_k - t_{k-1})
                     x int_{t_{k-1}}^{t_k} g(t_n - s) ds

    summed directly for every n (O(n^2)); a zero-length step is a jump, weighted g(t_n - t_k).
    ``rows``: evaluate only at these indices (default all)."""
    t = np.asarray(t, dtype=float)
    S0 = np.asarray(S0, dtype=float)
    rows = range(t.size) if rows is None else rows
    if not gammas:
        return S0[list(rows)].copy()
    dS = np.diff(S0, axis=0).reshape(-1, 9)
    dt = np.diff(t)
    first = S0[0].reshape(9)
    return np.array([_conv_row(t, first, dS, dt, i, gammas, taus) for i in rows]).reshape(-1, 3, 3)


def _cauchy(F, S) -> np.ndarray:
    J = np.linalg.det(F)
    return np.einsum("nik,nkl,njl->nij", F, S, F) / J[:, None, None]


def stress_history(material, t, F) -> np.ndarray:
    """Cauchy stress (n, 6) in Pa, order 11, 22, 33, 12, 23, 13, of a CFM material along F (n, 3, 3)
    at times t (n,) s, relaxed before t[0]: :func:`cfm_pk2_parts` and :func:`prony_convolution`."""
    F = np.asarray(F, dtype=float).reshape(-1, 3, 3)
    p = cfm_params(material)
    S_iso0, S_vol = cfm_pk2_parts(F, **p)
    gammas, taus = prony_values(material)
    sig = _cauchy(F, prony_convolution(t, S_iso0, gammas, taus) + S_vol)
    return np.stack([sig[:, 0, 0], sig[:, 1, 1], sig[:, 2, 2], sig[:, 0, 1], sig[:, 1, 2], sig[:, 0, 2]], axis=1)


def convolution_reference(material, t_rows, F_rows, sub=4000, pk2_parts=None) -> np.ndarray:
    """Cauchy stress (n, 3, 3) in Pa with F linear in time between rows: the hereditary integral
    on ``sub`` sub-steps per row interval (:func:`prony_convolution`), S0 from ``pk2_parts(material,
    F)`` (default: :func:`cfm_pk2_parts` with the material's values)."""
    t_rows = np.asarray(t_rows, dtype=float)
    F_rows = np.asarray(F_rows, dtype=float)
    if pk2_parts is None:
        p = cfm_params(material)

        def pk2_parts(_m, F):
            return cfm_pk2_parts(F, **p)
    w = np.linspace(0.0, 1.0, sub + 1)[1:]
    ts, Fs, rows = [t_rows[:1]], [F_rows[:1]], [0]
    for k in range(1, t_rows.size):
        ts.append(t_rows[k - 1] + w * (t_rows[k] - t_rows[k - 1]))
        Fs.append((1 - w)[:, None, None] * F_rows[k - 1] + w[:, None, None] * F_rows[k])
        rows.append(rows[-1] + sub)
    ts, Fs = np.concatenate(ts), np.concatenate(Fs)
    S0, Sv = pk2_parts(material, Fs)
    gammas, taus = prony_values(material)
    S_iso = prony_convolution(ts, S0, gammas, taus, rows)
    return _cauchy(F_rows, S_iso + Sv[rows])


def uniaxial_force(material, rate: float, stretch: float, size: float, steps: int = 400, hold: float = 0.0,
                   times=None):
    """Quasi-static uniaxial-stress reaction of a cube of edge ``size`` (m) at engineering strain
    rate ``rate`` (1/s) to ``stretch`` (-), then held ``hold`` s: returns (t (s), force (N)).

    At each row the lateral stretch solves sigma_22 = 0 with the hereditary integral over the rows
    so far (:func:`prony_convolution`, F = diag(l, lt, lt)); force = P11 x size^2, P = F S.
    ``times`` (s): extra rows (e.g. a run's output times), merged with the ``steps`` rows of the ramp."""
    t_load = abs(stretch - 1.0) / rate
    t = np.linspace(0.0, t_load, steps + 1)
    if hold > 0:
        t = np.concatenate([t, t_load + np.linspace(0.0, hold, steps + 1)[1:]])
    if times is not None:
        t = np.unique(np.concatenate([t, np.asarray(times, dtype=float)]))
    lam = 1.0 + np.sign(stretch - 1.0) * rate * np.minimum(t, t_load)
    p = cfm_params(material)
    gammas, taus = prony_values(material)
    S0 = np.zeros((t.size, 3, 3))
    Sv = np.zeros((t.size, 3, 3))
    P = np.zeros(t.size)
    lt_prev = 1.0

    def total(n, lt):
        F = np.diag([lam[n], lt, lt])[None]
        s0, sv = cfm_pk2_parts(F, **p)
        S0[n], Sv[n] = s0[0], sv[0]
        return prony_convolution(t[:n + 1], S0[:n + 1], gammas, taus, [n])[0] + Sv[n]

    for n in range(t.size):
        if n:
            lo, hi = lt_prev / 1.2, lt_prev * 1.2
            lt_prev = brentq(lambda x: total(n, x)[1, 1], lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200)
        S = total(n, lt_prev)
        P[n] = lam[n] * S[0, 0]
    return t, P * size ** 2
