"""A material with its parameter values bound: what every backend reads.

:class:`Material` is made by :meth:`MaterialSpec.bind <cfm_core.material.MaterialSpec.bind>` (or
:func:`~cfm_core.material.make_material` by registered name). Backends read ``param_array()``,
``prony_arrays()`` and the generated code (``numba_source()``, ``kernels("numpy" | "torch")``).
The numpy evaluation in :mod:`cfm_core.material.reference` is the reference every backend is
checked against.

Moduli convention (docs/conventions.md, section 2): with ``moduli="instantaneous"`` the isochoric
parameters are the instantaneous (g(0) = 1) values; with ``moduli="long-term"`` they are the
relaxed values, so the instantaneous isochoric energy is the written one divided by gamma_inf.
``elastic=True`` switches the Prony series off (g = 1) and uses the parameters as written.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import prony

if TYPE_CHECKING:  # the spec module imports this one
    from .spec import MaterialSpec


@dataclass(frozen=True)
class Material:
    """A material with parameter values bound (SI units), a moduli convention and elastic flag.

    Made by :meth:`MaterialSpec.bind <cfm_core.material.MaterialSpec.bind>`, which validates the
    values; immutable (:meth:`with_values` gives a changed copy).

    Attributes
    ----------
    spec : MaterialSpec
        The declaration: energy terms and Prony series.
    values : dict of str to float
        Every parameter's value in its SI unit (Pa, s, -), energy parameters and Prony
        ``g1, tau1, ...``.
    moduli : {"long-term", "instantaneous"}
        Whether the isochoric parameters are relaxed or instantaneous values (docs/conventions.md
        section 2).
    elastic : bool
        True: no Prony series (g = 1), parameters used as written.

    Raises
    ------
    InputError
        When not elastic and the Prony coefficients leave gamma_inf = 1 - sum below
        :data:`cfm_core.material.prony.GAMMA_INF_MIN` (checked at construction, with the same
        exact sum that :attr:`gamma_inf` and :attr:`iso_scale` use).
    """

    spec: MaterialSpec
    values: dict = field(repr=True)
    moduli: str = "long-term"
    elastic: bool = False

    def __post_init__(self):
        if not self.elastic:
            self.spec.prony.arrays(self.values)  # validates gamma_inf >= prony.GAMMA_INF_MIN

    @property
    def name(self) -> str:
        """The spec's (registered) name, e.g. ``"cfm"``."""
        return self.spec.name

    def prony_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The active Prony series as arrays (paper Eq. 8 as normalised in docs/conventions.md
        section 2).

        Returns
        -------
        gammas : ndarray, shape (k,)
            Relaxation coefficients g_i (-); shape (0,) when elastic.
        taus : ndarray, shape (k,)
            Relaxation times tau_i (s); shape (0,) when elastic.
        """
        if self.elastic:
            return np.zeros(0), np.zeros(0)
        return self.spec.prony.arrays(self.values)

    @property
    def gamma_inf(self) -> float:
        """Long-term Prony coefficient gamma_inf = 1 - sum g_i (-), 1 when elastic; computed by
        :func:`cfm_core.material.prony.gamma_inf` (exact sum), as every backend must use it."""
        return prony.gamma_inf(self.prony_arrays()[0])

    @property
    def iso_scale(self) -> float:
        """Factor on the written isochoric energy giving the instantaneous one (-): 1 / gamma_inf
        for long-term moduli with a Prony series, else 1 (docs/conventions.md section 2)."""
        if self.elastic or self.moduli == "instantaneous":
            return 1.0
        return 1.0 / self.gamma_inf

    def param_array(self) -> np.ndarray:
        """The parameter vector ``p`` of the generated functions.

        Returns
        -------
        ndarray, shape (k + 1,)
            float64 values of the k energy parameters in declaration order
            (``spec.energy_parameters``, SI units), then s_iso = :attr:`iso_scale` (-).
        """
        vals = [self.values[p.name] for p in self.spec.energy_parameters] + [self.iso_scale]
        return np.array(vals, dtype=np.float64)

    def numba_source(self) -> str:
        """Scalar Python source (math module) of the generated functions, for numba.

        Returns
        -------
        str
            Module source defining psi_energy, psi_grad, psi_hess_diag, psi_hess and
            psi_grad_hess_diag, each ``f(m1, m2, m3, p)`` (see :mod:`cfm_core.material.codegen`).
        """
        return self.spec.source("math")

    def kernels(self, dialect: str = "numpy"):
        """Compiled generated functions for an array dialect ("numpy" or "torch").

        Parameters
        ----------
        dialect : {"numpy", "torch", "math"}
            Code dialect; "numpy" also checks the spec (isotropy, stress-free reference).

        Returns
        -------
        namespace
            Attributes psi_energy, psi_grad, psi_hess_diag, psi_hess, psi_grad_hess_diag, each
            ``f(m1, m2, m3, p) -> tuple of arrays`` (Pa) with ``p`` from :meth:`param_array`.

        Raises
        ------
        InputError
            The energy cannot be traced, or the spec fails its checks (first numpy use).
        """
        return self.spec.kernels(dialect)

    def with_values(self, **changes) -> "Material":
        """A copy with some parameter values changed (validated), moduli and elastic kept.

        Parameters
        ----------
        **changes : float
            Parameter name -> new value in its SI unit, e.g. ``c=20.0`` (Pa), ``tau1=2e-3`` (s).

        Returns
        -------
        Material
            A new material; this one is unchanged.

        Raises
        ------
        InputError
            An unknown parameter name or a value outside its valid range.
        """
        return self.spec.bind({**self.values, **changes}, self.moduli, self.elastic)
