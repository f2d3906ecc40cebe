"""Calibration: fit material parameters to measured drop-test acceleration histories.

Measured curves (:mod:`cfm_core.studies.measured`): CSV with a header naming columns ``t`` (s, from first
contact: samples before t = 0 are ignored) and ``a`` (m/s^2, positive when the impactor
decelerates), any sampling, rows in time order, the whole pulse until separation. Each curve is
put on the simulation's grid exactly as a simulated history (box average on the 50 kHz grid,
:func:`postprocess.acceleration_histories`, then SAE J211 CFC 600, :func:`filters.cfc_filter`).

Objective (:class:`Problem`): the residual of curve j at grid time t_k is
``r_jk = (a_sim,j(t_k) - a_meas,j(t_k)) / max_k a_meas,j``, both filtered, over the measured
record [0, t_end,j] (the simulated raw history is padded with zeros to the record's length before
filtering, so the objective does not jump when the run's length changes). The drop test of curve
j is the scene with the curve's thickness. ``scipy.optimize.least_squares`` (trust region
reflective) minimises 1/2 sum r^2 over ln p for parameters whose range starts at 0 (all of the
CFM's; linear otherwise), within the parameters' valid ranges. The Jacobian is a forward
difference of relative step ``rel_step`` (default :data:`REL_STEP`); its p x (curves) drop tests
are submitted together to the runner (:mod:`cfm_core.studies.dask_runner`), as are the curves of a step.
Measured on the coarse drop test (2.5 mm hexahedra, numba), the objective is smooth down to
relative steps of 1e-7 (the changing number of explicit steps does not show); with 1e-3 the
forward-difference Jacobian is within 0.1 % of a central one for c, k1, k2 and 1.2 % for g1
(strongly nonlinear through g_inf = 1 - sum g_i under long-term moduli).

Confidence intervals (:func:`confidence`): cov = k s^2 (J^T J)^-1 in the fitted coordinates,
s^2 = SSR / (m - p), 95 % with Student's t on n - p degrees of freedom; for log coordinates
exp(ln p +- t sigma). The m residuals are grid samples of filtered (hence correlated) records: n
counts the independent ones (each record's rows, or 2 077 per s for CFC 600 where that is fewer,
:func:`cfm_core.studies.measured.independent_samples`) and k = m / n. With white measurement noise
the intervals then cover the truth as stated (tests/cfm_core/studies/test_study_truths.py); a
model error is not noise, so read them as a measure of identifiability beyond that.

"prony" in the list of fitted names stands for g1 and tau1, the term that relaxes during a drop
test (tau1 = 1 ms against a ~10 ms pulse). g2 and g3 (tau 0.1 s and 10 s) act as elastic within
10 ms and enter only through their sum (in g_inf), so drop tests cannot tell them apart (name
them explicitly to try). Under long-term moduli even k1 and g1 trade off (the pulse mostly fixes
k1 / g_inf): with noisy data fit k1, k2 with the Prony series fixed. A fitted g_i is bounded
above so that the fitted g_i together keep g_inf - 1e-6 (its floor) >= 1 % of its starting value.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import identifiability
from .dask_runner import SerialRunner, lost_reason
from ..errors import InputError, NumericalError
from .measured import CFC
from .differences import forward_jacobian, forward_steps
from .sweep import run_all
from ..material.registry import get_material
from ..material.registry import make_material
from ..material import prony
from ..post.filters import cfc_filter
from ..post import relative_l2

#: Default forward-difference step of the Jacobian, relative to the parameter (-).
REL_STEP = 1e-3
#: Names "prony" stands for in the list of fitted parameters.
PRONY = ("g1", "tau1")


# ----------------------------------------------------------------------------- parameters
def parse_fit_names(text: str, spec, prony: tuple, example: str) -> list[str]:
    """``c,k1,prony`` -> parameter names of a material spec, in the given order.

    Parameters
    ----------
    text : str
        Comma-separated names; ``prony`` stands for the names in ``prony``.
    spec : MaterialSpec
        The material whose parameters may be named.
    prony : tuple of str
        What ``prony`` expands to (empty: the word is not allowed).
    example : str
        An example list for the message when none is given (``"k1,k2"``).

    Returns
    -------
    list of str
        The names.

    Raises
    ------
    InputError
        An unknown or repeated name, or an empty list.
    """
    known = [p.name for p in spec.parameters]
    names = []
    for item in str(text).split(","):
        item = item.strip()
        for name in (list(prony) if item == "prony" and prony else [item]):
            if name not in known:
                raise InputError(f"--fit {item!r}: material '{spec.name}' has no parameter of that name; its "
                                 f"parameters are {', '.join(known)}"
                                 f"{' (and prony = ' + ', '.join(prony) + ')' if prony else ''}.")
            if name in names:
                raise InputError(f"--fit names {name} twice; give each parameter once.")
            names.append(name)
    if not names:
        raise InputError(f"--fit needs at least one parameter name, e.g. --fit {example}.")
    return names


def fit_names(text: str, scene) -> list[str]:
    """``c,k1,k2,prony`` -> parameter names of the scene's material (prony: :data:`PRONY`, the term
    that relaxes during a drop test); see :func:`parse_fit_names`. A name that no layer of a
    layered specimen takes from the [material] section (every layer names its own material or
    gives that parameter itself) is refused: the drop tests would not depend on it
    (:func:`cfm_core.scene.layers.refuse_unused`)."""
    from ..scene.layers import refuse_unused

    spec = get_material(scene.material.name)
    names = parse_fit_names(text, spec, PRONY if spec.prony is not None else (), "k1,k2")
    refuse_unused(scene, names, lambda n: f"--fit {n}",
                  "no drop test depends on it and the fit cannot determine it",
                  "Let a layer take {name} from [material] (one without a material or a {name} of its own), or "
                  "drop {name} from --fit.")
    return names


def from_log(v: float) -> float:
    """The parameter p of a log coordinate v = ln p: the shortest decimal float whose ``math.log`` is v.

    Several floats p share one ln p (near p = 900 about seven: ln p has a coarser grid than p), and
    ``math.exp`` picks one of them, not the value written: exp(ln 900) = 900.0000000000001. Of the
    floats that map to v, the one with the fewest significant digits is as exact a reading of v as
    any, and it gives back the value the coordinate came from (a start, a bound) to the bit, so
    that a fit that did not move a parameter writes 900.0, not 900.0000000000001. Where no shorter
    float maps to v, exp(v); inf from v = 709 (p = 8.2e307) on, 0 below the float range.

    Parameters
    ----------
    v : float
        The coordinate ln p.

    Returns
    -------
    float
        p.
    """
    if v >= 709.0:  # a near-flat coordinate's interval: at the float range's end (math.exp raises beyond)
        return math.inf
    p = math.exp(v)
    if not (p > 0.0 and math.isfinite(p)):
        return p
    for digits in range(1, 17):
        q = float(f"{p:.{digits}g}")
        if q > 0.0 and math.log(q) == v:
            return q
    return p


@dataclass(frozen=True)
class Coordinates:
    """Fitted coordinates x of the parameters p: x = ln p (``log``) or x = p, with bounds.

    A log coordinate maps back to p by :func:`from_log` (the shortest float with that logarithm),
    so ``to_params(to_x(p)) == p`` for every value written with up to 14 significant digits.
    """

    names: tuple
    units: tuple
    log: tuple
    lower: np.ndarray
    upper: np.ndarray

    def value(self, i: int, v: float) -> float:
        """Parameter ``i``'s value (SI) at coordinate value ``v``."""
        return from_log(float(v)) if self.log[i] else float(v)

    def to_params(self, x) -> dict:
        return {n: self.value(i, v) for i, (n, v) in enumerate(zip(self.names, x))}

    def to_x(self, params: dict) -> np.ndarray:
        return np.array([math.log(params[n]) if lg else params[n] for n, lg in zip(self.names, self.log)])


def material_values(scene) -> dict:
    """Every parameter of the scene's material: its overrides, else the defaults (SI units)."""

    m = scene.material
    return dict(make_material(m.name, m.parameter_dict, m.moduli, m.elastic).values)


def scene_values(scene, names) -> dict:
    """The scene's values of ``names`` (its overrides, else the material's defaults), not checked as a set:
    a start or swept value may be what makes them valid (a scene with g2 = 0.5 next to the default g1 =
    0.45 sums above 1; calibrating or sweeping g1 from 0.3 was refused for the 0.45 it replaces).

    Raises
    ------
    InputError
        A name the material does not have.
    """
    spec = get_material(scene.material.name)
    known = {**{p.name: p.default for p in spec.parameters}, **scene.material.parameter_dict}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise InputError(f"{', '.join(unknown)}: not a parameter of material '{spec.name}'; its parameters: "
                         f"{', '.join(p.name for p in spec.parameters)}.")
    return {n: known[n] for n in names}


def coordinates(names, scene, start: dict) -> Coordinates:
    """Coordinates and bounds from the parameters' ranges (see the module docstring).

    start: values of all the material's parameters at the start (SI units).
    """

    spec = get_material(scene.material.name)
    decl = {p.name: p for p in spec.parameters}
    gammas = [p.name for p in (spec.prony.parameters[::2] if spec.prony else ())]
    fitted_g = [n for n in names if n in gammas]
    g_inf = prony.gamma_inf(start[g] for g in gammas)
    units, logs, lo, hi = [], [], [], []
    for n in names:
        p = decl[n]
        log = p.low >= 0.0 and start[n] > 0.0
        low, high = p.low, p.high
        if n in fitted_g:
            # all fitted g_i at their upper bounds still leave gamma_inf above cfm's floor (prony.GAMMA_INF_MIN):
            # with the bare 0.99 g_inf an evaluation near the bound was refused and ended the fit
            high = min(high, start[n] + 0.99 * max(g_inf - prony.GAMMA_INF_MIN, 0.0) / len(fitted_g))
        if log:
            low = math.log(low) if low > 0.0 else -math.inf
            high = math.log(high) if math.isfinite(high) else math.inf
        span = 1e-9 * max(1.0, abs(low) if math.isfinite(low) else 1.0)
        units.append(p.unit)
        logs.append(log)
        lo.append(low + span if math.isfinite(low) else low)  # open bounds: stay strictly inside
        hi.append(high - span if math.isfinite(high) else high)
    return Coordinates(tuple(names), tuple(units), tuple(logs), np.array(lo), np.array(hi))


# ----------------------------------------------------------------------------- the problem
@dataclass
class Evaluation:
    """One point of the objective: parameters, cost 1/2 sum r^2, rel. L2 per curve, histories."""

    params: dict
    cost: float
    rel_l2: list
    residual: np.ndarray
    histories: list


@dataclass
class Problem:
    """Residuals and Jacobian of the fit, with every drop test run through ``runner``."""

    scene: object
    curves: list
    coords: Coordinates
    backend: str = "numba"
    runner: object = field(default_factory=SerialRunner)
    rel_step: float = REL_STEP
    progress: object = None
    options: dict = field(default_factory=dict)
    runs: int = 0
    history: list = field(default_factory=list)
    _cache: dict = field(default_factory=dict)
    _start: float = field(default_factory=time.perf_counter)

    def simulate(self, points: list) -> list:
        """Filtered simulated histories on each curve's grid, for each parameter dict in points."""

        scenes = [self.scene.with_overrides(thickness=c.thickness) for c in self.curves]
        tasks = [(s, params, self.backend, self.options) for params in points for s in scenes]

        def failure(i: int, error: str) -> NumericalError:
            lost = lost_reason(error)
            if lost:
                return NumericalError(f"{lost}: the calibration stopped after {self.runs} drop tests. A calibration "
                                      f"keeps no partial results: start the scheduler and its workers and rerun the "
                                      f"same command (it starts over).")
            params, curve = points[i // len(scenes)], self.curves[i % len(scenes)]
            values = ", ".join(f"{k} = {v:.6g}" for k, v in params.items())
            return NumericalError(f"the drop test of curve '{curve.name}' ({curve.thickness:g} m) failed at "
                                  f"{values}: {error}")

        results = run_all(self.runner, tasks, failure)
        self.runs += len(tasks)
        rate = float(self.scene.settings.output_rate)
        out = []
        for k in range(len(points)):
            hist = []
            for j, c in enumerate(self.curves):
                raw = results[k * len(scenes) + j]["a_raw"]
                n = max(raw.size, c.t.size)
                a = cfc_filter(np.concatenate([raw, np.zeros(n - raw.size)]), rate, cfc=CFC, pad="zero")
                hist.append(a[:c.t.size])
            out.append(hist)
        return out

    def _evaluate(self, xs: list) -> list[Evaluation]:

        points = [self.coords.to_params(x) for x in xs]
        evals = []
        for params, hist in zip(points, self.simulate(points)):
            r = np.concatenate([(h - c.a) / c.peak for h, c in zip(hist, self.curves)])
            rel = [relative_l2(h, c.a) for h, c in zip(hist, self.curves)]
            evals.append(Evaluation(params, 0.5 * float(r @ r), rel, r, hist))
        return evals

    def evaluate(self, x) -> Evaluation:
        """The objective at x (cached; recorded in the history and reported to progress)."""
        key = np.asarray(x, dtype=float).tobytes()
        if key not in self._cache:
            ev = self._evaluate([np.asarray(x, dtype=float)])[0]
            self._cache[key] = ev
            self.history.append({"evaluation": len(self.history) + 1, "cost": ev.cost, "parameters": ev.params,
                                 "rel_l2": ev.rel_l2, "drop_tests": self.runs,
                                 "elapsed": time.perf_counter() - self._start})
            if self.progress:
                values = ", ".join(f"{k} = {v:.5g}" for k, v in ev.params.items())
                fits = ", ".join(f"{100 * e:.2f} %" for e in ev.rel_l2)
                self.progress(f"evaluation {len(self.history)}: cost {ev.cost:.4e}, rel. L2 {fits}; {values} "
                              f"({self.runs} drop tests, {time.perf_counter() - self._start:.1f} s)")
        return self._cache[key]

    def residuals(self, x) -> np.ndarray:
        return self.evaluate(x).residual

    def jacobian(self, x) -> np.ndarray:
        """Forward differences d r / d x, all perturbed drop tests submitted at once."""
        x = np.asarray(x, dtype=float)
        base = self.evaluate(x).residual
        h = [self.rel_step if lg else self.rel_step * max(abs(x[i]), 1e-12) for i, lg in enumerate(self.coords.log)]
        steps = forward_steps(x, self.coords.upper, h)
        return forward_jacobian(lambda xs: [ev.residual for ev in self._evaluate(xs)], x, base, steps)


# ----------------------------------------------------------------------------- fitting
def confidence(x, jac, residual, coords: Coordinates, level: float = 0.95, ranges: dict | None = None,
               samples: float | None = None) -> dict:
    """{name: {value, std, ci}} and the correlation matrix from the Jacobian (see the docstring).

    std is the standard error of p (delta method); ci the ``level`` interval; None where J^T J is
    singular or where :func:`cfm_core.studies.identifiability.analyse` finds the parameter not
    separately identifiable (|correlation| >= 0.99 with another, or in a near-null direction of the
    scaled J^T J): then ci is widened to the extent of the valley within ``ranges`` (name -> (low,
    high) in SI units: the parameters' valid ranges; default the fit's bounds; None without one), "identifiability" holds the combinations the data do determine, with their intervals,
    and "warnings" says so; "flat" ({name: warning}) the parameters whose interval overflows the float
    range (withheld, with a warning).

    samples: the independent samples among the m residuals (filtered records: each carries the
    information of about m / samples grid points, :func:`cfm_core.studies.measured.independent_samples`);
    default m. With n = min(samples, m) and k = m / n, cov = k s^2 (J^T J)^-1 and Student's t has n - p
    degrees of freedom (band-limited noise with smooth Jacobian columns: J^T R J = k J^T J for the
    noise's correlation matrix R). Counting every grid point of a CFC 600 record as independent made
    the intervals about 5 times too narrow (3 of 10 noisy synthetic fits covered the truth).
    """
    from scipy import stats

    m, p = jac.shape
    n_ind = float(m) if not samples or samples >= m else float(samples)
    k = m / n_ind
    dof = max(n_ind - p, 1.0)
    s2 = float(residual @ residual) / max(m - p, 1)
    jtj = jac.T @ jac
    q = float(stats.t.ppf(0.5 + level / 2.0, dof))
    rank = np.linalg.matrix_rank(jtj)
    cov = k * s2 * np.linalg.pinv(jtj) if rank == p else None
    out, values, flat = {}, coords.to_params(x), {}
    for i, n in enumerate(coords.names):
        if cov is None or not cov[i, i] >= 0.0:
            out[n] = {"value": values[n], "std": None, "ci": None}
            continue
        sd = math.sqrt(cov[i, i])
        if coords.log[i]:
            ci, std = [coords.value(i, x[i] - q * sd), coords.value(i, x[i] + q * sd)], values[n] * sd
        else:
            ci, std = [x[i] - q * sd, x[i] + q * sd], sd
        if not all(math.isfinite(v) for v in (*ci, std)):  # a flat direction: beyond the float range
            out[n] = {"value": values[n], "std": None, "ci": None,
                      "withheld": "the linearised interval exceeds the float range: the data hardly depend on it"}
            flat[n] = identifiability.flat_warning(n)
            continue
        out[n] = {"value": values[n], "std": std, "ci": ci}
    corr = None
    if cov is not None:
        d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        corr = (cov / np.outer(d, d)).tolist()
    bounds = ranges or {n: tuple(coords.value(i, b) for b in (lo, hi))
                        for i, (n, lo, hi) in enumerate(zip(coords.names, coords.lower, coords.upper))}
    ident = identifiability.analyse(x, jac, k * s2, q, coords.names, coords.log, values, bounds, residual)
    warnings = list(ident["warnings"]) + [text for n, text in flat.items() if n not in ident["unidentified"]]
    poor = identifiability.poorly_determined(out, [n for n in coords.names if n not in ident["unidentified"]])
    for n, rel in poor.items():  # the linearisation cannot hold over an interval wider than the value
        warnings.append(identifiability.poor_warning(n, rel, out[n]["ci"], coords.units[coords.names.index(n)]))
        out[n].update(ci=None, withheld=f"poorly determined: relative standard error {rel:.3g} "
                                        f"(above {identifiability.POOR_STD:g})")
    for n in ident["unidentified"]:  # one point of a valley: its own interval would claim too much
        valley = ident["valley"].get(n)
        valley = valley if valley and all(math.isfinite(v) for v in valley) else None
        out[n].update(std=None, ci=valley, withheld="not separately identifiable: " + (
            "the interval is the valley's extent within the bounds" if valley else "no interval"))
    return {"parameters": out, "correlation": corr, "dof": dof, "s2": s2, "t_quantile": q, "level": level,
            "independent_samples": n_ind, "correlation_factor": k,
            "cond_JTJ": float(np.linalg.cond(jtj)) if rank == p else None, "identifiability": ident,
            "poorly_determined": poor, "flat": flat, "warnings": warnings}


def mark_bounds(conf: dict, x, coords: Coordinates, what: str = "bound") -> dict:
    """Record in ``conf`` the fitted parameters that ended on a bound, with their intervals withheld.

    Adds ``at_bound`` ({name: {side, bound (SI), unit}}, :func:`identifiability.at_bounds`) and a
    warning per such parameter naming the bound; returns the ``at_bound`` dict.
    """
    bounds = identifiability.at_bounds(x, coords)
    for n, entry in bounds.items():
        text = identifiability.bound_warning(n, entry, what)
        conf["parameters"][n].update(ci=None, std=None, withheld=f"ended on the {entry['side']} {what}")
        conf.setdefault("warnings", []).append(text)
    conf["at_bound"] = bounds
    return bounds


@dataclass
class FitResult:
    """What :func:`fit` found: start and fitted evaluations, confidence, the problem, scipy's answer."""

    problem: Problem
    start: Evaluation
    final: Evaluation
    confidence: dict
    status: str
    wall: float


def stopped_at_limit(res) -> bool:
    """Whether ``least_squares`` stopped at its evaluation limit (scipy's status 0, ``max_nfev``) before
    converging (:func:`fit` and :func:`cfm_core.studies.fit.fit_lab` withhold their intervals then): its
    values are where it stopped, not a minimum, and intervals from its Jacobian mean nothing.

    Parameters
    ----------
    res : scipy.optimize.OptimizeResult
        What ``least_squares`` returned (its ``status``).

    Returns
    -------
    bool
        True when it stopped at ``max_nfev``.
    """
    return int(res.status) == 0


def fit(scene, curves: list, names: list, start: dict | None = None, backend: str = "numba",
        runner=None, rel_step: float = REL_STEP, max_evaluations: int = 60, progress=None,
        options: dict | None = None) -> FitResult:
    """Fit ``names`` of the scene's material to the measured curves by least squares.

    start: starting values (default: the scene's material values); every other parameter keeps
    the scene's value; options: backend options of every drop test. Returns a :class:`FitResult`
    (a parameter that ends on a bound is named in ``confidence["at_bound"]`` and the warnings,
    its interval withheld); see the module docstring for the method.
    """
    from scipy.optimize import least_squares

    start = {n: (start or {}).get(n, v) for n, v in scene_values(scene, names).items()}
    values = material_values(scene.with_overrides(parameters=start))  # InputError: invalid start
    for c in curves:
        try:
            scene.with_overrides(thickness=c.thickness)
        except InputError as exc:
            raise InputError(f"--data {c.path}:{c.thickness:g}: this thickness does not fit the scene: {exc}") from None
    if not (isinstance(rel_step, float) and 1e-8 < rel_step < 0.1):
        raise InputError(f"rel_step = {rel_step!r} is not allowed: give a relative step in (1e-8, 0.1).")
    coords = coordinates(names, scene, values)
    x0 = np.clip(coords.to_x(start), coords.lower, coords.upper)
    problem = Problem(scene, curves, coords, backend, runner or SerialRunner(), rel_step, progress,
                      dict(options or {}))
    t0 = time.perf_counter()
    res = least_squares(problem.residuals, x0, jac=problem.jacobian, bounds=(coords.lower, coords.upper),
                        method="trf", x_scale=1.0, xtol=1e-6, ftol=1e-10, gtol=1e-10, max_nfev=max_evaluations)
    final = problem.evaluate(res.x)
    decl = {p.name: p for p in get_material(scene.material.name).parameters}
    known = [c.samples for c in curves]
    conf = confidence(res.x, res.jac, final.residual, coords, ranges={n: (decl[n].low, decl[n].high) for n in names},
                      samples=sum(known) if all(v > 0 for v in known) else None)
    bounds = mark_bounds(conf, res.x, coords, "bound of its valid range")
    conf["warnings"] = [n for c in curves for n in getattr(c, "notes", ())] + conf["warnings"]
    miss = identifiability.misfit_warning({c.name: e for c, e in zip(curves, final.rel_l2)}, "relative L2")
    if miss:
        conf["warnings"].append(miss)
        for n in names:
            conf["parameters"][n].update(ci=None, std=None, withheld="the fitted model misses the data")
    if any(getattr(c, "late", "") for c in curves):  # a record cut after contact: tight intervals around a biased fit
        for n in names:
            conf["parameters"][n].update(ci=None, std=None, withheld="a measured record starts after contact")
    if stopped_at_limit(res):  # the intervals would be those of a point that is not the minimum
        conf["warnings"].append(
            f"the fit stopped at the limit of {max_evaluations} evaluations (max_evaluations) before converging: "
            f"the values are where it stopped, not a minimum, and their intervals are withheld; raise it "
            f"(--max-evaluations) or start nearer.")
        for n in names:
            conf["parameters"][n].update(ci=None, std=None, withheld="the fit stopped before converging")
    status = str(res.message) + ("; ended on a bound: " + ", ".join(bounds) if bounds else "")
    return FitResult(problem, problem.evaluate(x0), final, conf, status, time.perf_counter() - t0)


from .calibrate_output import fitted_scene, write_fit  # noqa: E402,F401  (the outputs, kept importable here)
