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

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the spec module imports this one
    from .spec import MaterialSpec


@dataclass(frozen=True)
class Material:
    """A material with parameter values bound (SI units), a moduli convention and elastic flag."""

    spec: MaterialSpec
    values: dict = field(repr=True)
    moduli: str = "long-term"
    elastic: bool = False

    def __post_init__(self):
        if not self.elastic:
            self.spec.prony.arrays(self.values)  # validates sum of gammas < 1

    @property
    def name(self) -> str:
        return self.spec.name

    def prony_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(gammas, taus) of the active Prony series; empty arrays when elastic."""
        if self.elastic:
            return np.zeros(0), np.zeros(0)
        return self.spec.prony.arrays(self.values)

    @property
    def iso_scale(self) -> float:
        """Factor on the written isochoric energy giving the instantaneous one (-)."""
        if self.elastic or self.moduli == "instantaneous":
            return 1.0
        gammas, _ = self.prony_arrays()
        return 1.0 / (1.0 - math.fsum(gammas))

    def param_array(self) -> np.ndarray:
        """Energy parameter values in declaration order, then s_iso (float64)."""
        vals = [self.values[p.name] for p in self.spec.energy_parameters] + [self.iso_scale]
        return np.array(vals, dtype=np.float64)

    def numba_source(self) -> str:
        """Scalar Python source (math module) of psi_energy, psi_grad, psi_hess_diag, psi_hess."""
        return self.spec.source("math")

    def kernels(self, dialect: str = "numpy"):
        """Compiled generated functions for an array dialect ("numpy" or "torch")."""
        return self.spec.kernels(dialect)

    def with_values(self, **changes) -> "Material":
        """A copy with some parameter values changed (validated)."""
        return self.spec.bind({**self.values, **changes}, self.moduli, self.elastic)
