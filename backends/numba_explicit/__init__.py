"""Explicit dynamics on the CPU with numba: the ``numba`` backend.

Total Lagrangian hex8 elements with one-point integration (Flanagan-Belytschko mean gradient)
and viscous hourglass control, lumped mass, central differences with the stable step
dt = 0.9 min_e L_e / c_e recomputed every step from the current tangent (L_e from the
Flanagan-Belytschko eigenvalue bound, edge / sqrt(3) for a cube; c_e from max_a d^2 Psi / d lambda_a^2), kinematic (momentum-exchange) contact with a rigid
impactor (hemisphere, sphere, flat with a rounded rim, plane; translating along its free directions)
and a rigid plane, so the contact never limits the step (docs/conventions.md section 5). The
material's generated scalar code and the kernels (``kernels/``) are compiled together by numba
(one element pass per material of a model's parts, elements grouped by part)
and cached on disk (``codegen``). numba is imported only when a run or a point evaluation starts.

Energies (Result.energies, J, full model): kinetic = 1/2 sum m v^{n-1/2} . v^{n+1/2} (the
leapfrog's own kinetic energy at t^n, from the two mid-step velocities); internal = stress work
sum_e V0 (S^n + S^{n+1})/2 : (E^{n+1} - E^n); hourglass, contact = energy dissipated by the
hourglass forces and by the contact constraints (friction included); external = work of
prescribed motion and gravity. The force works balance the kinetic energy exactly, so
``Result.energy_error()`` measures the stress work against the nodal-force work: it is exact
for a linear elastic model and O(dt^2) otherwise.

Threads: the element, node and energy loops run in parallel (numba prange; chunks of element
blocks, see ``kernels/element.py``). The default thread count is the cores free to this process
(``cfm_backends.threads.free_cores``); with numba's OpenMP layer, ``OMP_WAIT_POLICY=PASSIVE``
(set unless already set, before numba starts its threads) keeps threads from spinning.

Options of :meth:`NumbaExplicitBackend.run`: :class:`.options.NumbaOptions` (declared once with unit,
default and allowed values; listed by ``cfm backends --options`` and in the method's docstring):
the shared explicit-solver options (``cfm_backends.explicit.options``) and ``threads`` (default:
the free cores, or 1 for models under 1000 elements, where starting threads costs more than it saves).
"""

from __future__ import annotations

import numpy as np

from cfm_backends.explicit import errors
from cfm_backends.explicit.checks import check_point_inputs
from cfm_backends.explicit.options import document_run
from cfm_core.errors import NumericalError
from cfm_core.material.prony import gamma_inf
from cfm_core.simulation.backend import Backend

from .options import NumbaOptions

__all__ = ["NumbaExplicitBackend"]


class NumbaExplicitBackend(Backend):
    """Explicit hex8 solver compiled with numba (CPU, float64, parallel element loop)."""

    name = "numba"
    kind = "explicit"
    description = ("explicit total Lagrangian hex8 (one-point, viscous hourglass), kinematic contact "
                   "with a rigid impactor (hemisphere, sphere, flat, plane) and plane, parts, numba on the CPU")
    needs_tangent = False
    devices = ("cpu",)
    dtypes = ("float64",)
    requires = ("numba",)
    options_class = NumbaOptions

    def run(self, model, *, progress=None, **options):
        """Run a :class:`cfm_core.scene.Model`; return a :class:`cfm_core.simulation.result.Result`.

        Raises InputError (an unknown option or a value out of range, a bad model) or NumericalError
        (element inversion, non-finite stress, time-step collapse) naming the element and the time (s).
        """
        from .solver import run_model

        self.check_model(model)
        return run_model(model, progress, **options)

    def point(self, material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Cauchy stress (n, 6) in Pa (11, 22, 33, 12, 23, 13) along F (n, 3, 3) at times t (n,) in s.

        The same compiled constitutive update as the solver: sigma = J^-1 F S F^T, Prony series on
        the isochoric part, undeformed and relaxed before t[0].
        """
        from . import codegen

        t, F = check_point_inputs(t, F)
        gam, tau = (np.ascontiguousarray(a, dtype=np.float64) for a in material.prony_arrays())
        p = np.ascontiguousarray(material.param_array(), dtype=np.float64)
        out = np.zeros((t.shape[0], 6))
        ginf = gamma_inf(gam)  # the one exact sum
        with codegen.announce(material, "point_history"):  # its first call compiles it (once per machine)
            mod = codegen.load(material)
            status, i, J, m0, m1, m2 = mod.point_history(t, F, p, gam, tau, ginf, out)
        if status == 1:
            raise NumericalError(f"point {i} (t = {t[i]:.6g} s): det F = {J:.4g} <= 0 (inverted).",
                                 time=float(t[i]), element=int(i), quantity="J")
        if status != 0:
            raise errors.nonfinite(material, f"point {i} (t = {t[i]:.6g} s)", (m0, m1, m2), J, float(t[i]), int(i))
        return out


document_run(NumbaExplicitBackend, NumbaOptions)
