"""cfm_core: backend-neutral core of the circular fiber model (CFM) framework.

Materials are defined once (energy terms of the isochoric principal stretches, a volumetric term
of J, an optional Prony series); backends (numba, torch, scikit-fem) obtain energy, stress and
tangent from that single definition. SI units everywhere: m, s, kg, Pa.
"""

from .errors import InputError, NumericalError
from .material import Material, MaterialSpec, make_material
from .parameters import Parameter, nonnegative, positive
from .prony import PronySeries
from .registry import (get_backend, get_material, get_term, refresh, register_backend, register_material,
                       register_term)
from .terms import Term, isochoric, volumetric

__version__ = "0.1.0"

__all__ = [
    "InputError", "NumericalError", "Material", "MaterialSpec", "make_material", "Parameter", "positive",
    "nonnegative", "PronySeries", "get_backend", "get_material", "get_term", "refresh", "register_backend",
    "register_material", "register_term", "Term", "isochoric", "volumetric",
]
