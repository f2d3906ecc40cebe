"""Material stability in the spirit of Abaqus's Drucker check, and warnings for a run entering it.

Two criteria, both on the instantaneous elastic response (g = 1, what an impact sees):

- "dS/dE": the 6x6 Mandel form of the material tangent CC = dS/dE
  (:func:`cfm_core.material.reference.tangent`) must be positive definite (convexity of psi in E);
- "U''(J)": convexity of the volumetric energy in J (d^2 psi / d J^2 > 0 along F = J^(1/3) I); the
  Ogden term (beta = 9) loses it for J > 10^(1/9) = 1.29;
- "Drucker": Abaqus's criterion d tau : d eps > 0 for every increment of logarithmic strain eps,
  tau the Kirchhoff stress. For an isotropic material at a diagonal F this is positive
  definiteness of the 3x3 principal block d tau_a / d eps_b together with the shear moduli
  (tau_a - tau_b) / (eps_a - eps_b) (their limit for equal stretches), all by finite differences.

Test paths (isochoric for the first three, like Abaqus's incompressible test data), nominal strain
e = lambda - 1 from -0.9 to 2: uniaxial diag(l, l^-1/2, l^-1/2), equibiaxial diag(l, l, l^-2),
planar diag(l, 1, 1/l), volumetric diag(l, l, l) (J = l^3).
"""

from __future__ import annotations

import warnings

import numpy as np

PATHS = {
    "uniaxial": lambda l: (l, l ** -0.5, l ** -0.5),
    "equibiaxial": lambda l: (l, l, l ** -2.0),
    "planar": lambda l: (l, np.ones_like(l), 1.0 / l),
    "volumetric": lambda l: (l, l, l),
}
#: Relative tolerance: an eigenvalue below -RTOL * (largest |eigenvalue|) counts as a loss
#: (analytic tangent); RTOL_FD for the finite-difference criteria.
RTOL = 1e-9
RTOL_FD = 1e-6
#: Criteria that drucker_warnings checks by default. dS/dE is left out: positive definiteness of
#: dS/dE fails for any hydrostatic tension of every material (the geometric term -2 J U' C^-1 (x) C^-1),
#: so it is reported in the stability map but would warn on every swelling run.
WARN_CRITERIA = ("Drucker", "U''(J)")
_W = np.array([1.0, 1.0, 1.0, np.sqrt(2.0), np.sqrt(2.0), np.sqrt(2.0)])
_VOIGT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))


class DruckerWarning(UserWarning):
    """A run entered a strain state where the material tangent is not positive definite."""


def _elastic(material):
    return material if material.elastic else material.with_values()


def mandel_tangent(material, F) -> np.ndarray:
    """(n, 6, 6) Mandel matrix of dS/dE (Pa): eigenvalues are those of the 4th-order tangent."""
    from cfm_core.material.reference import tangent

    C = tangent(material, F)
    M = np.empty((C.shape[0], 6, 6))
    for I, (i, j) in enumerate(_VOIGT):
        for K, (k, l) in enumerate(_VOIGT):
            M[:, I, K] = _W[I] * _W[K] * C[:, i, j, k, l]
    return M


def min_eig_dSdE(material, F) -> np.ndarray:
    """Smallest eigenvalue of dS/dE divided by the largest |eigenvalue| (-), per F."""
    ev = np.linalg.eigvalsh(mandel_tangent(material, F))
    return ev[:, 0] / np.abs(ev).max(axis=1)


def _kirchhoff_principal(material, lam) -> np.ndarray:
    from cfm_core.material.reference import pk2

    F = np.zeros((lam.shape[0], 3, 3))
    for a in range(3):
        F[:, a, a] = lam[:, a]
    S = pk2(material, F)
    return np.stack([lam[:, a] ** 2 * S[:, a, a] for a in range(3)], axis=1)


def min_eig_drucker(material, lam, h: float = 1e-6) -> np.ndarray:
    """Abaqus criterion at principal stretches lam (n, 3): smallest eigenvalue of d tau / d eps
    (principal block and shear moduli) divided by the largest |eigenvalue| (-)."""
    lam = np.asarray(lam, dtype=float)
    n = lam.shape[0]
    eps = np.log(lam)
    D = np.empty((n, 3, 3))
    for b in range(3):
        d = np.zeros(3)
        d[b] = h
        D[:, :, b] = (_kirchhoff_principal(material, np.exp(eps + d)) -
                      _kirchhoff_principal(material, np.exp(eps - d))) / (2 * h)
    D = 0.5 * (D + np.transpose(D, (0, 2, 1)))
    tau = _kirchhoff_principal(material, lam)
    shear = []
    for a, b in ((0, 1), (1, 2), (0, 2)):
        de = eps[:, a] - eps[:, b]
        close = np.abs(de) < 1e-4
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.where(close, 0.5 * (D[:, a, a] - D[:, a, b]), (tau[:, a] - tau[:, b]) / np.where(close, 1, de))
        shear.append(g)
    ev = np.concatenate([np.linalg.eigvalsh(D), np.stack(shear, axis=1)], axis=1)
    return ev.min(axis=1) / np.abs(ev).max(axis=1)


def _robust(fn, *arrays) -> np.ndarray:
    """fn over a batch; where it raises (e.g. the fibre exponential overflows), split the batch and
    return NaN for the points that fail on their own."""
    from cfm_core.errors import NumericalError

    try:
        with np.errstate(all="ignore"):
            return np.asarray(fn(*arrays), dtype=float)
    except (NumericalError, FloatingPointError, OverflowError):
        n = arrays[0].shape[0]
        if n == 1:
            return np.full(1, np.nan)
        h = n // 2
        return np.concatenate([_robust(fn, *(a[:h] for a in arrays)), _robust(fn, *(a[h:] for a in arrays))])


def volumetric_curvature(material, J, h: float = 1e-4) -> np.ndarray:
    """d^2 psi / d J^2 along F = J^(1/3) I by central differences, relative to its value at J = 1 (-)."""
    from cfm_core.material.reference import energy

    J = np.asarray(J, dtype=float)

    def psi(j):
        return energy(material, j[:, None, None] ** (1.0 / 3.0) * np.eye(3))

    d2 = (psi(J * (1 + h)) - 2 * psi(J) + psi(J * (1 - h))) / (J * h) ** 2
    one = np.ones(1)
    d0 = (psi(one * (1 + h)) - 2 * psi(one) + psi(one * (1 - h))) / h ** 2
    return d2 / abs(d0[0])


def unstable_intervals(e, bad) -> list[list[float]]:
    """Contiguous runs of True in ``bad`` over the grid ``e`` as [[e_first, e_last], ...]."""
    out, start = [], None
    for k, flag in enumerate(bad):
        if flag and start is None:
            start = k
        if start is not None and (not flag or k == len(bad) - 1):
            end = k if flag else k - 1
            out.append([float(e[start]), float(e[end])])
            start = None
    return out


def stability_map(material, e_min: float = -0.9, e_max: float = 2.0, n: int = 291) -> dict:
    """Per path and criterion: the intervals of nominal strain where positive definiteness is lost,
    and the (e, relative smallest eigenvalue) curves. Non-finite tangents count as lost."""
    material = _elastic(material)
    e = np.linspace(e_min, e_max, n)
    lam = 1.0 + e
    out = {"grid": [e_min, e_max, n], "paths": {}}
    for path, f in PATHS.items():
        l3 = np.stack(np.broadcast_arrays(*f(lam)), axis=1)
        F = np.zeros((n, 3, 3))
        for a in range(3):
            F[:, a, a] = l3[:, a]
        crits = {"dS/dE": (_robust(lambda f: min_eig_dSdE(material, f), F), RTOL),
                 "Drucker": (_robust(lambda l: min_eig_drucker(material, l), l3), RTOL_FD)}
        if path == "volumetric":
            crits["U''(J)"] = (_robust(lambda j: volumetric_curvature(material, j), lam ** 3), RTOL_FD)
        res = {}
        for crit, (r, tol) in crits.items():
            res[crit] = {"intervals": unstable_intervals(e, np.isfinite(r) & (r < -tol)),
                         "not_evaluable": unstable_intervals(e, ~np.isfinite(r)),
                         "min_eig_rel": [float(x) if np.isfinite(x) else None for x in r]}
        out["paths"][path] = res
    out["e"] = e.tolist()
    return out


def drucker_warnings(material, F_history, emit: bool = True, criteria=WARN_CRITERIA) -> list[str]:
    """Messages (and DruckerWarnings if ``emit``) for the states of a history F (n, 3, 3) where the
    material is unstable by ``criteria`` (default: Abaqus's Drucker criterion and convexity of the
    volumetric energy in J; "dS/dE" may be added); one message per contiguous range of indices
    and criterion. Empty list: stable all along. Uses the instantaneous elastic response."""
    from cfm_core.material.kinematics import as_batch, principal

    material = _elastic(material)
    F = as_batch(F_history)
    m, _, _ = principal(F)
    lam = np.sqrt(np.maximum(m, 0.0))
    msgs = []
    J = np.prod(lam, axis=1)
    fns = {"dS/dE": (lambda f: min_eig_dSdE(material, f), F, RTOL),
           "Drucker": (lambda l: min_eig_drucker(material, l), lam, RTOL_FD),
           "U''(J)": (lambda j: volumetric_curvature(material, j), J, RTOL_FD)}
    for crit in criteria:
        fn, arg, tol = fns[crit]
        r = _robust(fn, arg)
        bad = np.isfinite(r) & (r < -tol)
        for i0, i1 in unstable_intervals(np.arange(len(r)), bad):
            i0, i1 = int(i0), int(i1)
            msgs.append(f"material '{material.name}': the {crit} criterion fails (not positive definite) at history "
                        f"points {i0}..{i1} (principal stretches {np.round(lam[i0], 4).tolist()} .. "
                        f"{np.round(lam[i1], 4).tolist()}, J {J[i0]:.4g} .. {J[i1]:.4g}): the material is unstable "
                        f"there (as Abaqus's Drucker check would report); results in that range are not reliable.")
    if emit:
        for msg in msgs:
            warnings.warn(msg, DruckerWarning, stacklevel=2)
    return msgs


#: The volumetric energy of the Ogden term (beta = 9), U = kappa/81 (9 ln J + J^-9 - 1), has
#: U'' = kappa/81 (90 J^-11 - 9 J^-2): convex exactly for J < 10^(1/9) (analytic, paper Eq. 7).
J_CONVEXITY_LIMIT = 10.0 ** (1.0 / 9.0)


def checks(maps: dict) -> list[dict]:
    """Verdict rows on the stability maps of :func:`stability_map` ({material: map}).

    - every registered material's map was computed (a broken plugin or a raising map fails);
    - materials with the Ogden volumetric term (cfm, and every map whose U''(J) loss starts near
      J = 1.29): U''(J) is lost from J = 10^(1/9) = 1.2915 (within one grid step of the map) to the
      end of the grid, and nowhere below: the analytic result of Eq. 7;
    - cfm: the Drucker criterion holds on every isochoric path over the whole grid (the fibres only
      stiffen), and the stress is evaluable on the uniaxial path (compression to e = -0.9).
    """
    rows = []
    for name, smap in maps.items():
        if "error" in smap:
            rows.append({"check": f"Drucker map of '{name}'", "passed": False, "reason": smap["error"]})
            continue
        rows.append({"check": f"Drucker map of '{name}'", "passed": True, "reason": "computed"})
    cfm = maps.get("cfm")
    if cfm is None or "error" in cfm:
        rows.append({"check": "Drucker map of 'cfm'", "passed": None if cfm is None else False,
                     "reason": "the cfm material is not registered" if cfm is None else cfm["error"]})
        return rows
    e = np.array(cfm["e"])
    de = float(e[1] - e[0])
    iv = cfm["paths"]["volumetric"]["U''(J)"]["intervals"]
    if len(iv) == 1:
        e0, e1 = iv[0]
        J0 = (1.0 + e0) ** 3
        J_prev = (1.0 + e0 - de) ** 3
        ok = J_prev <= J_CONVEXITY_LIMIT <= J0 and abs(e1 - e[-1]) < 1e-12
        reason = (f"U''(J) lost from J = {J0:.4g} (grid step before: J = {J_prev:.4g}) to e = {e1:+.2f}; "
                  f"analytic limit J = 10^(1/9) = {J_CONVEXITY_LIMIT:.4f}")
    else:
        ok, reason = False, f"U''(J) lost on {len(iv)} intervals {iv}, expected one from J = 1.29 to the end"
    rows.append({"check": "cfm: U''(J) lost at J = 1.29 (Ogden beta = 9)", "passed": bool(ok), "reason": reason})
    lost = {p: r["Drucker"]["intervals"] for p, r in cfm["paths"].items() if p != "volumetric" and r["Drucker"]["intervals"]}
    rows.append({"check": "cfm: Drucker criterion holds on the isochoric paths", "passed": not lost,
                 "reason": "holds on uniaxial, equibiaxial and planar paths" if not lost else f"lost: {lost}"})
    ne = cfm["paths"]["uniaxial"]["Drucker"]["not_evaluable"]
    rows.append({"check": "cfm: stress evaluable on the uniaxial path", "passed": not ne,
                 "reason": "evaluable from e = -0.9 to 2" if not ne else f"not evaluable on {ne}"})
    return rows
