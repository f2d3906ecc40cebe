"""One time step: predictor, Newton iterations with the consistent tangent, generalized-alpha update.

Residual and tangent at the iterate q for a step dt (Newmark relations with (beta, gamma) of the
generalized-alpha method; M = 0 and alpha_m = alpha_f = 0 when quasi-static):

    a(q) = (q - q_n - dt v_n) / (beta dt^2) - (1/(2 beta) - 1) a_n
    R(q) = M [(1 - alpha_m) a(q) + alpha_m a_n] + (1 - alpha_f) f(q) + alpha_f f(q_n) - f_ext
    K(q) = (1 - alpha_m) M / (beta dt^2) + (1 - alpha_f) df/dq,     f = f_int + dPhi_c/dq

Convergence is judged against the forces actually present, never against a stiffness: the
free-dof residual |R| must fall below ``rtol`` x the largest of |f_int| (reactions included),
|M a|, |f_c| and |f_ext| of the iterate (N), plus the user's ``atol`` (N, default 0). Multiplying
every modulus by a factor multiplies both sides by it; raising kappa alone (towards
incompressibility) leaves the forces and so the tolerance unchanged. What float64 cannot resolve
is the round-off of the volumetric forces, about eps kappa0 h^2 per dof (J - 1 carries an absolute
error ~eps, times the bulk modulus kappa0, times a face area h^2): when Newton stagnates there
(:data:`STALL_RATIO`, within :data:`STALL_BAND` x that floor) the step is accepted as
*round-off limited* (``StepInfo.stalled``) with the residual it reached, and the driver reports
the force balance attained (a warning, or an error above its limit), never "converged" silently.

A step from state n to t + dt either converges (a new :class:`State`) or raises
:class:`StepFailure` (Newton not converged in ``max_iterations``, divergence, J <= 0 at a Gauss
point, a non-finite material value or a failed linear solve); the driver then cuts the step.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from cfm_core.errors import NumericalError

from .element import Inverted
from .linear import Constraints, LinearSolveError, dot, norm
from .system import System

_EPS = float(np.finfo(np.float64).eps)
#: A Newton iterate whose residual fell by less than this factor is stagnating (-).
STALL_RATIO = 0.5
#: Stagnation is accepted as round-off only below this many times the round-off scale
#: eps kappa0 h^2 sqrt(free dofs) (N; the measured stagnation levels were 0.7-1.7 times eps kappa0 h^2
#: on one element, kappa0 from 6.7e8 to 6.7e14 Pa).
STALL_BAND = 100.0


@dataclass
class State:
    """Converged state at time t (s): q, v, a (m, m/s, m/s^2), Prony history, forces (N, modelled part).

    fz, fxy: the contact force on the impactor (N; z, and x and y for a laterally moving one);
    lam_sphere, lam_plane: contact multipliers (N) of the candidate nodes (see :mod:`.contact`);
    dissipation (J): the integrator's numerical dissipation in the step that led here;
    f_parts (parts, n): the internal forces of each part (N; None for one material).
    """

    t: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    hist: object | None
    f_int: np.ndarray
    f_c: np.ndarray
    fz: float = 0.0
    fxy: tuple = (0.0, 0.0)
    lam_sphere: np.ndarray | None = None
    lam_plane: np.ndarray | None = None
    pen_sphere: float = 0.0
    pen_plane: float = 0.0
    dissipation: float = 0.0
    f_parts: np.ndarray | None = None


class StepFailure(Exception):
    """A rejected step; ``quantity``, ``element`` and ``value`` say why (for the final error)."""

    def __init__(self, message: str, quantity: str, element: int | None = None, value: float | None = None):
        super().__init__(message)
        self.quantity = quantity
        self.element = element
        self.value = value


@dataclass
class StepInfo:
    """Newton iterations, residual norms (N), linear (CG) iterations and the local error estimate (-).

    scale: the force scale of the accepted iterate (N) the tolerance was relative to; stalled:
    the step was accepted at the round-off floor with residuals[-1] (N) above the tolerance.
    """

    iterations: int = 0
    residuals: list = field(default_factory=list)
    linear_iterations: int = 0
    error: float = 0.0
    scale: float = 0.0
    stalled: bool = False


def generalized_alpha(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, beta, gamma) of the generalized-alpha method (Chung and Hulbert 1993).

    rho_inf (-) is the spectral radius at infinite frequency: 1 keeps every mode (the trapezoidal
    rule, Newmark average acceleration), 0 removes the highest modes in one step. Second-order
    accurate for every rho_inf in [0, 1]; the momentum balance is taken at the generalized
    midpoint: M a_(n+1-alpha_m) + f(q_(n+1-alpha_f)) = f_ext, forces interpolated linearly.
    """
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 - am + af
    beta = 0.25 * (1.0 - am + af) ** 2
    return am, af, beta, gamma


class Stepper:
    """Newton solver of one step for a :class:`System` with the checked options ``o``."""

    def __init__(self, system: System, o: dict, linear_solver):
        self.sys = system
        self.o = o
        self.linear_solver = linear_solver  # an object of .linear with solve(data, b) -> (x, iterations)
        self.constraints = Constraints(system.pattern, system.constrained)
        self.atol = float(o["atol"]) if o["atol"] is not None else 0.0
        #: round-off scale of the residual norm (N): eps kappa0 h^2 per free dof (module docstring)
        h = system.disc.size
        self.roundoff = _EPS * system.kappa0 * h * h * math.sqrt(max(int((~system.constrained).sum()), 1))
        self.rtol = o["rtol"] if o["rtol"] is not None else (1e-6 if system.has_w else 1e-9)
        self.dynamic = not system.quasi_static
        self.alpha_m, self.alpha_f, self.beta, self.gamma = generalized_alpha(o["rho_inf"])
        self.times = system.times  # s per phase, shared with the system and the linear solver

    def _nonfinite_residual(self, R: np.ndarray, f_int: np.ndarray) -> StepFailure:
        """The rejection of an iterate whose residual norm is not finite, with its cause: forces whose
        squares overflow float64 (finite entries above ~1e154 N: a modulus near the float64 limit,
        mu = 1e306 Pa gave only "non-finite residual"), or a non-finite force entry (a diverging
        iterate), naming the element that holds it."""
        with np.errstate(invalid="ignore"):
            big = np.abs(np.where(np.isfinite(R), R, np.inf))
        e = self._worst_element(big)
        where = "at the impactor" if e is None else f"in element {e}"
        if np.isfinite(R).all():
            peak = float(np.abs(f_int).max()) if f_int.size else 0.0
            return StepFailure(f"non-finite residual: the forces overflow float64 (the largest residual {big.max():.3g} N "
                               f"{where}, internal forces up to {peak:.3g} N: their squares exceed 1.8e308); the "
                               f"material's stiffness here is beyond what a float64 solve can carry (a modulus or "
                               f"a stiffening exponent far too large: check the parameters and their units)",
                               "residual overflow", element=e, value=float(big.max()))
        return StepFailure(f"non-finite residual {where} (the Newton iterate diverged)", "residual", element=e)

    def _worst_element(self, R: np.ndarray) -> int | None:
        """An element holding the node with the largest residual (None: the impactor dof)."""
        k = int(np.argmax(np.abs(R)))
        if k >= 3 * self.sys.n_nodes:
            return None
        hits = np.flatnonzero((self.sys.disc.conn == k // 3).any(axis=1))
        return int(hits[0]) if hits.size else None

    def prescribed(self, t: float) -> float:
        pr = self.sys.model.prescribed
        return pr.displacement(t) if pr is not None else 0.0

    def step(self, s: State, dt: float, q_pred: np.ndarray) -> tuple[State, StepInfo]:
        """Advance s by dt (s) from the predictor q_pred (prescribed dofs are set here)."""
        sys, o = self.sys, self.o
        t1 = s.t + dt
        q = q_pred.copy()
        if sys.presc_dofs.size:
            q[sys.presc_dofs] = self.prescribed(t1)
        free = ~sys.constrained
        am, af = (self.alpha_m, self.alpha_f) if self.dynamic else (0.0, 0.0)
        c0 = 1.0 / (self.beta * dt * dt) if self.dynamic else 0.0
        info = StepInfo()
        r0 = None
        lam = (s.lam_sphere, s.lam_plane) if s.lam_sphere is not None else None
        times = self.times
        augment = o["contact"] == "augmented"
        pen_tol = o["penetration_tol"] * sys.disc.size
        augmentations = 0
        k_step = sys.penalty
        for it in range(o["max_iterations"] + 1):
            try:
                ev = sys.evaluate(q, s.hist, dt, tangent=True, lam=lam, k=k_step)
            except Inverted as exc:
                raise StepFailure(f"J = {exc.value:.4g} <= 0 in element {exc.element}", "J", exc.element, exc.value)
            except NumericalError as exc:
                raise StepFailure(str(exc), exc.quantity or "material", exc.element)
            if self.dynamic:
                a1 = c0 * (q - s.q - dt * s.v) - (0.5 / self.beta - 1.0) * s.a
                a1[sys.constrained] = 0.0
                inertia = sys.mass * ((1.0 - am) * a1 + am * s.a)
            else:
                a1 = np.zeros_like(q)
                inertia = np.zeros_like(q)
            f_new = ev.f_int + ev.f_c
            R = inertia + (1.0 - af) * f_new + af * (s.f_int + s.f_c) - sys.f_ext
            Rf = np.where(free, R, 0.0)
            with np.errstate(over="ignore", invalid="ignore"):  # a diverging iterate is rejected below
                rn = norm(Rf)
                scale = max(norm(ev.f_int), norm(inertia),
                            norm(ev.f_c), norm(sys.f_ext))
            # round-off floor: the inertia term evaluates (1 - alpha_m) c0 M q with q ~ |u|, which
            # at small dt carries an absolute error ~ eps c0 M |q|
            with np.errstate(over="ignore", invalid="ignore"):
                floor = 100.0 * _EPS * (1.0 - am) * c0 * norm(sys.mass * np.abs(q))
            tol = self.rtol * scale + self.atol + floor
            info.residuals.append(rn)
            if not np.isfinite(rn):
                raise self._nonfinite_residual(Rf, ev.f_int)
            # stagnation at the round-off floor: accepted as such (the driver reports it)
            stalled = (rn > tol and len(info.residuals) >= 2 and rn > STALL_RATIO * info.residuals[-2]
                       and rn <= STALL_BAND * self.roundoff and r0 is not None)
            if rn <= tol or stalled:
                cs = ev.contact
                if (augment and cs is not None and augmentations < 5
                        and max(cs.max_pen_sphere, cs.max_pen_plane) > pen_tol):
                    # penetration above the tolerance: update the multipliers within the step
                    # (an Uzawa iteration; from the second one on with a 4x stiffer k for this step,
                    # where the tissue is much stiffer than k) and continue Newton from here
                    lam = (cs.p_sphere, cs.p_plane)
                    augmentations += 1
                    if augmentations >= 2:
                        k_step *= 4.0
                    r0 = None
                    continue
                info.iterations = it
                info.scale = scale
                info.stalled = stalled
                break
            if r0 is None:
                r0 = rn
            elif rn > 1e8 * r0 or it == o["max_iterations"]:
                e = self._worst_element(Rf)
                raise StepFailure(f"Newton did not converge in {it} iterations (residual {rn:.3g} N, "
                                  f"tolerance {tol:.3g} N = rtol {self.rtol:g} x force scale {scale:.3g} N"
                                  f"{f' + atol {self.atol:g} N' if self.atol else ''}; round-off floor of the "
                                  f"residual ~{self.roundoff:.3g} N = eps x kappa0 {self.sys.kappa0:.4g} Pa x h^2 "
                                  f"x sqrt(free dofs); largest residual "
                                  f"{'at the impactor' if e is None else f'in element {e}'})",
                                  "Newton residual", element=e, value=rn)
            tic = time.perf_counter()
            K = (1.0 - af) * ev.K
            if self.dynamic:
                K[sys.pattern.diag] += (1.0 - am) * c0 * sys.mass
            self.constraints.apply(K)
            times["assembly"] += time.perf_counter() - tic
            try:
                # inexact Newton: an iterative solve only as accurate as the Newton tolerance needs
                eta = min(self.o["cg_rtol"], max(1e-12, 0.1 * tol / rn))
                dq, nit = self.linear_solver.solve(K, -Rf, rtol=eta)
                if not np.isfinite(dq).all():
                    raise LinearSolveError("non-finite solution")
            except LinearSolveError as exc:
                raise StepFailure(f"linear solve failed: {exc}", "linear solve")
            info.linear_iterations += nit
            q = q + dq
        v1 = s.v + dt * ((1.0 - self.gamma) * s.a + self.gamma * a1) if self.dynamic else np.zeros_like(q)
        if sys.presc_dofs.size:
            pr = sys.model.prescribed
            v1[sys.presc_dofs] = pr.velocity(t1 - 1e-12 * dt) if self.dynamic else 0.0
        cs = ev.contact
        diss = 0.0
        if self.dynamic:
            # the integrator's energy identity on the free dofs (where R = 0 is solved; the work of
            # the prescribed ones is the reaction's, recorded as external work):
            # dq . R = dK + dW_int + dW_c + D - dW_ext, with
            # D = dq . M abar - dK + (1/2 - alpha_f) dq . (f_(n+1) - f_n)   (J, modelled part)
            dqs = np.where(free, q - s.q, 0.0)
            abar = (1.0 - am) * a1 + am * s.a
            dK = 0.5 * dot(np.where(free, sys.mass * (v1 + s.v), 0.0), v1 - s.v)
            diss = (dot(dqs, sys.mass * abar) - dK
                    + (0.5 - af) * dot(dqs, f_new - s.f_int - s.f_c))
            # local error of the step (Zienkiewicz-Xie): e = (beta - 1/6) dt^2 (a_(n+1) - a_n) (m),
            # mass-weighted RMS norm relative to that of the displacement q_(n+1) (-)
            e = (self.beta - 1.0 / 6.0) * dt * dt * (a1 - s.a)
            den = dot(sys.mass, q * q)
            info.error = math.sqrt(dot(sys.mass, e * e) / den) if den > 0.0 else 0.0
        new = State(t=t1, q=q, v=v1, a=a1, hist=ev.history if ev.history is not None else s.hist,
                    f_int=ev.f_int, f_c=ev.f_c,
                    fz=cs.force_on_impactor if cs is not None else 0.0, fxy=lateral_force(cs),
                    lam_sphere=(cs.p_sphere if augment else s.lam_sphere) if cs is not None else None,
                    lam_plane=(cs.p_plane if augment else s.lam_plane) if cs is not None else None,
                    pen_sphere=cs.max_pen_sphere if cs is not None else 0.0,
                    pen_plane=cs.max_pen_plane if cs is not None else 0.0,
                    dissipation=diss,
                    f_parts=sys.parts.nodal_forces(sys.n) if sys.parts is not None else None)
        return new, info



def lateral_force(cs) -> tuple[float, float]:
    """(x, y) force on the impactor (N) of a contact state (zero without one or along z only)."""
    if cs is None or cs.force_vector is None:
        return (0.0, 0.0)
    return (float(cs.force_vector[0]), float(cs.force_vector[1]))
