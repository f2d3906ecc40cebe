"""What the septa fibres do to the paper's drop tests: sweep summary, calibration to the two peaks, figure.

Usage (numba, the paper's 1 mm mesh; the sweep itself is a ``cfm sweep`` command, see docs/user/septa.md)::

    cfm sweep --serial --scene docs/septa/drop-test-septa.toml --vary thickness=0.005,0.008 \\
        --vary k1s=0.001,30,100,300,1000,3000 --vary k2s=0.1,1,10 --out out/septa-sweep
    python -m cfm_verification.septa_study --sweep out/septa-sweep --out docs/septa

writes into --out: ``sweep.md`` (peak at 5 and 8 mm and the early acceleration at 8 mm per (k1s,
k2s)), ``calibration.json`` (fit of k1s, k2s to 80.7 g at 5 mm and 52.5 g at 8 mm, Jacobian,
singular values), ``calibration.md`` and ``septa.png``. SI units in files; peaks in g
(9.80665 m/s^2). "Early acceleration" is the CFC 600 acceleration at t = 2 ms after first contact
(8 mm: about 40 % of the time to peak), a measure of the early stiffness the paper finds too high.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

from cfm_core.post import G0
from cfm_core.scene.scene import load_scene
from cfm_core.studies.peaks import fit_peaks

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "docs" / "septa" / "drop-test-septa.toml"
EXPERIMENT = {0.005: 80.7, 0.008: 52.5}  # g, the paper's section 4
T_EARLY = 2e-3  # s


def read_sweep(folder) -> list[dict]:
    """Rows of a ``cfm sweep`` output with the early acceleration (g) read from each run's history."""
    folder = Path(folder)
    rows = []
    with open(folder / "sweep.csv", newline="") as fh:
        for row in csv.DictReader(fh):
            if row["status"] != "ok":
                continue
            run = folder / "runs" / row["run_id"] / "acceleration.csv"
            data = np.loadtxt(run, delimiter=",", skiprows=1)
            early = float(np.interp(T_EARLY, data[:, 0], data[:, 2])) / G0
            rows.append({"thickness": float(row["thickness [m]"]), "k1s": float(row["k1s [Pa]"]),
                         "k2s": float(row["k2s [-]"]), "peak_g": float(row["peak_g [g]"]), "early_g": early,
                         "t": data[:, 0], "a": data[:, 2] / G0})
    return rows


def sweep_table(rows) -> str:
    """Markdown table: one line per (k1s, k2s) with 5 and 8 mm peaks and the 8 mm early acceleration."""
    keys = sorted({(r["k1s"], r["k2s"]) for r in rows}, key=lambda k: (k[1], k[0]))
    by = {(r["k1s"], r["k2s"], r["thickness"]): r for r in rows}
    lines = ["| k1s (Pa) | k2s (-) | peak 5 mm (g) | peak 8 mm (g) | a(2 ms), 8 mm (g) |", "|---|---|---|---|---|"]
    for k1s, k2s in keys:
        r5, r8 = by.get((k1s, k2s, 0.005)), by.get((k1s, k2s, 0.008))
        cell = (lambda r, key: f"{r[key]:.1f}" if r else "-")
        lines.append(f"| {k1s:g} | {k2s:g} | {cell(r5, 'peak_g')} | {cell(r8, 'peak_g')} | {cell(r8, 'early_g')} |")
    lines.append(f"| experiment | | {EXPERIMENT[0.005]} | {EXPERIMENT[0.008]} | (not stated) |")
    return "\n".join(lines) + "\n"


def calibrate(out: Path, start: dict, say=None) -> dict:
    """Fit k1s, k2s of cfm-septa (CFM part at Table 1) to the two experimental peaks; write the results."""
    scene = load_scene(SCENE)
    result = fit_peaks(scene, EXPERIMENT, ["k1s", "k2s"], start, progress=say)
    data = {"names": result.names, "start": result.start, "fitted": result.fitted,
            "targets_g": {str(k): v for k, v in result.targets.items()},
            "peaks_g": {str(k): v for k, v in result.peaks.items()},
            "jacobian_dlnpeak_dlnp": result.jacobian.tolist(), "singular_values": result.singular_values,
            "condition": result.singular_values[0] / max(result.singular_values[-1], 1e-300),
            "status": result.status, "drop_tests": result.drop_tests, "wall_time": result.wall,
            "history": result.history,
            "units": {"k1s": "Pa", "k2s": "-", "peaks_g": "g (9.80665 m/s^2)", "targets_g": "g", "wall_time": "s",
                      "thickness keys": "m"}}
    (out / "calibration.json").write_text(json.dumps(data, indent=1))
    return data


def calibrated_runs(cal: dict) -> dict:
    """Drop tests of the calibrated cfm-septa at 5 and 8 mm: {thickness: (t s, a g, peak g, a(2 ms) g)}."""
    from cfm_core.studies.sweep import run_case

    scene = load_scene(SCENE)
    out = {}
    for h in sorted(EXPERIMENT):
        r = run_case((scene.with_overrides(thickness=h), cal["fitted"], "numba"))
        a = r["a_cfc"] / G0
        out[h] = (r["t"], a, float(r["summary"]["peak_g"]), float(np.interp(T_EARLY, r["t"], a)),
                  float(r["t"][np.argmax(a)]))
    return out


def calibration_table(rows, runs: dict, cal: dict) -> str:
    """Markdown: CFM alone, calibrated CFM + septa and the experiment at 5 and 8 mm."""
    base = {r["thickness"]: r for r in rows if r["k1s"] == min(x["k1s"] for x in rows) and r["k2s"] == 1.0}
    f = cal["fitted"]
    def t_peak(r):
        return 1e3 * float(r["t"][np.argmax(r["a"])])

    lines = ["| model | peak 5 mm (g) | peak 8 mm (g) | a(2 ms), 8 mm (g) | t_peak 5 / 8 mm (ms) |", "|---|---|---|---|---|",
             f"| CFM, Table 1 (k1s = 0) | {base[0.005]['peak_g']:.1f} | {base[0.008]['peak_g']:.1f} | "
             f"{base[0.008]['early_g']:.1f} | {t_peak(base[0.005]):.2f} / {t_peak(base[0.008]):.2f} |",
             f"| CFM + septa, k1s = {f['k1s']:.4g} Pa, k2s = {f['k2s']:.3g} | {runs[0.005][2]:.1f} | {runs[0.008][2]:.1f} | "
             f"{runs[0.008][3]:.1f} | {1e3 * runs[0.005][4]:.2f} / {1e3 * runs[0.008][4]:.2f} |",
             f"| experiment (paper, section 4) | {EXPERIMENT[0.005]} | {EXPERIMENT[0.008]} | not stated | not stated |"]
    return "\n".join(lines) + "\n"


def figure(out: Path, rows, calibrated: dict | None, runs: dict | None = None) -> None:
    """septa.png: peaks against k1s (5 and 8 mm, one line per k2s), the early acceleration at 8 mm, and
    (with ``runs``) the histories of the CFM alone and the calibrated CFM + septa."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15 if runs else 10, 4), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3 if runs else 2)
    ax1, ax2 = axes[0], axes[1]
    if runs:
        ax3 = axes[2]
        for h, colour in ((0.005, "tab:blue"), (0.008, "tab:orange")):
            base = next(r for r in rows if r["thickness"] == h and r["k2s"] == 1.0
                        and r["k1s"] == min(x["k1s"] for x in rows))
            ax3.plot(1e3 * base["t"], base["a"], "--", color=colour, label=f"CFM (Table 1), {1e3 * h:g} mm")
            t, a = runs[h][0], runs[h][1]
            ax3.plot(1e3 * t, a, "-", color=colour, label=f"CFM + septa (calibrated), {1e3 * h:g} mm")
            ax3.axhline(EXPERIMENT[h], color=colour, linewidth=0.8, linestyle=":")
        ax3.set_title("impactor acceleration (CFC 600); dotted: experimental peaks", fontsize=9)
        ax3.set_xlabel("time (ms)")
        ax3.set_ylabel("acceleration (g)")
        ax3.legend(fontsize=6, ncols=2, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.15))  # below: never over a curve
        ax3.grid(True, color="0.88", linewidth=0.6)
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")
    for k2s, colour in zip(sorted({r["k2s"] for r in rows}), colours):
        for h, style in ((0.005, "o-"), (0.008, "s--")):
            pts = sorted((r["k1s"], r["peak_g"]) for r in rows if r["k2s"] == k2s and r["thickness"] == h)
            if pts:
                ax1.semilogx(*zip(*pts), style, color=colour, label=f"{1e3 * h:g} mm, k2s = {k2s:g}")
        pts = sorted((r["k1s"], r["early_g"]) for r in rows if r["k2s"] == k2s and r["thickness"] == 0.008)
        if pts:
            ax2.semilogx(*zip(*pts), "s--", color=colour, label=f"8 mm, k2s = {k2s:g}")
    for h, p in EXPERIMENT.items():
        ax1.axhline(p, color="0.4", linewidth=0.8, linestyle=":")
        ax1.annotate(f"experiment {1e3 * h:g} mm: {p} g", (0.0, p), xycoords=("axes fraction", "data"), ha="left",
                     va="bottom" if h < 0.008 else "top", xytext=(3, 0), textcoords="offset points", fontsize=7)
        # at the left edge: the calibrated points sit at the right end of the dotted lines
    if calibrated:
        f = calibrated["fitted"]
        for h, marker in (("0.005", "*"), ("0.008", "P")):
            ax1.semilogx([f["k1s"]], [calibrated["peaks_g"][h]], marker, color="k", markersize=10,
                         label=f"calibrated, {1e3 * float(h):g} mm (k2s = {f['k2s']:.3g})")
        ax1.set_title(f"peak (CFC 600); calibrated: k1s = {f['k1s']:.3g} Pa, k2s = {f['k2s']:.3g}", fontsize=9)
    else:
        ax1.set_title("peak impactor acceleration (CFC 600)", fontsize=9)
    ax1.set_xlabel("septa stiffness k1s (Pa, long-term)")
    ax1.set_ylabel("peak acceleration (g)")
    ax1.legend(fontsize=6, ncols=2, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.15))  # below: never over a curve
    ax2.set_title("early stiffness: acceleration at 2 ms, 8 mm", fontsize=9)
    ax2.set_xlabel("septa stiffness k1s (Pa, long-term)")
    ax2.set_ylabel("acceleration at t = 2 ms (g)")
    ax2.legend(fontsize=6, ncols=2, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.15))  # below: never over a curve
    for ax in (ax1, ax2):
        ax.grid(True, color="0.88", linewidth=0.6)
    fig.savefig(out / "septa.png")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sweep", required=True, help="output folder of the cfm sweep above")
    p.add_argument("--out", required=True, help="folder for sweep.md, calibration.json/.md, septa.png")
    p.add_argument("--start", default="k1s=1000,k2s=1", help="start of the calibration, SI (default k1s=1000,k2s=1)")
    p.add_argument("--no-calibration", action="store_true", help="only the sweep table and figure")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = read_sweep(args.sweep)
    (out / "sweep.md").write_text(sweep_table(rows))
    cal = None
    if not args.no_calibration:
        start = {k: float(v) for k, v in (item.split("=") for item in args.start.split(","))}
        cal = calibrate(out, start, lambda line: print(line, file=sys.stderr, flush=True))
    elif (out / "calibration.json").is_file():
        cal = json.loads((out / "calibration.json").read_text())
    runs = None
    if cal:
        runs = calibrated_runs(cal)
        (out / "calibration.md").write_text(calibration_table(rows, runs, cal))
    figure(out, rows, cal, runs)
    print(f"wrote {out}/sweep.md, septa.png" + (", calibration.json, calibration.md" if cal else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
