"""Registry of solver backends (entry-point group ``cfm.backends``), a kind of :mod:`cfm_core.plugins`."""

from __future__ import annotations

from .. import plugins
from ..errors import InputError
from .backend import Backend

plugins.declare_kind(
    "backends", "cfm.backends", lambda obj: isinstance(obj, type) and issubclass(obj, Backend),
    "a Backend subclass", "install one with pip install 'cfm-materials[NAME]'")


def get_backend(name: str) -> Backend:
    """A new instance of the backend registered as ``name``.

    Parameters
    ----------
    name : str
        Registered backend name, e.g. ``"numba"``, ``"torch"``, ``"skfem"``, ``"numpy"``
        (``cfm backends`` lists them).

    Returns
    -------
    Backend
        A new instance; it may not be usable here (see :func:`backend_for`).

    Raises
    ------
    InputError
        Unknown name (the message lists the registered backends) or a broken plugin.
    """
    return plugins.get("backends", name)()


def backend_for(name: str) -> Backend:
    """An instance of backend ``name`` that can run here.

    Parameters
    ----------
    name : str
        Registered backend name.

    Returns
    -------
    Backend
        A new instance whose required libraries are installed.

    Raises
    ------
    InputError
        Unknown backend, or one whose libraries are missing (the message says which and how to
        install them).
    """
    backend = get_backend(name)
    ok, why = backend.available()
    if not ok:
        raise InputError(f"backend '{name}' is not available: {why}.")
    return backend


def register_backend(cls: type, name: str | None = None, overwrite: bool = False) -> type:
    """Register a :class:`Backend` subclass at run time.

    Parameters
    ----------
    cls : type
        A subclass of :class:`Backend` (the class, not an instance).
    name : str, optional
        Name to register under; default ``cls.name``.
    overwrite : bool
        Replace an existing registration or shadow an installed backend of that name.

    Returns
    -------
    type
        ``cls`` itself.

    Raises
    ------
    InputError
        ``cls`` is not a Backend subclass, or the name is taken and ``overwrite`` is False.
    """
    if not (isinstance(cls, type) and issubclass(cls, Backend)):
        raise InputError(f"register_backend expects a Backend subclass, got {cls!r}.")
    return plugins.register("backends", name or cls.name, cls, overwrite)
