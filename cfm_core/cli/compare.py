"""``cfm compare REF_DIR DIR...``: compare finished runs of any backends with a reference run."""

from __future__ import annotations

import numpy as np

from ..post.compare import SIGNALS, Run, compare_runs, read_run
from ..post.histories import G0
from ..post.compare_plot import plot_comparison
from ..post.plots import subtitled
from ..post.staging import adopt, check_file_target
from ..post.writers import write_json
from ..runs.provenance import describe_differences


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="compare finished runs (output directories) with a reference run",
                       description="Compare runs written by 'cfm drop-test' or 'cfm run' (any backends) with the "
                                   "first directory: relative L2 of the CFC 600 acceleration (or reaction force) "
                                   "over the common time range, peak and time-of-peak differences, wall times.")
    p.add_argument("reference", help="output directory of the reference run")
    p.add_argument("runs", nargs="+", help="output directories of the runs to compare")
    p.add_argument("--plot", help="also write a PNG here: the signals over each other and each run's difference from the reference")
    p.add_argument("--json", help="also write the rows as JSON here")


def cmd_compare(args) -> int:
    for flag, suffix in (("plot", ".png"), ("json", ".json")):  # before the runs are read: a directory, another
        if getattr(args, flag):                                     # kind of file, a run's file, an unwritable place
            check_file_target(getattr(args, flag), f"--{flag}", suffix=suffix, inputs=[args.reference, *args.runs])
    ref = read_run(args.reference)
    runs = [read_run(p) for p in args.runs]
    rows = compare_runs(ref, runs)
    differences = describe_differences({r.label: r.record for r in [ref, *runs]})
    unit = SIGNALS[ref.kind][1]
    scale, shown = (G0, "g") if unit == "m/s^2" else (1.0, unit)
    p0 = float(ref.y[np.argmax(np.abs(ref.y))])
    print(f"reference {ref.label}: peak {p0 / scale:.4g} {shown}, wall {ref.summary.get('wall_time', float('nan')):.3g} s")
    for r in rows:
        ratio = f", {r['wall_ratio']:.3g}x the reference's" if r["wall_ratio"] else ""
        magnitude = abs(r["peak"]) / abs(p0) - 1.0  # sign-free: + means a larger peak magnitude
        print(f"{r['run']}: peak {r['peak'] / scale:.4g} {shown} (|peak| {100 * magnitude:+.2f} % of the reference's), "
              f"t_peak {1e3 * r['t_peak_diff']:+.3f} ms, rel L2 {100 * r['rel_l2']:.2f} %, "
              f"wall {r['wall_time'] if r['wall_time'] is not None else float('nan'):.3g} s{ratio}")
    print("differences: " + ("; ".join(differences) if differences else "none recorded (same backend, options, "
                                                                         "dtype, material, scene and input files)"))
    written = []
    if args.json:
        write_json(args.json, {"reference": str(ref.path), "signal": SIGNALS[ref.kind][0], "unit": unit,
                               "differences": differences, "rows": rows})
        written.append(str(args.json))
    if args.plot:
        _plot(args.plot, [ref] + runs, scale, shown, differences)
        written.append(str(args.plot))
    for path in written:  # into a compared run's folder: it goes with that run when a later output replaces it
        adopt(path, [args.reference, *args.runs])
    if written:
        print(f"wrote {', '.join(written)}")
    return 0


def _plot(path, runs: list[Run], scale: float, shown: str, differences: list[str]) -> None:
    ylabel = f"{'Impactor acceleration' if shown == 'g' else 'Reaction force'} ({shown})"
    plot_comparison(path, [(r.label, r.t, r.y) for r in runs],
                    subtitled("Run comparison", differences or ["no recorded difference"]), ylabel, scale)


COMMANDS = {"compare": cmd_compare}
