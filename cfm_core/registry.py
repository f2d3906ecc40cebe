"""Registries of backends, materials and energy terms, found through entry points.

Entry-point groups: ``cfm.backends`` (a :class:`~cfm_core.backend.Backend` subclass),
``cfm.materials`` (a :class:`~cfm_core.material.MaterialSpec`), ``cfm.terms`` (a
:class:`~cfm_core.terms.Term`). Discovery is lazy and cached; :func:`refresh` clears the cache.
A plugin that fails to load or is of the wrong type becomes a ``RuntimeWarning`` naming it and the
error, and is listed as broken; the others still load. Two plugins with one name: a warning, the
first is kept. Objects registered at run time (:func:`register_material`,
:func:`register_backend`, :func:`register_term`) take precedence over entry points.
"""

from __future__ import annotations

import functools
import warnings
from importlib.metadata import entry_points

from .errors import InputError

GROUPS = {"backends": "cfm.backends", "materials": "cfm.materials", "terms": "cfm.terms"}
_runtime: dict[str, dict[str, object]] = {kind: {} for kind in GROUPS}


def _iter_entry_points(group: str):
    """The installed entry points of one group (patched in tests with fake EntryPoint objects)."""
    return list(entry_points(group=group))


@functools.lru_cache(maxsize=None)
def _entry_point_table(kind: str) -> dict:
    table: dict = {}
    for ep in _iter_entry_points(GROUPS[kind]):
        if ep.name in table:
            warnings.warn(
                f"two {kind} plugins are named '{ep.name}' ({table[ep.name].value} and {ep.value}); "
                f"keeping the first.", RuntimeWarning, stacklevel=3)
            continue
        table[ep.name] = ep
    return table


def _expected_type(kind: str):
    if kind == "backends":
        from .backend import Backend

        return Backend
    if kind == "materials":
        from .material import MaterialSpec

        return MaterialSpec
    from .terms import Term

    return Term


@functools.lru_cache(maxsize=None)
def _load(kind: str, name: str):
    """(object, None) or (None, error text) for one entry point."""
    ep = _entry_point_table(kind)[name]
    try:
        obj = ep.load()
    except Exception as exc:  # a broken plugin must not break the listing
        return None, f"failed to load {ep.value}: {type(exc).__name__}: {exc}"
    expected = _expected_type(kind)
    ok = isinstance(obj, type) and issubclass(obj, expected) if kind == "backends" else isinstance(obj, expected)
    if not ok:
        return None, f"{ep.value} is {obj!r}, not a {expected.__name__} as the '{GROUPS[kind]}' group requires"
    return obj, None


def names(kind: str) -> list[str]:
    """Names of all registered plugins of a kind (runtime first, then entry points), sorted."""
    return sorted(set(_runtime[kind]) | set(_entry_point_table(kind)))


def entries(kind: str) -> dict[str, tuple[object, str | None]]:
    """name -> (object or None, error or None) for every plugin of a kind; warns on broken ones."""
    out = {}
    for name in names(kind):
        if name in _runtime[kind]:
            out[name] = (_runtime[kind][name], None)
            continue
        obj, err = _load(kind, name)
        if err:
            warnings.warn(f"{kind[:-1]} plugin '{name}' is skipped: {err}", RuntimeWarning, stacklevel=2)
        out[name] = (obj, err)
    return out


def get(kind: str, name: str):
    """The plugin object of a kind by name; InputError listing the names that exist otherwise."""
    if name in _runtime[kind]:
        return _runtime[kind][name]
    if name in _entry_point_table(kind):
        obj, err = _load(kind, name)
        if err is None:
            return obj
        raise InputError(f"{kind[:-1]} '{name}' is installed but could not be used: {err}.")
    available = ", ".join(names(kind)) or "none"
    hint = {"backends": "install one with pip install 'cfm-materials[NAME]'",
            "materials": "register one with cfm_core.register_material or the 'cfm.materials' entry-point group",
            "terms": "register one with cfm_core.register_term or the 'cfm.terms' entry-point group"}[kind]
    raise InputError(f"unknown {kind[:-1]} '{name}'; available: {available} ({hint}).")


def get_material(name: str):
    """The :class:`~cfm_core.material.MaterialSpec` registered as ``name``."""
    return get("materials", name)


def get_backend(name: str):
    """A new instance of the backend registered as ``name``."""
    return get("backends", name)()


def get_term(name: str):
    """The :class:`~cfm_core.terms.Term` registered as ``name``."""
    return get("terms", name)


def _register(kind: str, name: str, obj, overwrite: bool):
    if not overwrite and (name in _runtime[kind] or name in _entry_point_table(kind)):
        raise InputError(f"a {kind[:-1]} named '{name}' is already registered; pass overwrite=True to replace it.")
    _runtime[kind][name] = obj
    return obj


def register_material(spec, name: str | None = None, overwrite: bool = False):
    """Register a :class:`~cfm_core.material.MaterialSpec` at run time (notebooks, tests)."""
    from .material import MaterialSpec

    if not isinstance(spec, MaterialSpec):
        raise InputError(f"register_material expects a MaterialSpec (compose terms with &), got {spec!r}.")
    name = name or spec.name
    spec = spec if spec.name == name else spec.named(name)
    spec.energy_parameters  # checks parameter declarations now
    return _register("materials", name, spec, overwrite)


def register_backend(cls, name: str | None = None, overwrite: bool = False):
    """Register a :class:`~cfm_core.backend.Backend` subclass at run time."""
    from .backend import Backend

    if not (isinstance(cls, type) and issubclass(cls, Backend)):
        raise InputError(f"register_backend expects a Backend subclass, got {cls!r}.")
    return _register("backends", name or cls.name, cls, overwrite)


def register_term(term, name: str | None = None, overwrite: bool = False):
    """Register an energy :class:`~cfm_core.terms.Term` at run time."""
    from .terms import Term

    if not isinstance(term, Term):
        raise InputError(f"register_term expects a Term (use @isochoric or @volumetric), got {term!r}.")
    return _register("terms", name or term.name, term, overwrite)


def unregister(kind: str, name: str) -> None:
    """Remove a runtime registration (no effect on entry points)."""
    _runtime[kind].pop(name, None)


def refresh() -> None:
    """Forget cached entry points (after installing or removing plugins)."""
    _entry_point_table.cache_clear()
    _load.cache_clear()
