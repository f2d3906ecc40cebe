"""Outcomes of finished runs: histories, summary, a table of the histories and the files.

An outcome keeps the scene it ran (fully resolved), the backend-neutral model, the backend's raw
:class:`~cfm_core.simulation.Result`, the post-processed histories and the summary. It offers the
histories as a pandas DataFrame (units in the column names) and writes itself: ``save(dir)``
writes exactly the files the command line writes (CSV, ``scene.toml``, plot, ``summary.json``
last, so that its presence means the output is complete), staged
(:func:`cfm_core.post.staging.staged_folder`): checked before anything is written, published
whole, the files of an earlier run in the folder replaced, files cfm did not write kept.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..post import G0, compare_histories
from ..tables import as_float
from ..post.plots import plot_acceleration, plot_reaction, subtitled
from ..post.staging import staged_folder
from ..post.fields import parse_fields
from ..post.vtu import write_field_series
from ..post.writers import write_drop_test, write_text, write_reaction
from ..scene.scene import scene_to_toml
from .provenance import describe_run, scene_paths

if TYPE_CHECKING:
    import pandas as pd


def _material_text(summary: dict) -> str:
    """``cfm (long-term)``, or ``ogden (elastic)``: the moduli convention only where it applies."""
    return f"{summary['material']} ({'elastic' if summary.get('elastic') else summary['moduli']})"


def _run_phrases(summary: dict) -> list[str]:
    """``["cfm (long-term)", "numba float64", "hourglass 0.05", "k2 = 3 (default 1.66)"]``: the
    material, the backend with its dtype, and what differs from the defaults
    (:func:`cfm_core.runs.provenance.describe_run`)."""
    record = summary.get("provenance")
    return [_material_text(summary), *(describe_run(record) if record else [summary.get("backend", "?")])]


def _staged_save(out, overwrite: bool, write, scene=None) -> Path:
    """``write(folder)`` into a stage beside ``out``, published into ``out`` when it succeeded (never
    removing a file ``scene`` reads: its mesh)."""
    inputs = scene_paths(scene) if scene is not None else []
    with staged_folder(out, what="output directory", overwrite=overwrite, inputs=inputs) as stage:
        write(stage)
    return Path(out)


@dataclass
class DropTestOutcome:
    """A finished drop test.

    Attributes
    ----------
    scene : Scene
        The resolved scene that ran (all overrides applied).
    model : Model
        The backend-neutral model built from it.
    result : Result
        The backend's raw histories.
    t : ndarray, shape (n,)
        Time from first contact, s (uniform grid at the scene's output rate, 50 kHz by default).
    a_raw, a_cfc : ndarray, shape (n,)
        Impactor acceleration, m/s^2, positive when decelerating: box average of the contact
        force / mass, and filtered with SAE J211/1 CFC 600.
    summary : dict
        Metrics and run statistics as in ``summary.json`` (units under ``"units"``).
    """

    scene: object
    model: object
    result: object
    t: np.ndarray
    a_raw: np.ndarray
    a_cfc: np.ndarray
    summary: dict

    @property
    def peak_g(self) -> float:
        """Peak of the CFC 600 acceleration in g (9.80665 m/s^2)."""
        return float(self.summary["peak_g"])

    def to_dataframe(self) -> pd.DataFrame:
        """The histories as a table.

        Returns
        -------
        pandas.DataFrame
            Columns ``t [s]``, ``a_raw [m/s^2]``, ``a_cfc600 [m/s^2]`` and ``a_cfc600 [g]``,
            one row per sample (n rows).
        """
        import pandas as pd  # deferred: ~0.3 s to import, and a run that writes its files does not need it

        return pd.DataFrame({"t [s]": self.t, "a_raw [m/s^2]": self.a_raw, "a_cfc600 [m/s^2]": self.a_cfc,
                             "a_cfc600 [g]": self.a_cfc / G0})

    def title(self) -> str:
        """Plot title naming what ran.

        Returns
        -------
        str
            Two lines: thickness (mm), speed (m/s), impactor mass (g) and radius (mm), friction,
            element size (mm), the mesh file when one is read; material with its moduli convention
            (or "elastic"), backend and dtype, backend options and material parameters that differ
            from their defaults.
        """
        s, sc = self.summary, self.scene
        name = f"{sc.settings.name}: " if sc.settings.name not in (None, "", sc.type) else ""
        friction = f", friction {sc.contact.friction:g}" if sc.contact.friction else ""
        mesh = f", mesh {Path(sc.specimen.mesh).name}" if sc.specimen.mesh else ""
        return subtitled(f"{name}drop test {1e3 * s['thickness']:.1f} mm, {s['velocity']:g} m/s, "
                         f"{1e3 * sc.impactor.mass:g} g R{1e3 * sc.impactor.radius:g} mm{friction}, "
                         f"{1e3 * s['element_size']:g} mm elements{mesh}", _run_phrases(s), width=75)

    def save(self, out, plot: bool = True, vtu: bool = False, overwrite: bool = True, fields=None,
             full: bool = False) -> Path:
        """Write the run's files, the same the command line writes.

        ``acceleration.csv`` (t s, a_raw and a_cfc600 m/s^2), ``scene.toml`` (the resolved scene
        with its [run] section, so that ``cfm run --scene DIR/scene.toml`` repeats the run),
        ``acceleration.png`` and the ParaView series (``specimen_*.vtu``, ``specimen.pvd``), then
        ``summary.json`` last. Written into a stage beside ``out`` and published only when all
        were written; the files of an earlier cfm output in ``out`` (stale VTU frames included)
        are removed, files cfm did not write are kept.

        Parameters
        ----------
        out : str or path-like
            Output directory (created if missing).
        plot : bool
            Write ``acceleration.png``.
        vtu : bool
            Write the deformed specimen with its fields and the impactor over time (needs a run
            with stored frames, backend option ``frame_interval`` in s; :mod:`cfm_core.post.vtu`).
        overwrite : bool
            False: refuse a directory holding an earlier cfm output.
        fields : str or sequence of str, optional
            Field keys of the VTU files (:data:`cfm_core.post.fields.FIELDS`); None: the default set.
        full : bool
            Mirror the quarter model into the whole specimen in the VTU files.

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` exists and is not a directory, cannot be written, holds an earlier output and
            ``overwrite`` is False, or ``vtu`` was asked of a run without frames.
        NumericalError
            A history or summary value is not finite (nothing is published).
        """
        return _staged_save(out, overwrite, lambda folder: self.write(folder, plot, vtu, fields, full), self.scene)

    def write(self, folder, plot: bool = True, vtu: bool = False, fields=None, full: bool = False) -> list[str]:
        """Write the files of :meth:`save` into ``folder`` directly, without staging (for a caller
        that stages the folder itself, as the command line does around the whole run).

        Parameters
        ----------
        folder : str or path-like
            An existing, empty directory (a stage).
        plot, vtu, fields, full
            As for :meth:`save`.

        Returns
        -------
        list of str
            The names written, the ParaView frames as one ``specimen_*.vtu (N frames)`` entry
            (and ``impactor_*.vtu``, ``fields.json``).

        Raises
        ------
        InputError, NumericalError
            As for :meth:`save`.
        """
        out = Path(folder)
        names = ["acceleration.csv", "scene.toml", "summary.json"]
        if vtu:
            if not self.result.frames:
                raise InputError("vtu output needs a run with stored frames (backend option frame_interval, s; "
                                 "the command line's --vtu sets it).")
            names += write_field_series(out, self.model, self.result, parse_fields(fields), full=full)
        scene = self.scene
        if vtu and scene.run is not None:  # its repeat writes the same frames (cfm run --scene scene.toml)
            scene = scene.with_run(dataclasses.replace(scene.run, fields=",".join(parse_fields(fields)),
                                                       full=bool(full)))
        write_text(out / "scene.toml", scene_to_toml(scene))
        if plot:
            plot_acceleration(out / "acceleration.png", self.t, self.a_raw, self.a_cfc, self.title())
            names.insert(3, "acceleration.png")
        write_drop_test(out, self.t, self.a_raw, self.a_cfc, self.summary)
        return names

    def compare(self, reference: "DropTestOutcome") -> dict:
        """This run's CFC 600 acceleration against a reference run's.

        Parameters
        ----------
        reference : DropTestOutcome
            The run to compare with.

        Returns
        -------
        dict
            :func:`cfm_core.post.compare_histories` of the two: ``rel_l2`` (-), ``peak_diff``
            (-, this peak / reference peak - 1) and ``t_peak_diff`` (s, this minus the reference).
        """
        return compare_histories(self.t, self.a_cfc, reference.t, reference.a_cfc)


@dataclass
class ReactionOutcome:
    """A finished prescribed-motion run (single element, relaxation).

    Attributes
    ----------
    scene, model, result, summary
        As for :class:`DropTestOutcome`.
    t : ndarray, shape (n,)
        Time, s.
    stretch : ndarray, shape (n,)
        Prescribed stretch of the loaded face, -.
    force : ndarray, shape (n,)
        Reaction force on the loaded face, N (negative in compression).
    nominal : ndarray, shape (n,)
        Nominal (first Piola-Kirchhoff) stress, force / reference area, Pa.
    """

    scene: object
    model: object
    result: object
    t: np.ndarray
    stretch: np.ndarray
    force: np.ndarray
    nominal: np.ndarray
    summary: dict

    def to_dataframe(self) -> pd.DataFrame:
        """The histories as a table.

        Returns
        -------
        pandas.DataFrame
            Columns ``t [s]``, ``stretch [-]``, ``reaction_force [N]``, ``nominal_stress [Pa]``.
        """
        import pandas as pd  # deferred: ~0.3 s to import, and a run that writes its files does not need it

        return pd.DataFrame({"t [s]": self.t, "stretch [-]": self.stretch, "reaction_force [N]": self.force,
                             "nominal_stress [Pa]": self.nominal})

    def title(self) -> str:
        """Plot title naming what ran.

        Returns
        -------
        str
            Scene type, final stretch; material with its moduli convention, backend and dtype, and
            what differs from the defaults (as :meth:`DropTestOutcome.title`).
        """
        s = self.summary
        name = f"{self.scene.settings.name}: " if self.scene.settings.name not in (None, "", self.scene.type) else ""
        return subtitled(f"{name}{self.scene.type}, stretch {s['stretch']:g}", _run_phrases(s), width=75)

    def save(self, out, plot: bool = True, overwrite: bool = True) -> Path:
        """Write the run's files, the same the command line writes.

        ``reaction.csv`` (t s, stretch -, reaction_force N, nominal_stress Pa), ``scene.toml``
        (with its [run] section), ``reaction.png``, then ``summary.json`` last; staged as
        :meth:`DropTestOutcome.save`.

        Parameters
        ----------
        out : str or path-like
            Output directory (created if missing).
        plot : bool
            Write ``reaction.png``.
        overwrite : bool
            False: refuse a directory holding an earlier cfm output.

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` exists and is not a directory, cannot be written, or holds an earlier output
            and ``overwrite`` is False.
        NumericalError
            A history or summary value is not finite.
        """
        return _staged_save(out, overwrite, lambda folder: self.write(folder, plot), self.scene)

    def write(self, folder, plot: bool = True) -> list[str]:
        """Write the files of :meth:`save` into ``folder`` directly, without staging.

        Parameters
        ----------
        folder : str or path-like
            An existing, empty directory (a stage).
        plot : bool
            Write ``reaction.png``.

        Returns
        -------
        list of str
            The names written.

        Raises
        ------
        InputError, NumericalError
            As for :meth:`save`.
        """
        out = Path(folder)
        write_text(out / "scene.toml", scene_to_toml(self.scene))
        if plot:
            plot_reaction(out / "reaction.png", self.t, self.force, self.title())
        write_reaction(out, self.t, self.stretch, self.force, self.nominal, self.summary)
        return ["reaction.csv", "scene.toml", "summary.json", *(["reaction.png"] if plot else [])]


#: Bytes per value in the written files: CSV text (shortest repr), VTU (uncompressed base64 of
#: 8-byte values, 4/3 * 8; cfm_core.post.vtu).
_CSV_BYTES, _VTU_BYTES = 26, 11
#: Bytes of a PNG figure (6.4 x 4.2 in at 150 dpi), an upper estimate.
PNG_BYTES = 400_000


def output_bytes(scene, options: dict | None = None, plot: bool = True, vtu: bool = False) -> int:
    """An upper estimate of the size of a run's output, for the free-space check before the run.

    Parameters
    ----------
    scene : Scene
        The scene (end time in s, output rate in Hz, specimen geometry in m or its mesh file).
    options : dict, optional
        Backend options (``frame_interval``, s: how often a VTU frame is stored).
    plot : bool
        A PNG is written.
    vtu : bool
        The ParaView series is written.

    Returns
    -------
    int
        Bytes: the history CSV (4 columns at the output rate up to the end time), the PNG, and
        for ``vtu`` one frame per ``frame_interval`` up to the end time (points, displacement,
        velocity, cells and the default fields of :mod:`cfm_core.post.fields`, the impactor). A drop test stops once the impactor separates, well before its
        automatic end time, so this is several times what is written.
    """
    rows = scene.end_time * float(scene.settings.output_rate) + 2
    total = int(rows * 4 * _CSV_BYTES) + (PNG_BYTES if plot else 0) + 20_000
    interval = (options or {}).get("frame_interval")
    if not (isinstance(interval, (int, float)) and math.isfinite(as_float(interval)) and interval > 0):
        interval = None  # not given, or not a valid interval (the backend's option check says so)
    if vtu and interval and scene.type == "drop-test":
        frames = int(scene.end_time / float(interval)) + 2
        spec = scene.specimen
        if spec.mesh:
            try:
                per_frame = 8 * Path(spec.mesh).stat().st_size + 60_000
            except OSError:
                per_frame = 0
        else:
            h = spec.element_size
            sym = getattr(spec, "symmetry", "quarter")
            nx = max(1, round(spec.width / h / (2 if sym == "quarter" else 1)))
            ny = max(1, round(spec.width / h / (2 if sym in ("quarter", "half") else 1)))
            nz = max(1, round(spec.thickness / h))
            nodes, cells = (nx + 1) * (ny + 1) * (nz + 1), nx * ny * nz
            # points, displacement, velocity (9 per node); connectivity, offsets, types and every
            # default field (29 per cell); the impactor's surface (at most about 120 kB)
            per_frame = (9 * nodes + 29 * cells) * _VTU_BYTES + 120_000
        total += frames * per_frame
    return total
