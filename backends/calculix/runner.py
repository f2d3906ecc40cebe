"""Run ccx on a deck in a temporary folder and read its ``.dat`` back into a :class:`Result`."""

from __future__ import annotations

import os
import re
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from cfm_core.errors import InputError, NumericalError
from cfm_core.simulation.result import Result

from .deck import write_deck

_TOTAL = re.compile(r"total force \(fx,fy,fz\) for set (\S+) and time\s+(\S+)\s*\n\s*\n\s*(\S+)\s+(\S+)\s+(\S+)")
_UMAT_ERROR = re.compile(r"CFM-UMAT-ERROR (.*)")
_UMAT_CUTBACK = re.compile(r"umat \S+: error .*")
_ADAPTOR_CUTBACK = re.compile(r"CFM-UMAT-CUTBACK element (\d+) point (\d+) time (\S+)")

#: PNEWDT the CalculiX adaptor (adaptor.f) hands ccx when the UMAT refuses an iterate; the UMAT's
#: own line names Abaqus's 0.25, which ccx does not see.
ADAPTOR_PNEWDT = 0.5


def umat_refusals(log: str) -> str:
    """What ccx's log says about the iterates the UMAT refused: "" when none, else one line with
    their number, the last one's UMAT message (its Abaqus PNEWDT clause replaced by the cut ccx got
    from the adaptor, :data:`ADAPTOR_PNEWDT`) and, when the adaptor's line is there, its time (s)."""
    umat = _UMAT_CUTBACK.findall(log)
    if not umat:
        return ""
    last = umat[-1].strip().replace("; PNEWDT = 0.25", "")
    where = _ADAPTOR_CUTBACK.findall(log)
    at = f" at t = {_number(where[-1][2])} s" if where else ""
    return (f"the UMAT refused {len(umat)} iterate(s); ccx cut each increment back by PNEWDT = "
            f"{ADAPTOR_PNEWDT:g} (the CalculiX adaptor's); the last{at}: {last}")


def _number(text: str) -> str:
    """A Fortran-printed real as Python prints it (the text itself when it does not parse)."""
    try:
        return f"{float(text):.6g}"
    except ValueError:
        return text


def read_totals(text: str, nset: str) -> tuple[np.ndarray, np.ndarray]:
    """Times and total forces of a node set from a ccx ``.dat`` file (``*NODE PRINT, TOTALS=ONLY``, RF).

    Parameters
    ----------
    text : str
        The ``.dat`` file's content.
    nset : str
        Node set name (upper case).

    Returns
    -------
    t : ndarray, shape (m,)
        Total times (s) of the printed increments, steps concatenated (CalculiX prints each step's
        time from the step's start; they are made cumulative here).
    force : ndarray, shape (m, 3)
        Total reaction force (N) of the set in x, y, z.
    """
    rows = [(float(m.group(2)), float(m.group(3)), float(m.group(4)), float(m.group(5)))
            for m in _TOTAL.finditer(text) if m.group(1).upper() == nset.upper()]
    if not rows:
        return np.zeros(0), np.zeros((0, 3))
    a = np.array(rows)
    return a[:, 0], a[:, 1:]


def run_ccx(ccx: str, model, threads: int = 1, max_increment: float = np.inf, native: bool = False,
            keep: str | None = None, separation_time: float = 2e-4, progress=None,
            penalty: float | None = None) -> Result:
    """Write the deck of ``model``, run ``ccx`` on it, return the histories as a :class:`Result`.

    Parameters
    ----------
    ccx : str
        Path of the ccx executable (the project's build).
    model : Model
        A prescribed-motion model, or a drop test (:mod:`.drop`, :mod:`.dropread`).
    threads : int
        ``OMP_NUM_THREADS`` / ``CCX_NPROC_EQUATION_SOLVER`` for ccx.
    max_increment : float
        Largest time increment (s).
    native : bool
        CalculiX's own neo-Hookean material instead of the UMAT.
    keep : str, optional
        A folder to run in and keep (deck, ``.dat``, ``.frd``, ``.sta``); default a temporary one.
    separation_time : float
        Drop test: stop this long (s) after the impactor left the specimen (as the other backends).
    progress : callable, optional
        Drop test: called with the simulated time (s) while ccx runs.
    penalty : float, optional
        Drop test: contact penalty stiffness (Pa/m); default :data:`.drop.PENALTY`.

    Returns
    -------
    Result
        Prescribed motion: ``reaction_force`` (N, full model: times the symmetry factor) at the
        increments' ends, with t = 0 prepended at zero force. Drop test: see
        :func:`.dropread.drop_result`. ``info`` has ``deck_lines``, ``increments``.

    Raises
    ------
    NumericalError
        ccx stopped (no convergence, the smallest increment reached; the UMAT's error lines,
        naming element, point and time, are quoted).
    """
    from .dropread import drop_result, watch_ccx

    t0 = time.perf_counter()
    drop = model.sphere is not None
    with tempfile.TemporaryDirectory(prefix="cfm-ccx-") as tmp:
        work = Path(keep) if keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        deck = work / "job.inp"
        write_deck(model, deck, max_increment=max_increment, native=native, penalty=penalty)
        env = {**os.environ, **{k: str(threads) for k in ("OMP_NUM_THREADS", "CCX_NPROC_EQUATION_SOLVER",
                                                            "CCX_NPROC_RESULTS", "CCX_NPROC_STIFFNESS")}}
        t1 = time.perf_counter()
        if drop:
            code, log, dat, stopped = watch_ccx([ccx, "-i", "job"], work, env, model,
                                                separation_time=separation_time, progress=progress)
        else:
            proc = subprocess.run([ccx, "-i", "job"], cwd=work, capture_output=True, text=True, env=env)
            code, log, stopped = proc.returncode, proc.stdout + proc.stderr, False
            (work / "ccx.log").write_text(log)
            dat = (work / "job.dat").read_text() if (work / "job.dat").exists() else ""
        wall = time.perf_counter() - t1
        err = _UMAT_ERROR.search(log)
        if err:
            raise NumericalError(f"calculix backend: the generated UMAT stopped ccx: {err.group(1)} (model "
                                 f"'{model.name}').", quantity="umat")
        if not stopped and (code != 0 or "*ERROR" in log):
            msg = "\n".join(ln for ln in log.splitlines() if "ERROR" in ln)[:1500] or log[-1500:]
            refused = umat_refusals(log)
            if refused:
                msg += "\n" + refused
            raise NumericalError(f"calculix backend: ccx failed (exit {code}) on model '{model.name}':\n"
                                 f"{msg}", quantity="ccx")
        n_lines = len(deck.read_text().splitlines())
    if drop:
        info = {"solver": "CalculiX ccx 2.20", "element": "C3D8R", "deck_lines": n_lines, "threads": threads,
                "setup_time": t1 - t0, "umat_cutbacks": len(_UMAT_CUTBACK.findall(log))}
        return drop_result(model, dat, wall=wall, separation_time=separation_time, info=info)
    t, force = read_totals(dat, "NPRESC")
    if t.size == 0:
        raise NumericalError(f"calculix backend: ccx printed no reaction force for model '{model.name}'.",
                             quantity="ccx output")
    # step times restart at each step: make them cumulative
    total = np.empty_like(t)
    offset, last = 0.0, 0.0
    for i, ti in enumerate(t):
        if ti < last - 1e-15:
            offset += last
        total[i] = offset + ti
        last = ti
    if not np.isfinite(force).all():
        raise NumericalError(f"calculix backend: non-finite reaction force in model '{model.name}'.",
                             quantity="reaction force")
    dof = model.prescribed.dof
    times = np.concatenate([[0.0], total])
    rf = np.concatenate([[0.0], force[:, dof]]) * float(model.symmetry_factor)
    dts = np.diff(times)
    info = {"solver": "CalculiX ccx 2.20", "element": "C3D8R", "deck_lines": n_lines, "increments": int(t.size),
            "threads": threads, "setup_time": t1 - t0}
    return Result(t=times, backend="calculix", steps=int(t.size), wall_time=wall, reaction_force=rf,
                  dt_min=float(dts.min()), dt_max=float(dts.max()), info=info)


def check_ccx(ccx: str | None) -> str:
    """The ccx path, or InputError saying how to build it.

    Parameters
    ----------
    ccx : str or None
        Path from the build record.

    Returns
    -------
    str
        The path.

    Raises
    ------
    InputError
        No build: run ``cfm calculix build``.
    """
    if not ccx or not Path(ccx).exists():
        raise InputError("calculix backend: no CalculiX build with this material's UMAT; run `cfm calculix build` "
                         "(fetches calculix-ccx 2.20 from Debian's source package, builds it with the generated "
                         "UMATs linked in; about ten minutes once, then seconds per material).")
    return ccx
