"""``cfm compare REF_DIR DIR...``: compare finished runs (output directories of ``cfm drop-test`` or
``cfm run``) with a reference run, whichever backends wrote them.

A drop-test directory holds ``acceleration.csv`` (t s, a_raw and a_cfc600 m/s^2) and
``summary.json``; a prescribed-motion directory holds ``reaction.csv`` (t s, stretch -,
reaction_force N, nominal_stress Pa). The compared signal is the CFC 600 acceleration or the
reaction force; metrics from :func:`cfm_core.post.compare_histories` (relative L2 over the
common time range, relative peak difference, time-of-peak difference) plus the solver wall times.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..tables import as_float, decode, read_table
from .metrics import compare_histories, unit_hint, velocity_change

#: signal file -> (column compared, its unit)
SIGNALS = {"acceleration.csv": ("a_cfc600", "m/s^2"), "reaction.csv": ("reaction_force", "N")}


@dataclass
class Run:
    """A finished run read back from its output directory: t (s), y (signal), summary."""

    path: Path
    kind: str
    t: np.ndarray
    y: np.ndarray
    summary: dict

    @property
    def label(self) -> str:
        """The directory name and the backend, e.g. ``out_t32 (torch)``."""
        return f"{self.path.name} ({self.summary.get('backend', '?')})"

    @property
    def record(self) -> dict:
        """The run's provenance record (``summary["provenance"]``; for runs written before
        provenance existed, one made of the summary's backend, material and parameters) with
        the scene's values under ``scene_values`` (``"specimen.thickness"``, ...; material and
        [run] left out: the record has them), for
        :func:`cfm_core.runs.provenance.describe_differences`."""
        s = self.summary
        prov = s.get("provenance")
        record = dict(prov) if _cfm_record(prov) else {
            "backend": {"name": s.get("backend"), "dtype": s.get("dtype"), "device": s.get("device")},
            "material": {"name": s.get("material"), "moduli": s.get("moduli"), "elastic": s.get("elastic"),
                         "parameters": s.get("parameters") if isinstance(s.get("parameters"), dict) else {}}}
        values = {}
        scene = s.get("scene")
        for section, table in (scene if isinstance(scene, dict) else {}).items():
            if section in ("material", "run") or not isinstance(table, dict):
                continue
            values.update({f"{section}.{k}": v for k, v in table.items() if not isinstance(v, dict)})
        record["scene_values"] = values
        return record


def _cfm_record(prov) -> bool:
    """Whether ``prov`` has the shape of cfm's provenance record (another tool may write anything under
    that name): a non-empty object whose backend and material are objects, parts a list of objects and
    input files an object of texts, where present."""
    if not isinstance(prov, dict) or not prov:
        return False
    files = prov.get("input_files", {})
    return (all(isinstance(prov.get(k, {}), dict) for k in ("backend", "material"))
            and isinstance(prov.get("parts", []), list) and all(isinstance(p, dict) for p in prov.get("parts", []))
            and isinstance(files, dict) and all(isinstance(v, str) for v in files.values()))


def read_run(path) -> Run:
    """Read a run directory; InputError naming the directory and what is missing or malformed."""
    d = Path(path)
    if not d.exists():
        raise InputError(f"{d}: no such folder; give output directories of 'cfm drop-test' or 'cfm run'.")
    if not d.is_dir():
        raise InputError(f"{d}: not a directory; give output directories of 'cfm drop-test' or 'cfm run'.")
    if not (d / "summary.json").is_file():
        other = {"sweep.json": "cfm sweep: compare its runs, the folders in runs/", "fit.json": "cfm fit or cfm "
                 "calibrate: compare runs of fitted-scene.toml", "report.json": "cfm verify"}
        what = next((f"{d} is the output of {text}" for name, text in other.items() if (d / name).is_file()), None)
        raise InputError(f"{what}; give output folders of 'cfm drop-test' or 'cfm run'." if what else
                         f"{d}: no summary.json, so the run did not complete (summary.json is written last).")
    found = [name for name in SIGNALS if (d / name).is_file()]
    if not found:
        raise InputError(f"{d}: neither {' nor '.join(SIGNALS)} found.")
    name = found[0]
    column, _ = SIGNALS[name]
    table = read_table(d / name, ("t", column), {"t": "s", column: SIGNALS[name][1]}, strict=False,
                       what="run history")
    try:
        summary = json.loads(decode(d / "summary.json", (d / "summary.json").read_bytes(), "JSON"))
    except InputError:
        raise  # not UTF-8: the paragraph of tables.decode (a byte-order mark is skipped)
    except (ValueError, OSError) as exc:
        raise InputError(f"{d}: cannot read summary.json ({exc}).") from None
    if not isinstance(summary, dict):
        raise InputError(f"{d / 'summary.json'} holds a JSON {type(summary).__name__}, not an object; a run's "
                         f"summary.json is an object ({{\"backend\": ..., \"wall_time\": ...}}): give the output "
                         f"directory of a run.")
    wall = summary.get("wall_time")
    if not (isinstance(wall, (int, float)) and not isinstance(wall, bool) and math.isfinite(as_float(wall))
            and wall >= 0):
        summary = {k: v for k, v in summary.items() if k != "wall_time"}  # not seconds: not compared
    if table.data.shape[0] < 2:
        raise InputError(f"{d / name}: needs at least 2 rows, got {table.data.shape[0]}.")
    t = table.column("t")
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if back.size:
        k = int(back[0]) + 1
        raise InputError(f"{d / name}, line {list(table.lines)[k]}: t = {float(t[k])!r} s does not increase (the row "
                         f"before has t = {float(t[k - 1])!r} s); a history's times increase from row to row.")
    return Run(d, name, t, table.column(column), summary)


def check_units(run: Run, reference: Run) -> None:
    """InputError when ``run``'s history cannot be the same experiment as the reference's in SI units:
    its time span 20 x longer or shorter (t in ms or us?) or, for accelerations, its velocity change
    int a dt outside 0.3 - 3 x the reference's (a in g? t in ms?, :func:`.metrics.unit_hint`)."""
    span, span0 = float(run.t[-1] - run.t[0]), float(reference.t[-1] - reference.t[0])
    if not (span0 / SPAN_RATIO <= span <= SPAN_RATIO * span0):
        raise InputError(f"{run.path / run.kind}: its history lasts {span:g} s, {span / span0:.3g} x the reference's "
                         f"{span0:g} s ({reference.path}); both must be in s (is t in ms or us? divide it by 1000 "
                         f"or 1e6).")
    if run.kind == "acceleration.csv":
        dv, dv0 = velocity_change(run.t, run.y), velocity_change(reference.t, reference.y)
        ratio = dv / dv0 if dv0 != 0.0 else float("nan")
        if not (0.3 <= ratio <= 3.0):
            raise InputError(f"{run.path / run.kind}: its velocity change int a dt = {dv:.4g} m/s is {ratio:.3g} x the "
                             f"reference's {dv0:.4g} m/s ({reference.path}); runs of the same drop test agree within "
                             f"a few per cent.{unit_hint(ratio)}")


#: Largest ratio of the time spans of a compared run and the reference (:func:`check_units`).
SPAN_RATIO = 20.0


def compare_runs(reference: Run, others: list[Run]) -> list[dict]:
    """One row per other run: rel_l2, peak_diff (-), t_peak_diff (s) against the reference, and
    both solver wall times (s) with their ratio."""

    rows = []
    for r in others:
        if r.kind != reference.kind:
            raise InputError(f"{r.path} holds {r.kind} but the reference {reference.path} holds {reference.kind}; "
                             f"compare runs of the same kind of scene.")
        check_units(r, reference)
        c = compare_histories(r.t, r.y, reference.t, reference.y)
        wall, wall0 = r.summary.get("wall_time"), reference.summary.get("wall_time")
        rows.append({"run": r.label, **c, "wall_time": wall, "reference_wall_time": wall0,
                     "wall_ratio": (wall / wall0) if wall and wall0 else None,
                     "peak": float(r.y[np.argmax(np.abs(r.y))])})
    return rows
