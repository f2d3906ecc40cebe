"""Every kind of figure the project writes, rendered on a tiny run and checked for what a reader
trips on (issue 24, part 3).

:func:`drawn_figures` records each matplotlib figure drawn while it is active, with the text
artists actually drawn (tick labels outside the view are not); :func:`figure_problems` returns
one sentence per defect of a drawn figure:

- a text outside the figure, or two texts overlapping (boxes from the renderer,
  ``get_window_extent``);
- a legend covering a plotted line or marker, a text in the axes drawn over a curve;
- a labelled curve hidden under another drawn on top of it (the same pixels);
- non-integer ticks on an axis that counts (evaluations, iterations, steps);
- a stress axis in Pa whose ticks reach 10^4 (show kPa);
- a linear time axis over data that resolve times more than 10^4 apart (use a log axis);
- an experimental reference drawn in the colour of another curve than its own.

Figure kinds that fail today are listed in ``KNOWN`` as strict xfails with the defect found:
fixing the figure makes its test XPASS, which fails, so the entry is removed with the fix.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import re
from pathlib import Path

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from cfm_core.cli.app import main  # noqa: E402

G0 = 9.80665


# ----------------------------------------------------------------------------- recording
@contextlib.contextmanager
def drawn_figures():
    """Record the figures drawn on an Agg canvas inside the block: a list of
    ``(figure, renderer, [drawn Text artists])``, one entry per draw."""
    drawn, texts = [], {}
    canvas_draw, text_draw = FigureCanvasAgg.draw, Text.draw

    def record_canvas(canvas, *args, **kwargs):
        fig = canvas.figure
        texts[id(fig)] = []  # texts drawn by this draw only (not by a layout pass before it)
        try:
            out = canvas_draw(canvas, *args, **kwargs)
        finally:
            mine = texts.pop(id(fig))
        drawn.append((fig, canvas.get_renderer(), mine))
        return out

    def record_text(text, renderer, *args, **kwargs):
        out = text_draw(text, renderer, *args, **kwargs)
        fig = text.get_figure(root=True) if hasattr(text, "get_figure") else text.figure
        if text.get_visible() and text.get_text().strip() and id(fig) in texts:
            texts[id(fig)].append(text)
        return out

    FigureCanvasAgg.draw, Text.draw = record_canvas, record_text
    try:
        yield drawn
    finally:
        FigureCanvasAgg.draw, Text.draw = canvas_draw, text_draw


# ----------------------------------------------------------------------------- checks
def _name(text) -> str:
    s = text.get_text().replace("\n", " ")
    return repr(s if len(s) <= 40 else s[:37] + "...")


def _overlap(a, b, tol: float = 1.0) -> bool:
    return min(a.x1, b.x1) - max(a.x0, b.x0) > tol and min(a.y1, b.y1) - max(a.y0, b.y0) > tol


def text_problems(fig, renderer, texts) -> list[str]:
    """Texts outside the figure and pairs of overlapping texts (display boxes, 1 px tolerance)."""
    problems, boxes = [], []
    frame = fig.bbox
    for t in texts:
        box = t.get_window_extent(renderer)
        if box.x0 < frame.x0 - 1 or box.y0 < frame.y0 - 1 or box.x1 > frame.x1 + 1 or box.y1 > frame.y1 + 1:
            problems.append(f"text {_name(t)} runs off the figure ({box.x0:.0f}..{box.x1:.0f} x "
                            f"{box.y0:.0f}..{box.y1:.0f} px; figure {frame.width:.0f} x {frame.height:.0f})")
        boxes.append((t, box))
    for (t1, b1), (t2, b2) in itertools.combinations(boxes, 2):
        if _overlap(b1, b2):
            problems.append(f"texts {_name(t1)} and {_name(t2)} overlap")
    return problems


def _display_xy(line):
    return line.get_transform().transform(np.column_stack(line.get_data()).astype(float))


def _curves(ax):
    """The data lines of an axes: labelled lines with more than two points (not reference lines)."""
    return [ln for ln in ax.get_lines() if ln.get_visible() and len(ln.get_xdata()) > 2]


def legend_problems(fig, renderer) -> list[str]:
    """A legend drawn over a plotted line or marker of its axes."""
    problems = []
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None or not legend.get_visible():
            continue
        box = legend.get_window_extent(renderer)
        pad = legend.borderpad * legend.prop.get_size_in_points() * fig.dpi / 72.0  # empty margin
        box = type(box).from_extents(box.x0 + pad, box.y0 + pad, box.x1 - pad, box.y1 - pad)
        for line in ax.get_lines():
            if not line.get_visible():
                continue
            xy = _display_xy(line)
            xy = xy[np.isfinite(xy).all(axis=1)]
            if line.get_linestyle() in ("None", "", " ") or len(xy) < 2:
                hit = bool(np.any((xy[:, 0] > box.x0) & (xy[:, 0] < box.x1) & (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1)))
            else:
                hit = line.get_transform().transform_path(line.get_path()).intersects_bbox(box, filled=False)
            if hit:
                problems.append(f"the legend of axes {ax.get_title()!r} covers the line {line.get_label()!r}")
    return problems


def annotation_problems(fig, renderer) -> list[str]:
    """A text placed in an axes (annotation, label) drawn over one of its curves."""
    problems = []
    for ax in fig.axes:
        for text in ax.texts:
            if not (text.get_visible() and text.get_text().strip()):
                continue
            box = text.get_window_extent(renderer)
            for line in _curves(ax):
                if line.get_linestyle() not in ("None", "", " ") and \
                        line.get_transform().transform_path(line.get_path()).intersects_bbox(box, filled=False):
                    problems.append(f"the text {_name(text)} is drawn over the curve {line.get_label()!r}")
    return problems


def hidden_curve_problems(fig) -> list[str]:
    """A labelled curve drawn under a later one that covers it (display points within the later
    line's width, the later line solid and at least as wide)."""
    problems = []
    for ax in fig.axes:
        lines = [ln for ln in _curves(ax) if not ln.get_label().startswith("_")]
        for lower, upper in itertools.combinations(lines, 2):  # in drawing order: upper drawn later
            a, b = _display_xy(lower), _display_xy(upper)
            if a.shape != b.shape or upper.get_linestyle() != "-":
                continue
            width = max(upper.get_linewidth() * fig.dpi / 72.0, 1.0)
            if np.nanmax(np.abs(a - b)) < width and upper.get_linewidth() >= 0.9 * lower.get_linewidth():
                problems.append(f"the curve {lower.get_label()!r} is hidden under {upper.get_label()!r}")
    return problems


COUNT = re.compile(r"evaluation|iteration|\bsteps?\b|count|number of", re.I)


def tick_problems(fig) -> list[str]:
    """Counts with fractional ticks; stresses in Pa with ticks of 10^4 or more."""
    problems = []
    for ax in fig.axes:
        for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            label = axis.get_label().get_text()
            ticks = [v for v in axis.get_majorticklocs() if min(lo, hi) <= v <= max(lo, hi)]
            if COUNT.search(label) and axis.get_scale() == "linear" and any(abs(v - round(v)) > 1e-9 for v in ticks):
                problems.append(f"the axis {label!r} counts but has ticks {ticks}")
            if re.search(r"\(Pa\)|\[Pa\]", label) and ticks and max(abs(v) for v in ticks) >= 1e4:
                problems.append(f"the axis {label!r} has ticks up to {max(abs(v) for v in ticks):g} Pa: show kPa")
    return problems


def time_axis_problems(fig) -> list[str]:
    """A linear time axis whose curves resolve times more than 10^4 apart (a relaxation: ms
    loading, a hold of seconds): the early part is invisible. The resolution is the 1st percentile
    of the sample spacing, not its minimum: one short interval (a last row interpolated at the end
    time) resolves nothing."""
    problems = []
    for ax in fig.axes:
        label = ax.xaxis.get_label().get_text()
        if ax.get_xscale() != "linear" or not re.search(r"\btime\b", label, re.I):
            continue
        for line in _curves(ax):
            x = np.asarray(line.get_xdata(), dtype=float)
            steps = np.diff(x)
            steps = steps[steps > 0]
            fine = np.percentile(steps, 1.0) if steps.size else 0.0
            if steps.size and np.nanmax(np.abs(x)) / fine > 1e4:
                problems.append(f"the time axis {label!r} is linear but {line.get_label()!r} spans "
                                f"{np.log10(np.nanmax(np.abs(x)) / fine):.1f} decades of time: use a log axis")
                break
    return problems


EXPERIMENT = re.compile(r"\bexp(?:\.|eriment(?:al)?)\s+(?:peak\s+)?(\d+(?:\.\d+)?\s*mm)", re.I)


def _legend_entries(legend):
    """(text, colour) of a legend's entries."""
    handles = getattr(legend, "legend_handles", None) or getattr(legend, "legendHandles", [])
    return [(t.get_text(), h.get_color()) for t, h in zip(legend.get_texts(), handles) if hasattr(h, "get_color")]


def colour_problems(fig) -> list[str]:
    """An experimental reference (a text or legend entry naming 'exp. 8 mm' or 'experiment 8 mm')
    whose colour is not that of the curves of the same thickness (labelled curves, or legend
    entries naming the thickness), while such curves exist. One axes at a time, plus the figure's
    legends with every axes' curves."""
    from matplotlib.colors import to_hex

    def check(series, experiments):
        found = []
        for text, colour in experiments:
            key = EXPERIMENT.search(text).group(1).replace(" ", "")
            own = [(label, to_hex(c)) for label, c in series if key in label.replace(" ", "")]
            if own and to_hex(colour) not in {c for _, c in own} and to_hex(colour) != "#000000":
                other = [label for label, c in series if to_hex(c) == to_hex(colour)]
                found.append(f"the experiment {key} is drawn in the colour of {other or 'no curve'}, "
                             f"not of its own curves {[label for label, _ in own]}")
        return found

    def split(entries):
        return ([e for e in entries if not EXPERIMENT.search(e[0])], [e for e in entries if EXPERIMENT.search(e[0])])

    problems, everything = [], []
    for ax in fig.axes:
        entries = [(ln.get_label(), ln.get_color()) for ln in _curves(ax) if not ln.get_label().startswith("_")]
        entries += [(t.get_text(), t.get_color()) for t in ax.texts]
        if ax.get_legend() is not None:
            entries += _legend_entries(ax.get_legend())
        everything += entries
        problems += check(*split(entries))
    for legend in fig.legends:
        series, experiments = split(everything + _legend_entries(legend))
        problems += check(series, [e for e in experiments if e in _legend_entries(legend)])
    return list(dict.fromkeys(problems))


def difference_panel_problems(fig) -> list[str]:
    """A comparison of runs without a panel of their differences (identical runs hide each other)."""
    return [] if len(fig.axes) >= 2 else ["a comparison without a difference panel"]


def figure_problems(fig, renderer, texts) -> list[str]:
    """Every defect :mod:`this module <tests.test_figures>` checks, one sentence each."""
    return (text_problems(fig, renderer, texts) + legend_problems(fig, renderer) + annotation_problems(fig, renderer)
            + hidden_curve_problems(fig)
            + tick_problems(fig) + time_axis_problems(fig) + colour_problems(fig))


# ----------------------------------------------------------------------------- the checkers can fail
def _draw(fig):
    with drawn_figures() as drawn:
        fig.canvas.draw()
    return figure_problems(*drawn[-1])


def _fig():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4, 3), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def test_checker_finds_overlapping_and_clipped_texts():
    fig, ax = _fig()
    ax.plot([0, 1, 2], [0, 1, 0], label="data")
    ax.text(0.5, 0.5, "first label", transform=ax.transAxes)
    ax.text(0.5, 0.5, "second label", transform=ax.transAxes)
    fig.text(0.9, 0.5, "far off to the right")
    problems = _draw(fig)
    assert any("overlap" in p and "first label" in p for p in problems)
    assert any("runs off the figure" in p and "far off" in p for p in problems)


def test_checker_finds_a_legend_over_data_a_hidden_curve_and_bad_ticks():
    fig, ax = _fig()
    t = np.linspace(0.0, 30.0, 3001)
    t[1:100] = np.linspace(1e-5, 1e-3, 99)  # a ramp in ms, a hold of 30 s
    y = 3e5 * np.exp(-t)
    ax.plot(t, y, label="measured")
    ax.plot(t, y, "-", label="fitted")
    ax.plot([0, 15, 30], [1.5e5, 1.5e5, 1.5e5], label="across the middle")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("nominal stress (Pa)")
    ax.legend(loc="center right")
    ax.text(10.0, 1.4e5, "over the middle line")
    problems = _draw(fig)
    assert any("covers the line 'across the middle'" in p for p in problems)
    assert any("'measured' is hidden under 'fitted'" in p for p in problems)
    assert any("show kPa" in p for p in problems)
    assert any("'over the middle line' is drawn over the curve 'across the middle'" in p for p in problems)
    assert any("use a log axis" in p for p in problems)


def test_one_short_last_interval_is_no_span_of_decades():
    """A history sampled evenly whose last row is interpolated at the end time (an interval 1e-4 of
    the others) resolves no finer times: no log axis is asked for."""
    fig, ax = _fig()
    t = np.append(np.linspace(0.0, 4.9996, 480), 5.0)
    ax.plot(t, np.sin(t), label="reaction")
    ax.set_xlabel("Time (ms)")
    assert time_axis_problems(fig) == []
    fig, ax = _fig()
    ax.plot([1, 2, 3], [1.0, 0.5, 0.2], "o-")
    ax.set_xlabel("evaluation")
    assert any("counts" in p for p in _draw(fig))


def test_checker_finds_an_experiment_in_another_curves_colour():
    fig, ax = _fig()
    ax.plot(np.arange(5), np.arange(5), color="C0", label="6 mm")
    ax.plot(np.arange(5), 2 * np.arange(5), color="C1", label="8 mm")
    ax.axhline(3.0, color="C0", linestyle="--")
    ax.annotate("exp. 8 mm: 52.5 g", (1.0, 3.0), xycoords=("axes fraction", "data"), color="C0", ha="right")
    assert any("experiment 8mm is drawn in the colour of ['6 mm']" in p for p in _draw(fig))
    from matplotlib.lines import Line2D  # the same with the names in a figure legend, curves unlabelled

    fig, ax = _fig()
    ax.plot(np.arange(5), np.arange(5), color="C0")
    ax.plot(np.arange(5), 2 * np.arange(5), color="C1")
    fig.legend(handles=[Line2D([], [], color="C0", label="6 mm"), Line2D([], [], color="C1", label="8 mm"),
                        Line2D([], [], color="C0", linestyle="--", label="experiment 8 mm: 52.5 g")])
    assert any("experiment 8mm is drawn in the colour of ['6 mm']" in p for p in _draw(fig))


def test_a_clean_figure_passes():
    fig, ax = _fig()
    x = np.linspace(0, 10, 50)
    ax.plot(x, np.sin(x), label="sin")
    ax.plot(x, 0.5 * np.cos(x), label="cos")
    ax.set_ylim(-1.0, 2.5)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("value (-)")
    ax.legend(loc="upper right")
    assert _draw(fig) == []


# ----------------------------------------------------------------------------- the figure kinds
@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two tiny drop tests (20 mm wide, 5 mm thick, 2.5 mm hexahedra; k2 = 1.66 and 3): their
    output folders, and a scene file for them."""
    root = tmp_path_factory.mktemp("figures")
    scene = root / "tiny.toml"
    scene.write_text('[scene]\ntype = "drop-test"\n[specimen]\nwidth = 0.02\nthickness = 0.005\n'
                     'element_size = 0.0025\n')
    base, stiff = root / "base", root / "stiff"
    assert main(["drop-test", "--quiet", "--scene", str(scene), "--out", str(base)]) == 0
    assert main(["drop-test", "--quiet", "--scene", str(scene), "--param", "k2=3", "--out", str(stiff)]) == 0
    return {"root": root, "scene": scene, "base": base, "stiff": stiff}


def _history(folder, column: int = 2):
    """t (s) and the filtered (column 2) or raw (1) acceleration (m/s^2) of a drop-test folder."""
    data = np.loadtxt(Path(folder) / "acceleration.csv", delimiter=",", skiprows=1)
    return data[:, 0], data[:, column]


def kind_acceleration(runs, out):
    assert main(["drop-test", "--quiet", "--scene", str(runs["scene"]), "--out", str(out / "a")]) == 0


def kind_single_element(runs, out):
    assert main(["run", "--quiet", "--scene", "single-element", "--backend", "numba", "--out", str(out / "se")]) == 0


def kind_relaxation_reaction(runs, out):
    from cfm_core.post.plots import plot_reaction

    t = np.concatenate([np.linspace(0.0, 1e-3, 51), np.geomspace(1.1e-3, 30.0, 200)])
    force = np.where(t <= 1e-3, t / 1e-3, 0.02 + 0.98 * np.exp(-(t - 1e-3) / 2e-3))
    plot_reaction(out / "reaction.png", t, -0.5 * force, "relaxation (skfem): compress to 0.7 in 1 ms, hold 30 s")


def kind_point_uniaxial(runs, out):
    assert main(["point", "--material", "cfm", "--uniaxial", "--rate", "100", "--stretch", "0.5", "--param", "k1=1000",
                 "--out", str(out / "uniaxial.csv")]) == 0


def kind_compare(runs, out):
    assert main(["compare", str(runs["base"]), str(runs["stiff"]), "--plot", str(out / "cmp.png")]) == 0


def kind_compare_identical(runs, out):
    assert main(["compare", str(runs["base"]), str(runs["base"]), "--plot", str(out / "cmp.png")]) == 0


def kind_sweep_peaks(runs, out):
    scene = out / "named.toml"  # a named scene with a parameter override and a backend option: a long subtitle
    scene.write_text(runs["scene"].read_text().replace('type = "drop-test"', 'type = "drop-test"\nname = "tiny"')
                     + '[material]\nname = "cfm"\n[material.parameters]\nk1 = 1000\n')
    assert main(["sweep", "--serial", "--quiet", "--scene", str(scene), "--vary", "thickness=0.004,0.005",
                 "--vary", "k2=1.66,3", "--option", "hourglass=0.05", "--out", str(out / "sw")]) in (0, 1)


def kind_calibrate(runs, out):
    t, a = _history(runs["base"], column=1)  # the raw signal as the "measurement": a near-perfect fit
    data = out / "measured.csv"
    np.savetxt(data, np.column_stack([t, a]), delimiter=",", header="t,a", comments="")
    assert main(["calibrate", "--serial", "--scene", str(runs["scene"]), "--data", f"{data}:0.005",
                 "--fit", "k2", "--param", "k2=1.7", "--out", str(out / "cal")]) == 0


def _lab(out):
    lab = out / "lab"
    lab.mkdir()
    assert main(["point", "--material", "cfm", "--uniaxial", "--rate", "100", "--stretch", "0.6", "--no-plot",
                 "--out", str(lab / "comp.csv")]) == 0
    assert main(["point", "--material", "cfm", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--hold", "30",
                 "--no-plot", "--out", str(lab / "relax.csv")]) == 0
    return lab


def kind_fit(runs, out):
    lab = _lab(out)
    assert main(["fit", "--material", "cfm", "--test", f"{lab / 'comp.csv'}:uniaxial:100",
                 f"{lab / 'relax.csv'}:relaxation:100", "--fit", "k1", "--param", "k1=1000",
                 "--out", str(out / "fit")]) == 0


def kind_paper_overlay(runs, out):
    from cfm_verification import paper

    curves, rows = [], []
    for moduli, scale in (("long-term", 1.0), ("instantaneous", 2.5)):
        for h in paper.THICKNESSES:
            t = np.linspace(0.0, 0.011 * h / 0.008, 400)  # a pulse soft at first, peaking late
            a = scale * G0 * 56.8 * (0.008 / h) ** 1.5 * np.exp(-(((t / t[-1]) - 0.55) / 0.15) ** 2)
            curves.append((h, moduli, t, a))
    paper.write_figure(out / "overlay.png", curves, "numba", 1e-3)


def kind_verification_signals(runs, out):
    from cfm_verification import figures

    t, a = _history(runs["base"])
    t2, a2 = _history(runs["stiff"])
    figures.signals(out / "agreement.png", "Agreement: drop test 5 mm, numba against torch",
                    [("numba", t, a), ("torch", t2, a2)], "Impactor acceleration (g)", 1 / G0)


def kind_work_precision(runs, out):
    from cfm_verification import figures

    study = {"label": "8 mm drop test", "runs": [
        {"status": "completed", "backend": b, "options": o, "element_size": h, "wall": w, "peak_error": e,
         "rel_l2": 2 * e}
        for b, o, scale in (("numba", {}, 1.0), ("torch", {}, 6.7), ("skfem", {"error_tol": 2e-3}, 22.0))
        for h, w, e in ((0.002, 0.2 * scale, 2e-2), (0.001, 1.5 * scale, 5e-3), (0.0005, 12 * scale, 1.2e-3))]}
    assert figures.work_precision(out / "wp.png", study)


def kind_drucker_map(runs, out):
    from cfm_verification import figures

    e = list(np.linspace(-0.5, 0.5, 21))
    paths = {name: {crit: {"min_eig_rel": list(np.tanh(np.array(e) * k) + 0.1)} for crit in ("Drucker", "dS/dE")}
             for name, k in (("uniaxial", 1.0), ("equibiaxial", 2.0), ("shear", 0.5), ("hydrostatic", -3.0))}
    figures.drucker_map(out / "drucker.png", "cfm", {"e": e, "paths": paths})


def kind_septa(runs, out):
    from cfm_verification import septa_study

    t = np.linspace(0.0, 0.01, 200)
    rows = [{"thickness": h, "k1s": k1s, "k2s": k2s, "peak_g": 117.0 * (0.005 / h) / (1 + k1s / 3e4) * (1 + k2s / 20),
             "early_g": 6.0 + k1s / 1e3, "t": t, "a": 60 * np.sin(np.pi * t / 0.01) ** 2}
            for h in (0.005, 0.008) for k1s in (0.001, 100, 1000, 10000) for k2s in (0.1, 1.0, 10.0)]
    calibrated = {"fitted": {"k1s": 17971.0, "k2s": 1.8}, "peaks_g": {"0.005": 80.7, "0.008": 52.5}}
    runs_ = {h: (t, 0.4e4 * h * np.sin(np.pi * t / 0.01) ** 2, 80.0, 19.8, 0.004) for h in (0.005, 0.008)}
    septa_study.figure(out, rows, calibrated, runs_)


KINDS = {name[5:]: fn for name, fn in dict(globals()).items() if name.startswith("kind_")}
#: Checks that apply to some kinds only.
EXTRA = {"compare": difference_panel_problems, "compare_identical": difference_panel_problems}

#: Figure kinds that fail the checks today, with what fails (strict: a fix makes the test XPASS).
KNOWN: dict[str, str] = {
}


@pytest.mark.parametrize("kind", [pytest.param(k, marks=pytest.mark.xfail(reason=KNOWN[k], strict=True))
                                  if k in KNOWN else k for k in KINDS])
def test_figure_kind_reads_well(kind, runs, tmp_path):
    with drawn_figures() as drawn:
        KINDS[kind](runs, tmp_path)
    pngs = sorted(p.name for p in tmp_path.rglob("*.png"))
    assert drawn and pngs, f"{kind}: no figure drawn or written"
    extra = EXTRA.get(kind, lambda fig: [])
    problems = {f"figure {i} ({fig.axes[0].get_title() or fig._suptitle and fig._suptitle.get_text()!r})": p
                for i, (fig, renderer, texts) in enumerate(drawn)
                if (p := figure_problems(fig, renderer, texts) + extra(fig))}
    assert not problems, f"{kind} ({', '.join(pngs)}):\n" + json.dumps(problems, indent=1)


@pytest.mark.parametrize("kind, shown, hidden", [
    ("sweep_peaks", ["tiny", "numba float64", "hourglass 0.05", "k1 = 1000 (default 1320)"], ["k2 =", "thickness"]),
    ("point_uniaxial", ["uniaxial stress at 100 1/s", "k1 = 1000 (default 1320)"], []),
    ("fit", ["k1 = 1.32 kPa (start 1 kPa)"], []),
])
def test_titles_name_the_run(kind, shown, hidden, runs, tmp_path):
    """Titles name the scene, backend with dtype, options and parameter overrides (the varied
    names of a sweep left to its axes and legend)."""
    with drawn_figures() as drawn:
        KINDS[kind](runs, tmp_path)
    titles = [ax.get_title() for fig, _, _ in drawn for ax in fig.axes if ax.get_title()]
    assert titles, kind
    for title in titles:
        flat = " ".join(title.split())
        assert all(s in flat for s in shown), (kind, flat, shown)
        assert not any(h in flat.split("\n")[-1] for h in hidden), (kind, flat, hidden)
