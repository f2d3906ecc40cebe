"""Which fitted parameters the data determine: correlation, conditioning and determined combinations.

A least-squares fit can stop anywhere on a valley of its objective, and then the linearised
intervals s t sqrt((J^T J)^-1_ii) describe the curvature at the stopping point, not what the data
hold: in a twin experiment on drop tests (g2 with tau 0.1 s and g3 with tau 10 s act through their
sum within a 10 ms pulse), g2 and g3 have |correlation| 0.99997 and their 95 % intervals exclude the
truth by 100 half-widths. This module reads the Jacobian J (m, p) of the residuals in the fitted
coordinates x and reports

- the correlation matrix of the estimates (cov proportional to (J^T J)^-1);
- the condition number of the column-scaled J^T J (scaling removes the parameters' units);
- the directions of parameter space the data do not determine: eigenvectors of the scaled
  J^T J whose eigenvalue is below ``RATIO`` x the largest, or pairs with |correlation| >= ``CORR``
  (a warning); their intervals are widened when |correlation| >= ``CORR_WIDEN`` or when the
  Gauss-Newton step from the fit is longer than the interval's half-width (the fit stopped early
  along the valley or on a bound: the twin experiment's g2, g3);
- for each such pair (i, j) the combination the data do determine, linearised at the fit in the
  parameters themselves (SI units): p_i + c p_j, with c from the 2 x 2 block of J^T J in p
  (the direction n = (n_i, n_j) along which the fit does not change gives c = -n_i / n_j), its
  value, standard error and interval; linearised at the fit, so far along a curved valley the
  true parameters need not satisfy it to within that interval.

The fitted values of such parameters are one point of a valley: :mod:`cfm_core.studies.calibrate`
withholds their separate intervals (``ci`` None) and reports the determined combinations instead.
"""

from __future__ import annotations

import math

import numpy as np

#: |correlation| at or above which two parameters are reported as not separately identifiable (-).
CORR = 0.99
#: |correlation| at or above which their separate intervals are replaced by the valley's extent (-).
#: Equal to CORR: in the twin experiments even the k1-g1 pair (correlation -0.99966, fit converged,
#: recovered within 0.5 %) had linearised intervals that excluded the truth.
CORR_WIDEN = 0.99
#: Eigenvalue of the scaled J^T J below this fraction of the largest: an undetermined direction (-).
RATIO = 1e-6


def analyse(x, jac, s2: float, q: float, names, log, values: dict, bounds: dict | None = None,
            residual=None) -> dict:
    """Identifiability of a fit from its Jacobian.

    Parameters
    ----------
    x : ndarray, shape (p,)
        Fitted coordinates (ln p for log coordinates, else p).
    jac : ndarray, shape (m, p)
        Jacobian of the residuals with respect to x (-).
    s2 : float
        Residual variance SSR / (m - p) (-).
    q : float
        Student t quantile of the interval level (-).
    names : sequence of str
        Parameter names (p,).
    log : sequence of bool
        Whether each coordinate is ln p (p,).
    values : dict
        Fitted parameter values (SI units) by name.
    bounds : dict, optional
        (lower, upper) of each parameter in SI units: the extent of a valley is cut to them.
    residual : ndarray, shape (m,), optional
        Residuals at the fit: the Gauss-Newton step -(J^T J)^+ J^T r from the fit says how far
        the minimum may still be; where it exceeds a parameter's interval half-width (the fit
        stopped early along a valley, or on a bound), the interval claims more than the fit holds.

    Returns
    -------
    dict
        ``identifiable`` (bool), ``correlation`` ((p, p) list or None), ``cond_scaled`` (condition
        number of the column-scaled J^T J, None if a column is zero), ``undetermined`` (list of
        {direction: {name: component}} unit vectors in x), ``combinations`` (list of {parameters,
        coefficients, value, std, ci}), ``unidentified`` (names whose separate intervals must be
        withheld), ``valley`` ({name: [low, high]}: the range of a parameter of a pair along the
        valley p_i + c p_j = value +- its interval, within the bounds; a conservative interval in
        place of the withheld one) and ``warnings`` (text).
    """
    names = list(names)
    jac = np.asarray(jac, dtype=np.float64)
    p = len(names)
    jtj = jac.T @ jac
    norms = np.sqrt(np.diag(jtj))
    out = {"identifiable": True, "correlation": None, "cond_scaled": None, "undetermined": [],
           "combinations": [], "unidentified": [], "valley": {}, "warnings": []}
    zero = [names[i] for i in range(p) if not norms[i] > 0.0]
    if zero:
        out.update(identifiable=False, unidentified=zero)
        out["warnings"].append(f"the data do not depend on {', '.join(zero)} at the fitted values (zero Jacobian "
                               f"column): these parameters are not identifiable from these curves; fix them.")
        return out
    scaled = jtj / np.outer(norms, norms)
    w, v = np.linalg.eigh(scaled)
    out["cond_scaled"] = float(w[-1] / w[0]) if w[0] > 0 else math.inf
    corr = np.linalg.pinv(scaled)
    d = np.sqrt(np.maximum(np.diag(corr), 1e-300))
    corr = corr / np.outer(d, d)
    out["correlation"] = corr.tolist()
    bad = set()
    unconverged = set()
    if residual is not None:
        cov_x = s2 * np.linalg.pinv(jtj)
        step = -np.linalg.pinv(jtj) @ (jac.T @ np.asarray(residual, dtype=np.float64))
        half = q * np.sqrt(np.maximum(np.diag(cov_x), 0.0))
        unconverged = {names[i] for i in range(p) if abs(step[i]) > half[i]}
        out["gauss_newton_step"] = {n: float(v) for n, v in zip(names, step)}
    for k in np.flatnonzero(w < RATIO * w[-1]):
        vec = v[:, k] / norms  # back to x units
        vec = vec / np.linalg.norm(vec)
        out["undetermined"].append({"direction": {n: float(c) for n, c in zip(names, vec)},
                                    "eigenvalue_ratio": float(w[k] / w[-1])})
        bad.update(names[i] for i in np.flatnonzero(np.abs(vec) > 0.1))
    # the fitted parameters' Jacobian in p itself: dr/dp = dr/dx * dx/dp, dx/dp = 1/p for log coordinates
    vals = np.array([values[n] for n in names], dtype=np.float64)
    jp = jac / np.where(np.asarray(log, dtype=bool), vals, 1.0)[None, :]
    jtj_p = jp.T @ jp
    for i in range(p):
        for j in range(i + 1, p):
            if abs(corr[i, j]) < CORR:
                continue
            widen = abs(corr[i, j]) >= CORR_WIDEN or bool({names[i], names[j]} & unconverged)
            if widen:
                bad.update((names[i], names[j]))
            block = jtj_p[np.ix_([i, j], [i, j])]
            ww, vv = np.linalg.eigh(block)
            n_i, n_j = vv[:, 0]
            if abs(n_j) < 1e-12:
                continue
            c = -n_i / n_j
            value = vals[i] + c * vals[j]
            g = np.zeros(p)
            g[i], g[j] = 1.0, c
            var = s2 * float(g @ np.linalg.pinv(jtj_p) @ g)
            std = math.sqrt(max(var, 0.0))
            if widen:
                _valley(out["valley"], names[i], names[j], c, value - q * std, value + q * std, bounds or {})
            out["combinations"].append({"parameters": [names[i], names[j]], "coefficients": [1.0, float(c)],
                                        "value": float(value), "std": std,
                                        "ci": [float(value - q * std), float(value + q * std)],
                                        "correlation": float(corr[i, j])})
            combo = _combo(names[i], names[j], c)
            if widen:
                out["warnings"].append(
                    f"{names[i]} and {names[j]} are not separately identifiable from these data (correlation "
                    f"{corr[i, j]:+.5f}): the fit may stop anywhere on a valley where {combo} (linearised at the "
                    f"fit) = {value:.5g} stays about the same, so their separate values are one point of that "
                    f"valley: their intervals are widened to the valley within the parameters' bounds "
                    f"({_ranges(out['valley'], names[i], names[j])}); fix one of them, or add data that separate "
                    f"them (e.g. tests at other rates or durations).")
            else:
                out["warnings"].append(
                    f"{names[i]} and {names[j]} are strongly correlated (correlation {corr[i, j]:+.5f}): the data "
                    f"determine mainly {combo} = {value:.5g} (linearised at the fit); their separate "
                    f"intervals hold only as far as the linearisation does (the fit converged along the valley "
                    f"to within them).")
    if out["undetermined"] and not out["combinations"]:
        dirs = "; ".join(", ".join(f"{c:+.3f} {'ln ' if lg else ''}{n}" for (n, c), lg in zip(u["direction"].items(), log)
                                   if abs(c) > 0.1) for u in out["undetermined"])
        out["warnings"].append(
            f"J^T J is near-singular (scaled condition number {out['cond_scaled']:.3g}): the data do not determine "
            f"the parameter direction(s) {dirs}; the intervals of {', '.join(sorted(bad))} are withheld.")
    out["unidentified"] = [n for n in names if n in bad]
    out["identifiable"] = not bad
    out["strongly_correlated"] = sorted({n for c in out["combinations"] for n in c["parameters"]})
    return out


#: Relative standard error above which a parameter counts as poorly determined: its linearised
#: interval (wider than the value itself on either side) is withheld.
POOR_STD = 0.5


def poorly_determined(params: dict, names) -> dict:
    """The parameters whose standard error exceeds :data:`POOR_STD` times their value.

    Parameters
    ----------
    params : dict
        {name: {"value", "std", ...}} (:func:`cfm_core.studies.calibrate.confidence`), SI units.
    names : sequence of str
        The names to look at (those not already withheld for another reason).

    Returns
    -------
    dict
        {name: relative standard error std / |value| (-)}.
    """
    out = {}
    for n in names:
        value, std = params[n]["value"], params[n].get("std")
        if std is not None and value != 0 and std > POOR_STD * abs(value):
            out[n] = float(std / abs(value))
    return out


def poor_warning(name: str, rel: float, ci, unit: str = "") -> str:
    """The warning for a poorly determined parameter (:func:`poorly_determined`).

    Parameters
    ----------
    name : str
        The parameter.
    rel : float
        Its relative standard error (-).
    ci : sequence of 2 float or None
        The linearised interval being withheld (SI units), shown for what it is.
    unit : str
        The parameter's unit.

    Returns
    -------
    str
        One paragraph.
    """
    u = f" {unit}" if unit and unit != "-" else ""
    span = f" (the linearised interval [{ci[0]:.4g}, {ci[1]:.4g}]{u} would claim more than the fit holds)" if ci else ""
    return (f"{name} is poorly determined: relative standard error {rel:.3g} (above {POOR_STD:g}){span}; its "
            f"interval is withheld. The data hardly constrain it (e.g. a Prony time much longer than the pulse); "
            f"fix it, or add data that depend on it (tests at other rates or durations).")


#: Relative misfit (RMS or L2 of the residual over the curve's scale) of any curve above which the
#: model is taken not to describe the data: every linearised interval assumes that it does, so all
#: are withheld. Fits of the paper's curves miss by a few per cent; 0.5 leaves room for noisy
#: measurements and flags wrong units, signs, time origins or test kinds (a constant curve fitted
#: by the CFM: 62 %; a drop test recorded from 2 ms before contact: 124 %).
MISFIT_LIMIT = 0.5


def misfit_warning(misfits: dict, measure: str) -> str | None:
    """The warning when a fitted curve misses its data by more than :data:`MISFIT_LIMIT`, else None.

    Parameters
    ----------
    misfits : dict
        {curve label: relative misfit of the fitted curve (-)}.
    measure : str
        What the misfit is ("relative RMS", "relative L2"), for the text.

    Returns
    -------
    str or None
        One paragraph naming the worst curves; the caller withholds every interval.
    """
    bad = {k: v for k, v in misfits.items() if not v <= MISFIT_LIMIT}
    if not bad:
        return None
    listed = ", ".join(f"'{k}' {100 * v:.3g} %" for k, v in sorted(bad.items(), key=lambda kv: -kv[1]))
    return (f"the fitted model misses the data ({measure} {listed}; above {100 * MISFIT_LIMIT:g} %): it does not "
            f"describe these curves, so every interval, which assumes it does, is withheld. Check the data's "
            f"units and sign, the time origin (t = 0 at the start of loading or first contact) and the test kind, "
            f"or free other parameters.")


def flat_warning(name: str) -> str:
    """The warning for a parameter whose linearised interval overflows the float range (the residuals
    hardly depend on it), its interval withheld."""
    return (f"{name} is not determined by the data: its linearised interval exceeds the float range (the "
            f"residuals hardly change with it); its interval is withheld. Fix it, or add data that depend on it.")


def _combo(a: str, b: str, c: float) -> str:
    sign = "+" if c >= 0 else "-"
    k = abs(c)
    return f"{a} {sign} {b}" if abs(k - 1.0) < 5e-3 else f"{a} {sign} {k:.4g} {b}"


def _valley(valley: dict, a: str, b: str, c: float, low: float, high: float, bounds: dict) -> None:
    """Range of a and b along a + c b in [low, high] with both within their bounds (union into valley)."""
    la, ha = bounds.get(a, (-math.inf, math.inf))
    lb, hb = bounds.get(b, (-math.inf, math.inf))
    # a = v - c b: over b in [lb, hb] and v in [low, high]
    ends_a = [v - c * w for v in (low, high) for w in (lb, hb)]
    ra = [max(la, min(ends_a)), min(ha, max(ends_a))]
    ends_b = [(v - u) / c for v in (low, high) for u in (ra[0], ra[1])] if c != 0 else [lb, hb]
    rb = [max(lb, min(ends_b)), min(hb, max(ends_b))]
    for name, r in ((a, ra), (b, rb)):
        old = valley.get(name)
        valley[name] = [float(r[0]), float(r[1])] if old is None else [min(old[0], r[0]), max(old[1], r[1])]


def _ranges(valley: dict, *names) -> str:
    return ", ".join(f"{n} in [{valley[n][0]:.4g}, {valley[n][1]:.4g}]" for n in names if n in valley)


def at_bounds(x, coords, tol: float = 1e-6) -> dict:
    """The fitted parameters that ended on a bound of the optimiser's box.

    Parameters
    ----------
    x : ndarray, shape (p,)
        Fitted coordinates (ln p for log coordinates, else p).
    coords : Coordinates
        Names, units, log flags and bounds (``lower``, ``upper``) in the fitted coordinates.
    tol : float
        Distance (in x, relative to max(1, |bound|)) within which x counts as on the bound.

    Returns
    -------
    dict
        ``name -> {"side": "lower" | "upper", "bound": value (SI units), "unit": str}``; empty when
        no parameter is on a bound. A parameter on a bound is not at a minimum of the objective:
        the best value may lie beyond, and the linearised interval means nothing there.
    """
    out = {}
    for i, n in enumerate(coords.names):
        for side, b in (("lower", coords.lower[i]), ("upper", coords.upper[i])):
            if math.isfinite(b) and abs(x[i] - b) <= tol * max(1.0, abs(b)):
                out[n] = {"side": side, "bound": coords.value(i, b), "unit": coords.units[i]}
    return out


def bound_warning(name: str, entry: dict, what: str = "bound") -> str:
    """The warning text for a parameter that ended on a bound (:func:`at_bounds`)."""
    return (f"{name} ended on the {entry['side']} {what} {entry['bound']:.6g} {entry['unit']}: the fit did not find a "
            f"minimum inside the range (the best value may lie beyond it, or the data do not determine {name}); "
            f"its interval is withheld. Start nearer, widen the range or fix {name}.")
