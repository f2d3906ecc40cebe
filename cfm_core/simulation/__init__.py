"""The simulation layer: the backend interface and registry, the result type and the point driver.

A backend (backend.py, registered in registry.py) takes a :class:`~cfm_core.scene.Model` and
returns a :class:`Result` of raw histories (result.py); its options are typed (options.py).
point.py drives a material point along a deformation history or in uniaxial stress.
"""

from .backend import Backend
from .registry import backend_for, get_backend, register_backend
from .result import Result

__all__ = ["Backend", "backend_for", "get_backend", "register_backend", "Result"]
