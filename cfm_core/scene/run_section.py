"""The ``[run]`` section of a scene: how a run was made, so that its ``scene.toml`` repeats it.

Every ``scene.toml`` a run writes holds ``[run]``: the backend, its dtype and device, every
backend option as the run resolved it (defaults included) and the content digest of each input
file (the mesh). ``cfm run --scene DIR/scene.toml`` (and ``cfm.drop_test(cfm.load_scene(...))``)
then uses the same backend, options and dtype; a value given on the command line (or as an
argument in Python) overrides the file's, and the run says so. Scenes without ``[run]`` run
as before (the default backend and options).

The scene layer checks only the form of the section (names are text, options are a table of
plain values); whether the backend exists and declares the options is checked when the scene runs
(:func:`cfm_core.runs.settings.run_settings`), which names the section, the key and the value.

Example::

    [run]
    backend = "torch"
    dtype = "float32"
    device = "cpu"

    [run.options]              # every backend option as resolved, SI units
    hourglass = 0.05
    safety = 0.9

    [run.input_files]          # content digests of the files the scene reads
    "/data/specimen.vtu" = "sha256:8f1c..."

    [run.materials]            # definition digests of the materials it ran
    cfm = "3fbebec43ae559a257dc8c62"
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping

from ..errors import InputError, did_you_mean

__all__ = ["RunSettings"]


def _pairs(section: str, value, check) -> tuple:
    """A table as sorted (name, value) pairs, each value through ``check(name, value)``."""
    if not isinstance(value, Mapping):
        try:
            value = dict(value)
        except (TypeError, ValueError):
            raise InputError(f"[{section}] = {value!r} must be a table of name = value.") from None
    out = {}
    for k, v in value.items():
        if not isinstance(k, str) or not k.strip():
            raise InputError(f"[{section}] has a key {k!r}; keys must be non-empty names.")
        out[k] = check(k, v)
    return tuple(sorted(out.items()))


def _plain(section: str):
    def check(name, v):
        if isinstance(v, bool) or isinstance(v, str):
            return v
        if isinstance(v, (int, float)):
            if isinstance(v, float) and math.isnan(v):
                raise InputError(f"[{section}] {name} = nan is not allowed; give a number.")
            return v
        raise InputError(f"[{section}] {name} = {v!r} must be a number, true/false or text (SI units); "
                         f"tables and arrays are not options.")
    return check


def _digest(section: str):
    """Check of a content digest ``"sha256:<hex>"``, read in any case and kept in lower case (as cfm
    writes it, so that a digest retyped in upper case still compares equal)."""
    def check(name, v):
        if not isinstance(v, str) or not v.lower().startswith("sha256:"):
            raise InputError(f"[{section}] {name!r} = {v!r} must be a content digest \"sha256:<hex>\".")
        return v.lower()
    return check


#: Characters of a material definition digest (:func:`cfm_core.material.cache.definition_digest`).
DEFINITION_DIGITS = 24


def _definition(section: str):
    """Check of a material definition digest: 24 hexadecimal digits in any case, kept in lower case (as
    cfm writes it)."""
    def check(name, v):
        hexdigits = "0123456789abcdef"
        if not (isinstance(v, str) and len(v) == DEFINITION_DIGITS and all(c in hexdigits for c in v.lower())):
            got = (f"it is not text ({type(v).__name__})" if not isinstance(v, str) else
                   f"it has {len(v)} characters" if len(v) != DEFINITION_DIGITS else
                   "it has characters other than 0-9 and a-f")
            raise InputError(f"[{section}] {name} = {v!r} must be a material definition digest: "
                             f"{DEFINITION_DIGITS} hexadecimal digits (0-9, a-f in either case), as cfm writes it; "
                             f"{got}.")
        return v.lower()
    return check


@dataclass(frozen=True)
class RunSettings:
    """``[run]``: how a scene is run (all optional; None: the default).

    Parameters
    ----------
    backend : str, optional
        Registered backend name (``cfm backends``).
    dtype : str, optional
        Floating-point type, ``"float64"`` or ``"float32"`` (only backends with a choice accept
        float32).
    device : str, optional
        Device (``"cpu"``, ``"cuda"``, ``"cuda:N"``; only backends with a choice accept another
        than cpu).
    options : mapping or tuple of pairs
        Backend options by name, SI units (stored as sorted ``(name, value)`` pairs).
    input_files : mapping or tuple of pairs
        ``path -> "sha256:<hex>"``: content digests of the files the run read (its mesh).
    fields : str, optional
        The element fields a ``--vtu`` run wrote (comma-separated keys of
        :data:`cfm_core.post.fields.FIELDS`), so that its repeat writes the same frames.
    full : bool, optional
        Whether a ``--vtu`` run mirrored a quarter or half model into the whole specimen (``--full``).
    materials : mapping or tuple of pairs
        ``material name -> definition digest`` of every material the run used
        (:func:`cfm_core.material.cache.definition_digest`: its code, the values its code imports,
        its Prony defaults), so that a repeat says when a definition changed since. Each is 24
        hexadecimal digits, read in either case and kept in lower case, as cfm writes them (so are
        the content digests of ``input_files``).

    Raises
    ------
    InputError
        A name that is not text, an option value that is not a number, bool or text, a content
        digest not of the form ``sha256:<hex>``, or a definition digest not of 24 hexadecimal
        digits.
    """

    backend: str | None = None
    dtype: str | None = None
    device: str | None = None
    options: tuple = ()
    input_files: tuple = ()
    fields: str | None = None
    full: bool | None = None
    materials: tuple = ()

    def __post_init__(self):
        if self.fields is not None and (not isinstance(self.fields, str) or not self.fields.strip()):
            raise InputError(f"[run] fields = {self.fields!r} must be the --vtu fields as text (e.g. fields = "
                             f"\"von_mises,part\").")
        if self.full is not None and not isinstance(self.full, bool):
            raise InputError(f"[run] full = {self.full!r} must be true or false.")
        for key in ("backend", "dtype", "device"):
            v = getattr(self, key)
            if v is not None and (not isinstance(v, str) or not v.strip()):
                raise InputError(f"[run] {key} = {v!r} must be a non-empty name (e.g. backend = \"numba\").")
        if self.dtype is not None and self.dtype not in ("float64", "float32"):
            raise InputError(f"[run] dtype = {self.dtype!r} is not allowed; use 'float64' or 'float32'.")
        object.__setattr__(self, "options", _pairs("run.options", self.options, _plain("run.options")))
        object.__setattr__(self, "input_files", _pairs("run.input_files", self.input_files, _digest("run.input_files")))
        object.__setattr__(self, "materials", _pairs("run.materials", self.materials, _definition("run.materials")))

    @classmethod
    def from_table(cls, table, base_dir=None) -> "RunSettings":
        """The section from a TOML table; relative input-file paths taken from ``base_dir`` as a
        scene file's relative mesh path is.

        Parameters
        ----------
        table : mapping
            ``[run]`` as read from TOML.
        base_dir : str or path-like, optional
            The scene file's folder (None: paths as given).

        Returns
        -------
        RunSettings
            The validated section.

        Raises
        ------
        InputError
            Not a table, an unknown key (with a suggestion), or a value :class:`RunSettings` refuses.
        """
        if not isinstance(table, Mapping):
            raise InputError(f"[run] must be a table (section), got {table!r}.")
        allowed = ("backend", "dtype", "device", "options", "input_files", "fields", "full", "materials")
        for k in table:
            if k not in allowed:
                hint = did_you_mean(k, allowed)
                hint = f" ({hint[0].lower()}{hint[1:]})" if hint else ""
                raise InputError(f"unknown key '{k}' in [run]{hint}; allowed keys: {', '.join(allowed)}.")
        run = cls(**table)
        return run if base_dir is None else run.based_at(base_dir)

    @property
    def option_dict(self) -> dict:
        """The options as a new dict ``{name: value (SI)}``."""
        return dict(self.options)

    @property
    def file_dict(self) -> dict:
        """The input-file digests as a new dict ``{path: "sha256:<hex>"}``."""
        return dict(self.input_files)

    def based_at(self, base_dir) -> "RunSettings":
        """These settings with relative input-file paths taken from ``base_dir`` (as a scene file's
        relative mesh path is).

        Parameters
        ----------
        base_dir : str or path-like
            The scene file's folder.

        Returns
        -------
        RunSettings
            A new object; absolute paths are unchanged.
        """
        files = {(p if Path(p).expanduser().is_absolute() else str(Path(base_dir) / Path(p).expanduser())): d
                 for p, d in self.input_files}
        return replace(self, input_files=files)

    def as_dict(self) -> dict:
        """The section as TOML-ready nested dict (None entries and empty tables left out).

        Returns
        -------
        dict
            ``backend``, ``dtype``, ``device``, ``fields``, ``full`` (when set), ``options``, ``input_files``
            and ``materials`` (sub-tables, when not empty).
        """
        out = {k: getattr(self, k) for k in ("backend", "dtype", "device", "fields", "full")
               if getattr(self, k) is not None}
        if self.options:
            out["options"] = dict(self.options)
        if self.input_files:
            out["input_files"] = dict(self.input_files)
        if self.materials:
            out["materials"] = dict(self.materials)
        return out


def _value(v) -> str:
    import json

    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    return json.dumps(str(v), ensure_ascii=False)  # a JSON string is a valid TOML basic string


def _key(k: str) -> str:
    import json
    import re

    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k, ensure_ascii=False)


def run_toml(run: RunSettings) -> list[str]:
    """The TOML lines of a ``[run]`` section (with its ``options``, ``input_files`` and ``materials`` tables).

    Parameters
    ----------
    run : RunSettings
        The section.

    Returns
    -------
    list of str
        Lines, starting with a comment saying what the section is for.
    """
    d = run.as_dict()
    lines = ["# How this run was made: 'cfm run --scene THIS_FILE' repeats it (same backend, options and",
             "# dtype); a value on the command line overrides the one here. Options not listed: the backend's",
             "# default (an automatic choice).", "[run]"]
    lines += [f"{k} = {_value(d[k])}" for k in ("backend", "dtype", "device") if k in d]
    if "fields" in d or "full" in d:
        lines += ["# what its --vtu frames hold (fields) and whether they are mirrored into the whole specimen (full)"]
        lines += [f"{k} = {_value(d[k])}" for k in ("fields", "full") if k in d]
    if "options" in d:
        lines += ["", "[run.options]  # backend options as resolved, SI units ('cfm backends --options')"]
        lines += [f"{_key(k)} = {_value(v)}" for k, v in d["options"].items()]
    if "input_files" in d:
        lines += ["", "[run.input_files]  # content digests of the files the run read"]
        lines += [f"{_key(k)} = {_value(v)}" for k, v in d["input_files"].items()]
    if "materials" in d:
        lines += ["", "[run.materials]  # definition digests of the materials it ran (code, imported values, Prony defaults)"]
        lines += [f"{_key(k)} = {_value(v)}" for k, v in d["materials"].items()]
    return lines
