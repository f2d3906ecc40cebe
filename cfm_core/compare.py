"""``cfm compare REF_DIR DIR...``: compare finished runs (output directories of ``cfm drop-test`` or
``cfm run``) with a reference run, whichever backends wrote them.

A drop-test directory holds ``acceleration.csv`` (t s, a_raw and a_cfc600 m/s^2) and
``summary.json``; a prescribed-motion directory holds ``reaction.csv`` (t s, stretch -,
reaction_force N, nominal_stress Pa). The compared signal is the CFC 600 acceleration or the
reaction force; metrics from :func:`cfm_core.postprocess.compare_histories` (relative L2 over the
common time range, relative peak difference, time-of-peak difference) plus the solver wall times.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

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
    from .postprocess import compare_histories

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


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="compare finished runs (output directories) with a reference run",
                       description="Compare runs written by 'cfm drop-test' or 'cfm run' (any backends) with the "
                                   "first directory: relative L2 of the CFC 600 acceleration (or reaction force) "
                                   "over the common time range, peak and time-of-peak differences, wall times.")
    p.add_argument("reference", help="output directory of the reference run")
    p.add_argument("runs", nargs="+", help="output directories of the runs to compare")
    p.add_argument("--plot", help="also write an overlay PNG of all signals here")
    p.add_argument("--json", help="also write the rows as JSON here")


def cmd_compare(args) -> int:
    from .postprocess import G0
    from .writers import write_json

    ref = read_run(args.reference)
    runs = [read_run(p) for p in args.runs]
    rows = compare_runs(ref, runs)
    unit = SIGNALS[ref.kind][1]
    scale, shown = (G0, "g") if unit == "m/s^2" else (1.0, unit)
    p0 = float(ref.y[np.argmax(np.abs(ref.y))])
    print(f"reference {ref.label}: peak {p0 / scale:.4g} {shown}, wall {ref.summary.get('wall_time', float('nan')):.3g} s")
    for r in rows:
        ratio = f", {r['wall_ratio']:.3g}x the reference's" if r["wall_ratio"] else ""
        print(f"{r['run']}: peak {r['peak'] / scale:.4g} {shown} ({100 * r['peak_diff']:+.2f} %), "
              f"t_peak {1e3 * r['t_peak_diff']:+.3f} ms, rel L2 {100 * r['rel_l2']:.2f} %, "
              f"wall {r['wall_time'] if r['wall_time'] is not None else float('nan'):.3g} s{ratio}")
    if args.json:
        write_json(args.json, {"reference": str(ref.path), "signal": SIGNALS[ref.kind][0], "unit": unit,
                               "rows": rows})
    if args.plot:
        _plot(args.plot, [ref] + runs, scale, shown)
    return 0


def _plot(path, runs: list[Run], scale: float, shown: str) -> None:
    from .plotting import _COLOURS, _figure, _save

    fig, ax = _figure("Run comparison")
    ax.set_ylabel(f"{'Impactor acceleration' if shown == 'g' else 'Reaction force'} ({shown})")
    for i, r in enumerate(runs):
        ax.plot(1e3 * r.t, r.y / scale, color=_COLOURS[i % len(_COLOURS)], linewidth=2.0 if i == 0 else 1.2,
                linestyle="-" if i == 0 else "--", label=r.label + (" (reference)" if i == 0 else ""))
    ax.legend(loc="best", fontsize=8, frameon=False)
    _save(fig, path)
