"""Measured drop-test curves: reading, checking and putting them on the simulation's grid.

A curve is a CSV with a header naming columns ``t`` (s, from first contact: samples before t = 0
are ignored) and ``a`` (m/s^2, positive when the impactor decelerates), any sampling, rows in
time order, the whole pulse until separation. It is put on the simulation's grid exactly as a
simulated history: box average on the 50 kHz grid (:func:`cfm_core.post.acceleration_histories`),
then SAE J211 CFC 600 (:func:`cfm_core.post.cfc_filter`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..errors import InputError
from ..post import acceleration_histories

#: Fewest samples a measured curve must have (rows after t >= 0).
MIN_POINTS = 10
#: Channel frequency class of the filter applied to measured and simulated curves (SAE J211/1).
CFC = 600.0


@dataclass(frozen=True)
class Curve:
    """A measured history on the simulation grid: t (s), a (m/s^2, CFC-filtered), the file."""

    name: str
    path: str
    thickness: float
    t: np.ndarray
    a: np.ndarray

    @property
    def peak(self) -> float:
        """Largest filtered measured acceleration (m/s^2), the residual scale."""
        return float(np.max(self.a))


# ----------------------------------------------------------------------------- measured data
def parse_data_spec(spec: str, default_thickness: float | None) -> tuple[str, float]:
    """``file.csv:0.005`` -> (file, thickness in m); without ``:thickness`` the default is used.

    default_thickness: the --scene file's thickness (m), or None (then a thickness is required).
    """
    path, sep, tail = str(spec).rpartition(":")
    thickness = None
    if sep and path:
        try:
            thickness = float(tail)
        except ValueError:
            path = spec  # a ':' that is part of the path
    else:
        path = spec
    if thickness is None:
        if default_thickness is None:
            raise InputError(f"--data {spec}: no specimen thickness; give it as {path}:THICKNESS in m "
                             f"(e.g. {path}:0.005 for 5 mm), or give a --scene whose thickness applies.")
        thickness = default_thickness
    if not (math.isfinite(thickness) and 1e-4 <= thickness <= 0.1):
        hint = f" (in m: {thickness:g} mm is {thickness / 1e3:g} m)" if 1.0 <= thickness <= 100.0 else ""
        raise InputError(f"--data {spec}: thickness {thickness!r} m is not allowed; it must be a number "
                         f"with 1e-4 <= thickness <= 0.1 m, the specimen's thickness{hint}.")
    return path, thickness


def read_measured(path) -> tuple[np.ndarray, np.ndarray]:
    """(t (s), a (m/s^2)) from a CSV with columns t and a; InputError naming the file and row.

    Lines starting with '#' and blank lines are skipped; the first other line is the header
    (other columns are ignored). Every value must be a finite number; t must increase.
    """
    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"data file '{p}' cannot be read: {getattr(exc, 'strerror', None) or exc}.") from None
    rows = [(n, line) for n, line in enumerate(lines, start=1) if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        raise InputError(f"data file '{p}' is empty; it needs a header line 't,a' and rows of time (s) "
                         f"and acceleration (m/s^2).")
    header = [h.strip() for h in rows[0][1].split(",")]
    if "t" not in header or "a" not in header:
        raise InputError(f"data file '{p}', line {rows[0][0]}: the header {rows[0][1].strip()!r} must name "
                         f"the columns t (s) and a (m/s^2), e.g. 't,a'.")
    it, ia = header.index("t"), header.index("a")
    values = np.empty((len(rows) - 1, 2))
    for k, (n, line) in enumerate(rows[1:]):
        cells = line.split(",")
        if len(cells) != len(header):
            raise InputError(f"data file '{p}', line {n}: {len(cells)} values for {len(header)} columns "
                             f"({', '.join(header)}).")
        for j, col in ((0, it), (1, ia)):
            try:
                values[k, j] = float(cells[col])
            except ValueError:
                values[k, j] = math.nan
            if not math.isfinite(values[k, j]):
                raise InputError(f"data file '{p}', line {n}: {header[col]} = {cells[col].strip()!r} is not a "
                                 f"finite number ({'s' if j == 0 else 'm/s^2'}).")
    t, a = values[:, 0], values[:, 1]
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        n = rows[1 + bad[0] + 1][0]
        raise InputError(f"data file '{p}', line {n}: t = {float(t[bad[0] + 1])!r} s does not increase (previous "
                         f"row: {float(t[bad[0]])!r} s); rows must be in time order.")
    keep = t >= 0.0
    if keep.sum() < MIN_POINTS:
        raise InputError(f"data file '{p}' has {int(keep.sum())} rows at t >= 0 s; at least {MIN_POINTS} are "
                         f"needed (t is the time from first contact, s).")
    return t[keep], a[keep]


def read_curve(spec: str, default_thickness: float | None, rate: float = 50_000.0, cfc: float = CFC) -> Curve:
    """A measured curve from ``file.csv[:thickness]`` on the grid k / rate, CFC-filtered."""

    path, thickness = parse_data_spec(spec, default_thickness)
    t, a = read_measured(path)
    # Box average of the (linearly interpolated) signal on the grid: the same resampling as a
    # simulated contact force, with mass 1 kg and the signal as the "force".
    grid, _, a_cfc = acceleration_histories(SimpleNamespace(t=t, impulse=None, contact_force=a), 1.0, rate, cfc)
    if not np.max(a_cfc) > 0.0:
        raise InputError(f"data file '{path}': the filtered acceleration is never positive; a is positive "
                         f"when the impactor decelerates (m/s^2): flip its sign.")
    return Curve(Path(path).stem, path, thickness, grid, a_cfc)


def read_curves(specs, scene, scene_given: bool) -> list[Curve]:
    """The curves of ``--data`` specs; names made unique; the same (file, thickness) twice is an error."""
    if not specs:
        raise InputError("give at least one --data FILE.csv[:THICKNESS] (t in s, a in m/s^2).")
    default = scene.specimen.thickness if scene_given else None
    rate = float(scene.settings.output_rate)
    curves, seen, names = [], set(), {}
    for spec in specs:
        c = read_curve(spec, default, rate)
        key = (str(Path(c.path).resolve()), c.thickness)
        if key in seen:
            raise InputError(f"--data {spec}: this file is given twice with thickness {c.thickness:g} m; "
                             f"give each measurement once.")
        seen.add(key)
        names[c.name] = names.get(c.name, 0) + 1
        name = c.name if names[c.name] == 1 else f"{c.name}-{names[c.name]}"
        curves.append(Curve(name, c.path, c.thickness, c.t, c.a))
    return curves
