"""The module names of version 0.1 (one flat ``cfm_core`` folder), kept importable for a while.

``from cfm_core import simulate`` or ``from cfm_core.calibrate import read_measured`` still work:
each old name is an alias module that looks its attributes up in the modules that now hold them,
with a ``DeprecationWarning`` naming the new place. New code should use the subpackages
(docs/architecture.md) or ``import cfm_core as cfm``. The aliases are made on first import of the
old name only, so they cost nothing otherwise.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings

#: old module (below cfm_core) -> the modules that now hold its names, searched in this order.
MOVED = {
    "simulate": ("runs.pipeline", "runs.outcomes"),
    "calibrate": ("studies.calibrate", "studies.measured"),
    "sweep": ("studies.sweep",), "dask_runner": ("studies.dask_runner",),
    "sweep_benchmark": ("studies.sweep",),
    "postprocess": ("post",), "filters": ("post.filters",), "writers": ("post.writers",),
    "plotting": ("post.plots",), "compare": ("post.compare",),
    "point": ("simulation.point",), "backend": ("simulation.backend",), "results": ("simulation.result",),
    "reference_backend": ("simulation.reference_backend",),
    "registry": ("material.registry", "simulation.registry", "plugins"),
    "builder": ("scene.builder",), "mesh": ("scene.mesh",), "model": ("scene.model",),
    "scene_sections": ("scene.sections",),
    "terms": ("material.terms", "material.spec"), "parameters": ("material.parameters",),
    "prony": ("material.prony",), "sym": ("material.sym",), "codegen": ("material.codegen",),
    "cache": ("material.cache",), "kinematics": ("material.kinematics",), "reference": ("material.reference",),
    "scene_cli": ("cli.scene",), "study_cli": ("cli.studies",),
}


class _Alias(types.ModuleType):
    """A module whose attributes come from the modules that now hold them."""

    def __init__(self, name: str, targets: tuple[str, ...]):
        super().__init__(name, f"Deprecated alias of {', '.join('cfm_core.' + t for t in targets)}.")
        self._targets = targets

    def __call__(self, *args, **kwargs):
        """``cfm.sweep(...)`` and ``cfm.calibrate(...)`` after an old ``import cfm_core.sweep``: the import
        system set the package attribute to this alias, so calls go on to the API function."""
        from .studies import api

        name = self.__name__.rpartition(".")[2]
        if not hasattr(api, name):
            raise TypeError(f"module {self.__name__!r} is not callable")
        return getattr(api, name)(*args, **kwargs)

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        for target in self._targets:
            module = importlib.import_module(f"cfm_core.{target}")
            if hasattr(module, attr):
                warnings.warn(f"{self.__name__}.{attr} has moved to cfm_core.{target}.{attr} (or import cfm_core as "
                              f"cfm); the old name will be removed.", DeprecationWarning, stacklevel=2)
                return getattr(module, attr)
        raise AttributeError(f"module {self.__name__!r} has no attribute {attr!r} (it was moved; see "
                             f"docs/architecture.md)")


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names below cfm_core and makes their alias modules."""

    def find_spec(self, fullname, path=None, target=None):
        prefix, _, leaf = fullname.partition(".")
        if prefix == "cfm_core" and leaf in MOVED:
            return importlib.machinery.ModuleSpec(fullname, self)
        return None

    def create_module(self, spec):
        return _Alias(spec.name, MOVED[spec.name.partition(".")[2]])

    def exec_module(self, module):
        return None


def install() -> None:
    """Put the finder of the old names on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())


def old_name(name: str):
    """The alias module of an old name below cfm_core (for ``from cfm_core import simulate``).

    Parameters
    ----------
    name : str
        An old module name (a key of :data:`MOVED`).

    Returns
    -------
    module
        The alias module.
    """
    return importlib.import_module(f"cfm_core.{name}")
