"""Running drop tests of a study on a runner: one by one, or as batches where the backend can.

A task is (scene, {name: value} in SI units, backend[, backend options]); :func:`map_cases`
yields a :class:`~cfm_core.studies.dask_runner.Done` per task, :func:`run_all` the results in
task order. Used by sweeps (:mod:`cfm_core.studies.sweep`) and calibrations
(:mod:`cfm_core.studies.calibrate`).
"""

from __future__ import annotations

import time

from ..errors import InputError
from ..runs import pipeline as simulate
from .dask_runner import Done, error_text


def overrides(case: dict) -> dict:
    """{name: value} -> keyword arguments of :meth:`Scene.with_overrides` (scene keys, parameters)."""
    from .sweep import SCENE_KEYS

    over = {k: v for k, v in case.items() if k in SCENE_KEYS}
    params = {k: v for k, v in case.items() if k not in SCENE_KEYS}
    if params:
        over["parameters"] = params
    return over


def _task(task):
    scene, case, backend = task[:3]
    return scene, case, backend, (task[3] if len(task) > 3 else None) or {}


def run_case(task) -> dict:
    """Run one drop test; task = (scene, {name: value}, backend[, options]). Runs on a Dask worker.

    Returns t (s), a_raw and a_cfc (m/s^2) and the summary (with ``run_time``, s, end to end).
    Errors (invalid values, numerical failures) propagate; the runner records them.
    """

    scene, case, backend, options = _task(task)
    start = time.perf_counter()
    outcome = simulate.drop_test(scene.with_overrides(**overrides(case)), backend, **options)
    return _case_result(outcome, time.perf_counter() - start)


def _case_result(outcome, run_time: float) -> dict:
    """What a finished run of a case returns: t (s), a_raw and a_cfc (m/s^2), the summary with
    ``run_time`` (s) added to it and to its units, and ``scene_toml``: the text of the run's
    ``scene.toml`` (the resolved scene with its [run] section, which repeats the run)."""
    from ..scene.scene import scene_to_toml

    summary = dict(outcome.summary, run_time=run_time)
    summary["units"] = dict(summary.get("units", {}), run_time="s")
    return {"t": outcome.t, "a_raw": outcome.a_raw, "a_cfc": outcome.a_cfc, "summary": summary,
            "scene_toml": scene_to_toml(outcome.scene)}


def run_cases(task) -> list:
    """Run drop tests as a batch; task = ([scene, ...], backend, models[, options]). Runs on a worker.

    The scenes share a mesh (grouped by :func:`map_cases`) and go through the backend's ``run_batch``
    (:func:`cfm_core.runs.pipeline.drop_tests`); models: their models, built by :func:`map_cases`
    (a runner in this process), or None (built here: models do not travel to other processes).
    Returns, per run, (True, the dict of :func:`run_case`) or (False, error text); ``run_time`` is
    the batch's time divided by its size.
    """
    scenes, backend, models = task[:3]
    options = (task[3] if len(task) > 3 else None) or {}
    start = time.perf_counter()
    outcomes = simulate.drop_tests(scenes, backend, models=models, **options)
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
    """Done objects of the drop tests ``tasks`` = [(scene, case, backend[, options])], in completion order.

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
    for task in tasks:
        scene, case, _, _ = _task(task)
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
    items = [([scenes[i] for i in members], tasks[members[0]][2], [models[i] for i in members] if local else None,
              _task(tasks[members[0]])[3]) for members in parts]
    for done in runner.map(run_cases, items):
        members = parts[done.index]
        if not done.ok:
            for i in members:
                yield Done(i, error=done.error)
            continue
        for i, (ok, value) in zip(members, done.value):
            yield Done(i, value) if ok else Done(i, error=value)


def run_all(runner, tasks: list, failure) -> list:
    """The results of the drop tests ``tasks`` = [(scene, case, backend[, options])] in task order.

    Parameters
    ----------
    runner : SerialRunner or DaskRunner
        Where the drop tests run (:func:`map_cases`: batches where the backend can).
    tasks : list of tuple
        (scene, {name: value} in SI units, backend name[, backend options]) per drop test.
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


