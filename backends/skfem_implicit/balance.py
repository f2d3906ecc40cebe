"""The force balance a run's accepted Newton steps attained, and its verdict (warning or error).

Newton's tolerance is relative to the forces present (:mod:`.stepper`); where float64 round-off
of the volumetric forces (~eps kappa0 h^2 per dof) keeps the residual above it, the step is
accepted at that floor and counted here. Relative to the largest force scale of the run, the
largest such residual is the relative accuracy of the reported forces (-).
"""

from __future__ import annotations

import math

from cfm_core.errors import NumericalError

#: Force balance (largest round-off-limited residual / largest force scale, -) above which a run stops.
BALANCE_LIMIT = 1e-3
#: A run warns when its force balance is worse than this many times the requested rtol (-).
WARN_FACTOR = 10.0


class Balance:
    """The force balance the accepted steps attained: largest residual over the run's force scale.

    A step Newton accepted at the round-off floor (``StepInfo.stalled``) balances its forces only
    to its last residual (N). Relative to the largest force scale of the run (N), that is the
    accuracy of the forces reported: above :data:`WARN_FACTOR` x ``rtol`` the run warns, above
    :data:`BALANCE_LIMIT` it stops (a NumericalError: the forces would be wrong by more than that
    fraction).

    Parameters
    ----------
    rtol : float
        The Newton tolerance the run asked for, relative to the force scale (-).
    """

    def __init__(self, rtol: float):
        self.rtol = rtol
        self.scale = 0.0       # N, largest force scale of an accepted step
        self.stalled = 0       # steps accepted at the round-off floor
        self.residual = 0.0    # N, largest residual of those

    def add(self, info) -> None:
        """Count an accepted step (a :class:`.stepper.StepInfo`: scale (N), stalled, residuals (N))."""
        self.scale = max(self.scale, info.scale)
        if info.stalled:
            self.stalled += 1
            self.residual = max(self.residual, info.residuals[-1])

    def relative(self) -> float:
        """Largest round-off-limited residual over the largest force scale (-); 0 without one."""
        if self.scale > 0.0:
            return self.residual / self.scale
        return math.inf if self.residual > 0.0 else 0.0

    def record(self) -> dict:
        """For ``Result.info["force_balance"]``: stalled_steps, largest_stalled_residual (N),
        force_scale (N), relative (-)."""
        return {"stalled_steps": self.stalled, "largest_stalled_residual": self.residual,
                "force_scale": self.scale, "relative": self.relative()}

    def verdict(self, model, stepper, t: float) -> list[str]:
        """The run's warnings (text, for ``Result.info["solver_warnings"]``).

        Raises NumericalError (quantity "force balance") when the relative balance is above
        :data:`BALANCE_LIMIT`; ``stepper`` gives the round-off scale, kappa0 and h named in the text.
        """
        rel = self.relative()
        if not self.stalled or rel <= WARN_FACTOR * self.rtol:
            return []
        text = (f"skfem backend: Newton reached only the round-off floor of the residual in {self.stalled} "
                f"step(s): the forces balance to {self.residual:.3g} N, {rel:.3g} of the largest force scale "
                f"{self.scale:.3g} N (requested rtol {self.rtol:g}); float64 resolves the volumetric forces only "
                f"to ~eps x kappa0 x h^2 = {stepper.roundoff:.3g} N with the bulk modulus kappa0 = "
                f"{stepper.sys.kappa0:.4g} Pa at element size h = {stepper.sys.disc.size:.3g} m")
        if rel > BALANCE_LIMIT:
            raise NumericalError(f"{text}, above the limit {BALANCE_LIMIT:g} in model '{model.name}': the "
                                 f"reported forces cannot be trusted. Lower kappa: the force differs from its "
                                 f"incompressible limit by about stress / (2 kappa) (measured on the CFM), so a "
                                 f"kappa 1e6 times the stresses is incompressible to ~5e-7.",
                                 time=t, quantity="force balance")
        return [text + "; the forces carry relative errors of about that size."]
