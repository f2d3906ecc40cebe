"""Outputs of ``cfm fit`` (:mod:`cfm_core.studies.fit`): a plot per test, the drop-test scene with the
fitted material, and fit.json, written last so that its presence means a complete fit.

fit.json: material, moduli convention, elastic flag; per fitted parameter the start, fitted value,
unit, standard error, 95 % interval (null where withheld) and coordinate; the fixed values; the
correlation matrix and condition number; identifiability warnings; per test the file, kind, rate
(1/s), weight, rows, largest |stress| (Pa) and rel. RMS at the start and at the end; costs, status,
evaluations, wall time (s) and every start tried.
"""

from __future__ import annotations

from pathlib import Path

from ..material.registry import get_material
from ..post.plots import _figure, _save
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


def plot_test(path, test: LabTest, P_start, P_fit) -> None:
    """PNG of a test: measured, start and fitted nominal stress (Pa) against stretch or shear (-).

    Parameters
    ----------
    path : str or Path
        Output PNG.
    test : LabTest
        The measured curve (against time for a relaxation test).
    P_start, P_fit : ndarray, shape (n,)
        Simulated nominal stress at the start and fitted values (Pa).
    """
    fig, ax = _figure(f"{test.name}: {test.kind}, {test.rate:g} 1/s")
    ax.set_xlabel(f"{KINDS[test.kind][0]} (-)" if test.kind != "relaxation" else "time (s)")
    ax.set_ylabel("nominal stress (Pa)")
    x = test.t if test.kind == "relaxation" else test.x
    ax.plot(x, test.P, "o", markersize=2.5, color="0.3", label="measured")
    ax.plot(x, P_start, "--", color="tab:orange", linewidth=1.2, label="start")
    ax.plot(x, P_fit, "-", color="tab:blue", linewidth=1.6, label="fitted")
    ax.legend(fontsize=8)
    _save(fig, path)


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
        plot_test(path, t, s, f)
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
            "wall_time": result.wall, "dof": result.confidence["dof"], "starts": result.tried,
            **(settings or {}),
            "units": {"rate": "1/s", "peak_stress": "Pa", "rel_rms": "-", "cost": "-", "wall_time": "s",
                      "parameters": "SI (see each parameter's unit)"}}
    files.append(write_json(out / "fit.json", data))
    return files
