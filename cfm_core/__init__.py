"""cfm_core: backend-neutral core of the circular fiber model (CFM) framework.

``import cfm_core as cfm`` gives the whole user API; the subpackages follow the flow of a run
(docs/architecture.md):

- :mod:`cfm_core.material`: energy terms, material specs, Prony series, generated code;
- :mod:`cfm_core.scene`: TOML scenes, meshes and the model builder;
- :mod:`cfm_core.simulation`: backends, their registry, results, the material-point driver;
- :mod:`cfm_core.post`: histories, the SAE J211 filter, metrics, summaries, files and plots;
- :mod:`cfm_core.runs`: a scene run end to end (drop test, reaction test);
- :mod:`cfm_core.studies`: sweeps, calibrations, lab fits (``cfm.sweep``, ``cfm.calibrate``,
  ``cfm.fit``, ``cfm.uniaxial`` return outcomes with ``to_dataframe()`` and ``save(dir)``);
- :mod:`cfm_core.cli`: the ``cfm`` command.

SI units everywhere: m, s, kg, Pa.
"""

from . import compat, plugins
from .errors import InputError, NumericalError
from .material import (Material, MaterialSpec, Parameter, PronySeries, Term, get_material, get_term, isochoric,
                       make_material, nonnegative, positive, register_material, register_term, sym, volumetric)
from .plugins import refresh
from .runs import DropTestOutcome, ReactionOutcome, drop_test, reaction_test, run_model
from .scene import Model, Scene, build_model, builtin_scene, builtin_scenes, load_scene
from .simulation import Backend, Result, get_backend, register_backend
from .studies.api import calibrate, fit, sweep, uniaxial

__version__ = "0.2.0"

compat.install()


def __getattr__(name: str):
    """``from cfm_core import simulate`` and the other module names of version 0.1 (deprecated)."""
    if name in compat.MOVED:
        return compat.old_name(name)
    raise AttributeError(f"module 'cfm_core' has no attribute {name!r}")

__all__ = [
    "plugins", "InputError", "NumericalError", "Material", "MaterialSpec", "Parameter", "PronySeries", "Term",
    "get_material", "get_term", "isochoric", "make_material", "nonnegative", "positive", "register_material",
    "register_term", "sym", "volumetric", "refresh", "DropTestOutcome", "ReactionOutcome", "drop_test",
    "reaction_test", "run_model", "Model", "Scene", "build_model", "builtin_scene", "builtin_scenes", "load_scene",
    "Backend", "Result", "get_backend", "register_backend", "sweep", "calibrate", "fit", "uniaxial",
]
