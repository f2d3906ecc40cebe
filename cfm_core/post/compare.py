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
        return f"{self.path.name} ({self.summary.get('backend', '?')})"


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
    with open(d / name, encoding="utf-8") as f:
        header = f.readline().strip().split(",")
    if "t" not in header or column not in header:
        raise InputError(f"{d / name}: header {','.join(header)} lacks 't' or '{column}'.")
    try:
        data = np.loadtxt(d / name, delimiter=",", skiprows=1, ndmin=2)
        summary = json.loads((d / "summary.json").read_text(encoding="utf-8"))
    except ValueError as exc:
        raise InputError(f"{d}: cannot read the run ({exc}).") from None
    if data.shape[0] < 2 or not np.isfinite(data).all():
        raise InputError(f"{d / name}: needs at least 2 finite rows, got {data.shape[0]} rows.")
    return Run(d, name, data[:, header.index("t")], data[:, header.index(column)], summary)


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
