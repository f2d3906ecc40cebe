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
    """Base class of solver backends (constructed without arguments).

    Attributes
    ----------
    name : str
        Registry name, e.g. ``"numba"``.
    kind : {"reference", "explicit", "implicit"}
        Solver family (docs/conventions.md section 5).
    description : str
        One line for ``cfm backends``.
    needs_tangent : bool
        Whether it uses the consistent material tangent.
    devices : tuple of str
        Devices it runs on, e.g. ``("cpu", "cuda")``.
    dtypes : tuple of str
        Floating-point types it supports, e.g. ``("float64", "float32")``.
    requires : tuple of str
        Import names that must be importable for the backend to be available.
    quasi_static : bool
        Whether it can run scenes without inertia (``model.meta["quasi_static"]``).
    hourglass_control : bool
        Whether its elements have hourglass modes held by hourglass forces, so that a hourglass
        energy is meaningful: the explicit one-point hexahedra have them; fully integrated
        (implicit) elements do not, and their summaries report the hourglass ratio as n/a (null).
        Default: ``kind == "explicit"``; a backend may set it as a class attribute.
    """

    name: str = ""
    kind: str = "explicit"
    description: str = ""
    needs_tangent: bool = False
    devices: tuple[str, ...] = ("cpu",)
    dtypes: tuple[str, ...] = ("float64",)
    requires: tuple[str, ...] = ()
    quasi_static: bool = False  # can run scenes without inertia (model.meta["quasi_static"])

    @property
    def hourglass_control(self) -> bool:
        """Whether a hourglass energy applies (one-point explicit hexahedra): ``kind == "explicit"``."""
        return self.kind == "explicit"

    def available(self) -> tuple[bool, str]:
        """Whether the backend is usable here; checks ``requires`` without importing them.

        Returns
        -------
        ok : bool
            True when every required package can be found.
        reason : str
            Empty when usable, else which package is missing and how to install it.
        """
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

        Parameters
        ----------
        model : Model
            The model to run.

        Raises
        ------
        InputError
            The model is quasi-static (or has density <= 0) and the backend is not
            ``quasi_static``; the message names the scene and suggests an implicit backend.
        """
        inertia_free = bool(model.meta.get("quasi_static")) or not model.density > 0.0
        if inertia_free and not self.quasi_static:
            raise InputError(
                f"backend '{self.name}' ({self.kind}) cannot run the {model.meta.get('scene_type', 'given')} "
                f"scene '{model.name}': it is quasi-static (no inertia, density = {model.density:g} kg/m^3), "
                f"and an explicit solver needs mass for its stable step. Run it with an implicit backend such as "
                f"'skfem' (cfm run --scene ... --backend skfem).")

    def point(self, material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Cauchy stress along a deformation history at one material point.

        Viscoelastic history starts from the undeformed, relaxed state at t[0] (a deformation
        present at t[0] is a jump).

        Parameters
        ----------
        material : Material
            A bound material.
        t : ndarray, shape (n,)
            Non-decreasing times (s).
        F : ndarray, shape (n, 3, 3)
            Deformation gradients (-), det F > 0.

        Returns
        -------
        ndarray, shape (n, 6)
            Cauchy stress (Pa), order s11, s22, s33, s12, s23, s13.

        Raises
        ------
        InputError
            In the base class: the backend has no material-point driver.
        """
        raise InputError(f"backend '{self.name}' has no material-point driver; evaluate material points with "
                         f"numpy (the reference, default), numba, torch or skfem.")

    def run(self, model, *, progress: Callable[[float], None] | None = None, **options):
        """Run a :class:`cfm_core.scene.Model`; return a :class:`cfm_core.simulation.result.Result`.

        Parameters
        ----------
        model : Model
            The backend-neutral model (SI units).
        progress : callable, optional
            Called with the simulated time (s) from time to time.
        **options
            The backend's typed options (``cfm backends --options``), e.g. ``device="cuda"``.

        Returns
        -------
        Result
            Raw histories of the full model (no post-processing).

        Raises
        ------
        InputError
            In the base class: this backend cannot run scenes (a material-point backend such as
            the numpy reference). Implementations raise InputError for bad options or a model
            they cannot run (:meth:`check_model`) and NumericalError when the run fails (naming
            element and time).
        """
        raise InputError(f"backend '{self.name}' ({self.kind}) evaluates material points only (cfm point "
                         f"--backend {self.name}); it cannot run the scene '{model.name}'. Run scenes with an "
                         f"explicit or implicit backend: numba, torch or skfem (cfm backends lists them).")
