"""The backend interface: what every solver provides, and the capabilities it declares.

A backend is a class registered under the ``cfm.backends`` entry-point group. Capabilities are
class attributes (xarray style). Heavy libraries (numba, torch, skfem) are imported inside
methods, never at module import, so listing backends stays cheap.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import InputError


class Backend:
    """Base class of solver backends.

    Class attributes: ``name``; ``kind`` ("reference", "explicit" or "implicit");
    ``description``; ``needs_tangent`` (uses the consistent tangent); ``devices``; ``dtypes``;
    ``requires``: import names that must be importable for the backend to be available.
    """

    name: str = ""
    kind: str = "explicit"
    description: str = ""
    needs_tangent: bool = False
    devices: tuple[str, ...] = ("cpu",)
    dtypes: tuple[str, ...] = ("float64",)
    requires: tuple[str, ...] = ()
    quasi_static: bool = False  # can run scenes without inertia (model.meta["quasi_static"])

    def available(self) -> tuple[bool, str]:
        """(True, "") when usable here, else (False, reason). Checks imports without importing."""
        import importlib.util

        for mod in self.requires:
            if importlib.util.find_spec(mod) is None:
                return False, f"python package '{mod}' is not installed (pip install 'cfm-materials[{self.name}]')"
        return True, ""

    def check_model(self, model) -> None:
        """InputError when this backend cannot run ``model`` (called by ``run`` before any work).

        Explicit backends need inertia: a quasi-static scene (``model.meta["quasi_static"]``, or
        density 0) has no stable time step, and its hold times (up to tens of seconds at
        relaxation times of 10 s) would take billions of explicit steps.
        """
        inertia_free = bool(model.meta.get("quasi_static")) or not model.density > 0.0
        if inertia_free and not self.quasi_static:
            raise InputError(
                f"backend '{self.name}' ({self.kind}) cannot run the {model.meta.get('scene_type', 'given')} "
                f"scene '{model.name}': it is quasi-static (no inertia, density = {model.density:g} kg/m^3), "
                f"and an explicit solver needs mass for its stable step. Run it with an implicit backend such as "
                f"'skfem' (cfm run --scene ... --backend skfem).")

    def point(self, material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Cauchy stress (n, 6) in Pa, order s11, s22, s33, s12, s23, s13, along a history.

        t: (n,) times in s; F: (n, 3, 3) deformation gradients. Viscoelastic history starts from
        the undeformed, relaxed state at t[0].
        """
        raise NotImplementedError(f"backend '{self.name}' has no material-point driver")

    def run(self, model, *, progress: Callable[[float], None] | None = None, **options):
        """Run a :class:`cfm_core.scene.Model`; return a :class:`cfm_core.simulation.result.Result`.

        progress, if given, is called with the simulated time (s) from time to time.
        """
        raise NotImplementedError(f"backend '{self.name}' cannot run scenes")
