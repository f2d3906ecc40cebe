"""The files of a sweep (:mod:`cfm_core.studies.sweep`): the table, the peak plot and sweep.json.

- ``sweep.csv`` (and ``sweep.parquet`` with pyarrow): one row per run in product order, headers
  ``name [unit]`` (SI units): ``run_id``, the varied names, ``status``, ``error``, the summary
  figures (:data:`SUMMARY_COLUMNS`);
- ``peaks.png``: peak acceleration against the first varied name;
- ``sweep.json`` (written last: its presence means the sweep's files are complete): the varied
  names and values, the counts, and the provenance record of the sweep
  (:func:`cfm_core.runs.provenance.provenance`: code, backend with resolved options, material with
  its definition digest, mesh content digest) with the ingredients of the run ids.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..post import SUMMARY_UNITS
from ..post.plots import _COLOURS, _figure, _save, display, display_text
from ..post.writers import atomic_write, write_json

if TYPE_CHECKING:
    import pandas as pd

#: Summary figures copied into the table, in this order.
SUMMARY_COLUMNS = ("peak_g", "t_peak", "duration", "pulse_width", "loading_time", "unloading_time",
                   "steps", "elements", "wall_time", "energy_error", "hourglass_ratio", "run_time")


def columns(axes: list[Axis]) -> list[tuple[str, str]]:
    """(key, header) of the table: run_id, the varied names, status, error, the run checks' warnings
    (joined by " | "), summary figures."""

    units = {**{k: u.split(" ")[0] for k, u in SUMMARY_UNITS.items()}, "run_time": "s"}
    return ([("run_id", "run_id")] + [(a.name, f"{a.name} [{a.unit}]") for a in axes]
            + [("status", "status"), ("error", "error"), ("warnings", "warnings")]
            + [(k, f"{k} [{units.get(k, '-')}]") for k in SUMMARY_COLUMNS])


TEXT_COLUMNS = ("run_id", "status", "error", "warnings")


def table_frame(rows: list, axes: list[Axis]) -> pd.DataFrame:
    """The sweep table as a DataFrame: one row per run, columns ``name [unit]`` (SI units),
    text columns run_id, status, error, warnings; numbers as float (NaN where a run has no value)."""
    import pandas as pd  # deferred: ~0.3 s to import; the cfm command imports this module for every command

    cols = columns(axes)
    data = {h: [r.get(k, "") if k == "warnings" else r[k] for r in rows] for k, h in cols}  # rows before warnings
    frame = pd.DataFrame(data, columns=[h for _, h in cols])
    for k, h in cols:
        frame[h] = frame[h].astype("string") if k in TEXT_COLUMNS else pd.to_numeric(frame[h], errors="coerce")
    return frame


def _shortest(value: float) -> str:
    """The shortest text that reads back to ``value`` (``repr``), integral values without ``.0``."""
    value = float(value)
    return str(int(value)) if value.is_integer() and abs(value) < 2**53 else repr(value)


def write_table(out: Path, rows: list, axes: list[Axis]) -> list[Path]:
    """Write sweep.csv and, with pyarrow installed, sweep.parquet atomically; returns the paths.

    Both hold the same table (:func:`table_frame`); ``pandas.read_csv(path)`` and
    ``pandas.read_parquet(path)`` read it back. Floats are written in Python's shortest form that
    reads back to the same float (``repr``: an input 1.66 as ``1.66``, not ``1.6599999999999999``),
    integral values without a fraction (``689``), missing values as empty cells."""
    frame = table_frame(rows, axes)
    out.mkdir(parents=True, exist_ok=True)
    files = [atomic_write(out / "sweep.csv", lambda tmp: frame.to_csv(tmp, index=False, float_format=_shortest,
                                                                        lineterminator="\n"))]
    try:  # parquet needs pyarrow (in the 'dask' and 'all' extras); the CSV is the complete record
        files.append(atomic_write(out / "sweep.parquet", lambda tmp: frame.to_parquet(tmp, index=False)))
    except ImportError:
        pass
    return files


def read_table(path) -> list[dict]:
    """Rows of a sweep.csv as dicts keyed by header; numbers as floats, empty cells as None."""
    import pandas as pd  # deferred: ~0.3 s to import; the cfm command imports this module for every command

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


def write_sweep_json(out: Path, axes: list, rows: list, record: dict, extra: dict) -> Path:
    """Write ``sweep.json``: varied names (unit, values), run counts, provenance and ``extra``.

    Parameters
    ----------
    out : pathlib.Path
        Folder (the stage of the output).
    axes : list of Axis
        The varied names.
    rows : list of dict
        The table's rows (``status`` counted).
    record : dict
        Provenance record (:func:`cfm_core.runs.provenance.provenance`).
    extra : dict
        Further JSON-able entries (executed, skipped, wall time in s, ...).

    Returns
    -------
    pathlib.Path
        The file.
    """
    data = {"vary": [{"name": a.name, "unit": a.unit, "values": list(a.values)} for a in axes],
            "runs": len(rows), "ok": sum(r["status"] == "ok" for r in rows),
            "failed": sum(r["status"] != "ok" for r in rows), "run_ids": [r["run_id"] for r in rows],
            **extra, "provenance": record}
    return write_json(out / "sweep.json", data)
