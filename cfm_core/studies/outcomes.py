"""Outcomes of studies: what ``cfm.sweep``, ``cfm.calibrate``, ``cfm.fit`` and ``cfm.uniaxial`` return.

Like :class:`cfm_core.runs.DropTestOutcome`, each holds its results, gives them as a pandas
DataFrame with the units in the column names (``to_dataframe()``), and writes the same files as
the command line (``save(...)``): through :func:`cfm_core.post.staging.staged_folder`, so the
files appear together only when all were written, and an earlier cfm output in the folder is
replaced, never mixed with the new one.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..post.staging import (MARKERS, check_changeable, check_file_target, check_folder_target, earlier_files,
                            remove_entry, replaced_note, staged_folder)
from ..post.writers import write_drop_test, write_json, write_text
from ..post.plots import subtitled
from ..runs.provenance import describe_run, json_ready, material_record, provenance, scene_files
from .sweep_output import plot_peaks, table_frame, write_sweep_json, write_table

if TYPE_CHECKING:
    import pandas as pd


def clear_earlier_output(out, keep: tuple = ()) -> Path:
    """Check ``out`` (before any work) and remove the files of an earlier cfm output in it now.

    A study that writes its results at the end but keeps a cache in the folder while it runs
    (a sweep's ``runs/``) must not leave an earlier invocation's table and plot looking current
    if it is interrupted. Foreign files are never touched (:func:`cfm_core.post.staging.earlier_files`).
    Nothing is removed unless every earlier file can be, and the kept entries (the run cache the
    study writes into, with each run folder) can be written
    (:func:`cfm_core.post.staging.check_changeable`).

    Parameters
    ----------
    out : str or path-like
        The output folder (not created here: the study's files make it).
    keep : tuple of str
        Entries to keep (the run cache).

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    InputError
        ``out`` cannot be an output folder (:func:`cfm_core.post.staging.check_folder_target`),
        an earlier file cannot be removed or a kept entry written (``out`` as it was), or a
        removal failed on the way (then named with the state it left).
    """
    out = check_folder_target(out, keep=keep)  # every earlier file removable, before any is removed
    if out.is_dir():
        check_changeable(out, [out / k for k in keep])  # the run cache and its run folders take new files
        earlier = earlier_files(out)
        replaced_note(out, earlier, "sweep")
        going = [p for p in earlier if p.name not in keep]
        for path in sorted(going, key=lambda p: p.name not in MARKERS):  # a completion marker first
            try:
                remove_entry(path)
            except OSError as exc:  # changed since the check (another process)
                raise InputError(f"--out {out}: {path} of the earlier cfm output there could not be removed "
                                 f"({exc.strerror or exc}); the earlier output was partly removed (its completion "
                                 f"marker first, so the folder no longer looks complete). Make it removable and "
                                 f"run the command again, or choose another --out folder.") from None
    return out


def _parameter_frame(names, units, rows: dict):
    """DataFrame with one column ``name [unit]`` per parameter and the given rows (index)."""
    import pandas as pd  # deferred: ~0.3 s to import

    cols = [f"{n} [{u or '-'}]" for n, u in zip(names, units)]
    data = {label: [np.nan if v is None else float(v) for v in values] for label, values in rows.items()}
    return pd.DataFrame.from_dict(data, orient="index", columns=cols)


def _interval_rows(names, start: dict, fitted: dict, conf: dict) -> dict:
    ci = [conf[n]["ci"] or (None, None) for n in names]
    return {"start": [start[n] for n in names], "fitted": [fitted[n] for n in names],
            "std": [conf[n]["std"] for n in names], "ci95_low": [c[0] for c in ci], "ci95_high": [c[1] for c in ci]}


# ----------------------------------------------------------------------------- sweep
@dataclass
class SweepOutcome:
    """A finished (or resumed) sweep.

    Attributes
    ----------
    scene : Scene
        The base scene.
    axes : list of Axis
        Varied names, units and values (SI).
    backend : str
        Backend name.
    options : dict
        The backend's options, all resolved.
    rows : list of dict
        One per run in product order: run_id, the values, status, error, summary figures.
    key : dict
        What every run id hashes (:func:`cfm_core.studies.sweep.run_key`).
    executed, skipped : int
        Runs computed by this call, and read back from the run cache.
    wall : float
        Wall time of the call (s).
    cache : pathlib.Path or None
        The content-keyed run cache (``OUT/runs``), or None (histories kept in memory).
    histories : dict
        run_id -> (t s, a_raw m/s^2, a_cfc m/s^2, summary) of runs computed without a cache.
    scene_texts : dict
        run_id -> the ``scene.toml`` text of that run (the resolved scene with its [run] section),
        for the runs in ``histories``: ``cfm run --scene runs/<id>/scene.toml`` repeats it.
    files : list of pathlib.Path
        The files written by the last :meth:`save`.
    """

    scene: object
    axes: list
    backend: str
    options: dict
    rows: list
    key: dict
    executed: int = 0
    skipped: int = 0
    wall: float = 0.0
    cache: Path | None = None
    histories: dict = field(default_factory=dict)
    scene_texts: dict = field(default_factory=dict)
    files: list = field(default_factory=list)

    @property
    def failed(self) -> int:
        """Number of runs that failed (their errors are in the table's ``error`` column)."""
        return sum(r["status"] != "ok" for r in self.rows)

    def to_dataframe(self) -> pd.DataFrame:
        """The sweep table.

        Returns
        -------
        pandas.DataFrame
            One row per run (product order, the last varied name fastest); columns ``run_id``,
            ``<name> [unit]`` per varied name (e.g. ``k2 [-]``, ``thickness [m]``), ``status``,
            ``error``, and the summary figures with units (``peak_g [g]``, ``t_peak [s]``, ...).
        """
        return table_frame(self.rows, self.axes)

    def provenance(self) -> dict:
        """The sweep's provenance record (code, backend with options, material, mesh digest).

        Returns
        -------
        dict
            :func:`cfm_core.runs.provenance.provenance` with ``run_id_key`` (what the ids hash).
        """
        from ..errors import InputError
        from ..material.registry import make_material
        from .sweep import first_values_scene

        try:
            m = self.scene.material
            material = make_material(m.name, m.parameter_dict, m.moduli, m.elastic)
        except InputError:  # valid only with the swept values (g2 = 0.5 in the scene, g1 swept from 0.3): the first's
            m = first_values_scene(self.scene, self.axes).material
            material = make_material(m.name, m.parameter_dict, m.moduli, m.elastic)
        return json_ready(provenance(self.backend, self.options, material, scene_files(self.scene),
                                     run_id_key=self.key))

    def title(self, record: dict | None = None) -> str:
        """Title of ``peaks.png`` (after "Peak acceleration, "): the scene's name, then the material,
        the backend with its dtype, and the options and material parameters that differ from their
        defaults, the varied names left out (the figure's axes and legend show them).

        Parameters
        ----------
        record : dict, optional
            The sweep's provenance record (default: :meth:`provenance`).

        Returns
        -------
        str
            The title, with a subtitle line of phrases.
        """
        m = self.scene.material
        varied = {a.name for a in self.axes}
        phrases = [p for p in describe_run(record or self.provenance()) if p.split(" = ")[0] not in varied]
        return subtitled(str(self.scene.settings.name), [f"{m.name} ({'elastic' if m.elastic else m.moduli})",
                                                         *phrases], width=75)

    def save(self, out) -> Path:
        """Write the sweep's files, the same ``cfm sweep`` writes.

        ``sweep.csv`` (and ``sweep.parquet`` with pyarrow), ``peaks.png``, ``runs/<id>/`` per run
        (``acceleration.csv``, ``scene.toml`` (the run's own, which ``cfm run --scene`` repeats) and
        ``summary.json``, or ``failed.json``) and ``sweep.json`` (values,
        counts, provenance), published together; the run cache is kept in place when ``out`` is
        the folder it lives in.

        Parameters
        ----------
        out : str or path-like
            Output directory (created; an earlier cfm output there is replaced).

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` cannot be written (checked first).
        """
        out = Path(out)
        same = self.cache is not None and out.exists() and out.resolve() == self.cache.parent.resolve()
        with staged_folder(out, keep=("runs",) if same else ()) as stage:
            if not same:
                self._write_runs(stage / "runs")
            files = write_table(stage, self.rows, self.axes)
            record = self.provenance()
            if any(r["status"] == "ok" for r in self.rows):
                plot_peaks(stage / "peaks.png", self.rows, self.axes, self.title(record))
                files.append(stage / "peaks.png")
            files.append(write_sweep_json(stage, self.axes, self.rows, record,
                                          {"executed": self.executed, "skipped": self.skipped, "wall_time": self.wall,
                                           "backend": self.backend, "units": {"wall_time": "s"}}))
        self.files = [out / f.name for f in files]
        return out

    def _write_runs(self, folder: Path) -> None:
        for r in self.rows:
            rid = r["run_id"]
            if rid in self.histories:
                if rid in self.scene_texts:
                    write_text(folder / rid / "scene.toml", self.scene_texts[rid])
                write_drop_test(folder / rid, *self.histories[rid])
            elif self.cache is not None and (self.cache / rid).is_dir():
                shutil.copytree(self.cache / rid, folder / rid)
            elif r["status"] != "ok":
                write_json(folder / rid / "failed.json", {"run_id": rid, "error": r["error"],
                                                          "sweep": {a.name: r[a.name] for a in self.axes}})


# ----------------------------------------------------------------------------- uniaxial
def uniaxial_title(material, rate: float, source: str) -> str:
    """Title of a uniaxial-stress figure.

    Parameters
    ----------
    material : Material
        The bound material.
    rate : float
        Engineering strain rate (1/s).
    source : str
        What computed the stress ("numpy reference", "backend numba along ...": cut before " along").

    Returns
    -------
    str
        ``cfm (long-term), uniaxial stress at 100 1/s, numpy reference`` and, on a second line, each
        material parameter that differs from its default (``k1 = 1000 (default 970)``).
    """
    m = material
    return subtitled(f"{m.name} ({'elastic' if m.elastic else m.moduli}), uniaxial stress at {rate:g} 1/s, "
                     f"{source.split(' along')[0]}", describe_run({"material": material_record(m)}), width=75)


def _point_csv(path: Path) -> bool:
    """Whether ``path`` is a CSV file ``cfm point`` wrote: its first line names the columns of the
    uniaxial response or of the stress along F(t) (``t [s],stretch [-],...``, units optional)."""
    from ..simulation.point import STRESS_UNITS, UNIAXIAL_UNITS

    try:
        with open(path, encoding="utf-8") as f:
            first = f.readline(4096)
    except (OSError, UnicodeDecodeError):
        return False
    names = [h.split(" [", 1)[0].strip() for h in first.strip().split(",")]
    return names in (list(UNIAXIAL_UNITS), list(STRESS_UNITS))


def point_targets(path, plot: bool, what: str = "--out", suffix: str | None = None, inputs=()) -> tuple[Path, Path]:
    """Check the files of a material-point output, all before any is written (``cfm point``,
    :meth:`UniaxialOutcome.save`): the CSV ``path`` and, with ``plot``, the PNG of the same name
    beside it.

    The CSV is named by the caller and replaced. The PNG is not named: an existing one is replaced
    only when it is the plot of an earlier ``cfm point`` output, the CSV beside it being one cfm
    point wrote; any other (a picture of the user's own) is refused, as files cfm did not write are
    never replaced by a name it derived (:mod:`cfm_core.post.staging`).

    Parameters
    ----------
    path : str or path-like
        The CSV file.
    plot : bool
        Whether the PNG is written.
    what : str
        How messages name ``path``.
    suffix : str, optional
        The suffix ``path`` must have (``".csv"``; None: any).
    inputs : iterable of path-like
        Files the command reads: neither file may be one of them.

    Returns
    -------
    tuple of pathlib.Path
        (the CSV, the PNG).

    Raises
    ------
    InputError
        A file cannot be written or replaced (:func:`cfm_core.post.staging.check_file_target`),
        or the PNG exists and is not the plot of an earlier cfm point output.
    """
    csv = check_file_target(path, what, suffix=suffix, inputs=inputs)
    png = csv.with_suffix(".png")
    if plot:
        if (png.exists() or png.is_symlink()) and not png.is_dir() and not _point_csv(csv):
            raise InputError(f"{what} {csv}: its plot is written to {png}, which exists and is not the plot of an "
                             f"earlier cfm point output ({csv} is {'not a CSV file cfm point wrote' if csv.exists() else 'missing'}); "
                             f"cfm does not replace a file it did not write under a name it chose. Move or remove "
                             f"{png.name}, name another {what} file, or "
                             f"{'add --no-plot' if what.startswith('--') else 'pass plot=False'}.")
        check_file_target(png, f"{what} (its plot)", inputs=inputs)
    return csv, png


def stale_plot(png: Path, why: str) -> str | None:
    """The warning for a plot an earlier ``cfm point`` run left beside the CSV a run that writes no
    plot replaced (``why``: what wrote none, and what to do); None if there is no such file."""
    if not png.is_file():
        return None
    return f"{png} is from an earlier run: {why}."


@dataclass
class UniaxialOutcome:
    """Uniaxial stress response of a material point (:func:`cfm_core.simulation.point.uniaxial`).

    Attributes
    ----------
    material : Material
        The bound material.
    rate : float
        Engineering strain rate (1/s).
    t, stretch, nominal, lateral : ndarray, shape (n,)
        Time (s), axial stretch (-), nominal stress P11 (Pa), lateral stretch (-).
    source : str
        What computed the stress (the numpy reference, or a backend along its path).
    warnings : list of str
        Warnings of the solve (e.g. the volumetric energy no longer convex).
    """

    material: object
    rate: float
    t: np.ndarray
    stretch: np.ndarray
    nominal: np.ndarray
    lateral: np.ndarray
    source: str = "numpy reference"
    warnings: list = field(default_factory=list)

    def to_dataframe(self) -> pd.DataFrame:
        """The response as a table.

        Returns
        -------
        pandas.DataFrame
            Columns ``t [s]``, ``stretch [-]``, ``nominal_stress [Pa]``, ``lateral_stretch [-]``.
        """
        import pandas as pd  # deferred: ~0.3 s to import

        return pd.DataFrame({"t [s]": self.t, "stretch [-]": self.stretch, "nominal_stress [Pa]": self.nominal,
                             "lateral_stretch [-]": self.lateral})

    def title(self) -> str:
        """Plot title: material, moduli convention (or elastic), rate (1/s), source, and the
        material parameters that differ from their defaults (:func:`uniaxial_title`)."""
        return uniaxial_title(self.material, self.rate, self.source)

    def save(self, path, plot: bool = True) -> Path:
        """Write the CSV ``cfm point --uniaxial --out PATH`` writes, and its plot beside it.

        Parameters
        ----------
        path : str or path-like
            The CSV file (header ``t [s],stretch [-],nominal_stress [Pa],lateral_stretch [-]``);
            the PNG gets the same name with suffix ``.png``.
        plot : bool
            Write the stress-stretch PNG.

        Returns
        -------
        pathlib.Path
            The CSV file.

        Raises
        ------
        InputError
            ``path`` is a directory or cannot be written, or the PNG cannot be replaced or is
            not the plot of an earlier cfm point output (:func:`point_targets`): checked first,
            nothing written.
        """
        from ..post.plots import plot_uniaxial
        from ..post.writers import write_csv
        from ..simulation.point import UNIAXIAL_UNITS
        from ..tables import unit_header

        path, png = point_targets(path, plot, "path")
        write_csv(path, unit_header(UNIAXIAL_UNITS), [self.t, self.stretch, self.nominal, self.lateral])
        if plot:
            plot_uniaxial(png, self.stretch, self.nominal, self.title())
        return path
