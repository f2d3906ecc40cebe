"""Implicit dynamics and quasi-static analysis with scikit-fem: the ``skfem`` backend.

Total Lagrangian hex8 elements assembled with scikit-fem's hexahedral basis (2 x 2 x 2 Gauss
points), locking free through the mean-dilatation (Q1/P0, equivalently F-bar) treatment of the
volumetric term; Newton's method with the consistent tangent taken from the material's single
definition (generated psi_grad / psi_hess and :func:`cfm_core.material.kinematics.tangent_from_principal`,
exact at repeated principal stretches; Prony history at the Gauss points with the tangent factor
:func:`cfm_core.material.prony.effective_factor`); generalized-alpha time integration for dynamic scenes
(rho_inf = 1 is Newmark average acceleration; the default rho_inf = 0 damps the penalty-contact
chatter, which makes the trapezoidal rule gain energy), a quasi-static mode (no inertia) for
scenes with ``model.meta["quasi_static"]``; adaptive steps (cut and retry when Newton fails,
grow when it converges fast); nodal penalty contact with the rigid sphere and plane, the sphere
being a rigid body with one dof (z) solved monolithically with the specimen (docs/conventions.md
section 5). scikit-fem is imported only when a run starts.

Options of :meth:`SkfemImplicitBackend.run` (all optional, see ``options.DEFAULTS``):
``quasi_static`` (None: from the model), ``volumetric`` ("mean-dilatation" | "full"),
``rho_inf`` (generalized-alpha, default 0), ``dt``, ``dt_min``, ``dt_max`` (s; default dt_max =
the model's output interval, so histories are recorded at least that often), ``segment_steps``
(steps per moving segment of a prescribed motion, default 50), ``grow``, ``grow_iterations``,
``cut``, ``max_iterations``, ``rtol``, ``atol`` (N), ``penalty`` (N/m per node; default
``penalty_factor`` (1e4) x kappa0 x h, kappa0 the small-strain bulk modulus, h the element size:
penetration well below 1 % of h), ``penalty_gap`` (default 1e-3 x h: the penalty force rises
quadratically over this first gap, so it is C^1 and Newton converges through contact changes),
``linear_solver`` ("auto" | "direct" | "cg"), ``direct_limit``,
``separation_time`` (s, default 2e-4), ``frame_interval`` (s), ``max_steps``, ``record_newton``
(residual sequences in info["newton"]).

Result.info: elements, dofs, linear_solver, volumetric, integrator, element_size (m),
newton_iterations, rejected_steps, linear_iterations (CG), setup_time (s); with contact: penalty
(N/m), penalty_gap (m), max_penetration_sphere / max_penetration_plane (m), penetration_ratio (-, over h), separated.
"""

from __future__ import annotations

import numpy as np

from cfm_core.simulation.backend import Backend
from cfm_core.errors import InputError

__all__ = ["SkfemImplicitBackend"]


class SkfemImplicitBackend(Backend):
    """Implicit total Lagrangian hex8 solver (Newton, consistent tangent) assembled with scikit-fem."""

    name = "skfem"
    kind = "implicit"
    quasi_static = True
    description = ("implicit total Lagrangian hex8 (2x2x2 Gauss, mean dilatation), Newton with the "
                   "consistent tangent, Newmark or quasi-static, adaptive steps, penalty contact; scikit-fem")
    needs_tangent = True
    devices = ("cpu",)
    dtypes = ("float64",)
    requires = ("skfem",)

    def run(self, model, *, progress=None, **options):
        """Run a :class:`cfm_core.scene.Model`; return a :class:`cfm_core.simulation.result.Result`.

        See the module docstring for the options. Raises InputError (unsupported model or bad
        option) or NumericalError (step failure at the smallest step, naming element, time (s)
        and quantity).
        """
        from .solver import run_model

        self.check_model(model)
        return run_model(model, progress, **options)

    def point(self, material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Cauchy stress (n, 6) in Pa (11, 22, 33, 12, 23, 13) along F (n, 3, 3) at times t (n,) in s.

        The solver's own Gauss-point update (:mod:`.constitutive`) with the local volumetric term;
        the material is undeformed and relaxed before t[0].
        """
        from .constitutive import point_history

        t = np.asarray(t, dtype=np.float64).reshape(-1)
        F = np.asarray(F, dtype=np.float64)
        if F.reshape(-1, 9).shape[0] != t.shape[0]:
            raise InputError(f"point: {t.shape[0]} times but {F.reshape(-1, 9).shape[0]} deformation gradients.")
        if t.size > 1 and not (np.diff(t) >= 0).all():
            i = int(np.argmax(np.diff(t) < 0)) + 1
            raise InputError(f"point: times must not decrease: t[{i}] = {t[i]:g} s < t[{i - 1}] = {t[i - 1]:g} s.")
        return point_history(material, t, F)
