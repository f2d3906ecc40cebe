"""Run generated user materials through their real calling conventions (gfortran + ctypes).

Each routine is compiled with gfortran into a shared library (cached by source hash in
``cache_dir("fortran")``) and called from Python with the argument list its solver uses,
written out once per solver below: every argument by reference, arrays column-major, the hidden
lengths of CHARACTER arguments appended by value (gfortran's convention, the same as Intel
Fortran's default on Linux). The drivers carry state variables between calls as a solver does
(the output state of one increment is the input of the next), so a restart from a saved state
is the same call sequence.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.linalg

from ..errors import InputError
from ..material.cache import cache_dir

FLAGS = ("-O2", "-fPIC", "-shared", "-std=f2008", "-ffixed-form", "-Wall")
ABAQUS_STANDARD = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # 11, 22, 33, 12, 13, 23
ABAQUS_EXPLICIT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0))  # 11, 22, 33, 12, 23, 31
LSDYNA = ABAQUS_EXPLICIT                                           # xx, yy, zz, xy, yz, zx


@dataclass(frozen=True)
class Library:
    """A compiled generated routine.

    Attributes
    ----------
    path : pathlib.Path
        The shared library.
    warnings : str
        What gfortran printed when it compiled the source (empty: warning-free).
    """

    path: Path
    warnings: str

    def function(self, name: str):
        """The Fortran routine ``name`` of the library, for ctypes.

        Parameters
        ----------
        name : str
            Fortran name (``"umat"``); lower-cased and given gfortran's trailing underscore.

        Returns
        -------
        ctypes function
            Arguments by reference (pointers), hidden character lengths appended by value.
        """
        return getattr(ctypes.CDLL(str(self.path)), name.lower() + "_")


def gfortran() -> str | None:
    """The gfortran compiler (``$CFM_GFORTRAN`` or ``gfortran`` on the PATH).

    Returns
    -------
    str or None
        Its path, or None when it is not installed.
    """
    return shutil.which(os.environ.get("CFM_GFORTRAN", "gfortran"))


def compile_library(source: str, name: str = "usermat") -> Library:
    """Compile a generated Fortran source into a shared library (cached by source hash).

    Parameters
    ----------
    source : str
        Fixed-form Fortran source (a generated UMAT, VUMAT or umat41 file).
    name : str
        Readable part of the cached file name.

    Returns
    -------
    Library
        The library and the compiler's warnings (kept beside it for later calls).

    Raises
    ------
    InputError
        gfortran is not installed (the message says how to install it).
    RuntimeError
        gfortran rejects the source (a generator defect; the message holds the compiler output).
    """
    compiler = gfortran()
    if compiler is None:
        raise InputError("gfortran is not installed; the export harness compiles the generated Fortran with it. "
                         "Install it (Debian/Ubuntu: apt-get install gfortran) or set CFM_GFORTRAN to its path.")
    key = hashlib.sha256((source + " ".join(FLAGS) + compiler).encode()).hexdigest()[:20]
    folder = cache_dir("fortran")
    lib, log = folder / f"{name}-{key}.so", folder / f"{name}-{key}.log"
    if lib.is_file() and log.is_file():
        return Library(lib, log.read_text())
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        src = Path(tmp) / f"{name}.f"
        src.write_text(source)
        out = Path(tmp) / "lib.so"
        done = subprocess.run([compiler, *FLAGS, str(src), "-o", str(out)], capture_output=True, text=True,
                              cwd=tmp, timeout=300)
        if done.returncode != 0:
            raise RuntimeError(f"gfortran could not compile the generated {name}:\n{done.stderr}")
        log.write_text(done.stderr)
        os.replace(out, lib)
    return Library(lib, log.read_text())


def _p(a):
    return a.ctypes.data_as(ctypes.c_void_p)


def _voigt(T, order):
    return np.array([T[a, b] for a, b in order])


def _tensor(v, order):
    T = np.empty((3, 3))
    for k, (a, b) in enumerate(order):
        T[a, b] = T[b, a] = v[k]
    return T


def run_umat(lib: Library, props, t, F, nstatv: int, statev=None, stress=None, cmname: str = "CFM") -> dict:
    """Call the UMAT along a history as Abaqus/Standard does (one increment per step).

    Parameters
    ----------
    lib : Library
        The compiled UMAT.
    props : array_like, shape (nprops,)
        Material constants (``PROPS``), SI units.
    t : array_like, shape (n,)
        Times (s); increment k goes from t[k-1] to t[k].
    F : array_like, shape (n, 3, 3)
        Deformation gradients; F[0] is the start of the first increment.
    nstatv : int
        ``NSTATV``.
    statev, stress : ndarray, optional
        State variables and Cauchy stress (order 11, 22, 33, 12, 13, 23) at t[0] (default zero:
        an undeformed, relaxed start); a restart passes a saved state.
    cmname : str
        ``CMNAME`` (the material name; CalculiX's adaptor dispatches on it).

    Returns
    -------
    dict
        ``stress`` (n, 6) Cauchy in Abaqus order (Pa; row 0 the start), ``ddsdde`` (n, 6, 6),
        ``statev`` (n, nstatv), ``pnewdt`` (n,), ``sse`` and ``scd`` (n,) (J/m^3).
    """
    fn = lib.function("umat")
    props = np.ascontiguousarray(props, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    n = t.size
    out = {"stress": np.zeros((n, 6)), "ddsdde": np.zeros((n, 6, 6)), "statev": np.zeros((n, nstatv)),
           "pnewdt": np.ones(n), "sse": np.zeros(n), "scd": np.zeros(n)}
    if statev is not None:
        out["statev"][0] = statev
    if stress is not None:
        out["stress"][0] = stress
    d = lambda v=0.0: np.array([v], dtype=np.float64)  # noqa: E731 - a scalar passed by reference
    i = lambda v: np.array([v], dtype=np.int32)  # noqa: E731
    name = ctypes.create_string_buffer(cmname.encode().ljust(80), 80)
    for k in range(1, n):
        stress_k = out["stress"][k - 1].copy()
        statev_k = out["statev"][k - 1].copy()
        ddsdde = np.zeros((6, 6), order="F")
        sse, spd, scd, rpl, drpldt, pnewdt = d(out["sse"][k - 1]), d(), d(out["scd"][k - 1]), d(), d(), d(1.0)
        ddsddt, drplde, stran, dstran = np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
        time = np.array([t[k - 1], t[k - 1]])
        f0, f1 = np.asfortranarray(F[k - 1]), np.asfortranarray(F[k])
        drot, coords = np.asfortranarray(np.eye(3)), np.zeros(3)
        args = [stress_k, statev_k, ddsdde, sse, spd, scd, rpl, ddsddt, drplde, drpldt, stran, dstran, time,
                d(t[k] - t[k - 1]), d(), d(), np.zeros(1), np.zeros(1)]
        fn(*[_p(a) for a in args], name, *[_p(a) for a in (
            i(3), i(3), i(6), i(nstatv), props, i(props.size), coords, drot, pnewdt, d(1e-3), f0, f1,
            i(1), i(1), i(1), i(1), i(1), i(k))], ctypes.c_size_t(80))
        out["stress"][k], out["statev"][k], out["ddsdde"][k] = stress_k, statev_k, ddsdde
        out["pnewdt"][k], out["sse"][k], out["scd"][k] = pnewdt[0], sse[0], scd[0]
    return out


def polar(F):
    """Right polar decomposition F = R U of each F (scipy.linalg.polar).

    Parameters
    ----------
    F : ndarray, shape (..., 3, 3)
        Deformation gradients (-), det F > 0.

    Returns
    -------
    R, U : ndarray, shape (..., 3, 3)
        Rotations and symmetric positive-definite right stretch tensors.
    """
    F = np.asarray(F, dtype=np.float64)
    flat = F.reshape(-1, 3, 3)
    R, U = np.empty_like(flat), np.empty_like(flat)
    for k, f in enumerate(flat):
        R[k], U[k] = scipy.linalg.polar(f, side="right")
        U[k] = 0.5 * (U[k] + U[k].T)
    return R.reshape(F.shape), U.reshape(F.shape)


def run_vumat(lib: Library, props, t, F, nstatev: int, density: float = 950.0, state=None) -> dict:
    """Call the VUMAT along histories as Abaqus/Explicit does: one call per increment for a block
    of ``nblock`` material points (each column of ``F`` a point's history).

    The solver's inputs are made as Explicit makes them: ``stretchNew`` = U and ``defgradNew`` =
    R^T F = U in the corotational frame (F = R U), ``strainInc`` the corotational increment of
    the midpoint rate of deformation (tensor shear components).

    Parameters
    ----------
    lib : Library
        The compiled VUMAT.
    props : array_like, shape (nprops,)
        Material constants, SI units.
    t : array_like, shape (n,)
        Times (s).
    F : array_like, shape (n, nblock, 3, 3)
        Deformation gradients of the block's points.
    nstatev : int
        ``nstatev``.
    density : float
        Reference density rho_0 (kg/m^3); the routine gets the current density rho_0 / J at the
        midstep, as Explicit passes it.
    state : ndarray, shape (nblock, nstatev), optional
        State at t[0] (default zero).

    Returns
    -------
    dict
        ``stress`` (n, nblock, 6) corotational Cauchy stress, order 11, 22, 33, 12, 23, 31 (Pa),
        ``state`` (n, nblock, nstatev), ``ener_intern`` (n, nblock) (J/kg), ``R`` (n, nblock, 3, 3).
    """
    fn = lib.function("vumat")
    props = np.ascontiguousarray(props, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    n, nb = F.shape[:2]
    R, U = polar(F)
    out = {"stress": np.zeros((n, nb, 6)), "state": np.zeros((n, nb, nstatev)), "ener_intern": np.zeros((n, nb)),
           "R": R}
    if state is not None:
        out["state"][0] = state
    i = lambda v: np.array([v], dtype=np.int32)  # noqa: E731
    d = lambda v: np.array([v], dtype=np.float64)  # noqa: E731
    cmname = ctypes.create_string_buffer(b"CFM".ljust(80), 80)
    z = lambda *shape: np.zeros(shape, order="F")  # noqa: E731
    for k in range(1, n):
        Fm, dF = 0.5 * (F[k] + F[k - 1]), F[k] - F[k - 1]
        _, Um = polar(Fm)
        Rm = np.einsum("nij,njk->nik", Fm, np.linalg.inv(Um))
        D = np.einsum("nij,njk->nik", dF, np.linalg.inv(Fm))
        D = 0.5 * (D + np.swapaxes(D, 1, 2))
        Dhat = np.einsum("nki,nkl,nlj->nij", Rm, D, Rm)
        strain_inc = np.asfortranarray([[Dhat[b, p, q] for p, q in ABAQUS_EXPLICIT] for b in range(nb)])
        stretch_old = np.asfortranarray([_voigt(u, ABAQUS_EXPLICIT) for u in U[k - 1]])
        stretch_new = np.asfortranarray([_voigt(u, ABAQUS_EXPLICIT) for u in U[k]])
        order9 = ABAQUS_EXPLICIT + ((1, 0), (2, 1), (0, 2))  # F11 F22 F33 F12 F23 F31 F21 F32 F13
        grad_old = np.asfortranarray([[u[p, q] for p, q in order9] for u in U[k - 1]])
        grad_new = np.asfortranarray([[u[p, q] for p, q in order9] for u in U[k]])
        stress_old = np.asfortranarray(out["stress"][k - 1])
        state_old = np.asfortranarray(out["state"][k - 1])
        stress_new, state_new = z(nb, 6), z(nb, nstatev)
        e_int_new, e_inel_new = z(nb), z(nb)
        args_a = [i(nb), i(3), i(3), i(nstatev), i(1), i(props.size), i(0), d(t[k]), d(t[k]), d(t[k] - t[k - 1])]
        rho = np.asfortranarray(density / np.linalg.det(Fm))
        args_b = [z(nb, 3), np.full(nb, 1e-3), props, rho, strain_inc, z(nb, 3), z(nb),
                  stretch_old, grad_old, z(nb, 1), stress_old, state_old, np.asfortranarray(out["ener_intern"][k - 1]),
                  z(nb), z(nb), stretch_new, grad_new, z(nb, 1), stress_new, state_new, e_int_new, e_inel_new]
        fn(*[_p(a) for a in args_a], cmname, *[_p(a) for a in args_b], ctypes.c_size_t(80))
        out["stress"][k], out["state"][k], out["ener_intern"][k] = stress_new, state_new, e_int_new
    return out


def run_lsdyna(lib: Library, cm, t, F, nhv: int, hsv=None, etype: str = "solid", tangent: bool = False) -> dict:
    """Call ``umat41`` along a history as LS-DYNA does with ``IHYPER = 1``: F written into
    ``hsv(nhv+1 .. nhv+9)`` column-major before each call, the stress of the last step passed in;
    with ``tangent`` also ``utan41`` after ``umat41`` at each step, as LS-DYNA's implicit solver
    asks for the material tangent: the same ``cm``, ``hsv`` (as umat41 left it, F behind the user
    variables), ``dt1`` and stress.

    Parameters
    ----------
    lib : Library
        The compiled umat41.
    cm : array_like
        Material constants (``cm``), SI units.
    t : array_like, shape (n,)
        Times (s).
    F : array_like, shape (n, 3, 3)
        Deformation gradients.
    nhv : int
        ``NHV`` of the card.
    hsv : ndarray, shape (nhv,), optional
        User history variables at t[0] (default zero).
    etype : str
        Element type passed (``"solid"``).
    tangent : bool
        Call ``utan41`` too.

    Returns
    -------
    dict
        ``stress`` (n, 6) Cauchy xx, yy, zz, xy, yz, zx (Pa), ``hsv`` (n, nhv), ``reject`` (n,) bool,
        ``failel`` (n,) bool; with ``tangent`` also ``es`` (n, 6, 6) (Pa; row 0 zero, no call there)
        and ``unsym`` (n,) bool.
    """
    fn = lib.function("umat41")
    fn_tan = lib.function("utan41") if tangent else None
    cm = np.ascontiguousarray(cm, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    n = t.size
    out = {"stress": np.zeros((n, 6)), "hsv": np.zeros((n, nhv)), "reject": np.zeros(n, bool),
           "failel": np.zeros(n, bool)}
    if tangent:
        out.update(es=np.zeros((n, 6, 6)), unsym=np.zeros(n, bool))
    if hsv is not None:
        out["hsv"][0] = hsv
    d = lambda v=0.0: np.array([v], dtype=np.float64)  # noqa: E731
    i = lambda v: np.array([v], dtype=np.int32)  # noqa: E731
    et = ctypes.create_string_buffer(etype.ljust(5).encode(), 5)
    for k in range(1, n):
        h = np.concatenate([out["hsv"][k - 1], F[k].ravel(order="F")])
        sig = out["stress"][k - 1].copy()
        dF = F[k] - F[k - 1]
        D = dF @ np.linalg.inv(0.5 * (F[k] + F[k - 1]))
        D = 0.5 * (D + D.T)
        eps = np.array([D[0, 0], D[1, 1], D[2, 2], 2 * D[0, 1], 2 * D[1, 2], 2 * D[2, 0]])
        failel, reject = i(0), i(0)
        args = [cm, eps, sig, d(), h, d(t[k] - t[k - 1]), d(1.0)]
        fn(*[_p(a) for a in args], et, *[_p(a) for a in (
            d(t[k]), d(), failel, np.zeros(1), np.zeros(1, np.int32), np.zeros(1), np.asfortranarray(np.eye(3)),
            d(1e-3), i(0), reject)], ctypes.c_size_t(5))
        out["stress"][k], out["hsv"][k] = sig, h[:nhv]
        out["reject"][k], out["failel"][k] = bool(reject[0]), bool(failel[0])
        if tangent:
            es, unsym = np.full((6, 6), np.nan, order="F"), i(1)
            args = [cm, eps, sig, d(), h, d(t[k] - t[k - 1]), unsym, d(1.0)]
            fn_tan(*[_p(a) for a in args], et, *[_p(a) for a in (
                d(t[k]), d(), es, np.zeros(1), np.zeros(1, np.int32), failel, np.zeros(1),
                np.asfortranarray(np.eye(3)))], ctypes.c_size_t(5))
            out["es"][k], out["unsym"][k] = es, bool(unsym[0])
    return out
