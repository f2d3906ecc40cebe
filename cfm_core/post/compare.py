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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..tables import read_table
from .metrics import compare_histories

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
        record = dict(s.get("provenance") or {
            "backend": {"name": s.get("backend"), "dtype": s.get("dtype"), "device": s.get("device")},
            "material": {"name": s.get("material"), "moduli": s.get("moduli"), "elastic": s.get("elastic"),
                         "parameters": s.get("parameters") or {}}})
        values = {}
        for section, table in (s.get("scene") or {}).items():
            if section in ("material", "run") or not isinstance(table, dict):
                continue
            values.update({f"{section}.{k}": v for k, v in table.items() if not isinstance(v, dict)})
        record["scene_values"] = values
        return record


def read_run(path) -> Run:
    """Read a run directory; InputError naming the directory and what is missing or malformed."""
    d = Path(path)
    if not d.is_dir():
        raise InputError(f"{d}: not a directory; give output directories of 'cfm drop-test' or 'cfm run'.")
    if not (d / "summary.json").is_file():
        raise InputError(f"{d}: no summary.json, so the run did not complete (summary.json is written last).")
    found = [name for name in SIGNALS if (d / name).is_file()]
    if not found:
        raise InputError(f"{d}: neither {' nor '.join(SIGNALS)} found.")
    name = found[0]
    column, _ = SIGNALS[name]
    table = read_table(d / name, ("t", column), {"t": "s", column: SIGNALS[name][1]}, strict=False,
                       what="run history")
    try:
        summary = json.loads((d / "summary.json").read_text(encoding="utf-8"))
    except (ValueError, OSError) as exc:
        raise InputError(f"{d}: cannot read summary.json ({exc}).") from None
    if table.data.shape[0] < 2:
        raise InputError(f"{d / name}: needs at least 2 rows, got {table.data.shape[0]}.")
    return Run(d, name, table.column("t"), table.column(column), summary)


def compare_runs(reference: Run, others: list[Run]) -> list[dict]:
    """One row per other run: rel_l2, peak_diff (-), t_peak_diff (s) against the reference, and
    both solver wall times (s) with their ratio."""

    rows = []
    for r in others:
        if r.kind != reference.kind:
            raise InputError(f"{r.path} holds {r.kind} but the reference {reference.path} holds {reference.kind}; "
                             f"compare runs of the same kind of scene.")
        c = compare_histories(r.t, r.y, reference.t, reference.y)
        wall, wall0 = r.summary.get("wall_time"), reference.summary.get("wall_time")
        rows.append({"run": r.label, **c, "wall_time": wall, "reference_wall_time": wall0,
                     "wall_ratio": (wall / wall0) if wall and wall0 else None,
                     "peak": float(r.y[np.argmax(np.abs(r.y))])})
    return rows
