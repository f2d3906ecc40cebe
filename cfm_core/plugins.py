"""Plugin registries found through entry points: the machinery shared by every kind of plugin.

Each layer declares the kinds it owns with :func:`declare_kind`: the material layer declares
``materials`` (group ``cfm.materials``, a :class:`~cfm_core.material.MaterialSpec`) and ``terms``
(``cfm.terms``, a :class:`~cfm_core.material.Term`), the simulation layer ``backends``
(``cfm.backends``, a :class:`~cfm_core.simulation.Backend` subclass) and the command line
``commands`` (``cfm.commands``, a command module). This module imports none of them, so the
imports go one way.

Discovery is lazy and cached; :func:`refresh` clears the cache (xarray's backend registry works
the same way). A plugin that fails to load or is of the wrong type becomes a ``RuntimeWarning``
naming it and the error, and is listed as broken; the others still load. Objects registered at
run time take precedence over entry points.

A name is never taken over silently: an entry point that reuses the name of a built-in (one of
the ``cfm-materials`` distribution) or of another distribution's plugin makes that name
*ambiguous*. Listing still works and shows the conflict; using the name raises an
:class:`~cfm_core.errors.InputError` naming both distributions and entry points, unless the
environment variable :data:`PREFER_ENV` names the distribution to use::

    CFM_PLUGIN_PREFER="cfm=my-cfm-fork"                       # any kind named 'cfm'
    CFM_PLUGIN_PREFER="materials:cfm=my-cfm-fork,backends:numba=cfm-materials"

:func:`origin` names the distribution chosen (it enters every run's provenance).
"""

from __future__ import annotations

import functools
import os
import re
import warnings
import weakref
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Callable

from .errors import InputError

#: Environment variable naming the distribution to use for an ambiguous plugin name: comma-separated
#: ``[kind:]name=distribution`` items, e.g. ``materials:cfm=my-cfm-fork`` or ``cfm=my-cfm-fork``.
PREFER_ENV = "CFM_PLUGIN_PREFER"

#: The distribution of the built-in plugins (this project's, see pyproject.toml).
BUILTIN_DISTRIBUTION = "cfm-materials"


@dataclass(frozen=True)
class Kind:
    """One kind of plugin: its entry-point group, the check an object must pass, and the hint
    printed when a name is unknown.

    Made by :func:`declare_kind`; immutable.

    Attributes
    ----------
    name : str
        Plural name of the kind, e.g. ``"materials"``; the key of every registry function.
    group : str
        Entry-point group searched for plugins, e.g. ``"cfm.materials"``.
    accepts : callable
        ``accepts(obj) -> bool``: whether a loaded or registered object is a valid plugin.
    expected : str
        What ``accepts`` wants, for messages (``"a MaterialSpec"``).
    hint : str
        How to add a plugin of this kind, printed with unknown names.
    """

    name: str
    group: str
    accepts: Callable[[object], bool]
    expected: str
    hint: str


_kinds: dict[str, Kind] = {}
_runtime: dict[str, dict[str, object]] = {}


def declare_kind(name: str, group: str, accepts: Callable[[object], bool], expected: str, hint: str) -> Kind:
    """Declare a kind of plugin (called once by the layer that owns it).

    Parameters
    ----------
    name : str
        Plural name of the kind, e.g. ``"materials"``.
    group : str
        Entry-point group, e.g. ``"cfm.materials"``.
    accepts : callable
        ``accepts(obj) -> bool``: whether a loaded object is a valid plugin of this kind.
    expected : str
        What ``accepts`` wants, for messages (``"a MaterialSpec"``).
    hint : str
        How to add a plugin of this kind, printed with unknown names.

    Returns
    -------
    Kind
        The declaration (also stored, so :func:`get`, :func:`register`, ... accept ``name``).
        Declaring a name again replaces its declaration and keeps its runtime registrations.
    """
    kind = Kind(name, group, accepts, expected, hint)
    _kinds[name] = kind
    _runtime.setdefault(name, {})
    return kind


def _kind(name: str) -> Kind:
    try:
        return _kinds[name]
    except KeyError:
        raise InputError(f"unknown plugin kind '{name}'; declared kinds: {', '.join(sorted(_kinds))}.") from None


@functools.lru_cache(maxsize=1)
def _installed_entry_points():
    """Every installed entry point, read once per process: ``entry_points(group=...)`` reads the
    entry-point files of every installed distribution on each call, and a run looks up several
    groups (commands, materials, backends)."""
    return entry_points()


def _iter_entry_points(group: str):
    """The installed entry points of one group (patched in tests with fake EntryPoint objects)."""
    return list(_installed_entry_points().select(group=group))


def _normalise(dist: str | None) -> str:
    """A distribution name compared the way pip compares them (PEP 503: case, ``-_.`` alike)."""
    return re.sub(r"[-_.]+", "-", dist).lower() if dist else ""


_dist_names: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _dist_of(ep) -> tuple[str | None, str | None]:
    """(distribution name, version) of an entry point, (None, None) when it does not say. Read once
    per distribution object: each read of ``name`` or ``version`` parses its metadata file again
    (2 ms; a run asked 38 times)."""
    dist = getattr(ep, "dist", None)
    if dist is None:
        return None, None
    try:
        return _dist_names[dist]
    except (KeyError, TypeError):
        pass
    found = getattr(dist, "name", None), getattr(dist, "version", None)
    try:
        _dist_names[dist] = found
    except TypeError:  # an object that cannot be weakly referenced or hashed: not kept
        pass
    return found


def _describe(ep) -> str:
    name, version = _dist_of(ep)
    who = f"{name} {version}" if name and version else (name or "an unknown distribution")
    builtin = ", the built-in" if _normalise(name) == BUILTIN_DISTRIBUTION else ""
    return f"{who} (entry point {ep.name} = {ep.value}{builtin})"


@functools.lru_cache(maxsize=None)
def _entry_point_table(kind: str) -> dict:
    """name -> tuple of the distinct entry points declaring it (the same distribution and target
    found twice on the path counts once)."""
    table: dict = {}
    for ep in _iter_entry_points(_kind(kind).group):
        same = table.setdefault(ep.name, [])
        key = (_normalise(_dist_of(ep)[0]), ep.value)
        if all((_normalise(_dist_of(o)[0]), o.value) != key for o in same):
            same.append(ep)
    return {name: tuple(eps) for name, eps in table.items()}


def preferences() -> dict:
    """The distributions chosen with :data:`PREFER_ENV` for ambiguous plugin names.

    Returns
    -------
    dict
        ``(kind or None, name) -> normalised distribution name``; ``None`` as kind: any kind.

    Raises
    ------
    InputError
        An item that is not ``[kind:]name=distribution``.
    """
    text = os.environ.get(PREFER_ENV, "").strip()
    out = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        m = re.fullmatch(r"(?:([A-Za-z_]+):)?([^=:\s]+)=([A-Za-z0-9][A-Za-z0-9._-]*)", item)
        if not m:
            raise InputError(f"{PREFER_ENV} item {item!r} is not '[kind:]name=distribution' (e.g. "
                             f"'materials:cfm=my-cfm-fork'); the whole value is {text!r}.")
        out[(m.group(1), m.group(2))] = _normalise(m.group(3))
    return out


def _resolve(kind: str, name: str):
    """(entry point, None) for a name of the entry-point table, or (None, why it is ambiguous)."""
    eps = _entry_point_table(kind)[name]
    if len(eps) == 1:
        return eps[0], None
    prefs = preferences()
    want = prefs.get((kind, name)) or prefs.get((None, name))
    what = f"{kind[:-1]} '{name}'"
    listed = " and ".join(_describe(ep) for ep in eps)
    if want:
        chosen = [ep for ep in eps if _normalise(_dist_of(ep)[0]) == want]
        if chosen:
            return chosen[0], None
        return None, (f"{what} is declared by {listed}, and {PREFER_ENV} prefers distribution '{want}', which "
                      f"declares no {what}; name one of those distributions")
    taken = any(_normalise(_dist_of(ep)[0]) == BUILTIN_DISTRIBUTION for ep in eps)
    return None, (f"{what} is declared by {listed}: " + ("a plugin reuses a built-in's name" if taken else
                  "two plugins share one name") + f", and none is chosen silently; set {PREFER_ENV}="
                  f"\"{kind}:{name}=DISTRIBUTION\" to the distribution to use, or uninstall the other")


@functools.lru_cache(maxsize=None)
def _load_entry_point(kind: str, name: str, dist: str | None, value: str):
    """(object, None) or (None, error text) for one entry point (cached by its origin)."""
    ep = next(e for e in _entry_point_table(kind)[name] if (_dist_of(e)[0], e.value) == (dist, value))
    try:
        obj = ep.load()
    except Exception as exc:  # a broken plugin must not break the listing
        return None, f"failed to load {ep.value}: {type(exc).__name__}: {exc}"
    spec = _kind(kind)
    if not spec.accepts(obj):
        return None, f"{ep.value} is {obj!r}, not {spec.expected} as the '{spec.group}' group requires"
    return obj, None


def _load(kind: str, name: str):
    """(object, None) or (None, error text) for the entry point of a name (ambiguity: an error)."""
    ep, err = _resolve(kind, name)
    if err:
        return None, err
    return _load_entry_point(kind, name, _dist_of(ep)[0], ep.value)


def names(kind: str) -> list[str]:
    """Names of all registered plugins of a kind: runtime registrations and entry points, sorted.

    Parameters
    ----------
    kind : str
        A declared kind, e.g. ``"materials"``, ``"terms"``, ``"backends"``, ``"commands"``.

    Returns
    -------
    list of str
        Sorted names, each once (broken plugins included: nothing is loaded here).

    Raises
    ------
    InputError
        ``kind`` was never declared with :func:`declare_kind`.
    """
    _kind(kind)
    return sorted(set(_runtime[kind]) | set(_entry_point_table(kind)))


def entries(kind: str) -> dict[str, tuple[object, str | None]]:
    """Every plugin of a kind, loaded, with the error of each broken one.

    Parameters
    ----------
    kind : str
        A declared kind, e.g. ``"materials"``.

    Returns
    -------
    dict of str to (object or None, str or None)
        ``name -> (obj, None)`` for a usable plugin, ``name -> (None, error text)`` for one that
        failed to load, is not of the kind's type or is declared by several distributions with
        none chosen (the text names them); runtime registrations win over entry points.

    Raises
    ------
    InputError
        ``kind`` was never declared.

    Warns
    -----
    RuntimeWarning
        One per broken plugin, naming it and the error.
    """
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
    """The plugin object of a kind by name (runtime registrations first, then entry points).

    Parameters
    ----------
    kind : str
        A declared kind, e.g. ``"materials"``.
    name : str
        The plugin's name, e.g. ``"cfm"``.

    Returns
    -------
    object
        The registered or loaded object (a MaterialSpec, a Term, a Backend subclass, ...).

    Raises
    ------
    InputError
        Unknown name (the message lists the names that exist and how to add one), a plugin
        that is installed but failed to load or is of the wrong type, a name declared by several
        distributions with none chosen in :data:`PREFER_ENV` (the message names them and their
        entry points), or an undeclared ``kind``.
    """
    if name in _runtime[_kind(kind).name]:
        return _runtime[kind][name]
    if name in _entry_point_table(kind):
        ep, ambiguous = _resolve(kind, name)
        if ambiguous:
            raise InputError(ambiguous + ".")
        obj, err = _load(kind, name)
        if err is None:
            return obj
        raise InputError(f"{kind[:-1]} '{name}' is installed but could not be used: {err}.")
    available = ", ".join(names(kind)) or "none"
    raise InputError(f"unknown {kind[:-1]} '{name}'; available: {available} ({_kind(kind).hint}).")


def register(kind: str, name: str, obj, overwrite: bool = False):
    """Register ``obj`` as plugin ``name`` of ``kind`` at run time (it takes precedence over an
    entry point of the same name).

    Parameters
    ----------
    kind : str
        A declared kind, e.g. ``"materials"``.
    name : str
        Name to register under.
    obj : object
        The plugin; must pass the kind's ``accepts`` check.
    overwrite : bool
        Replace an existing registration or shadow an entry point of the same name.

    Returns
    -------
    object
        ``obj`` itself.

    Raises
    ------
    InputError
        ``obj`` is not of the kind's type, the name is taken and ``overwrite`` is False, or an
        undeclared ``kind``.
    """
    spec = _kind(kind)
    if not spec.accepts(obj):
        raise InputError(f"a {kind[:-1]} plugin must be {spec.expected}, got {obj!r}.")
    if not overwrite and (name in _runtime[kind] or name in _entry_point_table(kind)):
        raise InputError(f"a {kind[:-1]} named '{name}' is already registered; pass overwrite=True to replace it.")
    _runtime[kind][name] = obj
    return obj


def unregister(kind: str, name: str) -> None:
    """Remove a runtime registration (no effect on entry points; an unknown name is ignored).

    Parameters
    ----------
    kind : str
        A declared kind, e.g. ``"backends"``.
    name : str
        The registered name.

    Raises
    ------
    InputError
        ``kind`` was never declared.
    """
    _runtime[_kind(kind).name].pop(name, None)


def origin(kind: str, name: str) -> dict:
    """Where a plugin comes from: its distribution and version, or that it was registered at run time.

    Parameters
    ----------
    kind : str
        A declared kind, e.g. ``"materials"``.
    name : str
        The plugin's name.

    Returns
    -------
    dict
        ``{"name", "distribution", "version", "value"}``: the distribution (``None`` for a runtime
        registration or an unknown entry point origin), its version, and the entry point's
        ``module:attribute`` (``"runtime"`` for :func:`register`).

    Raises
    ------
    InputError
        Unknown name, undeclared ``kind``, or a name several distributions declare with none
        chosen (:data:`PREFER_ENV`).
    """
    if name in _runtime[_kind(kind).name]:
        obj = _runtime[kind][name]
        return {"name": name, "distribution": None, "version": None,
                "value": f"runtime ({getattr(obj, '__module__', None) or type(obj).__module__})"}
    if name not in _entry_point_table(kind):
        get(kind, name)  # raises the unknown-name error
    ep, ambiguous = _resolve(kind, name)
    if ambiguous:
        raise InputError(ambiguous + ".")
    dist, version = _dist_of(ep)
    return {"name": name, "distribution": dist, "version": version, "value": ep.value}


def refresh() -> None:
    """Forget cached entry points and loaded plugins of every kind (after installing or removing
    plugins); runtime registrations are kept."""
    _installed_entry_points.cache_clear()
    _entry_point_table.cache_clear()
    _load_entry_point.cache_clear()
