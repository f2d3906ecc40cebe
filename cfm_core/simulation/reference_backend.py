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

        return kin.to_voigt(ref.stress_history(material, t, F))
