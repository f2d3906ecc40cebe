"""The backend interface: what every solver provides, and the capabilities it declares.

A backend is a class registered under the ``cfm.backends`` entry-point group. Capabilities are
class attributes (xarray style). Heavy libraries (numba, torch, skfem) are imported inside
methods, never at module import, so listing backends stays cheap.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


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

    def available(self) -> tuple[bool, str]:
        """(True, "") when usable here, else (False, reason). Checks imports without importing."""
        import importlib.util

        for mod in self.requires:
            if importlib.util.find_spec(mod) is None:
                return False, f"python package '{mod}' is not installed (pip install 'cfm-materials[{self.name}]')"
        return True, ""

    def point(self, material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Cauchy stress (n, 6) in Pa, order s11, s22, s33, s12, s23, s13, along a history.

        t: (n,) times in s; F: (n, 3, 3) deformation gradients. Viscoelastic history starts from
        the undeformed, relaxed state at t[0].
        """
        raise NotImplementedError(f"backend '{self.name}' has no material-point driver")

    def run(self, model, *, progress: Callable[[float], None] | None = None, **options):
        """Run a :class:`cfm_core.model.Model`; return a :class:`cfm_core.results.Result`.

        progress, if given, is called with the simulated time (s) from time to time.
        """
        raise NotImplementedError(f"backend '{self.name}' cannot run scenes")
