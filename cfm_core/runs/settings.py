"""How a scene is run: its ``[run]`` section merged with what the caller gives.

A scene's ``[run]`` section (:mod:`cfm_core.scene.run_section`, written into every
``scene.toml`` a run writes) names the backend, dtype, device and every option of the run that
wrote it, and the content digests of the files it read. :func:`plan_run` turns it into what the
backend is given: a backend or option given by the caller (the command line, or an argument of
:func:`cfm_core.drop_test`) overrides the file's, and the plan says so; a mesh whose content
changed since is warned about with both digests. :func:`run_record` is the ``[run]`` section a
finished run writes back.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..scene.run_section import RunSettings
from ..scene.scene import Scene
from ..simulation.registry import backend_for
from .provenance import backend_record, material_digests, scene_files

#: Values of dtype and device that a backend without that choice runs with.
FIXED = {"dtype": "float64", "device": "cpu"}


@dataclass
class RunPlan:
    """What a scene runs with.

    Attributes
    ----------
    backend : str
        Registered backend name.
    options : dict
        The backend options (SI units), dtype and device included where the backend declares them.
    notes : list of str
        What the caller's values changed against the scene's ``[run]`` section (printed before
        the run).
    warnings : list of str
        Input files whose content changed since the run that wrote the scene (printed, and listed
        in the summary's warnings).
    """

    backend: str
    options: dict
    notes: list = field(default_factory=list)
    warnings: list = field(default_factory=list)


def _show(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def plan_run(scene: Scene, backend: str | None = None, options: dict | None = None, default: str = "numba",
             given_as: dict | None = None, where: str = "the scene's [run]") -> RunPlan:
    """Merge the scene's ``[run]`` section with the backend and options the caller gives.

    Parameters
    ----------
    scene : Scene
        The scene; its ``run`` (None: no section) gives the backend, dtype, device and options.
    backend : str, optional
        The caller's backend; overrides ``[run] backend`` (whose options then do not apply).
    options : dict, optional
        The caller's backend options (dtype and device among them); each overrides the
        section's value of the same name.
    default : str
        Backend when neither the caller nor the section names one.
    given_as : dict, optional
        How the caller gave each value, for the notes: ``{"backend": "--backend torch",
        "hourglass": "--option hourglass=0.1", ...}`` (default ``name=value``).
    where : str
        How the notes name the section (e.g. ``"scene.toml [run]"``).

    Returns
    -------
    RunPlan
        Backend, options, notes and warnings.

    Raises
    ------
    InputError
        The section names an unknown or unavailable backend, an option the backend does not
        declare, a dtype or device the backend has no choice of, or a value out of an option's
        range (the message names ``[run]``, the key and the value).
    """
    run = scene.run or RunSettings()
    given = dict(options or {})
    given_as = dict(given_as or {})
    name = backend or run.backend or default
    notes = []
    try:
        be = backend_for(name)
    except InputError as exc:
        if backend is None and run.backend:
            raise InputError(f"{where} backend = {run.backend!r}: {exc}") from None
        raise
    specs = getattr(getattr(be, "options_class", None), "specs", dict)()
    from_file = {}
    if run.backend in (None, name):
        from_file = run.option_dict
        for key in ("dtype", "device"):
            if getattr(run, key) is not None:
                from_file[key] = getattr(run, key)
    elif backend is not None and run.backend != name:
        notes.append(f"{given_as.get('backend', f'backend={name}')} overrides {where} backend = {run.backend} "
                     f"(its options are not used)")
    for key, value in list(from_file.items()):
        if key in specs:
            spec = specs[key]
            if value == NONE_TEXT and spec.none and NONE_TEXT not in spec.choices:
                from_file[key] = None  # None written as text (TOML has no null): run_record
            continue
        if FIXED.get(key) == value:  # float64 on cpu: what a backend without the choice runs anyway
            del from_file[key]
            continue
        what = ("has no choice of " + key) if key in FIXED else "has no option of that name"
        raise InputError(f"{where} {'options.' if key not in FIXED else ''}{key} = {value!r}: backend '{name}' {what}; "
                         f"its options are {', '.join(specs) or 'none'} ('cfm backends --options' gives units and "
                         f"ranges). Remove the key or name another backend.")
    merged = dict(from_file)
    for key, value in given.items():
        if key in from_file and from_file[key] != value:
            notes.append(f"{given_as.get(key, f'{key}={_show(value)}')} overrides {where} {key} = {_show(from_file[key])}")
        merged[key] = value
    return RunPlan(name, merged, notes, changed_inputs(scene, where))


def changed_inputs(scene: Scene, where: str = "the scene's [run]") -> list[str]:
    """Warnings for input files of the scene whose content differs from the digest in ``[run]``, and
    for materials whose definition differs from the digest in ``[run.materials]``.

    Only files the scene still reads are checked (a mesh replaced by an override is not; an .inp
    mesh's included files are), and only materials it still runs.

    Parameters
    ----------
    scene : Scene
        The scene (its ``run.input_files`` and ``specimen.mesh``).
    where : str
        How the warnings name the section.

    Returns
    -------
    list of str
        One warning per changed file or material definition, naming it and both digests.
    """
    if scene.run is None:
        return []
    out = []
    if scene.run.materials:
        now = material_digests(scene)
        for name, recorded in scene.run.materials:
            if name in now and now[name] != recorded:
                out.append(f"material '{name}' is defined differently from the run that wrote this scene ({where} "
                           f"materials: {recorded}; now: {now[name]}: its code, a value the code imports or its "
                           f"Prony defaults changed), so this is not a repeat of that run")
    mesh = getattr(getattr(scene, "specimen", None), "mesh", None)
    if not scene.run.input_files or not mesh or not Path(mesh).is_file():
        return out
    now = {Path(p).resolve(): (p, d) for p, d in scene_files(scene).items()}   # the mesh and what it includes
    for path, recorded in scene.run.input_files:
        p, digest = now.get(Path(path).resolve(), (None, None))
        if digest is not None and digest != recorded:
            what = (f"mesh file {p}" if Path(p).resolve() == Path(mesh).resolve()
                    else f"file {p} (included by the mesh {mesh})")
            out.append(f"{what} changed since the run that wrote this scene ({where} input_files: "
                       f"{recorded}; now: {digest}), so this is not a repeat of that run")
    return out


#: How ``[run.options]`` writes None where the option's default is not None (TOML has no null).
NONE_TEXT = "none"


def run_record(scene: Scene, backend: str, options: dict | None = None) -> RunSettings:
    """The ``[run]`` section of a finished run: backend, dtype, device, every option as resolved
    (defaults included; options whose value is None, an automatic choice, are left out, unless
    the default is not None: then None is written as the text ``"none"``, which
    :func:`run_settings` reads back as None), the content digests of the files the scene read and
    the definition digests of its materials.

    Parameters
    ----------
    scene : Scene
        The scene that ran.
    backend : str
        Its backend.
    options : dict, optional
        The options it was given.

    Returns
    -------
    RunSettings
        The section.
    """
    rec = backend_record(backend, options)
    declared = getattr(backend_for(backend), "options_class", None)  # its class attributes: the defaults
    opts = {}
    for k, v in rec["options"].items():
        if k in FIXED:
            continue
        if v is not None:
            opts[k] = v
        elif getattr(declared, k, None) is not None:
            opts[k] = NONE_TEXT  # None chosen where the default is not None (error_tol = None, not 'auto')
    return RunSettings(backend, rec["dtype"], rec["device"], opts, scene_files(scene), materials=material_digests(scene))
