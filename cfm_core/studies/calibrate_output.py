"""Outputs of ``cfm calibrate`` (:func:`cfm_core.studies.calibrate.fit`): a plot per curve, the objective
history, the scene with the fitted parameters, and fit.json, written last (its presence means complete).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..post import G0
from ..post.plots import _figure, _save, plot_overlay
from ..post.writers import write_json, write_text
from ..scene.scene import scene_to_toml

def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name)


def fitted_scene(scene, result):
    """The scene with the fitted parameter values (SI units)."""
    return scene.with_overrides(parameters=result.final.params)


def write_fit(out, scene, result, settings: dict | None = None) -> list[Path]:
    """Write the fit's outputs into folder ``out`` (created; :meth:`CalibrationOutcome.save` passes
    the stage of a staged folder); fit.json last (its presence means complete).

    fit_<curve>.png (measured, start and fitted filtered histories), objective.png (cost per
    evaluation), fitted-scene.toml (the scene with the fitted material, for ``cfm drop-test
    --scene``), fit.json (parameters with start, fitted value, unit, standard error and 95 %
    interval; correlation; per-curve rel. L2 at start and end; objective history; drop-test count).
    """

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    pb, files = result.problem, []
    for j, c in enumerate(pb.curves):
        path = out / f"fit_{_safe(c.name)}.png"
        plot_overlay(path, [("measured (CFC 600)", c.t, c.a), ("start", c.t, result.start.histories[j]),
                            ("fitted", c.t, result.final.histories[j])],
                     f"{c.name}, {1e3 * c.thickness:g} mm: rel. L2 {100 * result.final.rel_l2[j]:.2f} %")
        files.append(path)
    fig, ax = _figure("Objective history")
    for line in list(ax.lines):  # the figure's zero line has no place on a log axis
        line.remove()
    ax.relim()
    ax.set_xlabel("evaluation")
    ax.set_ylabel("cost 1/2 sum r^2 (-)")
    ax.semilogy([h["evaluation"] for h in pb.history], [max(h["cost"], 1e-300) for h in pb.history], "o-")
    _save(fig, out / "objective.png")
    files.append(out / "objective.png")
    text = scene_to_toml(fitted_scene(scene, result))
    head = "".join(f"# fitted to {c.path} ({c.thickness:g} m)\n" for c in pb.curves)

    files.append(write_text(out / "fitted-scene.toml", head + text))
    conf = result.confidence
    params = {n: {"start": result.start.params[n], "fitted": result.final.params[n], "unit": u,
                  "std": conf["parameters"][n]["std"], "ci95": conf["parameters"][n]["ci"],
                  **({"withheld": conf["parameters"][n]["withheld"]} if "withheld" in conf["parameters"][n] else {}),
                  "coordinate": "log" if lg else "linear"}
              for n, u, lg in zip(pb.coords.names, pb.coords.units, pb.coords.log)}
    curves = [{"name": c.name, "file": str(c.path), "thickness": c.thickness, "samples": int(c.t.size),
               "peak_measured_g": c.peak / G0, "peak_fitted_g": float(np.max(h)) / G0,
               "rel_l2_start": s, "rel_l2": e}
              for c, h, s, e in zip(pb.curves, result.final.histories, result.start.rel_l2, result.final.rel_l2)]
    data = {"parameters": params, "correlation": conf["correlation"], "names": list(pb.coords.names),
            "cost_start": result.start.cost, "cost": result.final.cost, "curves": curves,
            "status": result.status, "drop_tests": pb.runs, "evaluations": len(pb.history),
            "wall_time": result.wall, "rel_step": pb.rel_step, "backend": pb.backend,
            "dof": conf["dof"], "t_quantile": conf["t_quantile"], "cond_JTJ": conf["cond_JTJ"],
            "warnings": conf.get("warnings", []), "identifiability": conf.get("identifiability"),
            "at_bound": conf.get("at_bound", {}),
            "history": pb.history, **(settings or {}),
            "units": {"thickness": "m", "peak_measured_g": "g (9.80665 m/s^2)", "peak_fitted_g": "g",
                      "rel_l2": "-", "cost": "-", "wall_time": "s", "elapsed": "s",
                      "parameters": "SI (see each parameter's unit)"}}
    files.append(write_json(out / "fit.json", data))
    return files
