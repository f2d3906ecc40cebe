"""Outputs of ``cfm calibrate`` (:func:`cfm_core.studies.calibrate.fit`): a plot per curve, the objective
history, the scene with the fitted parameters, and fit.json, written last (its presence means complete).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..post import G0
from ..post.plots import _COLOURS, _figure, _save, display, subtitled
from ..post.writers import _finite_array, write_json, write_text
from ..scene.scene import scene_to_toml


def plot_fit_curve(path, t, measured, start, fitted, title: str) -> None:
    """PNG of one calibration curve: the measured filtered history drawn wide and light, the start
    dashed and the fitted history thin and dark over it (a close fit leaves the measured curve
    visible on both sides of the fitted one); time in ms, acceleration in g; written atomically.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    t : array_like, shape (n,)
        Times (s).
    measured, start, fitted : array_like, shape (n,)
        Measured (CFC 600 filtered), start and fitted simulated accelerations (m/s^2).
    title : str
        Figure title.

    Raises
    ------
    NumericalError
        A non-finite value; no file is written.
    """
    ms = 1e3 * _finite_array("t", t, ndim=1)
    fig, ax = _figure(title)
    ax.plot(ms, _finite_array("measured", measured, ndim=1) / G0, color="0.72", linewidth=4.0,
            label="measured (CFC 600)", solid_capstyle="butt")
    ax.plot(ms, _finite_array("start", start, ndim=1) / G0, color=_COLOURS[1], linewidth=1.2,
            linestyle=(0, (4, 2)), label="start")
    ax.plot(ms, _finite_array("fitted", fitted, ndim=1) / G0, color=_COLOURS[0], linewidth=1.3, label="fitted")
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + 0.3 * (hi - lo))  # room for the legend above the curves
    ax.set_xlim(ms[0], ms[-1])
    ax.legend(loc="upper right", fontsize=8, framealpha=0.95, edgecolor="0.8")
    _save(fig, path)


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name)


def fitted_scene(scene, result):
    """The scene with the fitted parameter values (SI units) and the ``[run]`` section of the fit's
    drop tests (backend, dtype, device, every option as resolved), so that ``cfm drop-test --scene
    fitted-scene.toml`` repeats the fitted curve's run exactly."""
    from ..runs.settings import run_record

    fitted = scene.with_overrides(parameters=result.final.params)
    return fitted.with_run(run_record(fitted, result.problem.backend, result.problem.options))


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
    fitted = "; ".join(f"{n} = {result.final.params[n] * f:.4g}{' ' + u if u else ''} (start "
                       f"{result.start.params[n] * f:.4g}{' ' + u if u else ''})"
                       for n, (f, u) in zip(pb.coords.names, map(display, pb.coords.units)))
    for j, c in enumerate(pb.curves):
        path = out / f"fit_{_safe(c.name)}.png"
        plot_fit_curve(path, c.t, c.a, result.start.histories[j], result.final.histories[j],
                       subtitled(f"{c.name}, {1e3 * c.thickness:g} mm: rel. L2 {100 * result.final.rel_l2[j]:.2f} %",
                                 [fitted]))
        files.append(path)
    from matplotlib.ticker import MaxNLocator

    fig, ax = _figure(subtitled("Objective history", [fitted]))
    for line in list(ax.lines):  # the figure's zero line has no place on a log axis
        line.remove()
    ax.relim()
    ax.set_xlabel("evaluation")
    ax.set_ylabel("cost 1/2 sum r^2 (-)")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # evaluations are counted: no tick at 1.5
    ax.semilogy([h["evaluation"] for h in pb.history], [max(h["cost"], 1e-300) for h in pb.history], "o-",
                color=_COLOURS[0], markersize=4)
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
            "independent_samples": conf.get("independent_samples"), "correlation_factor": conf.get("correlation_factor"),
            "warnings": conf.get("warnings", []), "identifiability": conf.get("identifiability"),
            "at_bound": conf.get("at_bound", {}),
            "history": pb.history, **(settings or {}),
            "units": {"thickness": "m", "peak_measured_g": "g (9.80665 m/s^2)", "peak_fitted_g": "g",
                      "rel_l2": "-", "cost": "-", "wall_time": "s", "max_evaluations": "-", "elapsed": "s",
                      "parameters": "SI (see each parameter's unit)"}}
    files.append(write_json(out / "fit.json", data))
    return files
