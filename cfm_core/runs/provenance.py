"""Provenance: what produced an output, recorded in every file a run or study writes.

One record per run or study, the same everywhere (``summary.json``, the ``[run]`` section of
``scene.toml``, sweep/calibration/fit JSON, the verification report): the backend and where it
came from, its resolved options (defaults included, so a repeat does not depend on defaults that
may change), dtype, device and threads, the material and the digest of its definition, the
content digest of every input file, and the code that ran (:func:`cfm_core.fingerprint.code_state`).
"""

from __future__ import annotations

import math
import os
import platform
from pathlib import Path

from .. import fingerprint, plugins
from ..material.cache import definition_digest
from ..simulation.registry import backend_for


def resolved_options(backend: str, options: dict | None = None) -> dict:
    """A backend's options with every default filled in, as plain values.

    Parameters
    ----------
    backend : str
        Registered backend name.
    options : dict, optional
        The options given (``cfm backends --options`` lists names, units and ranges).

    Returns
    -------
    dict
        Every declared option of the backend with the value the run uses (given or default); a
        backend that declares no options class gets ``options`` as given.

    Raises
    ------
    InputError
        Unknown backend, an option it does not declare, or a value out of its range.
    """
    cls = getattr(backend_for(backend), "options_class", None)
    if cls is None:
        return dict(options or {})
    return cls.from_mapping(dict(options or {})).as_dict()


def backend_record(backend: str, options: dict | None = None) -> dict:
    """The backend part of a provenance record.

    Parameters
    ----------
    backend : str
        Registered backend name.
    options : dict, optional
        The options given to the run.

    Returns
    -------
    dict
        ``name``, ``distribution``, ``version``, ``entry_point`` (where the backend class came
        from), ``options`` (all resolved, :func:`resolved_options`), and ``dtype``, ``device``,
        ``threads`` (None where the backend has no such choice; threads None = the backend's
        automatic count).
    """
    where = plugins.origin("backends", backend)
    opts = resolved_options(backend, options)
    be = backend_for(backend)
    return {"name": backend, "distribution": where["distribution"], "version": where["version"],
            "entry_point": where["value"], "options": opts,
            "dtype": opts.get("dtype", (getattr(be, "dtypes", None) or ("float64",))[0]),
            "device": opts.get("device", (getattr(be, "devices", None) or ("cpu",))[0]),
            "threads": opts.get("threads")}


def material_record(material) -> dict:
    """The material part of a provenance record.

    Parameters
    ----------
    material : Material
        The bound material of the run (``model.material``).

    Returns
    -------
    dict
        ``name``, ``distribution``, ``version``, ``entry_point`` of the material plugin (None for
        a material composed in Python and not registered), ``definition_digest`` (changes when any
        term's source, parameters, the Prony defaults, the default moduli or the code generator
        change, :func:`cfm_core.material.cache.definition_digest`; None for interactively defined
        terms), ``terms`` (each energy term's name with the distribution, version and entry point
        of the ``cfm.terms`` plugin of that name, None where it is not registered),
        ``parameters`` (every value, SI), ``overrides`` (:func:`parameter_overrides`), ``moduli``,
        ``elastic``.
    """
    spec = material.spec
    where = _origin("materials", spec.name)
    terms = [*spec.isochoric, *((spec.volumetric,) if spec.volumetric else ())]
    return {"name": spec.name, "distribution": where["distribution"], "version": where["version"],
            "entry_point": where["value"], "definition_digest": definition_digest(spec),
            "terms": [{"name": t.name, **{k: v for k, v in _origin("terms", t.name).items() if k != "name"}}
                      for t in terms],
            "parameters": dict(material.values), "overrides": parameter_overrides(material),
            "moduli": material.moduli, "elastic": bool(material.elastic)}


def part_records(parts) -> list[dict]:
    """The parts of a model with several materials, for a provenance record and summary.json.

    Parameters
    ----------
    parts : sequence of Part
        ``Model.part_list()`` (name, bound material, density kg/m^3, element indices).

    Returns
    -------
    list of dict
        One per part in order: ``name``, ``density`` (kg/m^3), ``elements`` (modelled elements,
        count) and ``material`` (:func:`material_record`: name, definition digest, every
        parameter value in SI, overrides, moduli, elastic).
    """
    return [{"name": p.name, "density": float(p.density), "elements": int(len(p.elements)),
             "material": material_record(p.material)} for p in parts]


def _origin(kind: str, name: str) -> dict:
    """:func:`cfm_core.plugins.origin`, or Nones for a name not registered (composed in Python)."""
    try:
        return plugins.origin(kind, name)
    except ValueError:
        return {"name": name, "distribution": None, "version": None, "value": None}


def parameter_overrides(material) -> dict:
    """The material parameters whose value differs from the material's default.

    Parameters
    ----------
    material : Material
        A bound material.

    Returns
    -------
    dict
        ``name -> {"value": v, "default": d}`` (SI units), in the material's parameter order.
    """
    out = {}
    for p in material.spec.parameters:
        v = material.values.get(p.name)
        if v is not None and v != p.default:
            out[p.name] = {"value": v, "default": p.default}
    return out


def input_files(paths) -> dict:
    """Content digests of input files.

    Parameters
    ----------
    paths : iterable of str or path-like, or dict of name to path
        The files (a mesh, measured curves, lab tests); empty names and None are skipped.

    Returns
    -------
    dict
        ``path (as given) -> "sha256:<hex>"`` of each file's bytes.

    Raises
    ------
    InputError
        A file cannot be read.
    """
    from ..errors import InputError

    items = paths.items() if isinstance(paths, dict) else ((p, p) for p in paths)
    out = {}
    for label, path in items:
        if not path:
            continue
        try:
            out[str(label)] = "sha256:" + fingerprint.file_digest(path)
        except OSError as exc:
            raise InputError(f"input file {str(path)!r} cannot be read for its content digest: {exc}.") from None
    return out


def scene_files(scene) -> dict:
    """The input files a scene reads (its mesh), with their content digests (:func:`input_files`).

    Parameters
    ----------
    scene : Scene
        Any scene.

    Returns
    -------
    dict
        ``path -> "sha256:<hex>"``; empty for built-in meshes.
    """
    return input_files(scene_paths(scene))


def scene_paths(scene) -> list:
    """The files a scene reads: its [specimen] mesh as given, then, for an Abaqus .inp mesh, the
    files it includes (``*INCLUDE, INPUT=`` and ``INPUT=`` on ``*NODE``, ``*ELEMENT``, ``*ELSET``:
    :func:`cfm_core.scene.abaqus_inp.input_files`), whose content is part of the mesh; empty for
    built-in meshes. An output written where one of them lies must not remove it
    (:func:`cfm_core.post.staging.refuse_inputs`).

    Parameters
    ----------
    scene : Scene
        Any scene.

    Returns
    -------
    list of str or path-like
    """
    mesh = getattr(getattr(scene, "specimen", None), "mesh", None)
    if not mesh:
        return []
    if Path(mesh).suffix.lower() == ".inp" and Path(mesh).is_file():
        from ..scene.abaqus_inp import input_files as included

        return [mesh, *(str(p) for p in included(mesh))]
    return [mesh]


def provenance(backend: str | None = None, options: dict | None = None, material=None, files: dict | None = None,
               parts=None, **extra) -> dict:
    """A provenance record: code, machine, backend, material and input files.

    Parameters
    ----------
    backend : str, optional
        Backend name (omitted from the record when None, e.g. a fit that ran no backend).
    options : dict, optional
        The backend options given.
    material : Material, optional
        The bound material.
    files : dict, optional
        ``path -> digest`` from :func:`input_files` / :func:`scene_files`.
    parts : sequence of Part, optional
        The parts of a model with several materials (``Model.parts``); recorded under ``parts``
        (:func:`part_records`) when there are two or more, so that a one-material record is as
        before. ``material`` is then the first part's (as ``Model.material``).
    **extra
        Further JSON-able entries (e.g. ``overrides``: what the command line changed).

    Returns
    -------
    dict
        ``code`` (:func:`cfm_core.fingerprint.code_state`), ``python``, ``platform``,
        ``cpu_count`` (usable cores), ``backend`` (:func:`backend_record`), ``material``
        (:func:`material_record`), ``parts`` (with several parts), ``input_files`` and
        ``extra``'s entries.
    """
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count()
    record = {"code": dict(fingerprint.code_state()), "python": platform.python_version(),
              "platform": platform.platform(), "cpu_count": cores}
    if backend is not None:
        record["backend"] = backend_record(backend, options)
    if material is not None:
        record["material"] = material_record(material)
    if parts is not None and len(parts) > 1:
        record["parts"] = part_records(parts)
    record["input_files"] = dict(files or {})
    record.update(extra)
    return json_ready(record)  # strict JSON: an option such as dt_max = inf is written as "inf"


def material_digests(scene) -> dict:
    """``material name -> definition digest`` of every material a scene runs (its own and those
    its layers or parts name; :func:`cfm_core.material.cache.definition_digest`), leaving out those
    defined interactively (no digest).

    Parameters
    ----------
    scene : Scene
        The scene.

    Returns
    -------
    dict
        Sorted by name.
    """
    from ..material.registry import get_material
    from ..scene.layers import regions

    names = {scene.material.name, *(r.material for _, r in regions(scene) if getattr(r, "material", None))}
    digests = {n: definition_digest(get_material(n)) for n in sorted(names)}
    return {n: d for n, d in digests.items() if d is not None}


def describe_differences(records: dict) -> list[str]:
    """What differs between runs, one short phrase per difference, for titles and comparisons.

    Parameters
    ----------
    records : dict
        ``label -> provenance record`` (:func:`provenance`) of each run shown.

    Returns
    -------
    list of str
        E.g. ``"backend: numba | torch"``, ``"dtype: float64 | float32"``,
        ``"option hourglass: 0.1 | 0.05"``, ``"k2: 1.66 | 3"``, ``"mesh: a1b2c3 | d4e5f6"`` (content
        digests), in the order of ``records``; empty when nothing recorded differs.
    """
    recs = list(records.values())
    if len(recs) < 2:
        return []

    def flat(r: dict) -> dict:
        b, m = r.get("backend") or {}, r.get("material") or {}
        out = {"backend": b.get("name"), "dtype": b.get("dtype"), "device": b.get("device")}
        for prefix, pm in _materials(r, m):
            digest = pm.get("definition_digest")
            out.update({f"{prefix}material": pm.get("name"), f"{prefix}moduli": pm.get("moduli"),
                        f"{prefix}elastic": pm.get("elastic"),  # its code, helpers' values, Prony defaults:
                        f"{prefix}material definition": digest[:8] if isinstance(digest, str) else digest})
        out.update({f"option {k}": v for k, v in (b.get("options") or {}).items() if k not in ("dtype", "device")})
        for prefix, pm in _materials(r, m):
            out.update({f"{prefix}{k}": v for k, v in (pm.get("parameters") or {}).items()})
        for p in r.get("parts") or ():
            out.update({f"{p.get('name')} density": p.get("density"), f"{p.get('name')} elements": p.get("elements")})
        files = r.get("input_files") or {}
        out["input files"] = ", ".join(f"{Path(k).name}:{v.split(':')[-1][:8]}" for k, v in sorted(files.items())) or None
        out.update({k: v for k, v in (r.get("scene_values") or {}).items()})
        return out

    flats = [flat(r) for r in recs]
    keys = list(dict.fromkeys(k for f in flats for k in f))
    phrases = []
    for k in keys:
        values = [f.get(k) for f in flats]
        if k.startswith("option ") and any(k not in f for f in flats):
            continue  # an option of one backend only: the backend difference says it
        if any(v != values[0] for v in values[1:]):
            phrases.append(f"{k}: " + " | ".join(_fmt(v) for v in values))
    return phrases


def json_ready(value):
    """``value`` with infinite floats written as the text ``"inf"`` / ``"-inf"`` (JSON has no
    infinity; an option such as ``dt_max = inf`` means "no limit"). NaN is left as it is, so that
    the writers still refuse it.

    Parameters
    ----------
    value : JSON-like
        Nested dicts, lists and plain values.

    Returns
    -------
    JSON-like
        A copy with infinities as text.
    """
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    return value


#: Backend options that change what is stored, not the result: left out of titles.
OUTPUT_ONLY = ("frame_interval", "warm_up")


def _fmt(v) -> str:
    return "-" if v is None else (f"{v:g}" if isinstance(v, float) else str(v))


def describe_run(record: dict) -> list[str]:
    """How one run differs from the defaults, one short phrase each, for plot titles.

    Parameters
    ----------
    record : dict
        A provenance record (:func:`provenance`), e.g. ``summary["provenance"]``.

    Returns
    -------
    list of str
        The backend with its dtype (``"numba float64"``, ``"torch float32 cuda"``), then each
        backend option that differs from the backend's default (``"hourglass 0.05"``), then each
        material parameter that differs from the material's default (``"k2 = 3 (default 1.66)"``).
    """
    b, m = record.get("backend") or {}, record.get("material") or {}
    out = []
    if b.get("name"):
        device = b.get("device")
        out.append(" ".join(str(x) for x in (b["name"], b.get("dtype"), device if device not in (None, "cpu") else None)
                            if x))
        try:
            defaults = json_ready(resolved_options(b["name"], {}))
        except ValueError:  # a backend not installed here: its defaults are unknown
            defaults = {}
        for k, v in (b.get("options") or {}).items():
            if k in defaults and k not in ("dtype", "device", *OUTPUT_ONLY) and defaults[k] != v:
                out.append(f"{k} {_fmt(v)}")
    for prefix, pm in _materials(record, m):
        for k, d in (pm.get("overrides") or {}).items():
            out.append(f"{prefix}{k} = {_fmt(d.get('value'))} (default {_fmt(d.get('default'))})")
    return out


def _materials(record: dict, material: dict) -> list[tuple[str, dict]]:
    """``[("", material)]`` for a one-material record; ``[("skin: ", ...), ("fat: ", ...)]``, each
    part's material record prefixed by the part's name, for a record with ``parts``."""
    parts = record.get("parts")
    if not parts:
        return [("", material)]
    return [(f"{p.get('name')}: ", p.get("material") or {}) for p in parts]
