"""Figures of the built-in scenes beyond the paper's drop test, for the user guide:
``python -m cfm_verification.scenes_figure --out docs/scenes``.

Runs the paper's drop test (8 mm), ``layered-tissue`` and ``flat-impactor`` on one backend with
their built-in meshes (1 mm elements) and writes

- ``overlay.png``: their filtered impactor accelerations (CFC 600, g) against time (ms);
- ``layered_cut.png``: the von Mises stress (kPa) on the cut y = 0 of the layered run at its peak
  (the material section, deformed, with the impactor's section);
- ``table.md`` and ``results.json``: peak (g), time of peak and contact duration (s) of each,
  with the commit and backend.

About a minute of numba on 2 cores (the layered run is most of it: its stiff skin takes a small
step). SI units in the files; g and ms in the figure.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

SCENES = (("drop test 8 mm (paper)", "drop-test"), ("layered tissue", "layered-tissue"),
          ("flat impactor 1.25 m/s", "flat-impactor"))


def run_all(backend: str = "numba", vtu_dir: Path | None = None) -> tuple[list[dict], list]:
    """Run the three scenes; (rows of the table, overlay curves (label, t s, a_cfc m/s^2)).
    With ``vtu_dir``, the layered run's fields are saved there (``--vtu``)."""
    from cfm_core.runs.pipeline import drop_test
    from cfm_core.scene.scene import builtin_scene

    rows, curves = [], []
    for label, name in SCENES:
        layered = name == "layered-tissue" and vtu_dir is not None
        out = drop_test(builtin_scene(name), backend=backend, **({"frame_interval": 5e-4} if layered else {}))
        if layered:
            out.save(vtu_dir, vtu=True)
        df = out.to_dataframe()
        curves.append((label, df["t [s]"].to_numpy(), df["a_cfc600 [m/s^2]"].to_numpy()))
        rows.append({"scene": name, "label": label, "peak_g": float(out.peak_g),
                     "t_peak": float(out.summary["t_peak"]), "duration": float(out.summary["duration"]),
                     "elements": int(out.result.info["n_elements"])})
    return rows, curves


def markdown_table(rows, backend: str) -> str:
    """The rows as a Markdown table (peak g, times ms)."""
    lines = [f"| scene ({backend}, built-in 1 mm mesh) | peak (g) | time of peak (ms) | contact (ms) | elements |",
             "|---|---|---|---|---|"]
    lines += [f"| `{r['scene']}` | {r['peak_g']:.1f} | {1e3 * r['t_peak']:.2f} | {1e3 * r['duration']:.2f} | "
              f"{r['elements']} |" for r in rows]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/scenes", help="output directory")
    parser.add_argument("--backend", default="numba", help="backend name (default numba)")
    args = parser.parse_args(argv)
    from cfm_core.post.cutview import render_cut
    from cfm_core.post.plots import plot_overlay
    from cfm_core.post.writers import atomic_write, write_json

    from .machine import git_commit

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        rows, curves = run_all(args.backend, Path(tmp) / "layered")
        peak_t = next(r["t_peak"] for r in rows if r["scene"] == "layered-tissue")
        render_cut(Path(tmp) / "layered", peak_t, "von_mises", out / "layered_cut.png")
    plot_overlay(out / "overlay.png", curves, f"built-in scenes, {args.backend}, 1 mm elements (CFC 600)")
    write_json(out / "results.json", {"commit": git_commit(), "backend": args.backend, "rows": rows,
                                      "units": {"peak_g": "g", "t_peak": "s", "duration": "s"}})
    atomic_write(out / "table.md", lambda tmp: Path(tmp).write_text(markdown_table(rows, args.backend)))
    print(markdown_table(rows, args.backend))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
