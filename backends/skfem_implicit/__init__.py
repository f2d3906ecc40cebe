"""Implicit dynamics and quasi-static analysis of hexahedral meshes: the ``skfem`` backend.

What scikit-fem does here (:mod:`.discretization`, once per run): the mesh object (``MeshHex1``),
the trilinear hexahedron (``ElementHex1``) and its 2 x 2 x 2 Gauss rule, the isoparametric map
(``Basis``): shape-function gradients dN/dX and integration weights w = weight x det J at every
Gauss point, from which the lumped masses are summed. Everything after that is this project's own
code, because scikit-fem's form assembly is built for linear forms evaluated once, not for a
Newton iteration every few milliseconds:

- :mod:`.kernels` / :mod:`.compiled`: the Gauss-point and element work, compiled with numba from
  the material's generated scalar code (the single definition the numba backend also compiles):
  F, eigen-decomposition of C, stress, consistent tangent (exact at repeated principal stretches),
  Prony history, B^T D B, geometric and mean-dilatation (F-bar type, locking-free) terms;
  :mod:`.element` with :mod:`.constitutive` is the numpy reference of the same (``kernels="numpy"``),
  against which the tests check the compiled path;
- :mod:`.linear`: a fixed CSR pattern assembled in place, Dirichlet rows, and the solvers: MKL
  PARDISO via ctypes (pypardiso's library; ordering and symbolic analysis once per run, symmetric
  indefinite), block-Jacobi CG (compiled), SuperLU (scipy only);
- :mod:`.parts`: models with several parts, each part's material (its own compiled kernels,
  parameters, Prony series) on its own elements, per-element density in the lumped mass;
- :mod:`.contact`: frictionless node-to-rigid-surface contact with the paper's hemisphere (a rigid
  body moving along z, solved monolithically) and the plate, augmented Lagrangian with one
  multiplier update per step and semi-smooth Newton; :mod:`.impactor`: the same for every
  impactor shape ("sphere", "hemisphere", "flat" with a rounded or sharp rim, "plane") on the
  reference gap :func:`cfm_core.scene.impactor.impactor_gap`, the impactor free along any of x,
  y, z (its initial velocity vector), symmetry-plane nodes counted by their share;
- :mod:`.stepper` / :mod:`.solver`: generalized-alpha (rho_inf = 0 by default; 1 is Newmark
  average acceleration) or quasi-static steps, Newton with the consistent tangent, step size from
  a local error estimate (Zienkiewicz-Xie) with the tolerance ``error_tol``, the integrator's
  numerical dissipation as its own energy term.

Options of :meth:`SkfemImplicitBackend.run`: :class:`.options.SkfemOptions` (name, default, unit,
range and meaning of each; bad values raise InputError naming the option).

Result.info: elements, dofs, linear_solver, kernels, volumetric, integrator, element_size (m),
newton_iterations, rejected_steps (Newton failures), error_rejections (steps redone for accuracy),
linear_iterations (CG), setup_time (s, mesh, compilation or loading of the kernels, symbolic
analysis; not in wall_time), times (s per phase: element, assembly, factorization, solve), counts,
error_tol, failures; with contact: contact, penalty (N/m), max_penetration_sphere /
max_penetration_plane (m), penetration_ratio (-, over h), separated; with parts: part_energies
(per part: internal energy at the end and its largest value, J); with an impactor free in x or
y: momentum_x_drift, momentum_y_drift (kg m/s) and ``Result.impactor_lateral``. A flat impactor
with edge_radius = 0 runs with a warning (the rim is a stress singularity).
"""

from __future__ import annotations

import numpy as np

from cfm_core.errors import InputError
from cfm_core.simulation.backend import Backend

from .options import SkfemOptions

__all__ = ["SkfemImplicitBackend"]


class SkfemImplicitBackend(Backend):
    """Implicit total Lagrangian hex8 solver (Newton, consistent tangent) assembled with scikit-fem."""

    name = "skfem"
    kind = "implicit"
    quasi_static = True
    description = ("implicit total Lagrangian hex8 (scikit-fem basis, 2x2x2 Gauss, mean dilatation, compiled "
                   "kernels), Newton with the consistent tangent, generalized-alpha or quasi-static, "
                   "error-controlled steps, augmented-Lagrangian contact, PARDISO / CG")
    options_class = SkfemOptions
    needs_tangent = True
    devices = ("cpu",)
    dtypes = ("float64",)
    requires = ("skfem",)

    def run(self, model, *, progress=None, **options):
        """Run a :class:`cfm_core.scene.Model`; return a :class:`cfm_core.simulation.result.Result`.

        Options: :class:`.options.SkfemOptions`. Raises InputError (unsupported model or bad
        option) or NumericalError (step failure at the smallest step, naming element, time (s)
        and quantity).
        """
        from .solver import run_model

        self.check_model(model)
        return run_model(model, progress, **options)

    def check_model(self, model) -> None:
        """InputError when this backend cannot run ``model``, before any work (also what a sweep
        checks for each of its scenes before its first run).

        Parameters
        ----------
        model : Model
            A built model of any scene type (a sweep builds one per scene value to check).

        Raises
        ------
        InputError
            Friction on the contact (frictionless contact only), parts this backend cannot run
            (:func:`.parts.check_parts`), or the base class's conditions.
        """
        super().check_model(model)
        if float(model.friction) != 0.0:
            raise InputError(f"skfem backend: friction = {model.friction!r} is not supported (frictionless "
                             f"penalty contact only); set [contact] friction = 0 or use the numba backend.")
        if model.parts:
            from .parts import check_parts

            check_parts(model)

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
