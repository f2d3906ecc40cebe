"""Outputs of ``cfm fit`` (:mod:`cfm_core.studies.fit`): a plot per test, the drop-test scene with the
fitted material, and fit.json, written last so that its presence means a complete fit.

fit.json: material, moduli convention, elastic flag; per fitted parameter the start, fitted value,
unit, standard error, 95 % interval (null where withheld) and coordinate; the fixed values; the
correlation matrix and condition number; identifiability warnings; per test the file, kind, rate
(1/s), weight, rows, largest |stress| (Pa) and rel. RMS at the start and at the end; costs, status,
``evaluations`` (the optimiser's, summed over the starts: what ``max_evaluations`` limits per start),
``residual_evaluations`` (every one: the start's and the finite-difference Jacobian's included), wall
time (s) and every start tried (its ``evaluations``, ``converged``: false where it stopped at
``max_evaluations``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..material.registry import get_material
from ..post.plots import _COLOURS, _figure, _save, display, subtitled
from ..post.writers import write_json, write_text
from ..scene.scene import builtin_scene, scene_to_toml
from .fit import LabFitResult
from .lab_tests import KINDS, LabTest


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name)


def fitted_scene(result: LabFitResult, scene=None):
    """A drop-test scene with the fitted material.

    Parameters
    ----------
    result : LabFitResult
        The fit.
    scene : Scene, optional
        Drop-test scene to start from (default: the built-in one).

    Returns
    -------
    Scene
        The scene with the fitted material name, moduli convention, elastic flag and every parameter value.
    """
    scene = scene or builtin_scene("drop-test")
    return scene.with_overrides(material=result.material, moduli=result.moduli, elastic=result.elastic,
                                parameters=None).with_overrides(parameters=result.fitted)


def plot_test(path, test: LabTest, P_start, P_fit, phrases=()) -> None:
    """PNG of a test: measured, start and fitted nominal stress (Pa, shown in kPa) against stretch
    or shear (-), or against time (s) on a log axis for a relaxation test (the loading of
    milliseconds and the hold of seconds both visible). The measured curve is drawn wide and light
    under the thin fitted one, so that a close fit leaves it visible.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    test : LabTest
        The measured curve (against time for a relaxation test).
    P_start, P_fit : ndarray, shape (n,)
        Simulated nominal stress at the start and fitted values (Pa).
    phrases : sequence of str, optional
        Subtitle phrases (the fitted values).
    """
    fig, ax = _figure(subtitled(f"{test.name}: {test.kind}, {test.rate:g} 1/s", phrases))
    ax.set_ylabel("Nominal stress (kPa)")
    if test.kind == "relaxation":
        keep = np.asarray(test.t) > 0.0  # a log time axis: the sample at t = 0 cannot be shown
        x = np.asarray(test.t)[keep]
        ax.set_xscale("log")
        ax.set_xlabel("Time (s)")
    else:
        keep = slice(None)
        x = np.asarray(test.x)
        ax.set_xlabel(f"{KINDS[test.kind][0].capitalize()} (-)")
    kpa = 1e-3
    ax.plot(x, kpa * np.asarray(test.P)[keep], color="0.72", linewidth=4.0, solid_capstyle="butt",
            label="measured")
    ax.plot(x, kpa * np.asarray(P_start)[keep], color=_COLOURS[1], linewidth=1.2, linestyle=(0, (4, 2)),
            label="start")
    ax.plot(x, kpa * np.asarray(P_fit)[keep], "-", color=_COLOURS[0], linewidth=1.3, label="fitted")
    ax.legend(loc="best", fontsize=8, framealpha=0.95, edgecolor="0.8")
    _save(fig, path)


def _fitted_phrases(result: LabFitResult) -> list[str]:
    """``name = fitted unit (start value)`` per fitted parameter, in the units figures show."""
    phrases = []
    for n, u in zip(result.coords.names, result.coords.units):
        factor, shown = display(u)
        unit = f" {shown}" if shown else ""
        phrases.append(f"{n} = {result.fitted[n] * factor:.4g}{unit} (start {result.start[n] * factor:.4g}{unit})")
    return phrases


def write_lab_fit(out, result: LabFitResult, scene=None, settings: dict | None = None) -> list[Path]:
    """Write fit_<test>.png, fitted-scene.toml and, last, fit.json into ``out`` (fit.json means complete).

    Parameters
    ----------
    out : str or Path
        Output directory (created).
    result : LabFitResult
        The fit.
    scene : Scene, optional
        Drop-test scene fitted-scene.toml starts from (default: built-in).
    settings : dict, optional
        Extra entries for fit.json (e.g. total time).

    Returns
    -------
    list of Path
        The written files (:meth:`cfm_core.studies.outcomes.LabFitOutcome.save` writes them into
        the stage of a staged folder, published whole).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for t, s, f in zip(result.tests, result.P_start, result.P_fit):
        path = out / f"fit_{_safe(t.name)}.png"
        plot_test(path, t, s, f, _fitted_phrases(result))
        files.append(path)
    text = scene_to_toml(fitted_scene(result, scene))
    head = "".join(f"# material fitted by cfm fit to {t.path} ({t.kind}, {t.rate:g} 1/s)\n" for t in result.tests)

    files.append(write_text(out / "fitted-scene.toml", head + text))
    conf = result.confidence["parameters"]
    params = {}
    for n, u, lg in zip(result.coords.names, result.coords.units, result.coords.log):
        params[n] = {"start": result.start[n], "fitted": result.fitted[n], "unit": u, "std": conf[n]["std"],
                     "ci95": conf[n]["ci"], "coordinate": "log" if lg else "linear",
                     "interval": "withheld (see the warnings)" if n in result.withheld else "ok"}
    decl = {p.name: p.unit for p in get_material(result.material).parameters}
    fixed = {n: {"value": v, "unit": decl[n]} for n, v in result.fitted.items() if n not in params}
    tests = [{"name": t.name, "file": t.path, "kind": t.kind, "rate": t.rate, "weight": t.weight, "rows": int(t.t.size),
              "peak_stress": t.scale, "rel_rms_start": s, "rel_rms": e}
             for t, s, e in zip(result.tests, result.rel_rms("start"), result.rel_rms())]
    data = {"material": result.material, "moduli": result.moduli, "elastic": result.elastic,
            "parameters": params, "fixed": fixed, "names": list(result.coords.names),
            "correlation": result.confidence["correlation"], "cond_JTJ": result.confidence["cond_JTJ"],
            "identifiability_warnings": result.warnings, "at_bound": result.confidence.get("at_bound", {}),
            "tests": tests, "cost_start": result.cost_start,
            "cost": result.cost, "status": result.status, "evaluations": result.evaluations,
            "residual_evaluations": result.residual_evaluations, "wall_time": result.wall,
            "dof": result.confidence["dof"], "starts": result.tried,
            **(settings or {}),
            "units": {"rate": "1/s", "peak_stress": "Pa", "rel_rms": "-", "cost": "-", "wall_time": "s", "max_evaluations": "-",
                      "evaluations": "-", "residual_evaluations": "-",
                      "parameters": "SI (see each parameter's unit)"}}
    files.append(write_json(out / "fit.json", data))
    return files
