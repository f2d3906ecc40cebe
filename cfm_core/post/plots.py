"""Figures of drop-test histories (matplotlib, Agg canvas; no pyplot state, no global backend switch).

Inputs are SI (times in s, accelerations in m/s^2); the axes show time in ms and acceleration in
g = 9.80665 m/s^2, as the paper's Figure 3. PNG files are written atomically (temp, then rename).
A run's figure is drawn by the process :mod:`cfm_core.post.figure_process` started ahead of the
run, when one runs.
"""

from __future__ import annotations

import numpy as np

from . import figure_process
from .histories import G0
from .writers import _finite_array, atomic_write

_COLOURS = ["#1f4e9c", "#c0392b", "#27864a", "#8e44ad", "#d68910", "#17879b", "#555555", "#b03a7a"]


#: Units shown scaled in figures (files keep SI): SI unit -> (factor, shown unit).
DISPLAY_UNITS = {"m": (1e3, "mm"), "kg": (1e3, "g"), "s": (1e3, "ms"), "Pa": (1e-3, "kPa")}


def display(unit: str) -> tuple[float, str]:
    """(factor, unit text) to show a quantity in ``unit`` (SI) in a figure: lengths in mm, masses
    in g, times in ms, stresses in kPa; dimensionless ("-") shows no unit.

    Parameters
    ----------
    unit : str
        SI unit of the quantity, e.g. ``"m"``, ``"Pa"``, ``"-"``.

    Returns
    -------
    factor : float
        Multiply the SI value by it to get the shown value.
    shown : str
        The shown unit (``"mm"``, ``"kPa"``, ...); empty for ``"-"`` or ``""``; other units are
        shown as given with factor 1.
    """
    return DISPLAY_UNITS.get(unit, (1.0, "" if unit in ("-", "") else unit))


def display_text(name: str, value: float, unit: str) -> str:
    """``name = value unit`` for a legend, in the units of :func:`display` (``k2 = 1.66``,
    ``thickness = 5 mm``).

    Parameters
    ----------
    name : str
        Quantity name.
    value : float
        Value in ``unit`` (SI).
    unit : str
        SI unit, e.g. ``"m"``; ``"-"`` for dimensionless.

    Returns
    -------
    str
        The text, value formatted with ``:g`` in the shown unit.
    """
    factor, shown = display(unit)
    return f"{name} = {value * factor:g}{' ' + shown if shown else ''}"


def subtitled(title: str, phrases, width: int = 80, lines: int = 3) -> str:
    """A figure title with a subtitle of short phrases (what differs between the runs shown, or
    how one run differs from the defaults), wrapped to ``width`` characters and cut after
    ``lines`` lines (the cut ends with "...").

    Parameters
    ----------
    title : str
        The first line.
    phrases : sequence of str
        Joined with "; ".
    width : int
        Characters per subtitle line.
    lines : int
        Most subtitle lines.

    Returns
    -------
    str
        ``title`` alone when ``phrases`` is empty, else the title and the subtitle lines.
    """
    import textwrap

    text = "; ".join(str(p) for p in phrases)
    if not text:
        return title
    wrapped = textwrap.wrap(text, width=width, max_lines=lines, placeholder=" ...")
    return "\n".join([title, *wrapped])


def _title_size(title: str) -> float | None:
    """Font size (pt) of a title in a figure 6.4 in wide: the default (None) for up to two lines
    of at most 62 characters; smaller for a longer line, so that it stays inside the figure, and
    8 pt for three lines or more, so that the axes keep their room."""
    lines = title.split("\n")
    longest = max(len(line) for line in lines)
    if len(lines) >= 3 or longest > 78:
        return 8.0
    return None if longest <= 62 else 10.0


def _figure(title: str):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.2), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_title(title, fontsize=_title_size(title))
    ax.set_xlabel("Time (ms)")
    ax.set_ylabel("Impactor acceleration (g)")
    ax.grid(True, color="0.88", linewidth=0.6)
    ax.axhline(0.0, color="0.6", linewidth=0.6)
    return fig, ax


def _save(fig, path) -> None:
    """Write ``fig`` as a PNG atomically: one draw of the canvas (the constrained layout runs inside
    it), then its pixels. The same pixels and metadata as ``fig.savefig(path, format="png")``, which
    draws twice (a layout pass, then the image): a third less time."""
    from matplotlib.image import imsave

    fig.canvas.draw()
    atomic_write(path, lambda tmp: imsave(tmp, fig.canvas.buffer_rgba(), format="png", dpi=fig.dpi))


def plot_acceleration(path, t, a_raw, a_cfc, title: str) -> None:
    """Save a PNG of one history: raw (thin grey) and CFC 600 (bold) acceleration against time.

    Plotted in ms and g (9.80665 m/s^2), as the paper's Figure 3. The peak of the filtered curve
    is marked and labelled. Written atomically.

    Parameters
    ----------
    path : str or path-like
        The PNG file.
    t : array_like, shape (n,)
        Times (s).
    a_raw, a_cfc : array_like, shape (n,)
        Box-averaged and SAE J211/1 CFC 600 filtered impactor acceleration (m/s^2, positive
        decelerating).
    title : str
        Figure title.

    Raises
    ------
    InputError
        An input that is not 1-D.
    NumericalError
        A non-finite input value; no file is written.
    """
    t = _finite_array("t", t, ndim=1)
    a_raw = _finite_array("a_raw", a_raw, ndim=1)
    a_cfc = _finite_array("a_cfc", a_cfc, ndim=1)
    if figure_process.draw("plot_acceleration", path, t, a_raw, a_cfc, title):
        return
    fig, ax = _figure(title)
    ms = 1e3 * t
    k = int(np.argmax(a_cfc))
    ax.plot(ms, a_raw / G0, color="0.6", linewidth=0.7, label="raw (box average)")
    ax.plot(ms, a_cfc / G0, color=_COLOURS[0], linewidth=2.2,
            label=f"SAE J211 CFC 600 (peak {a_cfc[k] / G0:.1f} g at {ms[k]:.2f} ms)")
    ax.plot(ms[k], a_cfc[k] / G0, "o", color=_COLOURS[0], markersize=4)
    top = max(float(np.max(a_raw)), float(np.max(a_cfc))) / G0
    if top > 0.0:
        ax.set_ylim(top=1.15 * top)  # room for the legend
    ax.set_xlim(ms[0], ms[-1])
    ax.legend(loc="upper right", fontsize=8, frameon=False)
    _save(fig, path)


def plot_overlay(path, curves: list, title: str, reference_peaks: dict | None = None) -> None:
    """Save a PNG of several filtered histories on one axes (ms and g); written atomically.

    More than four curves put the legend beside the axes.

    Parameters
    ----------
    path : str or path-like
        The PNG file.
    curves : list of (str, array_like, array_like)
        ``(label, t (s) shape (n,), a_cfc (m/s^2) shape (n,))`` per curve.
    title : str
        Figure title.
    reference_peaks : dict of str to float, optional
        ``{label: peak acceleration in m/s^2}`` drawn as dashed horizontal lines (e.g.
        experimental peaks, 52.5 g = 52.5 * 9.80665 m/s^2, paper section 4); a line whose label
        equals a curve's label takes that curve's colour.

    Raises
    ------
    InputError
        An input that is not 1-D.
    NumericalError
        A non-finite input value; no file is written.
    """
    fig, ax = _figure(title)
    colour_of = {}
    t_max, top = 0.0, 0.0
    for i, (label, t, a) in enumerate(curves):
        t = _finite_array(f"t of {label!r}", t, ndim=1)
        a = _finite_array(f"a_cfc of {label!r}", a, ndim=1)
        colour_of[label] = _COLOURS[i % len(_COLOURS)]
        ax.plot(1e3 * t, a / G0, color=colour_of[label], linewidth=1.8, label=str(label))
        t_max = max(t_max, 1e3 * float(t[-1]))
        top = max(top, float(np.max(a)) / G0)
    for j, (label, peak) in enumerate((reference_peaks or {}).items()):
        peak = float(_finite_array(f"reference peak {label!r}", peak))
        colour = colour_of.get(label, _COLOURS[(len(curves) + j) % len(_COLOURS)])
        top = max(top, peak / G0)
        ax.axhline(peak / G0, color=colour, linestyle="--", linewidth=1.0)
        ax.annotate(f"exp. {label}: {peak / G0:.1f} g", (1.0, peak / G0), xycoords=("axes fraction", "data"),
                    xytext=(-4, 3), textcoords="offset points", ha="right", fontsize=7, color=colour)
    if t_max > 0.0:
        ax.set_xlim(0.0, t_max)
    ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]), top=1.25 * top if top > 0.0 else None)
    if len(curves) > 4:  # a long legend goes beside the axes (constrained layout makes room for it)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    elif curves:
        ax.legend(loc="upper right", fontsize=8, framealpha=0.95, edgecolor="0.8")
    _save(fig, path)


def plot_reaction(path, t, force, title: str) -> None:
    """Save a PNG of a reaction-force history, plotted in ms and N; written atomically.

    When the history spans more than three decades of time after its first sample (a relaxation
    hold of seconds after a load of milliseconds), the time axis is logarithmic.

    Parameters
    ----------
    path : str or path-like
        The PNG file.
    t : array_like, shape (n,)
        Times (s).
    force : array_like, shape (n,)
        Reaction force (N).
    title : str
        Figure title.

    Raises
    ------
    InputError
        An input that is not 1-D.
    NumericalError
        A non-finite input value; no file is written.
    """
    t = _finite_array("t", t, ndim=1)
    force = _finite_array("reaction_force", force, ndim=1)
    if figure_process.draw("plot_reaction", path, t, force, title):
        return
    fig, ax = _figure(title)
    ax.set_ylabel("Reaction force (N)")
    ms = 1e3 * t
    positive = ms > 0.0
    if positive.sum() > 1 and ms[-1] > 1e3 * ms[positive][0]:
        ax.set_xscale("log")
        ms, force = ms[positive], force[positive]
    k = int(np.argmax(np.abs(force)))
    ax.plot(ms, force, color=_COLOURS[0], linewidth=2.0,
            label=f"largest |F| = {abs(force[k]):.4g} N at {ms[k]:.3g} ms; final {force[-1]:.4g} N")
    ax.plot(ms[k], force[k], "o", color=_COLOURS[0], markersize=4)
    ax.legend(loc="best", fontsize=8, frameon=False)
    _save(fig, path)


def plot_uniaxial(path, stretch, nominal, title: str) -> None:
    """Save a PNG of a uniaxial test: nominal stress (Pa, shown in kPa) against stretch (-).

    Parameters
    ----------
    path : str or path-like
        The PNG file (written atomically).
    stretch : array_like, shape (n,)
        Stretch (-).
    nominal : array_like, shape (n,)
        Nominal stress (Pa).
    title : str
        Figure title.

    Raises
    ------
    InputError
        An input that is not 1-D.
    NumericalError
        A non-finite input value; no file is written.
    """
    stretch = _finite_array("stretch", stretch, ndim=1)
    nominal = _finite_array("nominal_stress", nominal, ndim=1)
    fig, ax = _figure(title)
    ax.set_xlabel("Stretch (-)")
    ax.set_ylabel("Nominal stress (kPa)")
    ax.plot(stretch, 1e-3 * nominal, color=_COLOURS[0], linewidth=2.0)
    ax.plot(stretch[-1], 1e-3 * nominal[-1], "o", color=_COLOURS[0], markersize=4,
            label=f"{1e-3 * nominal[-1]:.3g} kPa at stretch {stretch[-1]:.3g}")
    ax.legend(loc="best", fontsize=8, frameon=False)
    _save(fig, path)
