"""The Python API of studies: ``cfm.sweep``, ``cfm.calibrate``, ``cfm.fit`` and ``cfm.uniaxial``.

Each returns an outcome (:mod:`cfm_core.studies.outcomes`, :mod:`cfm_core.studies.fit_outcomes`) with ``to_dataframe()`` (units in the
column names) and ``save(...)`` (the files of the command line); ``cfm sweep``, ``cfm calibrate``,
``cfm fit`` are thin layers over them. With ``out`` given, the folder is checked before any work
and the files are written when the study ends. Progress: ``progress=True`` shows a bar
(``tqdm.auto``: a widget in Jupyter, a bar in a terminal, nothing when stderr is a log file), a
callable receives one line of text per step, False shows nothing. SI units everywhere.
"""

from __future__ import annotations

import time
import warnings as _warnings
from pathlib import Path

from ..errors import InputError
from ..post.staging import check_folder_target
from .fit_outcomes import CalibrationOutcome, LabFitOutcome, files_read
from .outcomes import SweepOutcome, UniaxialOutcome, clear_earlier_output


def _scene_file(scene) -> tuple:
    """(the scene's TOML file,) when ``scene`` is a path, else (): a file the study reads."""
    return (str(scene),) if isinstance(scene, (str, Path)) else ()


def _scene(scene):
    """A Scene from a Scene, a TOML path, or None (the built-in drop-test scene)."""
    from ..scene.scene import Scene, builtin_scene, load_scene

    if scene is None:
        return builtin_scene("drop-test")
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, (str, Path)):
        return load_scene(scene)
    raise InputError(f"scene = {scene!r}: give a Scene (cfm.builtin_scene, cfm.load_scene) or a TOML file path.")


def _bar(progress, total: int, desc: str):
    """A tqdm.auto bar for progress=True, the callable for a callable, else None."""
    if progress is True:
        import sys

        from tqdm.auto import tqdm

        return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, disable=None, mininterval=0.5)
    return progress if callable(progress) else None


def _planned(scene, backend: str | None, options: dict | None):
    """(the scene without its ``[run]`` section, the backend, the options) a study's drop tests run
    with: the scene's ``[run]`` (backend, dtype, device, options of the run that wrote it)
    overridden by ``backend`` and ``options`` as for :func:`cfm_core.drop_test`, notes on stderr
    when they override it. The section is merged here once, so the drop tests do not each repeat
    the notes, and they all run as planned."""
    import sys

    from ..runs.pipeline import report_warnings
    from ..runs.settings import plan_run

    plan = plan_run(scene, backend, options)
    for text in plan.notes:
        print(f"note: {text}", file=sys.stderr)
    report_warnings({"warnings": plan.warnings})
    return scene.with_run(None), plan.backend, plan.options


def sweep(scene=None, vary=None, backend: str | None = None, runner=None, out=None, progress=True,
          options: dict | None = None) -> SweepOutcome:
    """Drop tests for every combination of some scene values and material parameters.

    Parameters
    ----------
    scene : Scene or str or path-like, optional
        The drop-test scene (or its TOML file); default the built-in one.
    vary : dict
        ``{name: [values]}`` in SI units: scene values (thickness, velocity, element_size, width,
        mass, radius, density, friction) or material parameters (c, k1, k2, ...); the last name
        changes fastest. Every value is checked before any run.
    backend : str, optional
        Backend name (``cfm backends``); default: the scene's ``[run] backend`` (a scene.toml
        written by a run), else ``"numba"``. The section's dtype, device and options apply too,
        as in :func:`cfm_core.drop_test`; ``backend`` and ``options`` override them.
    runner : SerialRunner or DaskRunner, optional
        Where the runs go (:func:`cfm_core.studies.dask_runner.open_runner`); default: serially
        in this process.
    out : str or path-like, optional
        Output folder: the content-keyed run cache ``out/runs`` (a repeated call computes only
        what is not there) and, at the end, the files of ``cfm sweep``. Default: none, results in
        memory (``save`` writes them). Refused when the earlier output there holds the scene file
        (or its mesh), which the sweep would remove.
    progress : bool or callable
        True: a tqdm.auto bar; a callable: one line per finished run; False: none.
    options : dict, optional
        Backend options (``cfm backends --options``), part of the run ids.

    Returns
    -------
    SweepOutcome
        ``to_dataframe()`` (``k2 [-]``, ``peak_g [g]``, ...), ``rows``, ``save(dir)``.

    Raises
    ------
    InputError
        Unknown names, non-finite or out-of-range values (before any run), bad backend options,
        an unwritable ``out`` or one whose earlier output holds the scene file.
    """
    from . import sweep as sw

    read = _scene_file(scene)
    scene = _scene(scene)
    if vary is None:
        raise InputError("cfm.sweep needs vary={name: [values]} (SI units), e.g. vary={'k2': [1.6, 1.8]}.")
    scene, backend, options = _planned(scene, backend, options)
    axes = sw.parse_vary(vary, scene)
    sw.check_cases(scene, axes)
    sw.check_backend(scene, axes, backend)
    if out is not None:  # the earlier output goes now: not the scene file read from it
        check_folder_target(out, inputs=files_read((), scene, read))
    folder = clear_earlier_output(out, keep=("runs",)) if out is not None else None
    bar = _bar(progress, len(sw.cases(axes)), "sweep")
    result = sw.execute(scene, axes, backend, options, runner, folder / "runs" if folder else None, bar)
    if folder is not None:
        result.save(folder)
    return result


def calibrate(scene=None, data=None, fit="k1,k2", start: dict | None = None, backend: str | None = None, runner=None,
              out=None, progress=True, rel_step: float | None = None, max_evaluations: int = 60,
              options: dict | None = None) -> CalibrationOutcome:
    """Fit material parameters to measured drop-test acceleration histories (``cfm calibrate``).

    Parameters
    ----------
    scene : Scene or str or path-like, optional
        Drop-test scene (impactor, speed, mesh, fixed parameters); default the built-in one.
    data : list
        Measured curves: ``"file.csv:0.005"`` strings, (file, thickness in m) pairs or Curve
        objects (:func:`cfm_core.studies.measured.read_curves`); CSV with columns t (s, 0 at first
        contact) and a (m/s^2, positive decelerating). Without a thickness, the scene's applies
        when ``scene`` is given.
    fit : str or list of str
        Parameters to fit (``"k1,k2"``; ``prony`` = g1, tau1).
    start : dict, optional
        Starting values of fitted parameters (SI); default the scene's.
    backend, runner, options
        As for :func:`sweep`.
    out : str or path-like, optional
        Output folder (checked first; fit.json, plots and fitted-scene.toml written at the end).
        Refused when the earlier cfm output there holds a file the calibration reads (a curve,
        the scene file or its mesh), which writing the output would remove.
    progress : bool or callable
        True: a line per evaluation on stderr; a callable receives them; False: none.
    rel_step : float, optional
        Relative forward-difference step of the Jacobian (default 1e-3).
    max_evaluations : int
        Most objective evaluations.

    Returns
    -------
    CalibrationOutcome
        ``fitted``, ``warnings`` (identifiability, bounds reached), ``to_dataframe()``, ``save(dir)``.

    Raises
    ------
    InputError
        Bad names, files, values or ``out``; a fitted parameter that no layer of a layered
        specimen takes from [material] (:func:`cfm_core.studies.calibrate.fit_names`).
    NumericalError
        A drop test failed.
    """
    import sys

    from . import calibrate as cal
    from . import measured

    given, read, scene = scene is not None, _scene_file(scene), _scene(scene)
    scene, backend, options = _planned(scene, backend, options)
    names = cal.fit_names(",".join(fit) if isinstance(fit, (list, tuple)) else fit, scene)
    start = dict(start or {})
    extra = sorted(set(start) - set(names))
    if extra:
        raise InputError(f"start {', '.join(extra)}: only fitted parameters take a starting value (fitted: "
                         f"{', '.join(names)}); set fixed values in the scene.")
    items = list(data or [])
    curves = [d for d in items if isinstance(d, measured.Curve)]
    specs = [f"{d[0]}:{d[1]!r}" if isinstance(d, (tuple, list)) else str(d) for d in items
             if not isinstance(d, measured.Curve)]
    if specs or not curves:
        curves += measured.read_curves(specs, scene, scene_given=given)
    if not (isinstance(max_evaluations, int) and max_evaluations >= 1):
        raise InputError(f"max_evaluations = {max_evaluations!r} must be a whole number >= 1.")
    if out is not None:  # checked now; an earlier output there is replaced when the fit is saved, kept if it fails
        out = check_folder_target(out, inputs=files_read(curves, scene, read))
    say = (lambda line: print(line, file=sys.stderr, flush=True)) if progress is True else _bar(progress, 0, "")
    t0 = time.perf_counter()
    result = cal.fit(scene, curves, names, start, backend, runner, cal.REL_STEP if rel_step is None else rel_step,
                     max_evaluations, say, options)
    label = getattr(runner, "label", "serial (this process)")
    outcome = CalibrationOutcome(scene, result, backend, dict(options or {}),
                                 {"runner": label, "total_time": time.perf_counter() - t0,
                                  "max_evaluations": max_evaluations},  # the fit stops there: a repeat needs it
                                 read)
    if out is not None:
        outcome.save(out)
    return outcome


def fit(material: str = "cfm", tests=None, fit="c,k1,k2", start: dict | None = None, fixed: dict | None = None,
        moduli: str | None = None, elastic: bool = False, max_evaluations: int = 400, starts: int | None = None,
        scene=None, out=None, progress=False) -> LabFitOutcome:
    """Fit a registered material to laboratory tests (``cfm fit``).

    Parameters
    ----------
    material : str
        Registered material name.
    tests : list
        ``"FILE:KIND:RATE[:WEIGHT]"`` strings (kinds: uniaxial, relaxation, shear, equibiaxial,
        confined; rate in 1/s) or LabTest objects (:func:`cfm_core.studies.lab_tests.read_lab_test`).
    fit : str or list of str
        Parameters to fit (``prony`` = every g_i, tau_i).
    start, fixed : dict, optional
        Starting values of fitted parameters, values of the others (SI).
    moduli, elastic
        Moduli convention and whether the Prony series is off.
    max_evaluations : int
        Most residual evaluations per start.
    starts : int, optional
        Starting points (default 6 when a Prony time is fitted, else 1).
    scene : Scene or str, optional
        Drop-test scene fitted-scene.toml starts from (default: built-in). The fitted values go
        into its [material] section: a layered specimen must have a layer that takes each of
        them from there.
    out : str or path-like, optional
        Output folder (checked first; written at the end). Refused when the earlier cfm output
        there holds a file the fit reads (a test, the scene file or its mesh), which writing the
        output would remove.
    progress : bool or callable
        True: a line every 10 evaluations on stderr; a callable receives them.

    Returns
    -------
    LabFitOutcome
        ``fitted``, ``warnings``, ``to_dataframe()``, ``save(dir)``.

    Raises
    ------
    InputError
        Bad names, tests, values or ``out``; a fitted parameter that no layer of the scene's
        layered specimen takes (:func:`cfm_core.studies.fit.check_scene`).
    NumericalError
        A test's simulation failed.
    """
    import sys

    from . import fit as lab
    from .lab_tests import LabTest

    names = lab.fit_names(",".join(fit) if isinstance(fit, (list, tuple)) else fit, material)
    items = list(tests or [])
    read = lab.read_tests([t for t in items if not isinstance(t, LabTest)]) if any(
        not isinstance(t, LabTest) for t in items) else []
    tests = [t for t in items if isinstance(t, LabTest)] + read
    if not tests:
        raise InputError("cfm.fit needs tests=['FILE:KIND:RATE[:WEIGHT]', ...] (columns t s, stretch or shear -, "
                         "stress Pa).")
    read = _scene_file(scene)
    scene = _scene(scene) if scene is not None else None
    if scene is not None:  # fitted-scene.toml puts the values into [material]: a layer must take them from there
        lab.check_scene(scene, names)
    if out is not None:  # checked now; an earlier output there is replaced when the fit is saved, kept if it fails
        out = check_folder_target(out, inputs=files_read(tests, scene, read))
    say = (lambda line: print(line, file=sys.stderr, flush=True)) if progress is True else _bar(progress, 0, "")
    t0 = time.perf_counter()
    result = lab.fit_lab(material, tests, names, start, fixed, moduli, elastic, max_evaluations, say, starts)
    outcome = LabFitOutcome(result, scene, {"total_time": time.perf_counter() - t0,
                                            "max_evaluations": max_evaluations},  # per start: a repeat needs it
                            read)
    if out is not None:
        outcome.save(out)
    return outcome


def uniaxial(material: str = "cfm", rate: float = 1.0, stretch: float = 0.7, steps: int = 200, hold: float = 0.0,
             parameters: dict | None = None, moduli: str | None = None, elastic: bool = False,
             backend: str | None = None) -> UniaxialOutcome:
    """Uniaxial stress of a material point at a constant engineering strain rate (``cfm point --uniaxial``).

    Parameters
    ----------
    material : str
        Registered material name.
    rate : float
        Engineering strain rate (1/s), > 0.
    stretch : float
        Final stretch (-), e.g. 0.7 in compression.
    steps : int
        Steps of the loading ramp.
    hold : float
        Hold time at the final stretch (s).
    parameters : dict, optional
        Parameter values (SI); default the material's.
    moduli, elastic
        Moduli convention and whether the Prony series is off.
    backend : str, optional
        Evaluate the stress with this backend along the reference's path (default: numpy reference).

    Returns
    -------
    UniaxialOutcome
        t (s), stretch (-), nominal stress (Pa), lateral stretch (-); ``to_dataframe()``, ``save(path)``.

    Raises
    ------
    InputError
        Unknown material or backend, values out of range.
    NumericalError
        No lateral stretch balances the lateral stress, or a non-finite stress.
    """
    from ..material.registry import make_material
    from ..simulation import point
    from ..simulation.registry import backend_for

    m = make_material(material, dict(parameters or {}), moduli, elastic)
    with _warnings.catch_warnings(record=True) as caught:
        _warnings.simplefilter("always", RuntimeWarning)
        t, lam, P, lat = point.uniaxial(m, rate, stretch, steps, hold)
    source = "numpy reference"
    if backend not in (None, "numpy"):
        P, residual = point.uniaxial_on_backend(m, backend_for(backend), t, lam, lat)
        source = f"backend {backend} along the reference's path (lateral stress {residual:.1e} of the axial)"
    return UniaxialOutcome(m, float(rate), t, lam, P, lat, source, [str(w.message) for w in caught])
