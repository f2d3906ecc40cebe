"""Run a :class:`cfm_core.scene.Model` implicitly: adaptive time stepping, histories, Result.

Steps are cut (x ``cut``) and retried when Newton fails and grow (x ``grow``) after a fast
convergence, never beyond ``dt_max`` (default: the model's output interval, so histories are
recorded at least that often), and they land exactly on the breakpoints of a prescribed motion
and on the end time. Histories are recorded at every accepted step. Forces, impulses and
energies in the Result are for the full model (x ``model.symmetry_factor``), SI units.
``info["force_balance"]`` says how well the accepted steps balanced the forces (:mod:`.balance`);
a run whose Newton stopped at round-off above the requested accuracy warns through
``info["solver_warnings"]`` (passed on by the run checks) or, above 1e-3, stops.
"""

from __future__ import annotations

import math
import time
from collections import deque
from contextlib import ExitStack

import numpy as np

from cfm_backends.threads import num_threads
from cfm_core.errors import InputError, NumericalError
from cfm_core.material.compile_notice import announce_compile
from cfm_core.simulation.checks import Monitor
from cfm_core.simulation.result import Result

from .balance import Balance
from .compiled import module_source
from .options import check_options
from .history import Recorder
from .stepper import State, StepFailure, Stepper, lateral_force
from .system import System


class _ContactMonitor(Monitor):
    """The shared physics checks, whose penetration failures also name this backend's contact
    stiffness: a penalty of penalty_factor x kappa0 x h follows the bulk modulus, so a soft kappa0
    (666.1 Pa: kPa meant) makes soft rigid surfaces, and the nodes went through them while the
    message blamed the load and the mesh (explicit backends, with kinematic contact, ran it)."""

    def __init__(self, model, penalty: float, o: dict, kappa0: float, h: float):
        made = "" if o["penalty"] is not None else (f" (penalty_factor {o['penalty_factor']:g} x kappa0 {kappa0:.4g} "
                                                    f"Pa x h {h:.4g} m)")
        super().__init__(model, contact_hint=f" skfem's contact is a penalty of {penalty:.4g} N/m per node{made}: "
                                             f"if the material is meant to be this soft, a stiffer contact "
                                             f"(--option penalty=..., N/m) keeps the nodes out.")


def _quasi_static(model, o) -> bool:
    if o["quasi_static"] is not None:
        return bool(o["quasi_static"])
    return bool(model.meta.get("quasi_static", False))


class _Schedule:
    """Largest admissible step at time t: dt_max, end time, breakpoints of the prescribed motion."""

    def __init__(self, model, dt_max: float, segment_steps: int):
        self.end = float(model.end_time)
        self.dt_max = dt_max
        pr = model.prescribed
        self.times = np.asarray(pr.times, dtype=float) if pr is not None else np.zeros(0)
        self.values = np.asarray(pr.values, dtype=float) if pr is not None else np.zeros(0)
        self.segment_steps = segment_steps

    def segment(self, t: float) -> int:
        return int(np.searchsorted(self.times, t, side="right")) - 1

    def limit(self, t: float, dt: float) -> float:
        dt = min(dt, self.dt_max, self.end - t)
        i = self.segment(t)
        if 0 <= i < self.times.size - 1:
            seg = self.times[i + 1] - self.times[i]
            if self.values[i + 1] != self.values[i]:
                dt = min(dt, seg / self.segment_steps)
            dt = min(dt, self.times[i + 1] - t)
            if self.times[i + 1] - (t + dt) < 1e-9 * dt:  # land exactly on the breakpoint
                dt = self.times[i + 1] - t
        if self.end - (t + dt) < 1e-9 * dt:
            dt = self.end - t
        return dt


PARALLEL_MIN = 1000  # below this many elements the compiled kernels run on one thread (start-up costs more)


def run_model(model, progress=None, **options) -> Result:
    """Run ``model``; see :class:`cfm_backends.skfem_implicit.SkfemImplicitBackend`."""
    o = check_options(options)
    if o["kernels"] != "numba" or len(model.hexes) >= PARALLEL_MIN:
        return _run(model, progress, o)
    import numba

    with num_threads(numba, 1):
        return _run(model, progress, o)


def _run(model, progress, o) -> Result:
    wall0 = time.perf_counter()
    quasi = _quasi_static(model, o)  # friction and parts: SkfemImplicitBackend.check_model, before this
    if quasi and model.sphere is not None:
        raise InputError(f"skfem backend: model '{model.name}' has a rigid impactor, which needs inertia; "
                         f"run it dynamically (quasi_static=False).")
    for part in model.part_list():
        if not quasi and not (float(part.density) > 0.0):
            where = f"part '{part.name}' of model '{model.name}'" if model.parts else f"model '{model.name}'"
            raise InputError(f"{where}: density = {part.density!r} kg/m^3 must be > 0 for a "
                             f"dynamic run; quasi-static scenes set meta['quasi_static'] = True.")
    end = float(model.end_time)
    if not (end > 0.0 and math.isfinite(end)):
        raise InputError(f"model '{model.name}': end_time = {end!r} s must be finite and > 0.")
    sys_ = System(model, o["volumetric"], quasi, kernels=o["kernels"])
    h = sys_.disc.size
    sys_.penalty = float(o["penalty"]) if o["penalty"] is not None else o["penalty_factor"] * sys_.kappa0 * h
    solver = _linear_solver(sys_, o, quasi)
    if o["error_tol"] == "auto":  # accuracy-controlled steps for impacts; prescribed motions keep theirs
        o = {**o, "error_tol": 2e-3 if sys_.has_w else None}
    if o["dt_max"] is not None:
        dt_max = float(o["dt_max"])
    elif quasi or o["error_tol"] is None:
        dt_max = float(model.output_interval)
    else:  # the error estimate sets the step; the cap keeps the impulse history fine enough for
        # the 50 kHz resampling (measured: 2.5 output intervals, peak -0.5 %; 5 of them, -1.1 %)
        dt_max = 2.5 * float(model.output_interval)
    sched = _Schedule(model, dt_max, o["segment_steps"])
    if o["dt"] is not None:
        dt = float(o["dt"])
    elif quasi:
        dt = sched.limit(0.0, dt_max)
    else:
        dt = dt_max / 10.0
    dt_min = float(o["dt_min"]) if o["dt_min"] is not None else 1e-5 * dt_max
    if o["dt_min"] is not None and o["dt_max"] is not None and dt_min > dt_max:  # both given: contradictory
        raise InputError(f"skfem backend: option dt_min = {dt_min:g} s is above dt_max = {dt_max:g} s; the smallest "
                         f"step must not exceed the largest (leave dt_min out: 1e-5 dt_max).")
    stepper = Stepper(sys_, o, solver)
    with ExitStack() as notices:  # the first evaluation compiles the element kernels of each material
        if o["kernels"] == "numba":  # the numba backend's notice of a cold first run
            for name, material in {p.material.name: p.material for p in model.part_list()}.items():
                notices.enter_context(announce_compile(module_source(material), "cfm_skfem", "skfem", name,
                                                       "elements"))
        state = _initial_state(sys_, stepper)
    rec = Recorder(sys_, model)
    rec.record(state, None, 0.0)
    setup = time.perf_counter() - wall0
    frames = [] if o["frame_interval"] is None else [(0.0, np.zeros((sys_.n_nodes, 3)))]
    next_frame = o["frame_interval"] or math.inf
    q_prev, t_prev_seg = None, None
    stats = {"newton_iterations": 0, "rejected_steps": 0, "error_rejections": 0, "linear_iterations": 0}
    balance = Balance(stepper.rtol)  # force balance attained by the accepted steps
    tol = o["error_tol"] if (stepper.dynamic and o["error_tol"] is not None) else None
    newton_log = []
    failures = []  # (t (s), dt (s), quantity, message) of the first 50 rejected steps
    seen, separated_for, separated = False, 0.0, False
    next_progress = end / 100.0
    steps = 0
    monitor = _ContactMonitor(model, sys_.penalty, o, sys_.kappa0, h)  # physics checks, every ~1 % of the end time
    nodes = np.asarray(model.nodes, dtype=np.float64)
    impactor_z = lambda s: sys_.impactor_point(s.q)  # noqa: E731  - the whole reference point (m)
    recent = deque(maxlen=STALL_STEPS)  # times of the last accepted steps
    overflows = Overflows()  # steps rejected for a non-finite material term: named when the run stops
    while state.t < end * (1.0 - 1e-12):
        if steps >= o["max_steps"]:
            raise NumericalError(f"skfem backend: more than max_steps = {o['max_steps']} steps before "
                                 f"t = {end:g} s (reached t = {state.t:.6g} s).", time=state.t, quantity="steps")
        dt_try = sched.limit(state.t, dt)
        while True:
            q_pred = _predict(stepper, sched, state, dt_try, q_prev, t_prev_seg)
            try:
                new, info = stepper.step(state, dt_try, q_pred)
            except StepFailure as fail:
                stats["rejected_steps"] += 1
                if len(failures) < 50:
                    failures.append([state.t + dt_try, dt_try, fail.quantity, str(fail)])
                overflows.add(fail, state.t + dt_try, dt_try)
                if dt_try <= dt_min * (1.0 + 1e-12):
                    # the physical cause first: a last accepted state that already fails the run checks
                    # (penetration, folded corner, bottoming out) is reported as such, not its symptom
                    monitor.inspect(state.t, nodes + sys_.displacement(state.q), impactor_z(state))
                    raise _final_error(model, fail, state.t + dt_try, dt_try, overflows.since(recent)) from None
                dt_try = max(dt_try * o["cut"], dt_min)
                dt = dt_try
                continue
            stats["newton_iterations"] += info.iterations
            stats["linear_iterations"] += info.linear_iterations
            if tol is not None and info.error > 3.0 * tol:
                if dt_try <= dt_min * (1.0 + 1e-12):
                    # accepting it would march on at dt_min with the error uncontrolled (kappa = 100 Pa:
                    # minutes of 5e-10 s steps without a word): the step collapsed; its cause first
                    monitor.inspect(state.t, nodes + sys_.displacement(state.q), impactor_z(state))
                    raise _collapse_error(model, state.t, dt_try, info.error, tol, overflows.since(recent))
                # too large a local error: retry smaller (the step's work is counted above)
                stats["error_rejections"] += 1
                dt_try = max(dt_try * max(0.2, 0.9 * (tol / info.error) ** (1.0 / 3.0)), dt_min)
                dt = dt_try
                continue
            break
        balance.add(info)
        recent.append(new.t)
        if len(recent) == STALL_STEPS and new.t - recent[0] < STALL_FRACTION * end:
            # the step collapsed (Newton needing ever smaller steps): stop, its cause first, instead of
            # grinding on for hours at 1e-8 s steps
            monitor.inspect(new.t, nodes + sys_.displacement(new.q), impactor_z(new))
            raise _stall_error(model, new.t, new.t - recent[0], dt_try, info.iterations, end, overflows.since(recent))
        if o["record_newton"]:
            newton_log.append([new.t, dt_try, info.residuals])
        q_prev, t_prev_seg = (state.q, state.t), sched.segment(state.t + 0.5 * dt_try)
        rec.record(new, state, dt_try)
        state = new
        steps += 1
        if tol is not None:
            # accuracy first: the third-order local error sets the next step (0.5x to 2x)
            ratio = 0.9 * (tol / max(info.error, 1e-300)) ** (1.0 / 3.0)
            dt = dt_try * min(2.0, max(0.5, ratio))
            if info.iterations > 0.6 * o["max_iterations"]:
                dt = min(dt, dt_try * 0.7)
        elif info.iterations <= o["grow_iterations"]:
            dt = dt_try * o["grow"]
        elif info.iterations > 0.6 * o["max_iterations"]:
            dt = dt_try * 0.7
        else:
            dt = max(dt, dt_try)
        dt = max(dt, dt_min)
        if state.t >= next_frame - 1e-12 * end:
            frames.append((state.t, sys_.displacement(state.q).copy()))
            next_frame += o["frame_interval"]
        if monitor.due(state.t):
            monitor.check(state.t, nodes + sys_.displacement(state.q), impactor_z(state))
        if progress is not None and state.t >= next_progress:
            progress(state.t)
            next_progress = state.t + end / 100.0
        if sys_.has_w:
            if state.fz > 0.0:
                seen, separated_for = True, 0.0
            elif seen and state.v[sys_.w_dof] > 0.0:
                separated_for += dt_try
                if model.stop_after_separation and separated_for >= o["separation_time"] - 1e-12:
                    separated = True
                    break
    wall = time.perf_counter() - wall0 - setup  # solver time: the stepping loop only (as the numba backend)
    monitor.final(state.t, nodes + sys_.displacement(state.q), impactor_z(state))
    warnings = list(sys_.warnings) + balance.verdict(model, stepper, state.t)
    info = {"checks": monitor.report(), "force_balance": balance.record(), "solver_warnings": warnings,
            "elements": sys_.disc.n_elements, "dofs": sys_.n, "setup_time": setup,
            "times": dict(sys_.times), "counts": dict(sys_.counts), "contact": o["contact"],
            "error_tol": tol, "failures": failures,
            "linear_solver": solver.name, "kernels": o["kernels"], "volumetric": o["volumetric"],
            "integrator": "quasi-static" if quasi else f"generalized-alpha(rho_inf={o['rho_inf']:g})",
            "element_size": h, **stats}
    if sys_.has_w or model.plane is not None:
        info.update(penalty=sys_.penalty, max_penetration_sphere=rec.pen_s, max_penetration_plane=rec.pen_p,
                    penetration_ratio=max(rec.pen_s, rec.pen_p) / h, separated=separated)
    if o["record_newton"]:
        info["newton"] = newton_log
    return rec.result(model, steps, wall, frames, info)


def _linear_solver(sys_: System, o: dict, quasi: bool):
    """The linear solver object for this run (see :mod:`.linear` and the option ``linear_solver``)."""
    from . import linear

    kind = o["linear_solver"]
    if kind == "auto":
        kind = "direct" if quasi else "cg"
    why = linear.pardiso_problem() if kind == "pardiso" else None
    if why is not None:
        raise InputError(f"skfem backend: linear_solver = 'pardiso' needs MKL PARDISO, which cannot be loaded here "
                         f"({why}); install pypardiso (pip install pypardiso) where it finds MKL's mkl_rt, or use "
                         f"'cg', 'superlu' (scipy only) or 'auto'.")
    return linear.make_solver(kind, sys_.pattern, sys_.n_nodes, rtol=o["cg_rtol"], maxiter=o["cg_maxiter"],
                              times=sys_.times, counts=sys_.counts)


def _initial_state(sys_: System, stepper: Stepper) -> State:
    q = np.zeros(sys_.n)
    v = np.zeros(sys_.n)
    if sys_.has_w:
        v[sys_.imp_dofs] = sys_.sphere.velocity_vector[sys_.axes]
    pr = sys_.model.prescribed
    if pr is not None and not sys_.quasi_static:
        v[sys_.presc_dofs] = pr.velocity(0.0)
    hist = sys_.relaxed_history()
    ev = sys_.evaluate(q, hist, 0.0, tangent=False)
    a = np.zeros(sys_.n)
    if not sys_.quasi_static:
        free = ~sys_.constrained & (sys_.mass > 0)
        a[free] = (sys_.f_ext - ev.f_int - ev.f_c)[free] / sys_.mass[free]
    cs = ev.contact
    lam_s, lam_p = sys_.zero_multipliers()
    return State(0.0, q, v, a, hist, ev.f_int, ev.f_c, fz=cs.force_on_impactor if cs else 0.0,
                 fxy=lateral_force(cs), f_parts=sys_.parts.nodal_forces(sys_.n) if sys_.parts is not None else None,
                 lam_sphere=lam_s, lam_plane=lam_p)


def _predict(stepper: Stepper, sched: _Schedule, s: State, dt: float, q_prev, seg_prev) -> np.ndarray:
    """Newmark predictor (a_{n+1} = a_n) or, quasi-static, linear extrapolation within a segment."""
    if stepper.dynamic:
        return s.q + dt * s.v + 0.5 * dt * dt * s.a
    if q_prev is None or seg_prev != sched.segment(s.t + 0.5 * dt) or s.t <= q_prev[1]:
        return s.q.copy()
    return s.q + (s.q - q_prev[0]) * (dt / (s.t - q_prev[1]))


#: A run whose last STALL_STEPS accepted steps advanced less than STALL_FRACTION of its end time has
#: collapsed (a drop test takes ~2000 steps of ~4e-5 s; kappa = 100 Pa, nu = -0.99, took 1e-8 s steps).
STALL_STEPS = 200
STALL_FRACTION = 1e-4


class Overflows:
    """The steps rejected because a material term was not finite (the fibre exponential beyond exp(709),
    the volumetric term at J -> 0, a modulus near the float64 limit): the cause to name when the run
    stops, where the symptom is a collapsed step or a Newton iteration that does not converge (k2 = 1e9
    on the drop test: 14 such rejections among 240, and the run said only "the time step collapsed")."""

    def __init__(self):
        self.times = deque(maxlen=100_000)   # times (s) the rejected steps aimed at
        self.last = None                     # (t (s), dt (s), StepFailure) of the latest

    @staticmethod
    def overflowed(fail: StepFailure) -> bool:
        """Whether a rejected step failed on a non-finite material term (compiled.py, constitutive.py)."""
        return str(fail.quantity).startswith("non-finite")

    def add(self, fail: StepFailure, t: float, dt: float) -> None:
        """Record a rejected step aimed at time t (s) with step dt (s), if it overflowed."""
        if self.overflowed(fail):
            self.times.append(t)
            self.last = (t, dt, fail)

    def since(self, recent) -> tuple | None:
        """(count, t (s), dt (s), StepFailure) of the overflows since the oldest step in ``recent`` (the
        accepted steps of the stall window; all of them while it is not full), or None."""
        start = recent[0] if len(recent) == recent.maxlen else -math.inf
        n = sum(1 for t in self.times if t >= start)
        return (n, *self.last) if n and self.last is not None else None


def _overflow_cause(overflow) -> str:
    """The sentence naming the term that overflowed (the numba backend's wording, through
    :func:`cfm_core.material.diagnose.describe_nonfinite` in the failure's message); the usual
    suspects when none did (``overflow`` None)."""
    if overflow is None:
        return "an element folding, contact chattering, or a material far out of its range"
    n, t, dt, fail = overflow
    return (f"the material's energy overflows: {n} step(s) were rejected because a term is not finite, the "
            f"latest the step of {dt:.3g} s to t = {t:.6g} s: {str(fail).rstrip('.')}")


def _stall_error(model, t: float, advanced: float, dt: float, iterations: int, end: float,
                 overflow=None) -> NumericalError:
    """The error of a run whose steps collapsed (:data:`STALL_STEPS`, :data:`STALL_FRACTION`); ``overflow``
    (:meth:`Overflows.since`) names the material term that overflowed as the cause."""
    return NumericalError(
        f"skfem backend: the time step collapsed at t = {t:.6g} s in model '{model.name}': the last "
        f"{STALL_STEPS} steps advanced {advanced:.3g} s in all (less than {STALL_FRACTION:g} of the end time "
        f"{end:g} s; last step {dt:.3g} s, {iterations} Newton iterations), so the run would take hours and "
        f"no step follows the response ({_overflow_cause(overflow)}); the run cannot be trusted beyond this time.",
        time=t, **_overflow_where(overflow, "time step"))


def _collapse_error(model, t: float, dt: float, error: float, tol: float, overflow=None) -> NumericalError:
    """The error of a run whose local error stays above the tolerance at the smallest step; ``overflow``
    as for :func:`_stall_error`."""
    return NumericalError(
        f"skfem backend: the time step collapsed at t = {t:.6g} s in model '{model.name}': at the smallest "
        f"step dt_min = {dt:.3g} s the local error is {error:.3g}, above 3 x error_tol = {3.0 * tol:.3g}, so "
        f"no step can follow the response ({_overflow_cause(overflow)}); the run cannot be trusted beyond this time.",
        time=t, **_overflow_where(overflow, "time step"))


def _overflow_where(overflow, quantity: str) -> dict:
    """element and quantity of the error: the overflowed term's (as the numba backend reports an overflow),
    else ``quantity`` alone."""
    if overflow is None:
        return {"quantity": quantity}
    fail = overflow[3]
    return {"element": fail.element, "quantity": fail.quantity}


def _final_error(model, fail: StepFailure, t: float, dt: float, overflow=None) -> NumericalError:
    """The error of a step that failed at the smallest step dt (s); a failure that is not itself an
    overflow names the overflow among the rejected steps before (``overflow``, :meth:`Overflows.since`)."""
    where = f" in element {fail.element}" if fail.element is not None else ""
    cause = ""
    if overflow is not None and not Overflows.overflowed(fail):
        cause = f" The cause: {_overflow_cause(overflow)}."
        element, quantity = overflow[3].element, overflow[3].quantity
    else:
        element, quantity = fail.element, fail.quantity
    return NumericalError(
        f"skfem backend: the step to t = {t:.6g} s failed at the smallest step dt = {dt:.3g} s{where} "
        f"({fail.quantity}): {fail}.{cause} Model '{model.name}': lower the load, refine the mesh, or lower "
        f"dt_min / raise max_iterations.", time=t, element=element, quantity=quantity)
