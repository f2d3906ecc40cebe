"""Outcomes of finished runs: histories, summary, a table of the histories and the files.

An outcome keeps the scene it ran (fully resolved), the backend-neutral model, the backend's raw
:class:`~cfm_core.simulation.Result`, the post-processed histories and the summary. It offers the
histories as a pandas DataFrame (units in the column names) and writes itself: ``save(dir)``
writes exactly the files the command line writes (CSV, ``scene.toml``, plot, ``summary.json``
last, so that its presence means the output is complete).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..post import G0, compare_histories
from ..post.plots import plot_acceleration, plot_reaction
from ..post.writers import output_folder, write_drop_test, write_text, write_reaction, write_vtu_series
from ..scene.scene import scene_to_toml


def _material_text(summary: dict) -> str:
    """``cfm (long-term)``, or ``ogden (elastic)``: the moduli convention only where it applies."""
    return f"{summary['material']} ({'elastic' if summary.get('elastic') else summary['moduli']})"


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
        return pd.DataFrame({"t [s]": self.t, "a_raw [m/s^2]": self.a_raw, "a_cfc600 [m/s^2]": self.a_cfc,
                             "a_cfc600 [g]": self.a_cfc / G0})

    def title(self) -> str:
        """Plot title naming what ran.

        Returns
        -------
        str
            Two lines: thickness (mm), speed (m/s), impactor mass (g) and radius (mm), friction,
            element size (mm); material with its moduli convention (or "elastic"), backend.
        """
        s, sc = self.summary, self.scene
        name = f"{sc.settings.name}: " if sc.settings.name not in (None, "", sc.type) else ""
        friction = f", friction {sc.contact.friction:g}" if sc.contact.friction else ""
        return (f"{name}drop test {1e3 * s['thickness']:.1f} mm, {s['velocity']:g} m/s, "
                f"{1e3 * sc.impactor.mass:g} g R{1e3 * sc.impactor.radius:g} mm{friction}, "
                f"{1e3 * s['element_size']:g} mm elements\n{_material_text(s)}, {s['backend']}")

    def save(self, out, plot: bool = True, vtu: bool = False) -> Path:
        """Write the run's files, the same the command line writes.

        ``acceleration.csv`` (t s, a_raw and a_cfc600 m/s^2), ``scene.toml`` (the resolved scene,
        so that ``cfm run --scene DIR/scene.toml`` repeats the run), ``acceleration.png`` and the
        ParaView series (``specimen_*.vtu``, ``specimen.pvd``), then ``summary.json`` last: its
        presence means the output is complete.

        Parameters
        ----------
        out : str or path-like
            Output directory (created if missing).
        plot : bool
            Write ``acceleration.png``.
        vtu : bool
            Write the deformed specimen over time (needs a run with stored frames, backend option
            ``frame_interval`` in s).

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` exists and is not a directory, or ``vtu`` was asked of a run without frames.
        NumericalError
            A history or summary value is not finite (nothing is written as complete).
        """
        out = _prepare(out)
        if vtu:
            write_vtu_series(out, self.model.nodes, self.model.hexes, self.result.frames)
        write_text(out / "scene.toml", scene_to_toml(self.scene))
        if plot:
            plot_acceleration(out / "acceleration.png", self.t, self.a_raw, self.a_cfc, self.title())
        write_drop_test(out, self.t, self.a_raw, self.a_cfc, self.summary)
        return out

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
        return pd.DataFrame({"t [s]": self.t, "stretch [-]": self.stretch, "reaction_force [N]": self.force,
                             "nominal_stress [Pa]": self.nominal})

    def title(self) -> str:
        """Plot title naming what ran.

        Returns
        -------
        str
            Scene type, final stretch, material with its moduli convention, backend.
        """
        s = self.summary
        name = f"{self.scene.settings.name}: " if self.scene.settings.name not in (None, "", self.scene.type) else ""
        return f"{name}{self.scene.type}, stretch {s['stretch']:g}, {_material_text(s)}, {s['backend']}"

    def save(self, out, plot: bool = True) -> Path:
        """Write the run's files, the same the command line writes.

        ``reaction.csv`` (t s, stretch -, reaction_force N, nominal_stress Pa), ``scene.toml``,
        ``reaction.png``, then ``summary.json`` last.

        Parameters
        ----------
        out : str or path-like
            Output directory (created if missing).
        plot : bool
            Write ``reaction.png``.

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` exists and is not a directory.
        NumericalError
            A history or summary value is not finite.
        """
        out = _prepare(out)
        write_text(out / "scene.toml", scene_to_toml(self.scene))
        if plot:
            plot_reaction(out / "reaction.png", self.t, self.force, self.title())
        write_reaction(out, self.t, self.stretch, self.force, self.nominal, self.summary)
        return out


def _prepare(out) -> Path:
    """The output directory, created; a stale summary.json removed first (a failed run must not
    leave an earlier run's summary behind)."""
    return output_folder(out, marker="summary.json", what="output directory")
