"""Run a :class:`cfm_core.scene.Model` with the numba kernels: set-up, time loop, Result.

Python prepares the arrays (geometry, masses, constraints), then calls the compiled time loop
``advance`` in chunks (about 1 % of the end time each, or up to the next frame), reports
progress between chunks and turns failure codes into :class:`cfm_core.errors.NumericalError`.
Histories are recorded at every step. Forces, impulses and energies in the Result are for the
full model (times ``model.symmetry_factor``); SI units throughout.

The solver runs a renumbered copy of the model (``cfm_backends.explicit.renumber``, option
``renumber``): elements along a space-filling curve, nodes in first-touch order, so that each
block of elements touches a compact range of nodes. Frames, the physics checks and every node or
element named in an error are in the user's numbering.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np

from cfm_backends.explicit import errors, geometry, history, renumber
from cfm_backends.explicit.checks import check_model
from cfm_backends.explicit.options import initial_velocity
from cfm_backends.threads import num_threads
from cfm_core.errors import InputError
from cfm_core.material.prony import gamma_inf
from cfm_core.simulation.checks import Monitor
from cfm_core.simulation.result import Result

from . import codegen, scatter
from .frames import frame_state
from .kernels import layout as K
from .options import PARALLEL_MIN, NumbaOptions

@dataclass
class Prepared:
    """Arrays of one run in the layout the kernels expect (see kernels/layout.py)."""

    geo: tuple
    mat: tuple
    par: np.ndarray
    ipar: np.ndarray
    sc: np.ndarray
    st: tuple
    cnt: tuple
    presc: tuple
    nodes: np.ndarray
    ren: renumber.Renumbering


def prepare(model, o: NumbaOptions) -> Prepared:
    """Build all arrays of a run from the model and checked options (in the solver's numbering:
    ``Prepared.ren`` maps it to the user's)."""
    user_nodes, user_hexes = check_model(model)
    ren = renumber.plan(user_nodes, user_hexes, o.renumber)
    model = ren.model(model)
    nodes, hexes = model.nodes, model.hexes
    n, ne = nodes.shape[0], hexes.shape[0]
    rho = float(model.density)
    V0, B, G, L = geometry.hex_geometry(nodes, hexes)
    mass, free, pmask, pnodes = geometry.constraints(model, nodes, hexes, V0)
    pr = model.prescribed
    if pr is not None:
        presc = (pnodes, np.ascontiguousarray(nodes[pnodes, pr.dof]),
                 np.ascontiguousarray(pr.times, dtype=np.float64),
                 np.ascontiguousarray(pr.values, dtype=np.float64))
    else:
        presc = (np.zeros(0, np.int64), np.zeros(0), np.zeros(1), np.zeros(1))
    gam, tau = (np.ascontiguousarray(a, dtype=np.float64) for a in model.material.prony_arrays())
    p = np.ascontiguousarray(model.material.param_array(), dtype=np.float64)
    k = gam.shape[0]

    par = np.zeros(K.P_N)
    ipar = np.zeros(K.I_N, dtype=np.int64)
    sc = np.zeros(K.S_N)
    par[K.P_RHO] = rho
    par[K.P_HG] = o.hourglass
    par[K.P_SAFETY] = o.safety
    par[K.P_DTMAX] = o.dt_max
    par[K.P_COLLAPSE] = o.collapse
    par[K.P_MU] = float(model.friction)
    par[K.P_GRAV] = abs(float(model.gravity))
    par[K.P_SYM] = float(model.symmetry_factor)
    par[K.P_TEND] = float(model.end_time)
    par[K.P_SEPTIME] = o.separation_time
    par[K.P_GINF] = gamma_inf(model.material.prony_arrays()[0])  # the one exact sum
    ipar[K.I_HGWAVE] = 0 if o.hourglass_wave == "shear" else 1
    ipar[K.I_STOPSEP] = int(bool(model.stop_after_separation))
    sph = model.sphere
    if sph is not None:
        ipar[K.I_SPHERE] = 1
        par[K.P_RADIUS] = sph.radius
        par[K.P_SMASS] = sph.mass
        par[K.P_CX], par[K.P_CY] = sph.center[0], sph.center[1]
        sc[K.S_Z], sc[K.S_V] = sph.center[2], sph.velocity
    if model.plane is not None:
        ipar[K.I_PLANE] = 1
        par[K.P_PLANEZ] = model.plane.z
    if pr is not None:
        ipar[K.I_PRESC] = 1
        ipar[K.I_PDOF] = pr.dof
    sc[K.S_DTMIN] = math.inf
    sc[K.S_DTMAX] = 0.0

    v0 = initial_velocity(o, n, np.ones((n, 3)), "numba")
    v0 = None if v0 is None else ren.to_internal_nodes(v0) * free
    v = np.zeros((n, 3)) if v0 is None else v0
    snodes = np.ascontiguousarray(model.sphere_nodes if sph is not None else [], dtype=np.int64)
    plnodes = np.ascontiguousarray(model.plane_nodes if model.plane is not None else [], dtype=np.int64)
    hx = np.einsum("sa,eaj->esj", geometry.HG_BASE, nodes[hexes])    # h_alpha . X_k (m), (e, 4, 3)
    ed = block_arrays(B, hx, V0, L, rho * V0 ** (2.0 / 3.0) / 4.0)
    nblk = ed.shape[0] // (K.ED_N * K.BLOCK)
    sp = scatter.plan(hexes, n, K.BLOCK)
    if sp.rows >= 2 ** 31:
        raise InputError(f"numba backend: the mesh has {n} nodes; at most {2 ** 31 - 1 - (sp.rows - n)} are "
                         f"supported (32-bit node indices).")
    # 32-bit corner indices: half the index traffic of the element pass (meshes up to 2^31 nodes)
    geo = (np.ascontiguousarray(hexes, dtype=np.int32), np.ascontiguousarray(sp.slot, dtype=np.int32), sp.chunks,
           mass, free.astype(np.int8), pmask.astype(np.int8), sp.hptr, sp.hrow)   # 0/1 masks: 1 byte per dof
    st = (nodes.copy(), np.ascontiguousarray(v), np.zeros((n, 3)), ed, np.zeros(nblk * 6 * k * K.BLOCK),
          np.zeros(sp.rows * K.NF), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
          np.full(nblk, np.inf), np.zeros(nblk, dtype=np.int64), np.zeros(ne, dtype=np.int8), np.zeros((nblk, 4)))
    cnt = (snodes, plnodes, np.zeros((max(len(snodes), 1), 9)))
    return Prepared(geo, (p, gam, tau), par, ipar, sc, st, cnt, presc, nodes, ren)


def block_arrays(B, hx, V0, L, hgfac):
    """The block array of the element kernels (kernels/layout.py, rows ED_*).

    B (e, 8, 3) (1/m), hx (e, 4, 3) = h_alpha . X_k (m; the hourglass vectors are gamma_a,alpha
    = h_alpha,a - sum_k hx_alpha,k B_a,k), V0, L, hgfac (e,): per element. Returns ed (nblk * ED_N
    * BLOCK,): in block b = e // BLOCK, column i = e % BLOCK, row r holds ed[(b * ED_N + r) *
    BLOCK + i]. The state rows start at zero (undeformed, relaxed); columns beyond the last
    element are never used.
    """
    ne = V0.shape[0]
    nblk = -(-ne // K.BLOCK)
    rows = np.zeros((nblk * K.BLOCK, K.ED_N))
    rows[:ne, K.ED_B:K.ED_B + 24] = B.reshape(ne, 24)
    rows[:ne, K.ED_HX:K.ED_HX + 12] = hx.reshape(ne, 12)
    rows[:ne, K.ED_V0] = V0
    rows[:ne, K.ED_L] = L
    rows[:ne, K.ED_HGF] = hgfac
    return np.ascontiguousarray(rows.reshape(nblk, K.BLOCK, K.ED_N).transpose(0, 2, 1)).ravel()


def per_element(block: np.ndarray, n_rows: int, first: int, count: int, ne: int) -> np.ndarray:
    """Rows first .. first + count of a block array (n_rows rows per block, :func:`block_arrays`)
    as a per-element array (ne, count): e.g. the previous-step S, ``per_element(ed, K.ED_N,
    K.ED_SO, 6, ne)`` (Pa), in the solver's element order."""
    nblk = block.shape[0] // (n_rows * K.BLOCK)
    rows = block.reshape(nblk, n_rows, K.BLOCK)[:, first:first + count, :]
    return rows.transpose(0, 2, 1).reshape(nblk * K.BLOCK, count)[:ne].copy()


def _error(code: int, prep: Prepared, model):
    """The NumericalError of a failure code of the compiled loop (``model``: the user's; the
    element named in the user's numbering)."""
    sc = prep.sc
    t, e = float(sc[K.S_T]), prep.ren.user_element(int(sc[K.S_ERRE]))
    if code == K.R_INVERTED:
        return errors.inverted(model, e, t, sc[K.S_ERRV])
    if code == K.R_NONFINITE:
        m = (sc[K.S_ERRM0], sc[K.S_ERRM1], sc[K.S_ERRM2])
        return errors.nonfinite(model.material, f"element {e} at t = {t:.6g} s", m, sc[K.S_ERRV], t, e)
    if code == K.R_COLLAPSE:
        return errors.collapse(model, t, e, sc[K.S_ERRV], sc[K.S_DT0], prep.par[K.P_COLLAPSE])
    return errors.state(model, t)


def advance(mod, prep: Prepared, hist: np.ndarray, t_stop: float):
    """One call of the compiled loop: (rows, code)."""
    return mod.advance(prep.geo, prep.mat, prep.par, prep.ipar, prep.sc, prep.st, prep.cnt,
                       prep.presc, hist, t_stop)


_WARM: set = set()


def warm_up(mod, material) -> float:
    """Compile (or load from the cache) the time loop ``advance`` and all it calls on a 1-element
    model; seconds spent. ``point_history`` (material-point runs) is left to its first use: a run
    does not call it, and loading a kernel from numba's cache costs time too."""
    if id(mod) in _WARM:
        return 0.0
    from cfm_core.scene.model import Model, RigidPlane, RigidSphere

    nodes = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                      [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64) * 1e-3
    model = Model(name="warm-up", nodes=nodes, hexes=np.arange(8)[None, :], density=1000.0,
                  material=material, end_time=1e-9, output_interval=1e-9,
                  sphere=RigidSphere(0.05, 0.01, (0.0, 0.0, 0.051), -1.0), plane=RigidPlane(0.0),
                  sphere_nodes=np.arange(4, 8), plane_nodes=np.arange(4))
    start = time.perf_counter()
    prep = prepare(model, NumbaOptions())
    advance(mod, prep, np.zeros((4, K.H_N)), 1e-9)
    _WARM.add(id(mod))
    return time.perf_counter() - start


def run_model(model, progress=None, **options) -> Result:
    """Run ``model``; see :class:`cfm_backends.numba_explicit.NumbaExplicitBackend`."""
    o = NumbaOptions.from_mapping(options)
    # Worker threads that sleep at the end of a parallel loop instead of spinning: on a 2-core
    # machine where another process held one core, spinning OpenMP threads made 2 threads about
    # 10x slower than one, sleeping ones about as fast as one. Set before numba starts its threads
    # (no effect afterwards); a value the user chose is kept.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    import numba

    with num_threads(numba, o.threads, serial=model.n_elements < PARALLEL_MIN):
        t0 = time.perf_counter()
        with codegen.announce(model.material):
            mod = codegen.load(model.material)
            if o.warm_up:
                warm_up(mod, model.material)
        compile_time = time.perf_counter() - t0
        prep = prepare(model, o)
        return _loop(model, mod, prep, o, progress, compile_time, numba.get_num_threads())


def _loop(model, mod, prep: Prepared, o: NumbaOptions, progress, compile_time: float, threads: int) -> Result:
    end = float(model.end_time)
    tick = end / 100.0
    next_progress = tick
    fi = o.frame_interval
    frames = [(0.0, np.zeros_like(prep.nodes))] if fi else []
    states = [prep.ren.frame_state_to_user(frame_state(prep, model.n_elements, prep.mat[1].shape[0]))] if fi else []  # velocity, Prony state
    next_frame = fi if fi else math.inf
    chunks = []
    hist = np.zeros((4096, K.H_N))
    stop = "end_time"
    reported = 0.0
    conn = np.ascontiguousarray(model.hexes, dtype=np.int64)
    vols = np.empty((conn.shape[0], 8))
    ren = prep.ren
    # physics checks (cfm_core.simulation.checks), every ~1 % of the end time, on the user's
    # numbering (the positions renumbered back); the fold check compiled
    monitor = Monitor(model, corner_volumes=lambda x, hexes: mod.corner_volumes(x, conn, vols))
    z = (lambda: float(prep.sc[K.S_Z])) if model.sphere is not None else (lambda: None)
    start = time.perf_counter()
    while True:
        rows, code = advance(mod, prep, hist, min(next_progress, next_frame, monitor.next))
        chunks.append(hist[:rows].copy())
        if code >= K.R_INVERTED:
            raise _error(code, prep, model)
        t = float(prep.sc[K.S_T])
        if monitor.due(t):
            monitor.check(t, ren.to_user_nodes(prep.st[0]), z())
        if fi and t >= next_frame:
            frames.append((t, ren.to_user_nodes(prep.st[0] - prep.nodes)))
            states.append(ren.frame_state_to_user(frame_state(prep, model.n_elements, prep.mat[1].shape[0])))
            next_frame = (math.floor(t / fi) + 1) * fi
        if t >= next_progress:
            if progress is not None and min(t, end) > reported:
                reported = min(t, end)
                progress(reported)
            next_progress = (math.floor(t / tick) + 1) * tick
        if code == K.R_DONE:
            break
        if code == K.R_SEPARATED:
            stop = "separated"
            break
        if prep.sc[K.S_STEPS] >= o.max_steps:
            raise errors.max_steps(model, int(prep.sc[K.S_STEPS]), t)
    wall = time.perf_counter() - start
    monitor.final(t, ren.to_user_nodes(prep.st[0]), z())
    h = np.concatenate(chunks)
    res = _result(model, prep, h, wall, compile_time, threads, frames, stop, o)
    res.info["checks"] = monitor.report()
    res.frame_state = states
    return res


def _result(model, prep, h, wall, compile_time, threads, frames, stop, o) -> Result:
    sc = prep.sc
    return history.assemble(model, h, backend="numba", steps=int(sc[K.S_STEPS]), wall=wall,
                            dt0=float(sc[K.S_DT0]), dtmin=float(sc[K.S_DTMIN]), dtmax=float(sc[K.S_DTMAX]),
                            maxpen=float(sc[K.S_MAXPEN]), frames=frames, stop=stop, options=o,
                            info={"threads": threads, "compile_time": compile_time})
