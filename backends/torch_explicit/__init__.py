"""Explicit dynamics with torch on the CPU or a CUDA GPU: the ``torch`` backend.

The numba backend's algorithm (docs/conventions.md section 5: total Lagrangian hex8, one-point
integration, viscous hourglass control, lumped mass, central differences with the stable step
recomputed every step from the current tangent, kinematic contact with a rigid sphere and a rigid
plane, Prony recurrence, energy accounting, stop rule), vectorised over elements: a gather of the
nodal displacements and velocities, per-element kinematics, eigen-decomposition and stress in
batched tensor ops, and ``index_add_`` of the nodal forces. The time loop is Python. The material
comes from its single symbolic definition (generated torch code, ``cfm_core.material.codegen``). torch is
imported only when a run or a point evaluation starts.

Models with several parts (``Model.parts``: material, parameters and density per region) run with
the elements grouped by part (:mod:`.parts`); the rigid impactor may be a hemisphere (the paper's,
with its own contact, :mod:`.contact`), a sphere, a flat punch with a rounded rim or a plane, and may
move in x and y as well as z (:mod:`.impactor`, :mod:`.impactor_contact`; the in-plane history
columns of ``cfm_backends.explicit.history``). Batches share the part layout and the impactor shape.

Options of :meth:`TorchExplicitBackend.run`: :class:`.options.TorchOptions` (declared once with unit,
default and allowed values; listed by ``cfm backends --options`` and in the method's docstring):
the explicit-solver options shared with numba (``cfm_backends.explicit.options``: ``hourglass``,
``safety``, ...) plus ``device``, ``dtype``, ``threads``, ``compile`` and ``newton_block``.

float32 halves memory traffic but the fibre exponential exp(k2 (x-1)^2) overflows float32 at an
argument of about 88.7 (float64: 709): an overflow stops the run with a NumericalError naming the
element and the time and saying that the scene needs float64.
"""

from __future__ import annotations

import numpy as np

from cfm_backends.explicit.options import document_run
from cfm_core.simulation.backend import Backend

from .options import TorchOptions

__all__ = ["TorchExplicitBackend"]


class TorchExplicitBackend(Backend):
    """Explicit hex8 solver in batched torch ops (CPU or CUDA, float64 or float32)."""

    name = "torch"
    kind = "explicit"
    description = ("explicit total Lagrangian hex8 (one-point, viscous hourglass), kinematic contact "
                   "with a rigid impactor (hemisphere, sphere, flat, plane) and plane, parts, vectorised in "
                   "torch (CPU or CUDA)")
    needs_tangent = False
    devices = ("cpu", "cuda")
    dtypes = ("float64", "float32")
    requires = ("torch",)
    options_class = TorchOptions

    def run(self, model, *, progress=None, **options):
        """Run a :class:`cfm_core.scene.Model`; return a :class:`cfm_core.simulation.result.Result`.

        Raises InputError (bad options, CUDA requested
        but not available) or NumericalError (element inversion, non-finite stress, float32
        overflow, time-step collapse) naming the element and the time (s).
        """
        from .solver import run_model

        self.check_model(model)
        return run_model(model, progress, **options)

    def run_batch(self, models, *, progress=None, raise_errors: bool = True, sync_free: bool | None = None,
                  **options):
        """Run drop tests that share a mesh as one batched simulation; one Result per model.

        Parameters
        ----------
        models : sequence of cfm_core.scene.model.Model
            B drop tests (rigid sphere, no prescribed motion) with the same mesh, density,
            constraints, contact node sets, sphere radius, friction and material definition; they may
            differ in material parameter values, impact velocity, impactor mass, start height and
            end time (s).
        progress : callable, optional
            Called with the smallest simulated time (s) of the runs still going.
        raise_errors : bool
            True: raise the first run's NumericalError; False: put it in the list in place of the
            Result (the other runs are unaffected).
        sync_free : bool, optional
            No host synchronisation inside a step (default: True on CUDA, False on the CPU); on
            CUDA such a step runs as a captured CUDA graph unless the option ``cuda_graph=False``
            (``info['cuda_graph']`` says whether it did).
        **options
            The options of :meth:`run` (shared by all runs; ``frame_interval`` is not supported).

        Returns
        -------
        list of Result (or NumericalError)
            In the order of ``models``; each equals the same run done alone to round-off.
            ``wall_time`` is the batch's solver time divided by B; ``info['batch_wall_time']``
            the whole.

        Raises
        ------
        InputError
            Models that cannot share a batch (the message names the differing field), bad options
            (``cuda_graph=True`` on the CPU or with ``sync_free=False``).
        NumericalError
            A run failed (with ``raise_errors``), naming the run, the element and the time (s).
        """
        from .batch import run_batch

        for m in models:
            self.check_model(m)
        return run_batch(list(models), progress, raise_errors, sync_free, **options)

    def point(self, material, t: np.ndarray, F: np.ndarray, *, device: str = "cpu",
              dtype: str = "float64") -> np.ndarray:
        """Cauchy stress (n, 6) in Pa (11, 22, 33, 12, 23, 13) along F (n, 3, 3) at times t (n,) in s.

        The solver's constitutive update, batched over the history (Prony series on the
        isochoric part, undeformed and relaxed before t[0]); device and dtype as for ``run``.
        """
        from .point import point_history

        return point_history(material, t, F, device=device, dtype=dtype)


document_run(TorchExplicitBackend, TorchOptions)
