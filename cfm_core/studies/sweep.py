"""Parameter sweeps of the drop test: every combination of some scene and material values.

A sweep varies names of the drop-test scene (:data:`SCENE_KEYS`: thickness, velocity, ... in SI
units) and parameters of its material (``cfm``: c, k1, k2, kappa, g1, tau1, g2, tau2, g3, tau3) over
given values, runs the cartesian product (the last ``--vary`` changes fastest) on a runner of
:mod:`cfm_core.studies.dask_runner`. Every value is checked before any run: each case's scene is
built and its material bound (:func:`check_cases`), so a value out of range (or NaN, inf) stops
the sweep with an InputError naming it, not one run after others were computed.

Run ids are content keys (:func:`run_key`, :func:`run_id`): a hash of the scene (with the mesh
file's content digest in place of its path), the material definition's digest, the backend with
every option resolved, the code's source digest, and the run's values. With a cache folder
(``runs/`` of the output), a complete run is read back instead of computed (:func:`cached_summary`:
its ``summary.json`` parses, names the run and holds every figure of the table, and its
``acceleration.csv`` reads back to the same pulse figures); a changed mesh file, option, material
or code gives new ids, so nothing stale is reused. Failed runs are run again, and so is a damaged
entry (its files removed first, a note on stderr naming it).

Files: :mod:`cfm_core.studies.sweep_output` (table, plot, sweep.json) written by
:class:`cfm_core.studies.outcomes.SweepOutcome`.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import shutil
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from .. import fingerprint
from ..errors import InputError
from ..material.cache import definition_digest
from ..material.registry import get_material, make_material
from ..post.metrics import drop_test_metrics
from ..post.writers import DROP_TEST_COLUMN_UNITS, write_drop_test, write_json, write_text
from ..runs import pipeline as simulate  # noqa: F401  (sweep.simulate: what the runs call)
from ..runs.provenance import resolved_options, scene_files
from ..scene.scene import _UNITS as SCENE_UNITS
from ..scene.layers import refuse_unused, regions
from ..scene.scene import scene_to_dict
from ..tables import as_float, decode, read_table as read_history, shown
from .cases import _case_result, batches, map_cases, overrides, run_all, run_case, run_cases  # noqa: F401
from .dask_runner import SerialRunner, error_text
from .sweep_output import (SUMMARY_COLUMNS, TEXT_COLUMNS, columns, plot_peaks, read_table,  # noqa: F401
                           table_frame, write_table)

#: Scene keys a sweep can vary (SI units, see cfm_core/scene/scenes/drop-test.toml).
SCENE_KEYS = ("thickness", "velocity", "element_size", "width", "mass", "radius", "density", "friction")
#: Above this many runs, ``cfm sweep`` run from a terminal asks before starting (``--yes`` skips it).
CONFIRM_RUNS = 200
#: Measured cost of a drop test on numba (2 threads): 1.9 s for the default 8 mm specimen with 1 mm
#: hexahedra (docs/user/sweeps.md); the time scales with elements x steps, i.e. with volume / h^4.
REFERENCE_RUN = {"seconds": 1.9, "volume": 0.05 * 0.05 * 0.008, "element_size": 0.001}
#: Per-run overhead outside the solver (s): model build, post-processing, files.
RUN_OVERHEAD = 0.03


@dataclass(frozen=True)
class Axis:
    """One varied name with its unit and values (SI); ``text``: the values as given on the command
    line (``"0.005,0.006"``), or None (given as numbers), for messages only."""

    name: str
    unit: str
    values: tuple
    text: str | None = field(default=None, compare=False, repr=False)


# ----------------------------------------------------------------------------- what to run
def variable_units(scene) -> dict:
    """{name: unit} of everything a sweep (or a fit) of this drop-test scene can vary."""

    if scene.type != "drop-test":
        raise InputError(f"sweeps and calibrations run drop tests; the scene is a '{scene.type}' scene.")
    units = {k: SCENE_UNITS[k].split(",")[0] for k in SCENE_KEYS}
    for p in get_material(scene.material.name).parameters:
        units.setdefault(p.name, p.unit)
    return units


_BARE_INTEGER = re.compile(r"[+-]?[0-9]+")


def _comma_hint(text) -> str:
    """The decimal-comma reminder added to every error about a value of a comma-separated list."""
    if not isinstance(text, str) or "," not in text:
        return ""
    return (" Values are separated by commas, so a decimal number needs a decimal point (0.005, not 0,005); "
            "if a value was meant with a decimal comma, write it with a point.")


def _number(name: str, v, unit: str, text=None) -> float:
    """``v`` as a float in ``unit`` (SI); InputError naming the value (and the list ``text`` it came from)."""
    try:
        x = float(v.strip() if isinstance(v, str) else v)
    except (TypeError, ValueError):
        raise InputError(f"--vary {name}: value {str(v).strip()!r} is not a number ({unit}); "
                         f"give NAME=V1,V2,...{_comma_hint(text)}") from None
    if not math.isfinite(x):
        raise InputError(f"--vary {name}: value {str(v).strip()} is not a finite number ({unit}); every value "
                         f"of a sweep must be finite, in SI units.{_comma_hint(text)}")
    return x


def check_decimal_comma(name: str, text: str, unit: str = "") -> None:
    """InputError when the ``--vary`` values ``text`` look like a number written with a decimal comma.

    Values are separated by commas, so ``0,005`` is the two values 0 and 5, which nobody means. The
    rule, on the items between the commas (an item is "bare" when it is an integer without a
    decimal point or exponent, e.g. ``5``, ``005``, ``-0``):

    - a bare item after the first that starts with 0 and has more digits (``005``, ``05``): list
      values are not written with leading zeros, the digits of a decimal fraction are
      (``thickness=0,005``, ``k2=1,05``, ``thickness=0,005,0,006``);
    - exactly two bare items where the first is 0 (``0,5``, ``0,25``) or the second is 0
      (``5,0``): these read as 0.5 and 5.0 written with a decimal comma.

    Any other list is taken as written: ``k2=1,2``, ``k1=1000,1320``, ``c=10,100`` and also
    ``velocity=1,5`` (1 and 5 m/s: it cannot be told apart from a list, so the progress lines and
    the table show the two values). To sweep values the rule refuses, write one of them with a
    decimal point (``0.0,5``: the values 0 and 5).

    Parameters
    ----------
    name : str
        The varied name (for the message).
    text : str
        What followed ``NAME=`` on the command line.
    unit : str
        The name's SI unit (for the message).

    Raises
    ------
    InputError
        The values look like a decimal comma; the message gives the decimal reading and how to
        write either meaning.
    """
    items = [t.strip() for t in text.split(",")]
    bare = [bool(_BARE_INTEGER.fullmatch(t)) for t in items]
    at = next((k for k in range(1, len(items)) if bare[k] and bare[k - 1] and items[k][:1] == "0"
               and len(items[k].lstrip("+-")) > 1), None)
    if at is None and len(items) == 2 and all(bare) and (float(items[0]) == 0.0 or items[1] == "0"):
        at = 1
    if at is None:
        return
    whole, frac = items[at - 1], items[at]
    meant = f"{whole}.{frac}"
    numbers = [f"{float(t):g}" for t in items]
    listed = ", ".join(numbers[:-1]) + " and " + numbers[-1]
    unit = f" {unit}" if unit and unit != "-" else ""
    escape = (f" To sweep the two values {listed}{unit}, write one with a decimal point ({name}={whole}.0,{frac})."
              if len(items) == 2 else "")
    raise InputError(f"--vary {name}={text}: this reads as the values {listed}{unit}, but '{whole},{frac}' looks "
                     f"like the number {meant} written with a decimal comma; if you meant {meant} write a decimal "
                     f"point ({name}={meant}); values are separated by commas.{escape}")


def parse_vary(items, scene) -> list[Axis]:
    """The varied names and values -> axes; InputError naming the bad item and what is allowed.

    ``items``: ``NAME=V1,V2,...`` strings (the command line), or a mapping {name: values}
    (``cfm.sweep(vary={"k2": [1.6, 1.8]})``). Values must be finite numbers, each given once;
    command-line values that look like a number with a decimal comma (``thickness=0,005``) are
    refused (:func:`check_decimal_comma`), and every error about a comma-separated list says
    that values are separated by commas.
    """
    units = variable_units(scene)
    given = not isinstance(items, Mapping)  # command-line strings: their text is shown in messages
    if isinstance(items, Mapping):
        pairs = [(str(k), list(v) if isinstance(v, (list, tuple, range)) or hasattr(v, "tolist") else [v], str(k))
                 for k, v in items.items()]
    else:
        pairs = []
        for item in items or []:
            name, sep, text = str(item).partition("=")
            if not sep or not name.strip():
                raise InputError(f"--vary expects NAME=V1,V2,... (SI units), got {item!r}.")
            pairs.append((name.strip(), text.split(","), text))
            if name.strip() in units:
                check_decimal_comma(name.strip(), text, units[name.strip()])
    axes, seen = [], set()
    for name, raw, text in pairs:
        if name not in units:
            raise InputError(f"--vary {name}: unknown name; a drop-test sweep can vary the scene values "
                             f"{', '.join(SCENE_KEYS)} and the parameters of material "
                             f"'{scene.material.name}': {', '.join(n for n in units if n not in SCENE_KEYS)}.")
        if name in seen:
            raise InputError(f"--vary {name} is given twice; put all its values in one --vary.")
        seen.add(name)
        values = [_number(name, v, units[name], text if given else v)
                  for v in (raw.tolist() if hasattr(raw, "tolist") else raw)]
        if not values:
            raise InputError(f"--vary {name}: no values; give NAME=V1,V2,...")
        if len(set(values)) != len(values):
            raise InputError(f"--vary {name}: a value is repeated in {text!r}; give each value once."
                             f"{_comma_hint(text)}")
        axes.append(Axis(name, units[name], tuple(values), text if given else None))
    if not axes:
        raise InputError("a sweep needs at least one --vary NAME=V1,V2,... (SI units).")
    impactor = getattr(scene, "impactor", None)
    if any(a.name == "velocity" for a in axes) and isinstance(getattr(impactor, "velocity", None), (tuple, list)):
        vx, vy, vz = (float(c) for c in impactor.velocity)
        spec = (f"velocity = {math.hypot(vx, vy, vz):.6g}, angle = {math.degrees(math.atan2(math.hypot(vx, vy), -vz)):.6g}"
                + (f", azimuth = {math.degrees(math.atan2(vy, vx)):.6g}" if vy else ""))
        raise InputError(f"--vary velocity: the scene's impactor velocity is the vector {list(impactor.velocity)} m/s; "
                         f"a swept speed would replace it by a vertical impact. To sweep the speed of this oblique "
                         f"impact, give the scene's [impactor] velocity as a speed with an angle ({spec}).")
    layers = getattr(getattr(scene, "specimen", None), "layers", None)
    if layers and any(a.name == "thickness" for a in axes):
        raise InputError(f"--vary thickness: the specimen is layered ({len(layers)} [[specimen.layers]]); its thickness "
                         f"is the sum of the layers' and a sweep cannot tell which layer to change. Write one scene "
                         f"per thickness, or sweep a material parameter.")
    refuse_unused(scene, [a.name for a in axes if a.name == "density" or a.name not in SCENE_KEYS],
                  lambda name: f"--vary {name}", "every run would be the same, labelled with values never applied")
    return axes


def cases(axes: list[Axis]) -> list[dict]:
    """The cartesian product of the axes' values, as {name: value}; the last axis runs fastest."""
    return [dict(zip((a.name for a in axes), combo)) for combo in itertools.product(*(a.values for a in axes))]


def case_scene(scene, case: dict):
    """The scene of one case with its material bound once (InputError for a value out of range)."""
    sc = scene.with_overrides(**overrides(case))
    m = sc.material
    make_material(m.name, m.parameter_dict, m.moduli, m.elastic)
    return sc


def check_cases(scene, axes: list[Axis]) -> None:
    """Validate every case before any run: each case's scene is built and its material bound.

    Each axis value is first checked alone (a scene or material value out of range is named with
    its axis); then every combination, for ranges that depend on several values (e.g. the Prony
    coefficients' sum). Raises InputError naming the first bad value(s) and the section's rule.
    """
    for axis in axes:
        for v in axis.values:
            try:
                case_scene(scene, {axis.name: v})
            except (InputError, ValueError) as exc:
                unit = "" if axis.unit in ("", "-") else f" {axis.unit}"  # every digit: 0.470999 hid 0.4709990000000001
                raise InputError(f"--vary {axis.name}: value {shown(v)}{unit} is not allowed, so no run was "
                                 f"started: {exc}{_comma_hint(axis.text)}") from None
    if len(axes) > 1:
        for case in cases(axes):
            try:
                case_scene(scene, case)
            except (InputError, ValueError) as exc:
                raise InputError(f"--vary: the combination {_describe(case, axes)} is not allowed, so no run "
                                 f"was started: {exc}") from None


def check_backend(scene, axes: list[Axis], backend: str) -> None:
    """The backend's own model checks (``Backend.check_model``: e.g. skfem's frictionless contact)
    before any run, so that a sweep the backend cannot run is an InputError (exit 2), not a table of
    failed runs. The model of the scene as given is checked, and one per value of each scene axis
    (thickness, friction, ...; material parameters do not change what a backend accepts): at most
    one model build per scene value, not per combination.

    Parameters
    ----------
    scene : Scene
        The sweep's drop-test scene.
    axes : list of Axis
        The varied names and values (already checked by :func:`check_cases`).
    backend : str
        Backend name.

    Raises
    ------
    InputError
        The backend refuses a case's model; names the axis value.
    """
    from ..scene.builder import build_model
    from ..simulation.registry import backend_for

    be = backend_for(backend)
    first = first_values_scene(scene, axes)
    checks = [(None, first)] + [((a, v), scene.with_overrides(**overrides({a.name: v})))
                                for a in axes if a.name in SCENE_KEYS for v in a.values]
    for which, sc in checks:
        try:
            be.check_model(build_model(sc))
        except InputError as exc:
            where = ("the scene" + (" (each swept parameter at its first value)" if first is not scene else "") if which is None
                     else f"--vary {which[0].name}: value {which[1]:g} {which[0].unit}")
            raise InputError(f"{where} cannot run on backend '{backend}', so no run was started: {exc}") from None


def first_values_scene(scene, axes: list[Axis]):
    """The scene with every swept material parameter at its first value (the scene itself when none is
    swept): what to check or record for the sweep's material rather than the bare scene, which one of
    the swept values may be what makes valid (a scene with g2 = 0.5 beside the default g1 = 0.45 is
    not, swept over g1 = 0.3, 0.35 it is)."""
    materials = {a.name: a.values[0] for a in axes if a.name not in SCENE_KEYS}
    return scene.with_overrides(**overrides(materials)) if materials else scene


def estimate_seconds(scene, axes: list[Axis]) -> float:
    """Rough serial time of the sweep's drop tests on numba (s), from :data:`REFERENCE_RUN`.

    Each case's cost scales with its specimen volume / element_size^4 (elements x explicit steps);
    backends, machines and impact speeds differ, so read it as an order of magnitude.
    """
    ref = REFERENCE_RUN
    total = 0.0
    for case in cases(axes):
        sp = {k: case.get(k, getattr(scene.specimen, k)) for k in ("width", "thickness", "element_size")}
        volume = sp["width"] ** 2 * sp["thickness"]
        scale = (volume / ref["volume"]) * (ref["element_size"] / sp["element_size"]) ** 4
        total += RUN_OVERHEAD + ref["seconds"] * scale
    return total


# ----------------------------------------------------------------------------- run ids
def run_key(scene, backend: str, options: dict | None = None) -> dict:
    """What every run id of a sweep (or calibration) of ``scene`` shares: all that changes a result.

    Parameters
    ----------
    scene : Scene
        The base scene (before a case's values).
    backend : str
        Backend name.
    options : dict, optional
        Backend options given.

    Returns
    -------
    dict
        ``scene`` (its dict with the mesh path replaced by the file's content digest, or by the
        list of the digests of the file and of those it includes, for an .inp file with ``INPUT=``),
        ``material`` (definition digest, :func:`cfm_core.material.cache.definition_digest`),
        ``materials`` (the same of every material a layer or part names),
        ``backend`` and ``options`` (every option resolved,
        :func:`cfm_core.runs.provenance.resolved_options`), ``code``
        (:func:`cfm_core.fingerprint.source_digest`).

    Raises
    ------
    InputError
        Unknown backend, bad options, or the mesh file cannot be read.
    """
    d = scene_to_dict(scene)
    mesh = d.get("specimen", {}).get("mesh")
    if mesh:
        digests = scene_files(scene)
        found = list(digests.values())   # the mesh first, then the files an .inp includes
        d["specimen"] = dict(d["specimen"], mesh=found[0] if len(found) == 1 else found)
    return {"scene": d, "material": definition_digest(get_material(scene.material.name)),
            "materials": {n: definition_digest(get_material(n))
                          for n in sorted({r.material for _, r in regions(scene) if r.material})}, "backend": backend,
            "options": resolved_options(backend, options), "code": fingerprint.source_digest()}


def run_id(key: dict, case: dict) -> str:
    """Id (12 hex digits) of one run: the content digest of the :func:`run_key` and its values."""
    return fingerprint.digest({"key": key, "case": {k: repr(float(v)) for k, v in sorted(case.items())}}, 12)


# ----------------------------------------------------------------------------- the run cache
#: Summary figures every complete run writes (finite numbers): the pulse metrics (s, g), the step
#: count, the solver and run times (s). ``elements``, ``energy_error`` and ``hourglass_ratio`` may be
#: missing or null (backends without energies or hourglass modes) but are numbers when given.
CACHE_REQUIRED = ("peak_g", "t_peak", "duration", "pulse_width", "loading_time", "unloading_time", "steps",
                  "wall_time", "run_time")
#: Figures recomputed from a cached ``acceleration.csv`` that must equal its summary's.
CACHE_PULSE = ("peak_g", "t_peak", "duration", "pulse_width", "loading_time", "unloading_time")


def _finite_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(as_float(v))


def cached_summary(entry: Path, rid: str, case: dict) -> tuple[dict | None, str | None]:
    """The summary of a complete run in cache folder ``entry`` (``runs/<id>``), or why it is not one.

    Complete means everything a finished run writes (:func:`cfm_core.post.writers.write_drop_test`)
    is there and reads back: ``summary.json`` is a JSON object with ``run_id`` = ``rid``, the
    run's values under ``sweep`` (SI units), every :data:`CACHE_REQUIRED` figure a finite number
    and the optional table figures numbers or null; ``acceleration.csv`` has the header
    ``t [s],a_raw [m/s^2],a_cfc600 [m/s^2]``, at least two rows of finite numbers at increasing
    times, and gives the summary's pulse figures (:data:`CACHE_PULSE`) again
    (:func:`cfm_core.post.metrics.drop_test_metrics`, relative tolerance 1e-9).

    Parameters
    ----------
    entry : pathlib.Path
        The run's cache folder.
    rid : str
        Its run id (:func:`run_id`).
    case : dict
        Its values {name: value} (SI units).

    Returns
    -------
    summary : dict or None
        The summary when the entry is complete.
    damage : str or None
        None when the entry is complete or holds no summary.json (never finished, or failed);
        else one line saying what is wrong with it.
    """
    done = entry / "summary.json"
    if not entry.exists() and not entry.is_symlink():
        return None, None
    if not entry.is_dir():
        return None, "it is not a folder"
    if not done.exists() and not done.is_symlink():
        return None, None
    try:
        summary = json.loads(decode(done, done.read_bytes(), "JSON"))  # a byte-order mark skipped
    except (OSError, InputError) as exc:  # InputError: not UTF-8 (tables.decode)
        return None, f"summary.json cannot be read ({getattr(exc, 'strerror', None) or exc})"
    except ValueError as exc:
        return None, f"summary.json is not valid JSON ({exc})"
    if not isinstance(summary, dict):
        return None, "summary.json does not hold a JSON object"
    if summary.get("run_id") != rid:
        return None, f"summary.json names run {summary.get('run_id')!r}, not {rid!r}"
    values = summary.get("sweep")
    if not isinstance(values, dict) or values != {k: float(v) for k, v in case.items()}:
        return None, f"summary.json holds the values {values!r}, not {case!r}"
    bad = [k for k in CACHE_REQUIRED if not _finite_number(summary.get(k))]
    bad += [k for k in SUMMARY_COLUMNS if k not in CACHE_REQUIRED and summary.get(k) is not None
            and not _finite_number(summary.get(k))]
    if bad:
        return None, f"summary.json lacks finite numbers for {', '.join(bad)}"
    try:
        table = read_history(entry / "acceleration.csv", tuple(DROP_TEST_COLUMN_UNITS), DROP_TEST_COLUMN_UNITS,
                             exact=True, what="cached acceleration history")
        if table.data.shape[0] < 2:
            return None, "acceleration.csv has fewer than 2 rows"
        again = drop_test_metrics(table.column("t"), table.column("a_cfc600"), table.column("a_raw"))
    except (ValueError, OSError) as exc:  # InputError: missing, unreadable or malformed file
        return None, " ".join(str(exc).split())
    differ = [k for k in CACHE_PULSE if not math.isclose(again[k], summary[k], rel_tol=1e-9, abs_tol=1e-15)]
    if differ:
        return None, f"acceleration.csv does not give the summary's {', '.join(differ)} (incomplete or altered)"
    return summary, None


def _discard(entry: Path) -> None:
    """Remove a damaged cache entry's files (``entry`` itself when it is not a folder)."""
    if entry.is_dir() and not entry.is_symlink():
        for name in ("summary.json", "acceleration.csv"):
            f = entry / name
            if f.is_dir() and not f.is_symlink():
                shutil.rmtree(f)
            elif f.exists() or f.is_symlink():
                f.unlink()
    elif entry.exists() or entry.is_symlink():
        entry.unlink()


# ----------------------------------------------------------------------------- the sweep
def _row(rid: str, case: dict, summary: dict | None, error: str | None) -> dict:
    row = {"run_id": rid, **case, "status": "ok" if error is None else "failed", "error": error or "",
           "warnings": " | ".join((summary or {}).get("warnings", []))}  # a run cut short, high hourglass energy
    for key in SUMMARY_COLUMNS:
        row[key] = (summary or {}).get(key)
    return row


def _describe(case: dict, axes) -> str:
    return " ".join(f"{a.name}={shown(case[a.name])}" for a in axes)


def execute(scene, axes: list[Axis], backend: str = "numba", options: dict | None = None, runner=None,
            cache=None, progress=None):
    """Run (or resume) the sweep's drop tests; returns a :class:`~cfm_core.studies.outcomes.SweepOutcome`.

    cache: folder of the content-keyed run cache (``OUT/runs``; None: none, the histories are kept
    in memory). progress: a callable receiving one line per finished run, or an object with
    ``update(n)`` and ``close()`` (a tqdm bar), or None. Every case is validated first
    (:func:`check_cases`).
    """
    from .outcomes import SweepOutcome

    check_cases(scene, axes)
    runner = runner or SerialRunner()
    start = time.perf_counter()
    key = run_key(scene, backend, options)
    todo = cases(axes)
    ids = [run_id(key, c) for c in todo]
    rows: list = [None] * len(todo)
    pending = []
    cache = Path(cache) if cache is not None else None
    for i, (rid, case) in enumerate(zip(ids, todo)):
        summary, damage = cached_summary(cache / rid, rid, case) if cache is not None else (None, None)
        if summary is not None:
            rows[i] = _row(rid, case, summary, None)
            continue
        if damage is not None:
            print(f"note: run cache entry {cache / rid} ({_describe(case, axes)}) is damaged: {damage.rstrip('.')}; "
                  f"running it again", file=sys.stderr, flush=True)
            _discard(cache / rid)
        pending.append(i)
    result = SweepOutcome(scene, axes, backend, resolved_options(backend, options), rows, key,
                          skipped=len(todo) - len(pending), cache=cache)
    say = progress if callable(progress) else (lambda line: None)
    if result.skipped:
        say(f"{result.skipped} of {len(todo)} runs already complete in {cache}: skipped")
    tasks = [(scene, todo[i], backend, dict(options or {})) for i in pending]
    try:
        for n, done in enumerate(map_cases(runner, tasks), start=1):
            i = pending[done.index]
            rid, case = ids[i], todo[i]
            error = done.error
            if error is None:
                summary = dict(done.value["summary"], sweep=case, run_id=rid)
                try:
                    if cache is not None:
                        if done.value.get("scene_toml"):   # the run's own scene.toml: repeats it
                            write_text(cache / rid / "scene.toml", done.value["scene_toml"])
                        write_drop_test(cache / rid, done.value["t"], done.value["a_raw"], done.value["a_cfc"], summary)
                        (cache / rid / "failed.json").unlink(missing_ok=True)
                    else:
                        result.histories[rid] = (done.value["t"], done.value["a_raw"], done.value["a_cfc"], summary)
                        if done.value.get("scene_toml"):
                            result.scene_texts[rid] = done.value["scene_toml"]
                except (ValueError, RuntimeError) as exc:  # InputError, NumericalError: non-finite data
                    error = error_text(exc)
            if error is not None and cache is not None:
                (cache / rid).mkdir(parents=True, exist_ok=True)
                write_json(cache / rid / "failed.json", {"run_id": rid, "sweep": case, "error": error})
            rows[i] = _row(rid, case, done.value["summary"] if error is None else None, error)
            result.executed += 1
            if hasattr(progress, "update"):
                progress.update(1)
            what = (f"peak {rows[i]['peak_g']:.1f} g, {rows[i]['run_time']:.2f} s" if error is None
                    else f"FAILED: {error}")
            say(f"[{n + result.skipped}/{len(todo)}] {_describe(case, axes)}: {what} "
                f"({time.perf_counter() - start:.1f} s elapsed)")
    finally:
        if hasattr(progress, "close"):
            progress.close()
    result.wall = time.perf_counter() - start
    return result


def run_sweep(scene, axes: list[Axis], out, backend: str = "numba", runner=None, progress=None, options=None):
    """Run (or resume) a sweep into folder ``out`` and write its files (``cfm sweep``).

    The earlier files of a cfm output in ``out`` (an earlier sweep's table, plot, sweep.json) are
    removed before the first run, the run cache ``out/runs`` is kept for resuming; the new files
    are published when the sweep ends (:meth:`SweepOutcome.save`). runner: from
    :func:`cfm_core.studies.dask_runner.open_runner` (default: serial in this process); progress:
    callable receiving one line of text per finished run. Returns the SweepOutcome.
    """
    from .outcomes import clear_earlier_output

    check_cases(scene, axes)
    out = clear_earlier_output(out, keep=("runs",))
    result = execute(scene, axes, backend, options, runner, out / "runs", progress)
    result.files = result.save(out)
    return result
