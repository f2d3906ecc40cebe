"""The figure of ``cfm compare --plot``: the runs' signals over each other and, below, each run's
difference from the reference on the reference's times (identical runs would hide each other in
an overlay alone; the difference panel shows that they agree, and by how much they do not).
"""

from __future__ import annotations

import numpy as np

from .plots import _COLOURS, _save, _title_size
from .writers import _finite_array


def plot_comparison(path, curves: list, title: str, ylabel: str, scale: float = 1.0) -> None:
    """Save a PNG comparing runs with a reference: their signals (top) and each run's difference
    from the reference (bottom), time in ms; written atomically.

    The difference is taken on the reference's times inside the time range both runs cover (the
    run linearly interpolated). The reference is drawn solid and wide, the runs dashed over it, so
    a run equal to the reference stays visible; the difference panel names the largest difference.

    Parameters
    ----------
    path : str or path-like
        The PNG file.
    curves : list of (str, array_like, array_like)
        ``(label, t (s) shape (n,), signal (SI) shape (n,))`` per run; the first is the reference.
    title : str
        Figure title (may hold subtitle lines: what differs between the runs).
    ylabel : str
        Label of the signal axis with its shown unit, e.g. ``"Impactor acceleration (g)"``.
    scale : float
        The shown value is the signal divided by it (9.80665 to show m/s^2 in g).

    Raises
    ------
    InputError
        Fewer than two curves, or an input that is not 1-D.
    NumericalError
        A non-finite input value; no file is written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..errors import InputError

    if len(curves) < 2:
        raise InputError(f"plot_comparison: needs a reference and at least one run, got {len(curves)} curve(s).")
    curves = [(str(label), _finite_array(f"t of {label!r}", t, ndim=1),
               _finite_array(f"signal of {label!r}", y, ndim=1) / scale) for label, t, y in curves]
    fig = Figure(figsize=(6.4, 5.6), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1.0])
    top.set_title(title, fontsize=_title_size(title))
    (_, t0, y0), peak = curves[0], 0.0
    largest = []
    for i, (label, t, y) in enumerate(curves):
        colour = _COLOURS[i % len(_COLOURS)]
        style = {"linewidth": 2.4, "linestyle": "-"} if i == 0 else {"linewidth": 1.2, "linestyle": (0, (4, 2))}
        top.plot(1e3 * t, y, color=colour, label=label + (" (reference)" if i == 0 else ""), **style)
        peak = max(peak, float(np.max(np.abs(y))))
        if i == 0:
            continue
        inside = (t0 >= max(t0[0], t[0])) & (t0 <= min(t0[-1], t[-1]))
        diff = np.interp(t0[inside], t, y) - y0[inside]
        largest.append(float(np.max(np.abs(diff))) if diff.size else float("nan"))
        bottom.plot(1e3 * t0[inside], diff, color=colour, label=f"{label} - reference", **style)
    shown = ylabel.rsplit("(", 1)[-1].rstrip(")") if ylabel.endswith(")") else ""
    for ax in (top, bottom):
        ax.grid(True, color="0.88", linewidth=0.6)
        ax.axhline(0.0, color="0.6", linewidth=0.6)
    top.set_ylabel(ylabel)
    lo, hi = top.get_ylim()
    top.set_ylim(lo, hi + 0.45 * (hi - lo))  # room above the curves for the legend
    top.legend(loc="upper right", fontsize=7, framealpha=0.95, edgecolor="0.8")
    bottom.set_xlabel("Time (ms)")
    bottom.set_ylabel(f"Difference ({shown})" if shown else "Difference")
    worst = max((v for v in largest if np.isfinite(v)), default=0.0)
    if worst == 0.0:
        bottom.set_ylim(-1.0, 1.0)
        note = "identical to the reference at every compared time"
    else:
        lo, hi = bottom.get_ylim()
        bottom.set_ylim(lo, hi + 0.6 * (hi - lo))  # room above the curves for the note
        note = "largest |difference|: " + ", ".join(f"{v:.3g} {shown}".rstrip() for v in largest)
        if peak > 0.0:
            note += f" ({100 * worst / peak:.2g} % of the largest |signal|)"
    bottom.text(0.01, 0.96, note, transform=bottom.transAxes, ha="left", va="top", fontsize=7)
    _save(fig, path)
