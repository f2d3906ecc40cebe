"""Parameter sweeps of the drop test: every combination of some scene and material values.

A sweep varies names of the drop-test scene (:data:`SCENE_KEYS`: thickness, velocity, ... in SI
units) and parameters of its material (``cfm``: c, k1, k2, kappa, g1, tau1, g2, tau2, g3, tau3) over
given values, runs the cartesian product (the last ``--vary`` changes fastest) on a runner of
:mod:`cfm_core.studies.dask_runner`, and writes into ``out``:

- ``runs/<id>/acceleration.csv`` and ``summary.json`` per run (:func:`writers.write_drop_test`;
  the summary, written last, also holds the run's values under ``sweep``), or
  ``runs/<id>/failed.json`` (values and error text) for a run that failed;
- ``sweep.csv`` (and ``sweep.parquet`` when pyarrow is installed): one row per run, in product
  order, with the varied values, ``status`` ("ok" | "failed"), ``error`` and the summary figures.
  Headers carry the units: ``thickness [m]``, ``k1 [Pa]``, ``peak_g [g]``; ``run_time [s]`` is
  the whole run (model build, solver, post-processing), ``wall_time [s]`` the solver only;
- ``peaks.png``: peak acceleration against the first varied name, one line per combination of
  the others.

The run id is a hash of the scene, the backend and the run's values, so rerunning the command
skips every run whose ``summary.json`` exists (a changed scene or backend gives new ids); failed
runs are run again. Every run is validated where it runs: a value out of range fails that run
only, with the InputError's text in the table.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .dask_runner import Done, SerialRunner, error_text
from ..errors import InputError
from ..scene.scene import _UNITS as SCENE_UNITS
from ..scene.scene import scene_to_dict
from ..post.writers import atomic_write, output_folder, write_drop_test, write_json
from ..material.registry import get_material
from ..runs import pipeline as simulate
from ..post import SUMMARY_UNITS
from ..post.plots import _COLOURS, _figure, _save, display, display_text

#: Scene keys a sweep can vary (SI units, see cfm_core/scene/scenes/drop-test.toml).
SCENE_KEYS = ("thickness", "velocity", "element_size", "width", "mass", "radius", "density", "friction")
#: Summary figures copied into the table, in this order.
SUMMARY_COLUMNS = ("peak_g", "t_peak", "duration", "pulse_width", "loading_time", "unloading_time",
                   "steps", "elements", "wall_time", "energy_error", "hourglass_ratio", "run_time")


@dataclass(frozen=True)
class Axis:
    """One varied name with its unit and values (SI)."""

    name: str
    unit: str
    values: tuple


@dataclass
class SweepResult:
    """Rows of the table (dicts, product order) and counts of this invocation."""

    rows: list
    axes: list
    executed: int = 0
    skipped: int = 0
    wall: float = 0.0
    files: list = field(default_factory=list)

    @property
    def failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)


# ----------------------------------------------------------------------------- what to run
def variable_units(scene) -> dict:
    """{name: unit} of everything a sweep (or a fit) of this drop-test scene can vary."""

    if scene.type != "drop-test":
        raise InputError(f"sweeps and calibrations run drop tests; the scene is a '{scene.type}' scene.")
    units = {k: SCENE_UNITS[k].split(",")[0] for k in SCENE_KEYS}
    for p in get_material(scene.material.name).parameters:
        units.setdefault(p.name, p.unit)
    return units


def parse_vary(items, scene) -> list[Axis]:
    """``NAME=V1,V2,...`` strings -> axes; InputError naming the bad item and what is allowed."""
    units = variable_units(scene)
    axes, seen = [], set()
    for item in items or []:
        name, sep, text = str(item).partition("=")
        name = name.strip()
        if not sep or not name:
            raise InputError(f"--vary expects NAME=V1,V2,... (SI units), got {item!r}.")
        if name not in units:
            raise InputError(f"--vary {name}: unknown name; a drop-test sweep can vary the scene values "
                             f"{', '.join(SCENE_KEYS)} and the parameters of material "
                             f"'{scene.material.name}': {', '.join(n for n in units if n not in SCENE_KEYS)}.")
        if name in seen:
            raise InputError(f"--vary {name} is given twice; put all its values in one --vary.")
        seen.add(name)
        values = []
        for v in text.split(","):
            try:
                values.append(float(v))
            except ValueError:
                raise InputError(f"--vary {name}: value {v.strip()!r} is not a number "
                                 f"({units[name]}); give NAME=V1,V2,...") from None
        if len(set(values)) != len(values):
            raise InputError(f"--vary {name}: a value is repeated in {text!r}; give each value once.")
        axes.append(Axis(name, units[name], tuple(values)))
    if not axes:
        raise InputError("a sweep needs at least one --vary NAME=V1,V2,... (SI units).")
    return axes


def cases(axes: list[Axis]) -> list[dict]:
    """The cartesian product of the axes' values, as {name: value}; the last axis runs fastest."""
    return [dict(zip((a.name for a in axes), combo)) for combo in itertools.product(*(a.values for a in axes))]


def overrides(case: dict) -> dict:
    """{name: value} -> keyword arguments of :meth:`Scene.with_overrides` (scene keys, parameters)."""
    over = {k: v for k, v in case.items() if k in SCENE_KEYS}
    params = {k: v for k, v in case.items() if k not in SCENE_KEYS}
    if params:
        over["parameters"] = params
    return over


def run_id(scene, backend: str, case: dict) -> str:
    """Stable id (12 hex digits) of one run: hash of the scene, the backend and the values."""
    key = json.dumps({"scene": scene_to_dict(scene), "backend": backend,
                      "case": {k: repr(float(v)) for k, v in sorted(case.items())}}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:12]


def run_case(task) -> dict:
    """Run one drop test; task = (scene, {name: value}, backend). Runs on a Dask worker.

    Returns t (s), a_raw and a_cfc (m/s^2) and the summary (with ``run_time``, s, end to end).
    Errors (invalid values, numerical failures) propagate; the runner records them.
    """

    scene, case, backend = task
    start = time.perf_counter()
    outcome = simulate.drop_test(scene.with_overrides(**overrides(case)), backend)
    return _case_result(outcome, time.perf_counter() - start)


def _case_result(outcome, run_time: float) -> dict:
    """What a finished run of a case returns: t (s), a_raw and a_cfc (m/s^2) and the summary with
    ``run_time`` (s) added to it and to its units."""
    summary = dict(outcome.summary, run_time=run_time)
    summary["units"] = dict(summary.get("units", {}), run_time="s")
    return {"t": outcome.t, "a_raw": outcome.a_raw, "a_cfc": outcome.a_cfc, "summary": summary}


def run_cases(task) -> list:
    """Run drop tests as a batch; task = ([scene, ...], backend, models). Runs on a worker.

    The scenes share a mesh (grouped by :func:`map_cases`) and go through the backend's ``run_batch``
    (:func:`cfm_core.runs.pipeline.drop_tests`); models: their models, built by :func:`map_cases`
    (a runner in this process), or None (built here: models do not travel to other processes).
    Returns, per run, (True, the dict of :func:`run_case`) or (False, error text); ``run_time`` is
    the batch's time divided by its size.
    """
    scenes, backend, models = task
    start = time.perf_counter()
    outcomes = simulate.drop_tests(scenes, backend, models=models)
    share = (time.perf_counter() - start) / max(len(scenes), 1)
    return [(False, error_text(outcome)) if isinstance(outcome, Exception) else (True, _case_result(outcome, share))
            for outcome in outcomes]


def batches(backend: str) -> bool:
    """Whether ``backend`` runs drop tests sharing a mesh as one batch (has ``run_batch``)."""
    try:
        return hasattr(simulate.backend_for(backend), "run_batch")
    except InputError:
        return False


def map_cases(runner, tasks: list, batch_size: int = 64):
    """Done objects of the drop tests ``tasks`` = [(scene, case, backend)], in completion order.

    On a backend with ``run_batch`` (torch) the tasks whose models share a mesh
    (:func:`cfm_core.runs.pipeline.batch_key`) are sent to the runner as batches of at most
    ``batch_size`` (:func:`run_cases`), else one by one (:func:`run_case`); either way each task
    gets its own Done with its index in ``tasks``. The models are built once, here; a runner in this
    process (``runner.in_process``) runs them, others build them again where they run. A task whose
    model cannot be built (an invalid value) is done at once, with its error.
    """
    if not tasks or not batches(tasks[0][2]):
        yield from runner.map(run_case, tasks)
        return
    scenes, models = [], []
    for scene, case, _ in tasks:
        try:
            scenes.append(scene.with_overrides(**overrides(case)))
        except (ValueError, RuntimeError) as exc:  # an invalid value: that run fails alone
            scenes.append(None)
            models.append(exc)
            continue
        models += simulate.drop_test_models(scenes[-1:])
    for i, model in enumerate(models):
        if isinstance(model, Exception):
            yield Done(i, error=error_text(model))
    keys = [None if isinstance(m, Exception) else (t[2], simulate.batch_key(m)) for t, m in zip(tasks, models)]
    parts = simulate.batch_groups(keys, batch_size)
    local = getattr(runner, "in_process", False)
    items = [([scenes[i] for i in members], tasks[members[0]][2], [models[i] for i in members] if local else None)
             for members in parts]
    for done in runner.map(run_cases, items):
        members = parts[done.index]
        if not done.ok:
            for i in members:
                yield Done(i, error=done.error)
            continue
        for i, (ok, value) in zip(members, done.value):
            yield Done(i, value) if ok else Done(i, error=value)


def run_all(runner, tasks: list, failure) -> list:
    """The results of the drop tests ``tasks`` = [(scene, case, backend)] in task order, or an error.

    Parameters
    ----------
    runner : SerialRunner or DaskRunner
        Where the drop tests run (:func:`map_cases`: batches where the backend can).
    tasks : list of tuple
        (scene, {name: value} in SI units, backend name) per drop test.
    failure : callable
        ``failure(index, error text) -> Exception`` for a task that failed.

    Returns
    -------
    list of dict
        Per task, the dict of :func:`run_case`: t (s), a_raw and a_cfc (m/s^2), summary.

    Raises
    ------
    Exception
        ``failure(...)`` of the first task that fails (the tasks left are not waited for).
    """
    out: list = [None] * len(tasks)
    for done in map_cases(runner, tasks):
        if not done.ok:
            raise failure(done.index, done.error)
        out[done.index] = done.value
    return out


# ----------------------------------------------------------------------------- the sweep
def _row(rid: str, case: dict, summary: dict | None, error: str | None) -> dict:
    row = {"run_id": rid, **case, "status": "ok" if error is None else "failed", "error": error or ""}
    for key in SUMMARY_COLUMNS:
        row[key] = (summary or {}).get(key)
    return row


def _describe(case: dict, axes) -> str:
    return " ".join(f"{a.name}={case[a.name]:g}" for a in axes)


def run_sweep(scene, axes: list[Axis], out, backend: str = "numba", runner=None, progress=None) -> SweepResult:
    """Run (or resume) a sweep into folder ``out``; see the module docstring.

    runner: from :func:`cfm_core.studies.dask_runner.open_runner` (default: serial in this process).
    progress: callable receiving one line of text per finished run (e.g. printing to stderr).
    """
    runner = runner or SerialRunner()
    out = output_folder(out, create=False)
    start = time.perf_counter()
    todo = cases(axes)
    ids = [run_id(scene, backend, c) for c in todo]
    rows: list = [None] * len(todo)
    pending = []
    for i, (rid, case) in enumerate(zip(ids, todo)):
        done = out / "runs" / rid / "summary.json"
        if done.is_file():
            rows[i] = _row(rid, case, json.loads(done.read_text(encoding="utf-8")), None)
        else:
            pending.append(i)
    result = SweepResult(rows, axes, skipped=len(todo) - len(pending))
    say = progress or (lambda line: None)
    if result.skipped:
        say(f"{result.skipped} of {len(todo)} runs already complete in {out}/runs: skipped")
    tasks = [(scene, todo[i], backend) for i in pending]
    for n, done in enumerate(map_cases(runner, tasks), start=1):
        i = pending[done.index]
        rid, case = ids[i], todo[i]
        folder = out / "runs" / rid
        error = done.error
        if error is None:
            try:
                summary = dict(done.value["summary"], sweep=case, run_id=rid)
                write_drop_test(folder, done.value["t"], done.value["a_raw"], done.value["a_cfc"], summary)
                (folder / "failed.json").unlink(missing_ok=True)
            except (ValueError, RuntimeError) as exc:  # InputError, NumericalError: non-finite data
                error = error_text(exc)
        if error is not None:
            folder.mkdir(parents=True, exist_ok=True)
            write_json(folder / "failed.json", {"run_id": rid, "sweep": case, "error": error})
        rows[i] = _row(rid, case, done.value["summary"] if error is None else None, error)
        result.executed += 1
        wall = time.perf_counter() - start
        what = (f"peak {rows[i]['peak_g']:.1f} g, {rows[i]['run_time']:.2f} s" if error is None
                else f"FAILED: {error}")
        say(f"[{n + result.skipped}/{len(todo)}] {_describe(case, axes)}: {what} ({wall:.1f} s elapsed)")
    result.files = write_table(out, rows, axes)
    if any(r["status"] == "ok" for r in rows):
        plot_peaks(out / "peaks.png", rows, axes, f"{scene.settings.name}, {backend}")
        result.files.append(out / "peaks.png")
    result.wall = time.perf_counter() - start
    return result


# ----------------------------------------------------------------------------- the table
def columns(axes: list[Axis]) -> list[tuple[str, str]]:
    """(key, header) of the table: run_id, the varied names, status, error, summary figures."""

    units = {**{k: u.split(" ")[0] for k, u in SUMMARY_UNITS.items()}, "run_time": "s"}
    return ([("run_id", "run_id")] + [(a.name, f"{a.name} [{a.unit}]") for a in axes]
            + [("status", "status"), ("error", "error")]
            + [(k, f"{k} [{units.get(k, '-')}]") for k in SUMMARY_COLUMNS])


TEXT_COLUMNS = ("run_id", "status", "error")


def table_frame(rows: list, axes: list[Axis]) -> pd.DataFrame:
    """The sweep table as a DataFrame: one row per run, columns ``name [unit]`` (SI units),
    text columns run_id, status, error; numbers as float (NaN where a run has no value)."""
    cols = columns(axes)
    data = {h: [r[k] for r in rows] for k, h in cols}
    frame = pd.DataFrame(data, columns=[h for _, h in cols])
    for k, h in cols:
        frame[h] = frame[h].astype("string") if k in TEXT_COLUMNS else pd.to_numeric(frame[h], errors="coerce")
    return frame


def write_table(out: Path, rows: list, axes: list[Axis]) -> list[Path]:
    """Write sweep.csv and, with pyarrow installed, sweep.parquet atomically; returns the paths.

    Both hold the same table (:func:`table_frame`); ``pandas.read_csv(path)`` and
    ``pandas.read_parquet(path)`` read it back. Floats are written with 17 significant digits
    (exact round trip)."""
    frame = table_frame(rows, axes)
    out.mkdir(parents=True, exist_ok=True)
    files = [atomic_write(out / "sweep.csv", lambda tmp: frame.to_csv(tmp, index=False, float_format="%.17g",
                                                                        lineterminator="\n"))]
    try:  # parquet needs pyarrow (in the 'dask' and 'all' extras); the CSV is the complete record
        files.append(atomic_write(out / "sweep.parquet", lambda tmp: frame.to_parquet(tmp, index=False)))
    except ImportError:
        pass
    return files


def read_table(path) -> list[dict]:
    """Rows of a sweep.csv as dicts keyed by header; numbers as floats, empty cells as None."""
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    rows = frame.to_dict("records")
    for r in rows:
        for k, v in r.items():
            if k not in TEXT_COLUMNS:
                r[k] = float(v) if v != "" else None
    return rows


def plot_peaks(path, rows: list, axes: list[Axis], title: str) -> None:
    """PNG of peak acceleration (g) against the first varied name, one line per other combination."""

    first, others = axes[0], axes[1:]
    fig, ax = _figure(f"Peak acceleration, {title}")
    xfactor, xunit = display(first.unit)
    ax.set_xlabel(f"{first.name} ({xunit})" if xunit else first.name)
    ax.set_ylabel("Peak impactor acceleration, CFC 600 (g)")
    groups: dict = {}
    for r in rows:
        groups.setdefault(tuple(r[a.name] for a in others), []).append(r)
    for j, (key, group) in enumerate(groups.items()):
        x = xfactor * np.array([r[first.name] for r in group])
        y = np.array([r["peak_g"] if r["status"] == "ok" else math.nan for r in group])
        label = ", ".join(display_text(a.name, v, a.unit) for a, v in zip(others, key)) or None
        ax.plot(x, y, "o-", color=_COLOURS[j % len(_COLOURS)], linewidth=1.5, markersize=4, label=label)
    if others and len(groups) <= 16:
        ax.legend(fontsize=7, frameon=False, ncols=1 + len(groups) // 9)
    _save(fig, path)
