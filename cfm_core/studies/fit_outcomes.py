"""Outcomes of fits: what ``cfm.calibrate`` (drop-test curves) and ``cfm.fit`` (lab tests) return.

Each gives the fitted parameters as a DataFrame (``to_dataframe()``: a column ``name [unit]`` per
parameter; rows start, fitted, std, ci95_low, ci95_high) and writes the files of its command
through a staged folder (``save(dir)``), fit.json with the provenance of the fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from ..post.staging import staged_folder
from ..runs.provenance import input_files, json_ready, provenance, scene_files, scene_paths
from .outcomes import _interval_rows, _parameter_frame

if TYPE_CHECKING:
    import pandas as pd


def files_read(data, scene=None, extra=()) -> list:
    """The files a fit reads: its data's (tests or curves, each with ``path``), the scene's mesh, ``extra``.

    Parameters
    ----------
    data : iterable
        LabTest or Curve objects.
    scene : Scene, optional
        The scene (its [specimen] mesh file, if any).
    extra : iterable of str
        Other files read (the scene TOML).

    Returns
    -------
    list of str
        The paths (a test made in memory has the path "-", matching no file).
    """
    return [str(p) for p in (*(d.path for d in data), *scene_paths(scene), *extra) if p]


# ----------------------------------------------------------------------------- calibration
@dataclass
class CalibrationOutcome:
    """A finished calibration (:func:`cfm_core.studies.calibrate.fit`) with what ran it.

    Attributes
    ----------
    scene : Scene
        The scene fitted (start values in its material).
    result : FitResult
        Start and fitted evaluations, confidence (intervals, correlation, identifiability,
        bounds reached), the problem (curves, coordinates, objective history).
    backend : str
        Backend name.
    options : dict
        Backend options given.
    settings : dict
        Extra entries for fit.json (runner, total time in s).
    inputs : tuple of str
        Files read besides the measured curves and the scene's mesh (the scene TOML), which
        ``save`` never removes or replaces (:meth:`read_files`).
    """

    scene: object
    result: object
    backend: str = "numba"
    options: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    inputs: tuple = ()

    def read_files(self) -> list:
        """The files the calibration read: the measured curves, the scene's mesh and :attr:`inputs`."""
        return files_read(self.result.problem.curves, self.scene, self.inputs)

    @property
    def fitted(self) -> dict:
        """Every material parameter at the fit (SI units), fitted and fixed."""
        return dict(self.result.final.params)

    @property
    def warnings(self) -> list:
        """Identifiability and bound warnings (text)."""
        return list(self.result.confidence.get("warnings", []))

    def to_dataframe(self) -> pd.DataFrame:
        """The fitted parameters.

        Returns
        -------
        pandas.DataFrame
            Columns ``<name> [unit]`` per fitted parameter (``k1 [Pa]``, ``k2 [-]``); rows
            ``start``, ``fitted``, ``std`` (standard error), ``ci95_low``, ``ci95_high`` (NaN where
            an interval is withheld), SI units.
        """
        coords = self.result.problem.coords
        rows = _interval_rows(coords.names, self.result.start.params, self.result.final.params,
                              self.result.confidence["parameters"])
        return _parameter_frame(coords.names, coords.units, rows)

    def provenance(self) -> dict:
        """Provenance record: code, backend with resolved options, material, mesh and curve digests.

        Returns
        -------
        dict
            :func:`cfm_core.runs.provenance.provenance` of the calibration.
        """
        from ..material.registry import make_material

        m = self.scene.material
        files = {**scene_files(self.scene), **input_files([c.path for c in self.result.problem.curves])}
        return json_ready(provenance(self.backend, self.options,
                                    make_material(m.name, m.parameter_dict, m.moduli, m.elastic), files))

    def save(self, out) -> Path:
        """Write fit.json, fit_<curve>.png, objective.png and fitted-scene.toml (``cfm calibrate``).

        Parameters
        ----------
        out : str or path-like
            Output directory (an earlier cfm output there is replaced, unless that would remove a
            file read).

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` cannot be written, or writing there would remove or replace a file the
            calibration read (:meth:`read_files`; ``out`` is then left as it was).
        """
        from .calibrate import write_fit

        with staged_folder(out, inputs=self.read_files()) as stage:
            write_fit(stage, self.scene, self.result, {**self.settings, "provenance": self.provenance()})
        return Path(out)


# ----------------------------------------------------------------------------- lab fit
@dataclass
class LabFitOutcome:
    """A finished fit to laboratory tests (:func:`cfm_core.studies.fit.fit_lab`).

    Attributes
    ----------
    result : LabFitResult
        Fitted values, intervals, warnings, the tests and simulated stresses.
    scene : Scene or None
        Drop-test scene that fitted-scene.toml starts from (None: built-in).
    settings : dict
        Extra entries for fit.json.
    inputs : tuple of str
        Files read besides the tests (the scene TOML), which ``save`` never removes or replaces
        (:meth:`read_files`).
    """

    result: object
    scene: object = None
    settings: dict = field(default_factory=dict)
    inputs: tuple = ()

    def read_files(self) -> list:
        """The files the fit read: the tests, the scene's mesh and :attr:`inputs`."""
        return files_read(self.result.tests, self.scene, self.inputs)

    @property
    def fitted(self) -> dict:
        """Every parameter of the material at the fit (SI units)."""
        return dict(self.result.fitted)

    @property
    def warnings(self) -> list:
        """Identifiability and bound warnings (text)."""
        return list(self.result.warnings)

    def to_dataframe(self) -> pd.DataFrame:
        """The fitted parameters.

        Returns
        -------
        pandas.DataFrame
            Columns ``<name> [unit]`` per fitted parameter; rows ``start``, ``fitted``, ``std``,
            ``ci95_low``, ``ci95_high`` (NaN where withheld), SI units.
        """
        r = self.result
        rows = _interval_rows(r.coords.names, r.start, r.fitted, r.confidence["parameters"])
        return _parameter_frame(r.coords.names, r.coords.units, rows)

    def provenance(self) -> dict:
        """Provenance record: code, material with its definition digest, lab-test file digests.

        Returns
        -------
        dict
            :func:`cfm_core.runs.provenance.provenance` (no backend: the tests run at a material point).
        """
        from ..material.registry import make_material

        r = self.result
        material = make_material(r.material, r.start, r.moduli, r.elastic)
        return json_ready(provenance(None, None, material, input_files([t.path for t in r.tests])))

    def save(self, out) -> Path:
        """Write fit_<test>.png, fitted-scene.toml and fit.json (``cfm fit``).

        Parameters
        ----------
        out : str or path-like
            Output directory (an earlier cfm output there is replaced, unless that would remove a
            file read).

        Returns
        -------
        pathlib.Path
            The output directory.

        Raises
        ------
        InputError
            ``out`` cannot be written, or writing there would remove or replace a file the fit
            read (:meth:`read_files`; ``out`` is then left as it was).
        """
        from .fit_output import write_lab_fit

        with staged_folder(out, inputs=self.read_files()) as stage:
            write_lab_fit(stage, self.result, self.scene, {**self.settings, "provenance": self.provenance()})
        return Path(out)
