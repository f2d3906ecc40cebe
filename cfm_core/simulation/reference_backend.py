"""The numpy reference as a (material-point only) backend, so ``--backend numpy`` works."""

from __future__ import annotations

import numpy as np

from .backend import Backend
from ..material import kinematics as kin
from ..material import reference as ref


class NumpyReferenceBackend(Backend):
    """Reference evaluation in numpy float64 (material point only): the truth for verification."""

    name = "numpy"
    kind = "reference"
    description = "numpy float64 reference (material point only)"
    needs_tangent = False

    def point(self, material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Cauchy stress along a deformation history: :func:`cfm_core.material.reference.stress_history`.

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
            Mismatched or decreasing times, or an invalid F.
        NumericalError
            Non-finite generated derivatives (fibre exponential overflow).
        """
        return kin.to_voigt(ref.stress_history(material, t, F))
