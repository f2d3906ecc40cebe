"""One time step: predictor, Newton iterations with the consistent tangent, generalized-alpha update.

Residual and tangent at the iterate q for a step dt (Newmark relations with (beta, gamma) of the
generalized-alpha method; M = 0 and alpha_m = alpha_f = 0 when quasi-static):

    a(q) = (q - q_n - dt v_n) / (beta dt^2) - (1/(2 beta) - 1) a_n
    R(q) = M [(1 - alpha_m) a(q) + alpha_m a_n] + (1 - alpha_f) f(q) + alpha_f f(q_n) - f_ext
    K(q) = (1 - alpha_m) M / (beta dt^2) + (1 - alpha_f) df/dq,     f = f_int + dPhi_c/dq

A step from state n to t + dt either converges (a new :class:`State`) or raises
:class:`StepFailure` (Newton not converged in ``max_iterations``, divergence, J <= 0 at a Gauss
point, a non-finite material value or a failed linear solve); the driver then cuts the step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cfm_core.errors import NumericalError

from .constitutive import History
from .element import Inverted
from .linear import LinearSolveError, constrain, solve
from .system import System

_EPS = float(np.finfo(np.float64).eps)


@dataclass
class State:
    """Converged state at time t (s): q, v, a (m, m/s, m/s^2), Prony history, forces (N, modelled)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    hist: History | None
    f_int: np.ndarray
    f_c: np.ndarray
    fz: float = 0.0
    contact_energy: float = 0.0
    pen_sphere: float = 0.0
    pen_plane: float = 0.0


class StepFailure(Exception):
    """A rejected step; ``quantity``, ``element`` and ``value`` say why (for the final error)."""

    def __init__(self, message: str, quantity: str, element: int | None = None, value: float | None = None):
        super().__init__(message)
        self.quantity = quantity
        self.element = element
        self.value = value


@dataclass
class StepInfo:
    iterations: int = 0
    residuals: list = field(default_factory=list)
    linear_iterations: int = 0


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

    def __init__(self, system: System, o: dict, linear_solver: str, atol: float):
        self.sys = system
        self.o = o
        self.linear_solver = linear_solver
        self.atol = atol
        self.dynamic = not system.quasi_static
        self.alpha_m, self.alpha_f, self.beta, self.gamma = generalized_alpha(o["rho_inf"])

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
        for it in range(o["max_iterations"] + 1):
            try:
                ev = sys.evaluate(q, s.hist, dt, tangent=True)
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
            rn = float(np.linalg.norm(Rf))
            scale = max(float(np.linalg.norm(ev.f_int)), float(np.linalg.norm(inertia)),
                        float(np.linalg.norm(ev.f_c)), float(np.linalg.norm(sys.f_ext)))
            # round-off floor: the inertia term evaluates (1 - alpha_m) c0 M q with q ~ |u|, which
            # at small dt carries an absolute error ~ eps c0 M |q|
            floor = 100.0 * _EPS * (1.0 - am) * c0 * float(np.linalg.norm(sys.mass * np.abs(q)))
            tol = o["rtol"] * scale + self.atol + floor
            info.residuals.append(rn)
            if not np.isfinite(rn):
                raise StepFailure("non-finite residual", "residual")
            if rn <= tol:
                info.iterations = it
                break
            if r0 is None:
                r0 = rn
            elif rn > 1e8 * max(r0, self.atol) or it == o["max_iterations"]:
                e = self._worst_element(Rf)
                raise StepFailure(f"Newton did not converge in {it} iterations (residual {rn:.3g} N, "
                                  f"tolerance {tol:.3g} N; largest residual "
                                  f"{'at the impactor' if e is None else f'in element {e}'})",
                                  "Newton residual", element=e, value=rn)
            K = (1.0 - af) * ev.K
            if self.dynamic:
                K = K + _diag((1.0 - am) * c0 * sys.mass)
            K = constrain(K, sys.constrained)
            try:
                dq, nit = solve(K, -Rf, self.linear_solver, sys.n_nodes)
            except LinearSolveError as exc:
                raise StepFailure(f"linear solve failed: {exc}", "linear solve")
            info.linear_iterations += nit
            q = q + dq
        v1 = s.v + dt * ((1.0 - self.gamma) * s.a + self.gamma * a1) if self.dynamic else np.zeros_like(q)
        if sys.presc_dofs.size:
            pr = sys.model.prescribed
            v1[sys.presc_dofs] = pr.velocity(t1 - 1e-12 * dt) if self.dynamic else 0.0
        cs = ev.contact
        new = State(t=t1, q=q, v=v1, a=a1, hist=ev.history if ev.history is not None else s.hist,
                    f_int=ev.f_int, f_c=ev.f_c,
                    fz=cs.force_on_impactor if cs is not None else 0.0,
                    contact_energy=cs.energy if cs is not None else 0.0,
                    pen_sphere=cs.max_pen_sphere if cs is not None else 0.0,
                    pen_plane=cs.max_pen_plane if cs is not None else 0.0)
        return new, info


def _diag(d: np.ndarray):
    import scipy.sparse as sps

    return sps.diags(d, format="csr")
