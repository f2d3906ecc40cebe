"""The drop test's histories from ccx's ``.dat`` file, the separation stop, and its :class:`Result`.

The deck (:func:`.drop.drop_deck_lines`) prints, at every converged increment, the impactor
reference node's displacement and velocity (``*NODE PRINT, NSET=NREF``: U, V) and the contact
statistics of the specimen's top surface against the impactor (``*CONTACT PRINT``: the total
surface force on the slave surface, N). ccx prints no statistics block at an increment without
contact: the force is zero there. It also prints the energy totals of :data:`.drop.ENERGY_PRINTS`
(:func:`read_energies`), from which the Result's energy histories and balance come.
"""

from __future__ import annotations

import re

import numpy as np

from cfm_core.errors import NumericalError
from cfm_core.simulation.result import Result

_NUM = r"[-+]?\d*\.?\d+(?:[eEdD][-+]?\d+)?"
_NODE = re.compile(rf"(displacements|velocities) \(vx,vy,vz\) for set NREF and time\s+({_NUM})\s*\n\s*\n"
                   rf"\s*\d+\s+({_NUM})\s+({_NUM})\s+({_NUM})")
_STAT = re.compile(rf"statistics for slave set STOP, master set SCAP and time\s+({_NUM})\s*\n\s*\n[^\n]*\n\s*\n"
                   rf"\s*({_NUM})\s+({_NUM})\s+({_NUM})")

_ETOT = re.compile(rf"total (internal|kinetic) energy for set (\S+) and time\s+({_NUM})\s*\n\s*\n\s*({_NUM})")
_CELS = re.compile(rf"total contact spring energy for time\s+({_NUM})\s*\n\s*\n\s*({_NUM})")
#: What the energy balance of a CalculiX drop test leaves out (Result.info["energy_note"]).
ENERGY_NOTE = ("CalculiX prints no hourglass energy and no numerical dissipation: the work of its C3D8R "
               "hourglass forces and the energy its alpha method removes count as energy-balance error")
#: Result.info["hourglass_note"] of a CalculiX drop test (the summary's hourglass_ratio_note).
HOURGLASS_NOTE = ("n/a: CalculiX does not report the energy of its C3D8R hourglass control (the hourglass "
                  "history is zero, not measured)")


def read_energies(text: str) -> dict[float, dict[str, float]]:
    """The energy totals of each printed increment of a drop-test ``.dat`` (:data:`.drop.ENERGY_PRINTS`).

    Parameters
    ----------
    text : str
        The ``.dat`` file's content.

    Returns
    -------
    dict
        Increment end time (s) to a dict with ``"internal ESPEC"``, ``"kinetic ESPEC"``,
        ``"kinetic ECAP"`` (J, quarter model as ccx ran it, when printed) and ``"contact"`` (J,
        elastic energy of every contact element; ccx prints it as 0 when none exists).
    """
    out: dict[float, dict[str, float]] = {}
    for m in _ETOT.finditer(text):
        out.setdefault(float(m.group(3)), {})[f"{m.group(1)} {m.group(2).upper()}"] = float(m.group(4))
    for m in _CELS.finditer(text):
        out.setdefault(float(m.group(1)), {})["contact"] = float(m.group(2))
    return out


def energy_histories(model, text: str, t: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """The Result's energy histories (J, full model) of a drop test, or {} when ccx printed none.

    Parameters
    ----------
    model : Model
        The drop-test model that ran (symmetry factor, impactor mass and velocity).
    text : str
        The ``.dat`` file's content.
    t : ndarray, shape (m,)
        The Result's times (s), t[0] = 0 (the start, printed by no increment).
    v : ndarray, shape (m,)
        Impactor velocity (m/s), for the start's kinetic energy.

    Returns
    -------
    dict
        ``kinetic`` (specimen + impactor cap), ``internal`` (specimen: ccx's integral of S : dE,
        the viscous work included), ``contact`` (penalty springs of both contact pairs),
        ``hourglass`` and ``external`` (zeros: ccx reports no hourglass energy, see
        :data:`HOURGLASS_NOTE`; the deck has no loads, and fixed and symmetry dofs do no work),
        each shape (m,); {} when an increment lacks one of the printed totals (a ``.dat`` from a
        deck without :data:`.drop.ENERGY_PRINTS`).
    """
    e = read_energies(text)
    keys = ("internal ESPEC", "kinetic ESPEC", "kinetic ECAP", "contact")
    rows = [e.get(float(ti), {}) for ti in t[1:]]
    if not all(k in r for r in rows for k in keys):
        return {}
    k = float(model.symmetry_factor)
    sph = model.sphere
    a = np.array([[r[name] for name in keys] for r in rows]).reshape(-1, 4)
    start = np.array([[0.0, 0.0, 0.5 * sph.mass * float(v[0]) ** 2, 0.0]])  # the specimen at rest, unloaded
    a = k * np.concatenate([start, a])
    zero = np.zeros(t.size)
    return {"kinetic": a[:, 1] + a[:, 2], "internal": a[:, 0], "contact": a[:, 3], "hourglass": zero,
            "external": zero.copy()}


def read_drop(text: str) -> dict[str, np.ndarray]:
    """Histories of the impactor from a drop-test ``.dat`` (complete increments only).

    Parameters
    ----------
    text : str
        The ``.dat`` file's content (possibly of a run still going or stopped: an increment
        whose velocity block is missing is left out).

    Returns
    -------
    dict
        ``t`` (s, increment ends), ``uz`` (m, reference-node displacement along z), ``vz``
        (m/s), ``fz`` (N, total z force of the impactor on the specimen's top surface, as
        printed: negative when pressing down; 0 where ccx printed no contact), each shape (m,).
    """
    disp, vel = {}, {}
    for m in _NODE.finditer(text):
        (disp if m.group(1) == "displacements" else vel)[m.group(2)] = float(m.group(5))
    force = {m.group(1): float(m.group(4)) for m in _STAT.finditer(text)}
    keys = [k for k in disp if k in vel]
    t = np.array([float(k) for k in keys])
    return {"t": t, "uz": np.array([disp[k] for k in keys]), "vz": np.array([vel[k] for k in keys]),
            "fz": np.array([force.get(k, 0.0) for k in keys])}


def separation_index(t: np.ndarray, force: np.ndarray, v: np.ndarray, separation_time: float) -> int | None:
    """The increment at which the run stops after the impactor left the specimen, or None.

    The rule of the other backends (skfem's solver, the explicit ones): once contact was seen,
    the impactor has separated when the contact force is zero and it moves up; the run stops
    when it has been separated for ``separation_time``.

    Parameters
    ----------
    t : ndarray, shape (m,)
        Increment end times (s).
    force : ndarray, shape (m,)
        Contact force on the impactor (N, + decelerating a downward impactor).
    v : ndarray, shape (m,)
        Impactor velocity along z (m/s).
    separation_time : float
        How long it must have been separated (s).

    Returns
    -------
    int or None
        Index into ``t`` of the last increment kept, or None while the impactor is in contact.
    """
    seen, since = False, None
    for i in range(t.size):
        if force[i] > 0.0:
            seen, since = True, None
        elif seen and v[i] > 0.0:
            if since is None:
                since = t[i - 1] if i > 0 else 0.0
            if t[i] - since >= separation_time - 1e-12:
                return i
    return None


def drop_result(model, text: str, *, wall: float, separation_time: float, info: dict) -> Result:
    """The :class:`Result` of a drop test from its ``.dat`` (full model: forces times the symmetry factor).

    Parameters
    ----------
    model : Model
        The drop-test model that ran.
    text : str
        The ``.dat`` file's content.
    wall : float
        ccx's wall time (s).
    separation_time : float
        Stop rule (s, :func:`separation_index`); the histories end there when it applies.
    info : dict
        Entries merged into ``Result.info``.

    Returns
    -------
    Result
        ``t`` (s, from 0), ``contact_force`` (N, + decelerating), ``impulse`` (N s, the momentum
        the impactor lost: ccx's rigid body integrated by ccx, so the acceleration resampled
        from it is the impactor's), ``acceleration`` (m/s^2), ``impactor_z`` (m, reference point)
        and ``impactor_v`` (m/s), ``energies`` (J, :func:`energy_histories`; with
        ``info["energy_note"]`` saying what the balance leaves out, ``info["hourglass_note"]``).

    Raises
    ------
    NumericalError
        No increment printed, or non-finite histories.
    """
    h = read_drop(text)
    if h["t"].size == 0:
        raise NumericalError(f"calculix backend: ccx printed no increment of the drop test '{model.name}'.",
                             quantity="ccx output")
    for name in ("uz", "vz", "fz"):
        if not np.isfinite(h[name]).all():
            raise NumericalError(f"calculix backend: non-finite impactor history ({name}) in '{model.name}'.",
                                 quantity=name)
    sph = model.sphere
    k = float(model.symmetry_factor)
    force = -h["fz"] * k
    stop = separation_index(h["t"], force, h["vz"], separation_time) if model.stop_after_separation else None
    n = h["t"].size if stop is None else stop + 1
    t = np.concatenate([[0.0], h["t"][:n]])
    force = np.concatenate([[0.0], force[:n]])
    v = np.concatenate([[sph.velocity], h["vz"][:n]])
    z = float(sph.center[2]) + np.concatenate([[0.0], h["uz"][:n]])
    impulse = sph.mass * k * (v - sph.velocity)
    dts = np.diff(t)
    info = {**info, "increments": int(n), "stop": "separated" if stop is not None else "end_time"}
    energies = energy_histories(model, text, t, v)
    for name, e in energies.items():
        if not np.isfinite(e).all():
            raise NumericalError(f"calculix backend: non-finite {name} energy in '{model.name}'.", quantity=name)
    if energies:
        info.update(energy_note=ENERGY_NOTE, hourglass_note=HOURGLASS_NOTE)
    else:
        info["energy_note"] = "ccx printed no energy totals (a deck without the energy print requests)"
    mass_full = model.mass_full if model.mass_full else sph.mass * k
    return Result(t=t, backend="calculix", steps=int(n), wall_time=wall, contact_force=force, impulse=impulse,
                  acceleration=force / mass_full, impactor_z=z, impactor_v=v, energies=energies,
                  dt_min=float(dts.min()), dt_max=float(dts.max()), info=info)


def watch_ccx(cmd, work, env, model, *, separation_time: float, poll: float = 1.0, progress=None):
    """Run ccx on the drop test, stopping it once the impactor has separated (as the other backends do).

    Parameters
    ----------
    cmd : list of str
        The ccx command line (run in ``work``).
    work : Path
        The run folder (``job.dat`` is read while ccx runs).
    env : dict
        Environment of ccx.
    model : Model
        The drop-test model (its ``stop_after_separation`` applies).
    separation_time : float
        Stop rule of :func:`separation_index` (s).
    poll : float
        Seconds between reads of the ``.dat``.
    progress : callable, optional
        Called with the simulated time (s) reached.

    Returns
    -------
    returncode : int
        ccx's exit status (None-free; a stopped run gives 0).
    log : str
        ccx's standard output and error.
    text : str
        The ``.dat`` content, complete increments only when the run was stopped.
    stopped : bool
        Whether the run was stopped after separation.
    """
    import subprocess
    import time

    dat = work / "job.dat"
    k = float(model.symmetry_factor)
    stopped = False
    with open(work / "ccx.log", "w") as log:
        proc = subprocess.Popen(cmd, cwd=work, stdout=log, stderr=subprocess.STDOUT, env=env)
        try:
            while proc.poll() is None:
                time.sleep(poll)
                if not dat.exists():
                    continue
                h = read_drop(dat.read_text())
                if h["t"].size < 2:
                    continue
                t, f, v = h["t"][:-1], -h["fz"][:-1] * k, h["vz"][:-1]  # the last one may be half written
                if progress is not None:
                    progress(float(t[-1]))
                if model.stop_after_separation and separation_index(t, f, v, separation_time) is not None:
                    proc.terminate()
                    proc.wait()
                    stopped = True
        except BaseException:
            proc.kill()
            proc.wait()
            raise
    text = dat.read_text() if dat.exists() else ""
    if stopped:
        cut = [m.start() for m in _NODE.finditer(text) if m.group(1) == "displacements"]
        text = text[:cut[-1]] if cut else text  # drop the increment being written when ccx was stopped
    return (0 if stopped else proc.returncode), (work / "ccx.log").read_text(), text, stopped
