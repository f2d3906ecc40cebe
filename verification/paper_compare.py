"""Drop-test peaks, times and durations next to the paper's experimental facts (section 4).

These are model-against-experiment findings, reported as "reproduced" or "not reproduced"; they do
not decide the suite's exit status (a software check does not fail because the model differs from
the tissue). Quick mode reuses ``docs/paper/results.json`` (written by ``python -m
cfm_verification.paper``) when it exists, else runs the 8 mm test on a coarse (2 mm) mesh.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .paper import EXPERIMENT_PEAKS_G, G0, THICKNESSES

RESULTS_JSON = Path(__file__).resolve().parent.parent / "docs" / "paper" / "results.json"


def _row(h, s) -> dict:
    keys = ("peak_g", "t_peak", "duration", "loading_time", "unloading_time", "energy_error", "wall_time")
    return {"thickness": h, **{k: s.get(k) for k in keys}}


def simulate(backend: str, cache, thicknesses=THICKNESSES, element_size=1e-3) -> tuple[list, list, str]:
    from cfm_core.scene.scene import builtin_scene

    rows, curves = [], []
    for h in thicknesses:
        scene = builtin_scene("drop-test").with_overrides(thickness=h, element_size=element_size)
        r = cache.run(scene, backend)
        if not r["ok"]:
            rows.append({"thickness": h, "error": r["message"]})
            continue
        rows.append(_row(h, r["summary"]))
        curves.append((f"{1e3 * h:g} mm", r["t"], r["y"]))
    return rows, curves, f"simulated now on '{backend}', element {1e3 * element_size:g} mm, long-term moduli"


def stored_or_coarse(backend: str, cache, path=RESULTS_JSON) -> tuple[list, list, str]:
    path = Path(path)
    if path.is_file():
        data = json.loads(path.read_text())
        rows = [r for r in data.get("rows", []) if r.get("moduli", "long-term") == "long-term"]
        if rows:
            return [_row(r["thickness"], r) for r in rows], [], f"reused {path} (long-term moduli)"
    rows, curves, _ = simulate(backend, cache, (0.008,), element_size=2e-3)
    return rows, curves, f"{path} not found: 8 mm only, coarse 2 mm mesh on '{backend}'"


def soft_then_stiff(t, a) -> dict:
    """Loading is 'soft then stiff' when the pulse is convex on the way up: at half the loading time
    (from 5 % of the peak to the peak) the acceleration is below half the peak."""
    a = np.asarray(a)
    k = int(np.argmax(a))
    peak = a[k]
    i0 = int(np.argmax(a >= 0.05 * peak))
    mid = 0.5 * (t[i0] + t[k])
    ratio = float(np.interp(mid, t[: k + 1], a[: k + 1]) / peak)
    return {"ratio_at_half_loading": ratio, "reproduced": ratio < 0.5}


def facts(rows, curves, curve_note: str) -> list[dict]:
    """The paper's qualitative and quantitative facts against the simulated rows."""
    good = sorted([r for r in rows if "peak_g" in r and r["peak_g"] is not None], key=lambda r: r["thickness"])
    out = []
    for r in good:
        exp = EXPERIMENT_PEAKS_G.get(round(r["thickness"], 6))
        if exp:
            d = (r["peak_g"] - exp) / exp
            out.append({"fact": f"peak at {1e3 * r['thickness']:g} mm: experiment {exp} g",
                        "simulation": f"{r['peak_g']:.1f} g ({100 * d:+.0f} %)", "reproduced": abs(d) <= 0.15})
    if len(good) >= 2:
        p = [r["peak_g"] for r in good]
        out.append({"fact": "peak rises as thickness falls (52.5 g thickest to 80.7 g at 5 mm)",
                    "simulation": ", ".join(f"{1e3 * r['thickness']:g} mm: {r['peak_g']:.1f} g" for r in good),
                    "reproduced": all(x > y for x, y in zip(p, p[1:]))})
        d = [r["duration"] for r in good]
        out.append({"fact": "shorter impacts for thinner specimens",
                    "simulation": ", ".join(f"{1e3 * r['thickness']:g} mm: {1e3 * r['duration']:.2f} ms" for r in good),
                    "reproduced": all(x < y for x, y in zip(d, d[1:]))})
    if good:
        out.append({"fact": "loading longer than unloading",
                    "simulation": ", ".join(f"{1e3 * r['thickness']:g} mm: {1e3 * r['loading_time']:.2f} / "
                                            f"{1e3 * r['unloading_time']:.2f} ms" for r in good),
                    "reproduced": all(r["loading_time"] > r["unloading_time"] for r in good)})
    for label, t, a in curves:
        s = soft_then_stiff(t, a)
        out.append({"fact": f"soft-then-stiff loading ({label}{curve_note})",
                    "simulation": f"a at half the loading time = {100 * s['ratio_at_half_loading']:.0f} % of the peak",
                    "reproduced": s["reproduced"]})
    return out


def compare(mode: str, backend: str | None, cache, extra_curve=None) -> dict:
    """Rows, facts and a note on the source. extra_curve: (label, t, a) used for the soft-then-stiff
    check when the rows come from the stored JSON (which keeps no histories)."""
    if backend is None:
        return {"source": "no backend can run drop tests", "rows": [], "facts": [], "curves": []}
    if mode == "full":
        rows, curves, source = simulate(backend, cache)
        note = ""
    else:
        rows, curves, source = stored_or_coarse(backend, cache)
        note = ""
        if not curves and extra_curve is not None:
            curves, note = [extra_curve], ", the quick suite's small drop test"
    return {"source": source, "rows": rows, "facts": facts(rows, curves, note), "curves": curves,
            "experiment_peaks_g": {str(k): v for k, v in EXPERIMENT_PEAKS_G.items()}, "g0": G0}
