"""Fit a registered material's parameters to laboratory tests (the paper's first stage).

The tests (:mod:`cfm_core.studies.lab_tests`: uniaxial, relaxation, shear, equibiaxial, confined)
are simulated at a material point, vectorised over their time steps. Objective: with P_jk the
nominal stress of test j at row k (Pa), n_j its rows, w_j its weight and s_j = max_k |P_meas,jk|,

    r_jk = sqrt(w_j / n_j) (P_sim,jk - P_meas,jk) / s_j,      cost = 1/2 sum r^2

so each curve counts by its weight, not by its number of rows or its stress level.
``scipy.optimize.least_squares`` (trust region reflective, 2-point Jacobian) works on ln p for
parameters whose range starts at 0 and on p otherwise, inside the parameters' valid ranges; a
fitted Prony coefficient g_i is bounded so that the fitted ones keep gamma_inf = 1 - sum g_i at or above
cfm's floor (:data:`cfm_core.material.prony.GAMMA_INF_MIN`)
(:func:`cfm_core.studies.calibrate.coordinates`).

Intervals (:func:`cfm_core.studies.calibrate.confidence`): cov = s^2 (J^T J)^-1, 95 % Student t;
they assume independent residuals and a correct model. Identifiability (:func:`identifiability`):
when two fitted parameters are correlated with |r| >= :data:`CORRELATION_LIMIT`, or the
correlation matrix has a condition number above :data:`CONDITION_LIMIT` (near-singular J^T J),
the data fix a combination, not each value: a warning names them (printed and in fit.json) and
their intervals are withheld (null), not reported as if they meant something. So are all of them when
the reported start stopped at ``max_evaluations`` before converging
(:func:`~cfm_core.studies.calibrate.stopped_at_limit`, the
rule of ``cfm calibrate``): its values are not a minimum.

Noise: a curve's stress at its undeformed rows is called a load-cell offset (:func:`offset_warnings`)
only when it stands out of the noise measured on the curve (:func:`stress_noise`).

Files (plots, fitted-scene.toml, fit.json): :mod:`cfm_core.studies.fit_output`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path

import numpy as np

from ..errors import InputError, NumericalError
from ..material.registry import get_material
from ..scene.scene import builtin_scene
from .calibrate import Coordinates, confidence, coordinates, parse_fit_names, stopped_at_limit
from .identifiability import at_bounds, bound_warning, misfit_warning, poor_warning
from .lab_tests import KINDS, LabTest, read_lab_test, simulate, undeformed

#: |correlation| at or above which two parameters are reported as not separately identifiable.
CORRELATION_LIMIT = 0.99
#: Condition number of the correlation matrix above which J^T J counts as near-singular.
CONDITION_LIMIT = 1e10
#: A parameter fitted in log coordinates is searched within start / SEARCH_FACTOR .. start * SEARCH_FACTOR
#: (and its valid range); a value that ends on this box is reported as not determined.
SEARCH_FACTOR = 1e4
#: A fitted coordinate this close to a bound of its search range (relative to max(1, |bound|)) is put on the
#: bound: the trust-region method stops a few units of the last bit inside it, and the value is then
#: reported as the bound itself (700.0, not 699.999999999999), at a change far below its tolerance (1e-10).
SNAP = 1e-12
#: Starting points of a fit that includes a Prony time (the given start and PRONY_STARTS - 1 others).
PRONY_STARTS = 6


def parse_test_spec(spec: str) -> tuple[str, str, float, float]:
    """Split a ``--test`` argument.

    Parameters
    ----------
    spec : str
        ``FILE:KIND:RATE[:WEIGHT]``, e.g. ``comp.csv:uniaxial:0.01`` (rate in 1/s).

    Returns
    -------
    tuple
        (file, kind, rate in 1/s, weight -).

    Raises
    ------
    InputError
        A missing or unknown kind, or a rate or weight that is not a number.
    """
    parts = str(spec).rsplit(":", 3)
    if len(parts) == 4 and parts[1] in KINDS:
        path, kind, rate, weight = parts
    elif len(parts) >= 3 and parts[-2] in KINDS:
        path, kind, rate = str(spec).rsplit(":", 2)
        weight = "1"
    else:
        raise InputError(f"--test {spec!r}: expected FILE:KIND:RATE[:WEIGHT] with KIND one of {', '.join(KINDS)}, "
                         f"RATE the loading's engineering strain rate in 1/s and WEIGHT a positive number, e.g. "
                         f"comp.csv:uniaxial:0.01 or fast.csv:uniaxial:1:2.")
    values = []
    for label, text in (("RATE (1/s)", rate), ("WEIGHT (-)", weight)):
        try:
            values.append(float(text))
        except ValueError:
            raise InputError(f"--test {spec!r}: {label} = {text!r} is not a number.") from None
    return path, kind, values[0], values[1]


def read_tests(specs) -> list[LabTest]:
    """Read the tests of ``--test`` arguments.

    Parameters
    ----------
    specs : list of str
        ``FILE:KIND:RATE[:WEIGHT]`` each.

    Returns
    -------
    list of LabTest
        In the given order, names made unique.

    Raises
    ------
    InputError
        No tests, or any problem of a file (:func:`cfm_core.studies.lab_tests.read_lab_test`).
    """
    if not specs:
        raise InputError("give at least one --test FILE:KIND:RATE[:WEIGHT] (columns t s, stretch or shear -, "
                         "stress Pa).")
    tests, seen = [], {}
    for spec in specs:
        path, kind, rate, weight = parse_test_spec(spec)
        stem = Path(path).stem
        seen[stem] = seen.get(stem, 0) + 1
        tests.append(read_lab_test(path, kind, rate, weight, stem if seen[stem] == 1 else f"{stem}-{seen[stem]}"))
    return tests


def fit_names(text: str, material: str) -> list[str]:
    """Expand the ``--fit`` list into parameter names.

    Parameters
    ----------
    text : str
        Comma-separated names, e.g. ``c,k1,prony`` (``prony``: every g_i and tau_i).
    material : str
        Registered material name.

    Returns
    -------
    list of str
        Parameter names in the given order.

    Raises
    ------
    InputError
        An unknown or repeated name, or an empty list.
    """
    spec = get_material(material)
    prony = tuple(p.name for p in spec.prony.parameters) if spec.prony else ()
    return parse_fit_names(text, spec, prony, "c,k1,k2")


def check_scene(scene, names) -> None:
    """Refuse fitted parameters that the drop-test scene of fitted-scene.toml would not use.

    fitted-scene.toml is the scene with the fitted material in its [material] section; in a
    layered specimen a layer that names its own material, or gives a parameter itself, does not
    take that parameter from there, so a fitted value no layer takes would change no drop test.

    Parameters
    ----------
    scene : Scene
        The drop-test scene (``--scene``).
    names : list of str
        Fitted parameter names.

    Raises
    ------
    InputError
        Naming the first such parameter and why no layer takes it
        (:func:`cfm_core.scene.layers.refuse_unused`).
    """
    from ..scene.layers import refuse_unused

    refuse_unused(scene, names, lambda n: f"--fit {n}",
                  "its fitted value would go into fitted-scene.toml's [material] section, where no drop test reads it",
                  "Let a layer take {name} from [material] (one without a material or a {name} of its own), or "
                  "drop {name} from --fit.")


#: A test whose measured stresses are this many times larger (or smaller) than the starting material's
#: is warned about as a probable unit slip (a stress column in kPa read as Pa).
STRESS_SLIP = 100.0


def stress_scale_warnings(tests, start_stresses) -> list[str]:
    """Warnings for tests whose measured stresses are :data:`STRESS_SLIP` times off the starting material's.

    The stress column is read in Pa; a column in kPa (or MPa) makes every measured value 1e-3 (1e-6)
    times the material's, and the fit then ends on its search bounds with a large misfit (kPa data
    of the Table 1 material: k1 and k2 on their lower bounds, rel. RMS 143 %), when it should say
    what is wrong.

    Parameters
    ----------
    tests : list of LabTest
        The tests (measured nominal stress P in Pa).
    start_stresses : list of ndarray
        The starting material's nominal stress (Pa) at each test's rows.

    Returns
    -------
    list of str
        One warning per such test, naming the ratio and the likely unit.
    """
    out = []
    for test, sim in zip(tests, start_stresses):
        scale = float(np.max(np.abs(sim))) if np.size(sim) else 0.0
        if not (scale > 0.0 and test.scale > 0.0):
            continue
        ratio = test.scale / scale
        if 1.0 / STRESS_SLIP <= ratio <= STRESS_SLIP:
            continue
        decade = round(math.log10(ratio) / 3.0)
        unit = {-1: "kPa", -2: "MPa", 1: "Pa multiplied by 1000 twice (kPa converted to Pa twice)"}.get(decade)
        guess = f" Is its stress column in {unit}? The column is read in Pa." if unit else " The column is read in Pa."
        out.append(f"test '{test.name}' ({test.path}): its measured stresses (largest |P| {test.scale:.4g} Pa) are "
                   f"{ratio:.3g}x those of the starting material (largest {scale:.4g} Pa).{guess} Convert it to Pa, "
                   f"or check the starting values (--param) if they are far off.")
    return out


#: Stress at the undeformed rows of a test, as a fraction of its largest |stress|, from which the
#: curve is said to carry an offset (-).
OFFSET = 0.01
#: ... and the standard errors of the undeformed rows' mean stress (noise / sqrt(rows), the noise from
#: :func:`stress_noise`) it must exceed too, so that one noisy undeformed row is not called an offset (-).
OFFSET_NOISE = 4.0
#: The noise is judged on the rows up to the first beyond this fraction of the largest deformation, and
#: on at least NOISE_ROWS rows (-).
NOISE_SPAN = 0.5
NOISE_ROWS = 10


def stress_noise(test) -> float:
    """Standard deviation of the measured stress's noise near the undeformed state (Pa), robust.

    Each row's departure from the straight line in time through its two neighbours,
    e_k = P_k - ((1 - w) P_(k-1) + w P_(k+1)) with w = (t_k - t_(k-1)) / (t_(k+1) - t_(k-1)), holds no
    trace of the curve's level or slope (its curvature enters as P'' dt^2 / 2, small on a sampled
    curve) and, for white noise of standard deviation sigma, has the standard deviation
    sigma sqrt(1 + (1 - w)^2 + w^2). So sigma = 1.4826 median |e_k / sqrt(1 + (1 - w)^2 + w^2)| (the
    median absolute deviation of a normal distribution; robust to the kink where the loading starts),
    over the rows up to the first beyond :data:`NOISE_SPAN` of the largest deformation, at least
    :data:`NOISE_ROWS`.

    Parameters
    ----------
    test : LabTest
        The test (t in s, deformation x, measured nominal stress P in Pa).

    Returns
    -------
    float
        sigma (Pa); 0 with fewer than 3 rows to judge.
    """
    t, P = np.asarray(test.t, float), np.asarray(test.P, float)
    d = np.abs(np.asarray(test.x, float) - undeformed(test.kind))
    beyond = np.flatnonzero(d > NOISE_SPAN * d.max())
    n = max(int(beyond[0]) + 1 if beyond.size else t.size, NOISE_ROWS)
    t, P = t[:n], P[:n]
    if t.size < 3:
        return 0.0
    w = (t[1:-1] - t[:-2]) / (t[2:] - t[:-2])
    e = (P[1:-1] - ((1.0 - w) * P[:-2] + w * P[2:])) / np.sqrt(1.0 + (1.0 - w) ** 2 + w**2)
    return float(1.4826 * np.median(np.abs(e)))


def offset_warnings(tests) -> list[str]:
    """Warnings for tests whose stress at the undeformed state is not zero: a load cell not zeroed
    (a tare). The model's stress there is exactly zero, so the fit bends the parameters to absorb
    the offset: 1 % of the peak moved k1 by 7.5 % and k2 by 9 %, with tight intervals that
    excluded the truth. The fit's intervals are withheld where this is said.

    The undeformed rows' mean stress is called an offset when it exceeds both :data:`OFFSET` of the
    test's largest |stress| and :data:`OFFSET_NOISE` standard errors of that mean, noise / sqrt(rows)
    with the noise of :func:`stress_noise`: a single undeformed row of a curve with 1 % noise is
    1 % off zero one time in three, which is noise, not a tare.

    Parameters
    ----------
    tests : list of LabTest
        The tests (deformation x, measured nominal stress P in Pa).

    Returns
    -------
    list of str
        One warning per such test: its undeformed rows' mean stress (Pa) and its share of the peak.
    """
    out = []
    for test in tests:
        base = undeformed(test.kind)
        rest = np.flatnonzero(np.abs(np.asarray(test.x) - base) <= 1e-12)
        if rest.size == 0 or not test.scale > 0.0:
            continue
        level = float(np.mean(np.asarray(test.P)[rest]))
        noise = stress_noise(test)
        if abs(level) > OFFSET * test.scale and abs(level) > OFFSET_NOISE * noise / math.sqrt(rest.size):
            scatter = f"; the stress's noise there is {noise:.3g} Pa" if noise > 0.0 else ""
            out.append(f"test '{test.name}' ({test.path}): its stress is {level:.4g} Pa ({100 * abs(level) / test.scale:.2g} % "
                       f"of its largest |stress|) at the undeformed state ({KINDS[test.kind][0]} = {base:g}, "
                       f"{rest.size} row(s){scatter}), where the material's is 0: a load-cell offset? Subtract it "
                       f"from the stress column; the fit bends the parameters to absorb it, so no interval is given.")
    return out


def identifiability(conf: dict, names, at_bound=()) -> tuple[list[str], set]:
    """Identifiability warnings of a fit (module docstring).

    Parameters
    ----------
    conf : dict
        From :func:`cfm_core.studies.calibrate.confidence` (``parameters``, ``correlation``).
    names : list of str
        Fitted parameter names, in the order of the correlation matrix.
    at_bound : dict or sequence of str
        Names whose fitted value ended on the search box or the valid range (a dict of
        :func:`cfm_core.studies.identifiability.at_bounds`: the warning names the bound).

    Returns
    -------
    tuple
        (list of warning texts, set of names whose intervals are withheld).
    """
    pre = [bound_warning(n, at_bound[n], "end of its search range") if isinstance(at_bound, dict) else
           f"{n} ended on the edge of its search range ({conf['parameters'][n]['value']:.6g}): the data do not "
           f"determine it (or the range excludes the best value); its interval is withheld." for n in at_bound]
    poor = {n: rel for n, rel in conf.get("poorly_determined", {}).items() if n not in at_bound}
    pre += [poor_warning(n, rel, None) for n, rel in poor.items()]  # their intervals: withheld by confidence()
    flat = {n: text for n, text in conf.get("flat", {}).items() if n not in at_bound}
    pre += list(flat.values())
    warnings, withheld = _correlations(conf, names)
    return pre + warnings, withheld | set(at_bound) | set(poor) | set(flat)


def _correlations(conf: dict, names) -> tuple[list[str], set]:
    corr = conf["correlation"]
    if corr is None:
        return ([f"J^T J is singular: the data do not determine {', '.join(names)} (some combination of them "
                 f"leaves every residual unchanged); intervals withheld."], set(names))
    corr = np.asarray(corr)
    warnings, withheld = [], set()
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if abs(corr[i, j]) >= CORRELATION_LIMIT:
                warnings.append(f"{names[i]} and {names[j]} are correlated (r = {corr[i, j]:+.4f}): the data fix a "
                                f"combination of them, not each; their intervals are withheld.")
                withheld |= {names[i], names[j]}
    cond = float(np.linalg.cond(corr)) if len(names) > 1 else 1.0
    if not cond <= CONDITION_LIMIT:
        warnings.append(f"J^T J is near-singular (condition number of the correlation matrix {cond:.3g} > "
                        f"{CONDITION_LIMIT:g}): some combination of {', '.join(names)} is not determined by the "
                        f"data; all intervals are withheld.")
        withheld |= set(names)
    return warnings, withheld


def _search_box(coords: Coordinates, values: dict) -> Coordinates:
    """The valid ranges, narrowed for log coordinates to start / SEARCH_FACTOR .. start * SEARCH_FACTOR
    (the logarithms of those two values, so that a fit ending there reports them to the bit:
    :func:`cfm_core.studies.calibrate.from_log`)."""
    def scaled(v, power):  # v * SEARCH_FACTOR**power in decimal, rounded once: 0.07 * 1e4 = 700.0 (not ...01)
        return float(Decimal(repr(float(v))) * Decimal(repr(SEARCH_FACTOR)) ** power)

    low = [math.log(scaled(values[n], -1)) if lg else -math.inf for n, lg in zip(coords.names, coords.log)]
    high = [math.log(scaled(values[n], 1)) if lg else math.inf for n, lg in zip(coords.names, coords.log)]
    return Coordinates(coords.names, coords.units, coords.log, np.maximum(coords.lower, low),
                       np.minimum(coords.upper, high))


def _start_offsets(coords: Coordinates, x0, values: dict, names, starts: int) -> list[np.ndarray]:
    """Offsets from x0 of the starting points: 0 first, then a scrambled Halton sequence (seed 0) within a
    decade of the start for log coordinates (ln 10 either way), within +-50 % for linear ones, clipped
    to the search box. Deterministic."""
    out = [np.zeros_like(x0)]
    if starts > 1:
        from scipy.stats import qmc

        u = qmc.Halton(len(x0), scramble=True, seed=0).random(starts - 1)
        half = np.where(coords.log, math.log(10.0), 0.5 * np.maximum(np.abs(x0), 1e-12))
        lo, hi = coords.lower - x0, coords.upper - x0
        for row in u:
            out.append(np.clip((2 * row - 1) * half, lo + 1e-9 * np.abs(lo), hi - 1e-9 * np.abs(hi)))
    return out


def _trf(fun, y0, bounds, max_evaluations: int):
    """``least_squares`` (trust region reflective, 2-point Jacobian, xtol = ftol = gtol = 1e-10) from y0,
    then, if it stopped on the gradient test with evaluations left, again from where it stopped
    without that test (xtol and ftol only), kept if its cost is no higher; ``nfev`` counts both.

    The gradient test reads the gradient scaled by the distance to the bound it points at (Coleman and
    Li's scaling), so a fit whose optimum lies on or near a bound stops early: a Prony coefficient
    fitted toward sum g_i = 1 - 1e-6 (gamma_inf at cfm's floor) stopped after 4 evaluations at gamma_inf
    = 6.9e-6 with a 95 % interval 14 standard deviations from the truth; the second run reaches it
    to 1e-9 (scipy.optimize.least_squares, ``gtol``; T. F. Coleman, Y. Li, SIAM J. Optim. 6, 1996)."""
    from scipy.optimize import least_squares

    res = least_squares(fun, y0, bounds=bounds, method="trf", jac="2-point", x_scale=1.0, xtol=1e-10, ftol=1e-10,
                        gtol=1e-10, max_nfev=max_evaluations)
    if res.status == 1 and res.nfev < max_evaluations:
        more = least_squares(fun, res.x, bounds=bounds, method="trf", jac="2-point", x_scale=1.0, xtol=1e-10,
                             ftol=1e-10, gtol=None, max_nfev=max_evaluations - res.nfev)
        if float(more.fun @ more.fun) <= float(res.fun @ res.fun):
            more.nfev += res.nfev
            return more
        res.nfev += more.nfev
    return res


def _rel_rms(P, test: LabTest) -> float:
    """RMS of (simulated - measured) nominal stress over the test's largest |measured| stress (-)."""
    return float(np.sqrt(np.mean((np.asarray(P) - test.P) ** 2)) / test.scale)


def _limit_warnings(tried, best_stopped: bool, max_evaluations: int) -> list[str]:
    """The warnings for starts stopped at ``max_evaluations`` before converging
    (:func:`~cfm_core.studies.calibrate.stopped_at_limit`):
    the reported one (its intervals withheld), or others (the best start may then not be the best fit)."""
    limited = sum(1 for t in tried if t.get("converged") is False)
    limit = f"the limit of {max_evaluations} evaluations (--max-evaluations, per start)"
    if best_stopped and len(tried) == 1:
        return [f"the fit stopped at {limit} before converging: the values are where it stopped, not a minimum, "
                f"and their intervals are withheld; raise --max-evaluations or start nearer (--param)."]
    if best_stopped:
        others = f" ({limited - 1} other start(s) stopped there too)" if limited > 1 else ""
        return [f"the best of the {len(tried)} starts stopped at {limit} before converging{others}: the values are "
                f"where it stopped, not a minimum, and their intervals are withheld; raise --max-evaluations."]
    if limited:
        return [f"{limited} of {len(tried)} starts stopped at {limit} before converging, so the best start may not "
                f"be the best fit; raise --max-evaluations."]
    return []


@dataclass
class LabFitResult:
    """What :func:`fit_lab` found.

    Attributes
    ----------
    material, moduli : str
        Material name and moduli convention.
    elastic : bool
        Whether the Prony series was off.
    coords : Coordinates
        Fitted coordinates (names, units, log flags, search box).
    tests : list of LabTest
        The measured curves.
    start, fitted : dict
        Every parameter's value at the start and at the end (SI units).
    P_start, P_fit : list of ndarray
        Simulated nominal stress per test at the start and at the end (Pa), each simulated from a
        clean state (no lateral stretches remembered from other parameters): a function of the
        parameters alone, equal to the optimiser's evaluation there to the Newton tolerance.
    cost_start, cost : float
        Objective 1/2 sum r^2 at the start and at the end (-).
    confidence : dict
        Standard errors, 95 % intervals (None where withheld), correlation matrix.
    warnings : list of str
        Identifiability warnings.
    withheld : set of str
        Names whose intervals are withheld.
    status : str
        scipy's termination message of the best start.
    evaluations : int
        The optimiser's evaluations (scipy's ``nfev``: what ``max_evaluations`` limits per start; the
        finite-difference Jacobian's columns not included), summed over the starts that finished.
    residual_evaluations : int
        Every residual evaluation: the one at the starting values, the optimiser's and its
        finite-difference Jacobian's columns, failed starts included (the length of ``history``).
    wall : float
        Optimisation wall time (s).
    history : list of float
        Cost of every evaluation (-).
    tried : list of dict
        Start, result, cost, ``evaluations`` (the optimiser's), ``converged`` (False: stopped at
        ``max_evaluations``) and ``residual_evaluations`` of every start; a failed one: the error.
    """

    material: str
    moduli: str
    elastic: bool
    coords: Coordinates
    tests: list
    start: dict
    fitted: dict
    P_start: list
    P_fit: list
    cost_start: float
    cost: float
    confidence: dict
    warnings: list
    withheld: set
    status: str
    evaluations: int
    wall: float
    history: list = field(default_factory=list)
    tried: list = field(default_factory=list)
    residual_evaluations: int = 0

    def rel_rms(self, which: str = "fit") -> list[float]:
        """Relative RMS error per test.

        Parameters
        ----------
        which : str
            "fit" (the fitted parameters) or "start".

        Returns
        -------
        list of float
            RMS of (simulated - measured) over the largest |measured| stress (-), per test.
        """
        sims = self.P_fit if which == "fit" else self.P_start
        return [_rel_rms(s, t) for s, t in zip(sims, self.tests)]


def fit_lab(material: str, tests: list, names: list, start: dict | None = None, fixed: dict | None = None,
            moduli: str | None = None, elastic: bool = False, max_evaluations: int = 200,
            progress=None, starts: int | None = None) -> LabFitResult:
    """Fit ``names`` of the registered ``material`` to the lab tests by least squares.

    Parameters
    ----------
    material : str
        Registered material name (``cfm materials``).
    tests : list of LabTest
        Measured curves (:func:`read_tests`).
    names : list of str
        Parameters to fit (:func:`fit_names`).
    start : dict, optional
        Starting values of fitted parameters (SI); default: the material's defaults (or ``fixed``).
    fixed : dict, optional
        Values of the other parameters (SI); default: the material's defaults.
    moduli, elastic
        Moduli convention ("instantaneous" | "long-term", default the material's) and whether the Prony
        series is off.
    max_evaluations : int
        Most residual evaluations of the optimiser (per start).
    progress : callable, optional
        Receives a line of text every 10 evaluations.
    starts : int, optional
        Number of starting points (:func:`_start_offsets`); default :data:`PRONY_STARTS` when a Prony
        time is fitted (Prony fits have local minima: a time far above the test's duration has no
        effect, and the fit can stop there), else 1. The lowest cost wins; all are in fit.json.
        Each start begins from a clean state (no lateral stretches remembered from another), and
        a coordinate that ends within :data:`SNAP` of its bound is put on it.

    Returns
    -------
    LabFitResult

    Raises
    ------
    InputError
        Unknown names, values out of range, a fitted Prony parameter with ``elastic``, no tests.
    NumericalError
        A test's simulation failed (exponential overflow, no lateral stretch).
    """
    spec = get_material(material)
    if not tests:
        raise InputError("no tests to fit: give at least one --test FILE:KIND:RATE.")
    prony_names = {p.name for p in spec.prony.parameters} if spec.prony else set()
    if starts is None:
        starts = PRONY_STARTS if any(n.startswith("tau") and n in prony_names for n in names) else 1
    if not (isinstance(starts, int) and starts >= 1):
        raise InputError(f"starts = {starts!r} must be an integer >= 1.")
    if not (isinstance(max_evaluations, int) and max_evaluations >= 1):
        raise InputError(f"max_evaluations = {max_evaluations!r} must be an integer >= 1.")
    if elastic and prony_names & set(names):
        raise InputError(f"--fit {', '.join(sorted(prony_names & set(names)))}: the Prony series is switched off "
                         f"(--elastic); drop --elastic or fit the elastic parameters only.")
    overrides = {**(fixed or {}), **(start or {})}
    base = spec.bind(overrides, moduli, elastic)  # InputError for bad names or values
    moduli = base.moduli
    values = dict(base.values)
    scene = builtin_scene("drop-test").with_overrides(material=material, parameters=None)
    coords = _search_box(coordinates(names, scene, values), values)
    x0 = np.clip(coords.to_x(values), coords.lower, coords.upper)
    history = []
    memories = [{} for _ in tests]

    def bind(x):
        return spec.bind({**values, **coords.to_params(x)}, moduli, elastic)

    def stresses(x):
        m = bind(x)
        out = []
        for t, mem in zip(tests, memories):
            try:
                out.append(simulate(m, t, mem))
            except NumericalError as exc:  # which curve, at which parameters
                values = ", ".join(f"{k} = {v:.6g}" for k, v in coords.to_params(x).items())
                raise NumericalError(f"test '{t.name}' ({t.path}) at {values}: {exc}") from None
        return out

    def forget():
        """A clean state: no lateral stretches remembered from other parameters (another start's lead Newton
        astray), so what follows depends on its parameters alone (each start, the final evaluations)."""
        for mem in memories:
            mem.pop("lateral", None)

    def fresh(x):
        forget()
        return stresses(x)

    def residual(x):
        sims = stresses(x)
        r = np.concatenate([math.sqrt(t.weight / t.x.size) * (s - t.P) / t.scale for s, t in zip(sims, tests)])
        history.append(0.5 * float(r @ r))
        if progress and len(history) % 10 == 1:
            progress(f"evaluation {len(history)}: cost {history[-1]:.4e}; "
                     + ", ".join(f"{k} = {v:.5g}" for k, v in coords.to_params(x).items()))
        return r

    t0 = time.perf_counter()
    r0 = residual(x0)
    tried = []
    best = None
    failed = []
    for y0 in _start_offsets(coords, x0, values, names, starts):
        # Work in y = x - x0: scipy's first trust radius is |y0| (or 1 when y0 = 0), so the first step stays
        # near the start instead of jumping by |ln p| (a jump of ln tau by ~7 lands on the plateau where a
        # Prony time has no effect, and the fit stops there).
        done = len(history)
        forget()  # its result does not depend on the starts before it
        try:
            res = _trf(lambda y: residual(x0 + y), y0, (coords.lower - x0, coords.upper - x0), max_evaluations)
        except NumericalError as exc:  # a trial point of this start broke the model: the start is lost, not the fit
            tried.append({"start": coords.to_params(x0 + y0), "failed": str(exc),
                          "residual_evaluations": len(history) - done})
            failed.append(exc)
            continue
        res.x = x0 + res.x
        for bound in (coords.lower, coords.upper):  # a value on a bound is reported as the bound (SNAP)
            res.x = np.where(np.abs(res.x - bound) <= SNAP * np.maximum(1.0, np.abs(bound)), bound, res.x)
        tried.append({"start": coords.to_params(x0 + y0), "fitted": coords.to_params(res.x),
                      "cost": 0.5 * float(res.fun @ res.fun), "evaluations": int(res.nfev),
                      "converged": not stopped_at_limit(res), "residual_evaluations": len(history) - done})
        if best is None or tried[-1]["cost"] < 0.5 * float(best.fun @ best.fun):
            best = res
    if best is None:
        raise failed[0]
    res = best
    wall = time.perf_counter() - t0
    conf = confidence(res.x, res.jac, res.fun, coords)
    bounds = at_bounds(res.x, coords)
    conf["at_bound"] = bounds
    warnings, withheld = identifiability(conf, list(coords.names), bounds)
    start_stresses = fresh(x0)
    fitted_stresses = fresh(res.x)
    offsets = offset_warnings(tests)
    if offsets:
        withheld |= set(coords.names)
    warnings = stress_scale_warnings(tests, start_stresses) + offsets + warnings
    if failed:
        warnings.append(f"{len(failed)} of {len(tried)} start(s) ended where the model could not be evaluated "
                        f"(the first: {failed[0]}); the best of the other starts is reported, so a better fit may "
                        f"lie where those starts were heading.")
    warnings += _limit_warnings(tried, stopped_at_limit(res), max_evaluations)
    if stopped_at_limit(res):  # the intervals would be those of a point that is not the minimum
        withheld |= set(coords.names)
    miss = misfit_warning({t.name: _rel_rms(s, t) for s, t in zip(fitted_stresses, tests)}, "relative RMS")
    if miss:
        warnings.append(miss)
        withheld |= set(coords.names)
    for n in withheld:
        conf["parameters"][n]["ci"] = None
    if bounds:
        res.message = f"{res.message}; ended on a bound: {', '.join(bounds)}"
    fitted = dict(bind(res.x).values)
    return LabFitResult(material, moduli, bool(elastic), coords, tests, values, fitted, start_stresses,
                        fitted_stresses, 0.5 * float(r0 @ r0), 0.5 * float(res.fun @ res.fun), conf, warnings,
                        withheld, str(res.message), sum(t.get("evaluations", 0) for t in tried), wall, history,
                        tried, len(history))
