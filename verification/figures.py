"""PNG figures of the verification report (matplotlib Agg canvas, atomic writes via cfm_core)."""

from __future__ import annotations

import numpy as np

from cfm_core.post.histories import G0
from cfm_core.post.plots import _COLOURS, _save

_MARKERS = "osD^v<>p"


def _fig(title, xlabel, ylabel, ncols=1, size=(6.4, 4.2)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=130, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    fig.suptitle(title)
    for ax in axes:
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", color="0.9", linewidth=0.6)
    return fig, axes


def signals(path, title, curves, ylabel, scale=1.0, tscale=1e3) -> None:
    """curves: [(label, t (s), y)]; y shown times ``scale``, t in ms."""
    fig, (ax,) = _fig(title, "Time (ms)", ylabel)
    for i, (label, t, y) in enumerate(curves):
        ax.plot(tscale * np.asarray(t), scale * np.asarray(y), color=_COLOURS[i % len(_COLOURS)],
                linewidth=2.0 if i == 0 else 1.2, linestyle="-" if i == 0 else "--", label=label)
    ax.legend(fontsize=8, frameon=False)
    _save(fig, path)


def work_precision(path, study) -> bool:
    """Log-log error against wall time: one line per (backend, step option) through its element
    sizes, peak error and rel L2 side by side; the element size is written once per point, offset
    by step option so that labels of neighbouring points do not overlap."""
    runs = [r for r in study["runs"] if r.get("status") == "completed" and "peak_error" in r]
    if not runs:
        return False
    fig, axes = _fig(f"Work-precision: {study['label']}", "Wall time (s)", "", ncols=2, size=(10.4, 4.6))
    axes[0].set_ylabel("Relative peak error (-)")
    axes[1].set_ylabel("Relative L2 error (-)")
    series = sorted({(r["backend"], tuple(sorted(r["options"].items()))) for r in runs})
    backends = sorted({b for b, _ in series})
    for j, (name, opts) in enumerate(series):
        i = backends.index(name)
        k = [o for b, o in series if b == name].index(opts)
        mine = sorted([r for r in runs if r["backend"] == name and tuple(sorted(r["options"].items())) == opts],
                      key=lambda r: r["wall"])
        w = np.array([max(r["wall"], 1e-6) for r in mine])
        label = ", ".join([name] + [f"{key}={v:g}" for key, v in opts])  # "numba", "skfem, error_tol=0.002"
        for ax, key in zip(axes, ("peak_error", "rel_l2")):
            e = np.array([max(r[key], 1e-16) for r in mine])
            ax.loglog(w, e, marker=_MARKERS[i % len(_MARKERS)], color=_COLOURS[i % len(_COLOURS)],
                      linestyle="-" if k == 0 else "--", markerfacecolor="none" if k else None, label=label)
            for r, x, y in zip(mine, w, e):
                if r["element_size"] is not None:
                    ax.annotate(f"{1e3 * r['element_size']:g} mm", (x, y), xytext=(5, 6 if k == 0 else -11),
                                textcoords="offset points", fontsize=6, color=_COLOURS[i % len(_COLOURS)])
    for ax in axes:
        ax.axhline(0.01, color="0.5", linestyle=":", linewidth=1.0, label="1 % error")
    axes[1].legend(fontsize=7, frameon=False, loc="center left", bbox_to_anchor=(1.02, 0.5))
    _save(fig, path)
    return True


def drucker_map(path, name, smap) -> None:
    """Relative smallest eigenvalue (Drucker criterion) along each path against nominal strain."""
    which = "paper Table 1 values" if name == "cfm" else "its own defaults, not from the paper"
    fig, axes = _fig(f"Material stability: {name} (instantaneous response, {which})", "Nominal strain (-)", "",
                     ncols=2, size=(9.6, 4.0))
    e = np.array(smap["e"])
    for ax, crit in zip(axes, ("Drucker", "dS/dE")):
        ax.set_ylabel(f"min eigenvalue / max |eigenvalue| ({crit})")
        for i, (path_name, res) in enumerate(smap["paths"].items()):
            r = np.array([np.nan if x is None else x for x in res[crit]["min_eig_rel"]], dtype=float)
            ax.plot(e, r, color=_COLOURS[i % len(_COLOURS)], label=path_name)
        ax.axhline(0.0, color="k", linewidth=0.8)
        ax.set_yscale("symlog", linthresh=1e-6)
    handles, labels = axes[0].get_legend_handles_labels()  # one legend below the panels: it covers no curve
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=8, frameon=False)
    _save(fig, path)


def paper_overlay(path, curves, experiment_g, title) -> None:
    """The paper's drop tests side by side: one panel per moduli convention, one colour per
    thickness (the same in both panels), the experimental peaks as dashed lines in the colour of
    their thickness, named in the legend below the panels (it never covers a curve).

    Parameters
    ----------
    path : str or Path
        The PNG file (written atomically).
    curves : list of (float, str, array_like, array_like)
        ``(thickness (m), moduli convention, t (s) shape (n,), filtered acceleration (m/s^2) shape (n,))``.
    experiment_g : dict of float to float
        Experimental peak (g) by thickness (m), paper section 4.
    title : str
        Figure title.
    """
    from matplotlib.lines import Line2D

    conventions = list(dict.fromkeys(c[1] for c in curves))
    thicknesses = sorted({c[0] for c in curves})
    colour = {h: _COLOURS[i % len(_COLOURS)] for i, h in enumerate(thicknesses)}
    fig, axes = _fig(title, "Time from first contact (ms)", "Impactor acceleration, CFC 600 (g)",
                     ncols=len(conventions), size=(4.2 * len(conventions), 4.4))
    for ax, moduli in zip(axes, conventions):
        ax.set_title(f"{moduli} moduli", fontsize=10)
        top, t_end = 0.0, 0.0
        for h, m, t, a in curves:
            if m != moduli:
                continue
            g = np.asarray(a) / G0
            ax.plot(1e3 * np.asarray(t), g, color=colour[h], linewidth=1.6)
            top, t_end = max(top, float(g.max())), max(t_end, 1e3 * float(t[-1]))
        for h, peak in experiment_g.items():  # named in the legend: a label in the axes would cross curves
            ax.axhline(peak, color=colour.get(h, "0.3"), linestyle="--", linewidth=1.0)
        ax.set_xlim(0.0, t_end)
        ax.set_ylim(min(0.0, ax.get_ylim()[0]), 1.1 * max(top, *experiment_g.values()))
    handles = [Line2D([], [], color=colour[h], linewidth=1.6, label=f"{1e3 * h:g} mm") for h in thicknesses]
    handles += [Line2D([], [], color=colour.get(h, "0.3"), linestyle="--", linewidth=1.0,
                       label=f"experiment {1e3 * h:g} mm: {peak:g} g") for h, peak in sorted(experiment_g.items())]
    rows = max(1, len(experiment_g))  # the legend fills by column: the experiments make its last one
    fig.legend(handles=handles, loc="outside lower center", ncols=-(-len(handles) // rows), fontsize=8, frameon=False)
    _save(fig, path)
