"""The material layer: energy terms, their composition, Prony series, code generation, kinematics
and the numpy reference evaluation (paper Eq. 2-8, docs/conventions.md section 2).

Flow: ``@isochoric`` / ``@volumetric`` terms and a :class:`PronySeries` compose with ``&`` into a
:class:`MaterialSpec` (spec.py); binding parameter values gives a :class:`Material`
(material.py); the spec is traced with sympy once and emitted as scalar, numpy and torch code
(codegen.py, cached on disk by cache.py); kinematics.py turns principal-stretch derivatives into
stresses and tangents; reference.py is the numpy evaluation every backend is checked against.
"""

from . import sym
from .material import Material
from .parameters import Parameter, nonnegative, positive
from .prony import PronySeries
from .registry import get_material, get_term, make_material, register_material, register_term
from .spec import MODULI, MaterialSpec, Term, check_spec
from .terms import isochoric, volumetric

__all__ = ["sym", "Material", "Parameter", "nonnegative", "positive", "PronySeries", "get_material", "get_term",
           "make_material", "register_material", "register_term", "MODULI", "MaterialSpec", "Term", "check_spec",
           "isochoric", "volumetric"]
