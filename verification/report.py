"""Write the verification report: DIR/report.md, DIR/report.json and the PNG figures.

report.json holds every number of report.md (SI units; NaN and inf written as null, with the
field named in ``nonfinite_fields``). Figures: agreement_<scene>.png (signals of all backends),
workprecision_<n>.png (error against wall time), drucker_<material>.png, paper.png.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from cfm_core.post import G0
from cfm_core.fingerprint import code_label
from cfm_core.post.writers import atomic_write, write_json

from . import figures
from .stability import KNOWN_DEFECTS


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def _clean(o, path="", bad=None):
    """JSON-able copy: numpy to Python, NaN/inf to None (path recorded in ``bad``)."""
    if isinstance(o, dict):
        return {str(k): _clean(v, f"{path}.{k}", bad) for k, v in o.items() if k not in ("instance", "result")}
    if isinstance(o, (list, tuple)):
        return [_clean(v, f"{path}[{i}]", bad) for i, v in enumerate(o)]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist(), path, bad)
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (int, np.integer)):
        return int(o)
    if isinstance(o, (float, np.floating)):
        if not math.isfinite(float(o)):
            bad.append(path)
            return None
        return float(o)
    return o


def _e(x, fmt=".2e"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def _ok(p):
    return "pass" if p else ("n/a" if p is None else "**FAIL**")


def _md_header(rep) -> list[str]:
    m = rep["machine"]
    meaning = {"PASSED": "every check ran on every backend in scope and met its tolerance",
               "FAILED": "a check missed its tolerance or expected outcome, or a required backend is missing",
               "INCOMPLETE": "no check failed, but something in scope did not run: this is not a pass"}
    lines = [f"# CFM verification report ({rep['mode']} mode)", "",
             f"**Result: {rep['verdict']}** (exit {rep['exit_code']}: {meaning[rep['verdict']]}; "
             f"{rep['checks']} checks, {len(rep['failed'])} failed, {len(rep['incomplete'])} not run; "
             f"required backends: {', '.join(rep['required']) or 'none stated'}; sections: {', '.join(rep['sections'])})",
             ""]
    if rep["failed"]:
        lines += ["Failed checks:", ""] + [f"- {m}" for m in rep["failed"]] + [""]
    if rep["incomplete"]:
        lines += ["Not run (each makes the result INCOMPLETE):", ""] + [f"- {m}" for m in rep["incomplete"]] + [""]
    lines += [
             f"- git commit: `{rep['commit']}`"
             + (f"; code {code_label(rep['provenance']['code'])}, source digest "
                f"`{rep['provenance']['code']['source_digest']}`" if rep.get("provenance") else ""),
             f"- machine: {m['platform']}, {m['cpu_count']} CPUs ({m['processor']}), Python {m['python']}, "
             f"numpy {m['numpy']}, scipy {m['scipy']}, numba {m['numba']}, torch {m['torch']}, "
             f"scikit-fem {m['scikit-fem']}",
             f"- date: {rep['date']}; run time {rep['runtime']:.1f} s ("
             + ", ".join(f"{k} {v:.1f} s" for k, v in rep["timings"].items()) + ")", "",
             "## Backends", "", "| backend | kind | status | reason |", "|---|---|---|---|"]
    for b in rep["inventory"]:
        lines.append(f"| {b['name']} | {b['kind']} | {b['status']} | {b['reason'] or '-'} |")
    return lines + [""]


def _md_agreement(rep) -> list[str]:
    lines = ["## Agreement", "",
             "Metrics: relative L2 error over the event (stress norm for material points, reaction force for "
             "the single element, CFC 600 impactor acceleration for drop tests) over the UNION of the two time "
             "ranges (a drop-test signal is zero outside its own), relative peak difference, time-of-peak and "
             "duration differences; a drop test ending while loaded fails. Every backend, the numpy reference "
             "included, is compared with an independent truth where one exists (cfm_verification.truths); "
             "pairs of backends are labelled with the code they share, and a pair whose compared path is the "
             "same code is marked 'shared code' and does not count. Tolerances per pair kind:", "",
             "| pair | rel L2 limit | peak limit | t_peak limit (s) | duration limit (s) | why |",
             "|---|---|---|---|---|---|"]
    for k, t in rep["tolerances"].items():
        lines.append(f"| {k} | {t['rel_l2']:g} | {t['peak']:g} | {t['t_peak']:g} | {t['duration']:g} | {t['why']} |")
    lines += ["", "### Agreement table", "", "| check | case | a (reference) | b | pair | rel L2 | peak diff | "
              "t_peak diff (s) | duration diff (s) | verdict | shared code |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rep["agreement"]:
        verdict = ("shared code (not counted)" if r.get("informational") else _ok(r["passed"]))
        if r.get("error") and not r.get("informational"):
            verdict += f": {r['error']}"
        if r.get("pair") == "energy":
            verdict = f"energy error {_e(r.get('energy_error'), '.2e')} (limit {r['tol_energy']:g}): " + verdict
        lines.append(f"| {r['check']} | {r['case']} | {r['a']} | {r['b']} | {r['pair']} | {_e(r['rel_l2'])} | "
                     f"{_e(r['peak_diff'])} | {_e(r['t_peak_diff'])} | {_e(r.get('duration_diff'))} | {verdict} | "
                     f"{r.get('shared') or '-'} |")
    scenes = {r["case"] for r in rep["agreement"] if r["check"] != "material point"}
    runners = [b["name"] for b in rep["inventory"] if b["status"] == "available" and b["can_run"]]
    if len(runners) < 2:
        lines += ["", f"Only {len(runners)} backend(s) can run scenes here ({', '.join(runners) or 'none'}): no "
                  "backend-against-backend pair exists for the scene checks yet; the single element is checked "
                  "against the quasi-static uniaxial solution. Scenes: " + ", ".join(sorted(scenes)) + "."]
    return lines + [""]


def _md_wp(rep, figs) -> list[str]:
    lines = ["## Error against run time (work-precision)", ""]
    for i, s in enumerate(rep["work_precision"]):
        lines += [f"### {s['label']}", "", f"Reference: {s['reference']}."]
        if s.get("richardson"):
            r = s["richardson"]
            lines.append(f"Richardson extrapolation of the peak ({r['note']}, order {r['order']:.2f}): "
                         f"{_e(r['peak'], '.5g')}.")
        lines += ["", f"Fastest to 1 % error (peak and rel L2, against the reference above): **{s['first_to_1pct']}**.",
                  "", "| backend | element (mm) | step option | status | wall (s) | peak error | rel L2 |",
                  "|---|---|---|---|---|---|---|"]
        for r in s["runs"]:
            h = "-" if r["element_size"] is None else f"{1e3 * r['element_size']:g}"
            opts = ", ".join(f"{k}={v:g}" for k, v in r["options"].items())
            status = r["status"]
            if r["status"] not in ("completed",):
                status += f": {r.get('message', '')}"
            lines.append(f"| {r['backend']} | {h} | {opts} | {status} | {_e(r.get('wall'), '.3g')} | "
                         f"{_e(r.get('peak_error'))} | {_e(r.get('rel_l2'))} |")
        if figs.get(f"wp{i}"):
            lines += ["", f"![work-precision {s['label']}]({figs[f'wp{i}']})"]
        lines.append("")
    return lines


def _md_stability(rep, figs) -> list[str]:
    lines = ["## Stability on stiff and extreme cases", "",
             "Each case has an expected outcome per backend ('completes': finite results and an energy-balance "
             "error within the 1 % rule, or a material point within round-off of the independent truth; "
             "'diagnostic: X': stops with an InputError/NumericalError naming X). A row passes only when the "
             "observed outcome is the expected one.", "",
             "| case | backend | options | expected | verdict | check |", "|---|---|---|---|---|---|"]
    for r in rep["stability"]:
        opts = ", ".join(f"{k}={v}" for k, v in r["options"].items()) or "-"
        known = KNOWN_DEFECTS.get(f"stability / {r['case']} / {r['backend']}")
        note = f" (known defect: {known})" if known and r["passed"] is False else ""
        lines.append(f"| {r['case']} | {r['backend']} | {opts} | {r.get('expected', '-')} | {r['verdict']}{note} | "
                     f"{_ok(r['passed'])} |")
    lines += ["", "### Material stability (Drucker)", "",
              "Intervals of nominal strain (e = stretch - 1, from -0.9 to 2) where positive definiteness is lost, "
              "instantaneous elastic response at the material's default parameters. 'Drucker' is Abaqus's "
              "criterion (d tau : d ln V > 0); 'dS/dE' the Mandel 6x6 form of the tangent; 'U''(J)' the "
              "convexity of the volumetric energy (volumetric path). 'not evaluable' = the stress overflows "
              "float64 there. `cfm_verification.drucker.drucker_warnings(material, F_history)` warns when a "
              "history enters such a range.", "",
              "| check | result | verdict |", "|---|---|---|"]
    for r in rep.get("drucker_checks", []):
        lines.append(f"| {r['check']} | {r['reason']} | {_ok(r['passed'])} |")
    lines += ["", "| material | path | Drucker | dS/dE | U''(J) | not evaluable |", "|---|---|---|---|---|---|"]

    def iv(x):
        return "none" if not x else ", ".join(f"[{a:+.2f}, {b:+.2f}]" for a, b in x)

    for name, smap in rep["drucker"].items():
        if "error" in smap:
            lines.append(f"| {name} | - | {smap['error']} | | | |")
            continue
        for path, res in smap["paths"].items():
            lines.append(f"| {name} | {path} | {iv(res['Drucker']['intervals'])} | {iv(res['dS/dE']['intervals'])} | "
                         f"{iv(res[chr(85) + chr(39) + chr(39) + '(J)']['intervals']) if 'U' + chr(39) * 2 + '(J)' in res else '-'} | "
                         f"{iv(res['Drucker']['not_evaluable'])} |")
    for name in rep["drucker"]:
        if figs.get(f"drucker-{name}"):
            lines.append(f"\n![stability map {name}]({figs[f'drucker-{name}']})")
    return lines + [""]


def _md_paper(rep, figs) -> list[str]:
    p = rep["paper"]
    lines = ["## Paper comparison (drop tests at 1 m/s against the paper's experiments)", "",
             f"Source of the simulated values: {p['source']}. These facts compare the model with the tissue; "
             "they do not decide the suite's result. The stored results are reused only when reproduced:", ""]
    for c in p.get("checks", []):
        lines.append(f"- {c['check']}: {_ok(c['passed'])} ({c['reason']})")
    lines += ["",
             "| thickness (mm) | peak (g) | t_peak (ms) | contact (ms) | loading / unloading (ms) | experiment peak (g) |",
             "|---|---|---|---|---|---|"]
    exp = {float(k): v for k, v in p.get("experiment_peaks_g", {}).items()}
    for r in p["rows"]:
        if "error" in r:
            lines.append(f"| {1e3 * r['thickness']:g} | run failed: {r['error']} | | | | |")
            continue
        lines.append(f"| {1e3 * r['thickness']:g} | {r['peak_g']:.1f} | {1e3 * r['t_peak']:.2f} | "
                     f"{1e3 * r['duration']:.2f} | {1e3 * r['loading_time']:.2f} / {1e3 * r['unloading_time']:.2f} | "
                     f"{exp.get(round(r['thickness'], 6), '52.5-80.7')} |")
    lines += ["", "| experimental fact (paper section 4) | simulation | reproduced |", "|---|---|---|"]
    for f in p["facts"]:
        lines.append(f"| {f['fact']} | {f['simulation']} | {'yes' if f['reproduced'] else 'no'} |")
    if figs.get("paper"):
        lines += ["", f"![paper comparison]({figs['paper']})"]
    return lines + [""]


def write(out: Path, rep: dict, scene_runs: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    figs = {}
    for label, runs in scene_runs.items():
        curves = [(n, r["t"], r["y"]) for n, r in sorted(runs.items()) if r["ok"]]
        if curves:
            name = f"agreement_{_slug(label)}.png"
            drop = any(r["scene"] == "drop-test" for r in runs.values())
            figures.signals(out / name, f"Agreement: {label}", curves,
                            "Impactor acceleration, CFC 600 (g)" if drop else "Reaction force (N)",
                            scale=1 / G0 if drop else 1.0)
            figs[f"agree-{label}"] = name
    for i, s in enumerate(rep["work_precision"]):
        name = f"workprecision_{_slug(s['label'])}.png"
        if figures.work_precision(out / name, s):
            figs[f"wp{i}"] = name
    for mat, smap in rep["drucker"].items():
        if "error" not in smap:
            name = f"drucker_{_slug(mat)}.png"
            figures.drucker_map(out / name, mat, smap)
            figs[f"drucker-{mat}"] = name
    curves = rep["paper"].get("curves") or []
    if curves:
        figures.signals(out / "paper.png", "Drop tests at 1 m/s (CFC 600)", curves, "Impactor acceleration (g)", 1 / G0)
        figs["paper"] = "paper.png"
    rep["figures"] = sorted(figs.values())
    md = _md_header(rep) + _md_agreement(rep)
    md += [f"![{k}]({v})" for k, v in figs.items() if k.startswith("agree-")] + [""]
    md += _md_wp(rep, figs) + _md_stability(rep, figs) + _md_paper(rep, figs)
    rep_json = dict(rep)
    rep_json["paper"] = {k: v for k, v in rep["paper"].items() if k != "curves"}
    bad: list[str] = []
    clean = _clean(rep_json, "", bad)
    clean["nonfinite_fields"] = bad
    write_json(out / "report.json", clean)
    atomic_write(out / "report.md", lambda tmp: Path(tmp).write_text("\n".join(md) + "\n", encoding="utf-8"))
