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

Parts (``Model.parts``): the renumbering sorts the elements by part, so each part is one
contiguous range of internal elements; each part is blocked on its own (its last block may be
partial) and split into its own scatter chunks, with its density (lumped mass, hourglass factor,
wave speed), material parameters, Prony terms and gamma_inf (``parts``, kernels/layout.py PT_*).
The generated ``element_parts`` runs each part's pass with its material's compiled code
(``codegen``); the stable step is the minimum over all parts, the energies sum over them. A model
without parts runs exactly the arrays and operations it ran before parts existed.

Impactor: the paper's hemisphere moving along z keeps ``sphere_contact``; other shapes
(``sphere``, ``flat``, ``plane``) and lateral motion (``RigidSphere.moves``) run
``impactor_contact`` (kernels/impactor.py), which also records the in-plane columns
(``backends/explicit/history.py``).
"""

from __future__ import annotations

import functools
import math
import os
import time
from dataclasses import dataclass

import numpy as np

from cfm_backends.explicit import errors, geometry, history, renumber
from cfm_backends.explicit.checks import check_model
from cfm_backends.explicit.options import initial_velocity, step_cap
from cfm_backends import numba_target
from cfm_backends.threads import check_count, num_threads
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
    parts: tuple = ()
    ranges: list = None
    nblks: list = None
    ks: list = None


def part_ranges(model) -> list[tuple[int, int]]:
    """[first, end) internal element range of each part of a renumbered model (one part: all)."""
    ranges = []
    for part in model.part_list():
        el = np.asarray(part.elements, dtype=np.int64)
        ea, eb = (int(el[0]), int(el[-1]) + 1) if el.size else (0, 0)
        if el.size and (eb - ea != el.size or (ranges and ea != ranges[-1][1])):
            raise InputError(f"numba backend: part '{part.name}' is not one contiguous element range after "
                             f"renumbering (an internal error of the renumbering).")
        ranges.append((ea, eb))
    return ranges


def prepare(model, o: NumbaOptions) -> Prepared:
    """Build all arrays of a run from the model and checked options (in the solver's numbering:
    ``Prepared.ren`` maps it to the user's). Each part (``Model.part_list()``) is one contiguous
    range of internal elements whose blocks are a contiguous range of the block arrays; the
    global arrays in ``geo``, ``st`` hold all parts, ``parts`` views of them per part (layout.py,
    PT_*); ``mat`` is the first part's material arrays."""
    user_nodes, user_hexes = check_model(model)
    ren = renumber.plan(user_nodes, user_hexes, o.renumber, groups=model.element_part())
    model = ren.model(model)
    nodes, hexes = model.nodes, model.hexes
    n, ne = nodes.shape[0], hexes.shape[0]
    plist = model.part_list()
    ranges = part_ranges(model)
    V0, B, G, L = geometry.hex_geometry(nodes, hexes)
    mass, free, pmask, pnodes = geometry.constraints(model, nodes, hexes, V0)
    pr = model.prescribed
    if pr is not None:
        presc = (pnodes, np.ascontiguousarray(nodes[pnodes, pr.dof]),
                 np.ascontiguousarray(pr.times, dtype=np.float64),
                 np.ascontiguousarray(pr.values, dtype=np.float64))
    else:
        presc = (np.zeros(0, np.int64), np.zeros(0), np.zeros(1), np.zeros(1))
    mats = [tuple(np.ascontiguousarray(a, dtype=np.float64) for a in pt.material.prony_arrays()) for pt in plist]
    prm = [np.ascontiguousarray(pt.material.param_array(), dtype=np.float64) for pt in plist]

    par = np.zeros(K.P_N)
    ipar = np.zeros(K.I_N, dtype=np.int64)
    sc = np.zeros(K.S_N)
    par[K.P_RHO] = float(plist[0].density)
    par[K.P_HG] = o.hourglass
    par[K.P_SAFETY] = o.safety
    par[K.P_DTMAX] = step_cap(o, model)  # dt_max, and the output interval: histories at least that often
    par[K.P_COLLAPSE] = o.collapse
    par[K.P_MU] = float(model.friction)
    par[K.P_GRAV] = abs(float(model.gravity))
    par[K.P_SYM] = float(model.symmetry_factor)
    par[K.P_TEND] = float(model.end_time)
    par[K.P_SEPTIME] = o.separation_time
    par[K.P_GINF] = gamma_inf(plist[0].material.prony_arrays()[0])  # the one exact sum
    ipar[K.I_HGWAVE] = 0 if o.hourglass_wave == "shear" else 1
    ipar[K.I_STOPSEP] = int(bool(model.stop_after_separation))
    sph = model.sphere
    if sph is not None:
        impactor_parameters(sph, par, ipar, sc)
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
    eds, nblks = [], []
    for (ea, eb), pt in zip(ranges, plist):
        rho = float(pt.density)
        eds.append(block_arrays(B[ea:eb], hx[ea:eb], V0[ea:eb], L[ea:eb], rho * V0[ea:eb] ** (2.0 / 3.0) / 4.0))
        nblks.append(eds[-1].shape[0] // (K.ED_N * K.BLOCK))
    ed = eds[0] if len(eds) == 1 else np.concatenate(eds)
    nblk = sum(nblks)
    sp = scatter.plan(hexes, n, K.BLOCK, parts=ranges)
    if sp.rows >= 2 ** 31:
        raise InputError(f"numba backend: the mesh has {n} nodes; at most {2 ** 31 - 1 - (sp.rows - n)} are "
                         f"supported (32-bit node indices).")
    # 32-bit corner indices: half the index traffic of the element pass (meshes up to 2^31 nodes)
    geo = (np.ascontiguousarray(hexes, dtype=np.int32), np.ascontiguousarray(sp.slot, dtype=np.int32), sp.chunks,
           mass, free.astype(np.int8), pmask.astype(np.int8), sp.hptr, sp.hrow)   # 0/1 masks: 1 byte per dof
    ks = [m[0].shape[0] for m in mats]
    eh = np.zeros(sum(nb * 6 * k * K.BLOCK for nb, k in zip(nblks, ks)))
    st = (nodes.copy(), np.ascontiguousarray(v), np.zeros((n, 3)), ed, eh,
          np.zeros(sp.rows * K.NF), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
          np.full(nblk, np.inf), np.zeros(nblk, dtype=np.int64), np.zeros(ne, dtype=np.int8), np.zeros((nblk, 4)))
    parts = part_tuples(geo, st, sp.chunks, ranges, nblks, ks, mats, prm, plist,
                        codegen.distinct(tuple(pt.material for pt in plist))[1])
    cnt = (snodes, plnodes, np.zeros((max(len(snodes), 1), 12)))
    return Prepared(geo, (prm[0], *mats[0]), par, ipar, sc, st, cnt, presc, nodes, ren, parts, ranges, nblks, ks)


def part_tuples(geo, st, chunks, ranges, nblks, ks, mats, prm, plist, mat_index) -> tuple:
    """The time loop's ``parts`` (layout.py, PT_*): per part, views of the global arrays over its
    elements and blocks, its chunks (first block counted in the part), material and Prony arrays."""
    conn, slot = geo[0], geo[1]
    ed, eh, status, bdt, bemin, errv = st[3], st[4], st[11], st[9], st[10], st[12]
    out = []
    b0 = h0 = c0 = 0
    for (ea, eb), nb, k, (gam, tau), p, pt, mi in zip(ranges, nblks, ks, mats, prm, plist, mat_index):
        c1 = int(np.searchsorted(chunks[:, 0], b0 + nb, side="left"))
        ch = chunks[c0:c1 + 1].copy()
        ch[:, 0] -= b0
        nh = nb * 6 * k * K.BLOCK
        pp = np.zeros(K.PP_N)
        pp[K.PP_RHO] = float(pt.density)
        pp[K.PP_GINF] = gamma_inf(pt.material.prony_arrays()[0])
        pp[K.PP_E0] = ea
        pp[K.PP_MAT] = mi
        out.append((conn[ea:eb], slot[ea:eb], np.ascontiguousarray(ch), ed[b0 * K.ED_N * K.BLOCK:(b0 + nb) * K.ED_N * K.BLOCK],
                    eh[h0:h0 + nh], status[ea:eb], bdt[b0:b0 + nb], bemin[b0:b0 + nb], errv[b0:b0 + nb],
                    p, gam, tau, np.zeros(k), np.zeros(k), pp))
        b0 += nb
        h0 += nh
        c0 = c1
    return tuple(out)


def impactor_parameters(sph, par, ipar, sc) -> None:
    """The impactor's entries of par, ipar and sc (layout.py): the paper's hemisphere moving along
    z runs ``sphere_contact`` (I_GENERAL 0), any other shape or motion ``impactor_contact``."""
    ipar[K.I_SPHERE] = 1
    par[K.P_RADIUS] = sph.radius
    par[K.P_SMASS] = sph.mass
    par[K.P_CX], par[K.P_CY] = sph.center[0], sph.center[1]
    sc[K.S_Z], sc[K.S_V] = sph.center[2], sph.velocity
    sc[K.S_X], sc[K.S_Y] = sph.center[0], sph.center[1]
    moves = tuple(bool(m) for m in sph.moves)
    shape = getattr(sph, "shape", "hemisphere")
    ipar[K.I_SHAPE] = {"hemisphere": K.SH_HEMISPHERE, "sphere": K.SH_SPHERE, "flat": K.SH_FLAT,
                       "plane": K.SH_PLANE}[shape]
    ipar[K.I_GENERAL] = int(not (shape == "hemisphere" and moves == (False, False, True)))
    ipar[K.I_MOVX], ipar[K.I_MOVY], ipar[K.I_MOVZ] = (int(m) for m in moves)
    par[K.P_EDGE] = float(sph.edge_radius) if shape == "flat" else 0.0
    vx, vy = (float(c) for c in sph.velocity_xy)
    sc[K.S_VX] = vx if moves[0] else 0.0
    sc[K.S_VY] = vy if moves[1] else 0.0
    if not moves[2]:
        sc[K.S_V] = 0.0


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
        return errors.inverted(model, e, t, sc[K.S_ERRV], sc[K.S_DT0])
    if code == K.R_NONFINITE:
        m = (sc[K.S_ERRM0], sc[K.S_ERRM1], sc[K.S_ERRM2])
        material = model.part_list()[int(model.element_part()[e])].material
        return errors.nonfinite(material, f"element {e} at t = {t:.6g} s", m, sc[K.S_ERRV], t, e)
    if code == K.R_COLLAPSE:
        return errors.collapse(model, t, e, sc[K.S_ERRV], sc[K.S_DT0], prep.par[K.P_COLLAPSE])
    return errors.state(model, t)


def advance(mod, prep: Prepared, hist: np.ndarray, t_stop: float):
    """One call of the compiled loop: (rows, code)."""
    return mod.advance(prep.geo, prep.parts, prep.par, prep.ipar, prep.sc, prep.st, prep.cnt,
                       prep.presc, hist, t_stop)


_WARM: set = set()


def warm_up(mod, material) -> float:
    """Compile (or load from the cache) the time loop ``advance`` and all it calls, and the physics
    checks' scan, on a model of one element per material (``material``: one, or a tuple with one
    per part); seconds spent.
    ``point_history`` (material-point runs) is left to its first use: a run does not call it, and
    loading a kernel from numba's cache costs time too."""
    mats = codegen._materials(material)
    if (id(mod), len(mats)) in _WARM:
        return 0.0
    from cfm_core.scene.model import Model, Part, RigidPlane, RigidSphere

    ne = len(mats)
    xs = np.arange(ne + 1, dtype=np.float64)
    nodes = np.array([[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in xs]) * 1e-3
    idx = lambda i, y, z: int(z * 2 * (ne + 1) + y * (ne + 1) + i)           # noqa: E731
    hexes = np.array([[idx(i, 0, 0), idx(i + 1, 0, 0), idx(i + 1, 1, 0), idx(i, 1, 0),
                       idx(i, 0, 1), idx(i + 1, 0, 1), idx(i + 1, 1, 1), idx(i, 1, 1)] for i in range(ne)])
    parts = tuple(Part(f"p{i}", m, 1000.0, np.array([i])) for i, m in enumerate(mats)) if ne > 1 else ()
    top = np.flatnonzero(nodes[:, 2] > 0.0)
    model = Model(name="warm-up", nodes=nodes, hexes=hexes, density=1000.0,
                  material=mats[0], end_time=1e-9, output_interval=1e-9,
                  sphere=RigidSphere(0.05, 0.01, (0.0, 0.0, 0.051), -1.0), plane=RigidPlane(0.0),
                  sphere_nodes=top, plane_nodes=np.flatnonzero(nodes[:, 2] == 0.0), parts=parts)
    start = time.perf_counter()
    prep = prepare(model, NumbaOptions())
    advance(mod, prep, np.zeros((4, K.H_N)), 1e-9)
    from .scan import NumbaScan

    NumbaScan(model, 0.0, [])(prep.st[0], None)      # the physics checks' compiled pass too
    _WARM.add((id(mod), len(mats)))
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

    # The thread count is chosen after the kernels are loaded and the state prepared, just before
    # the time loop: the cores free then are the ones the loop gets (a figure process importing
    # matplotlib meanwhile, cfm_core.post.figure_process, is done by then). The warm-up's small
    # parallel calls run on one thread.
    check_count(o.threads)  # a count above the cores is refused before any kernel is loaded
    with num_threads(numba, 1):
        t0 = time.perf_counter()
        material = model.material if not model.multi_material else tuple(p.material for p in model.parts)
        with codegen.announce(material):
            mod = codegen.load(material)
            if o.warm_up:
                warm_up(mod, material)
        compile_time = time.perf_counter() - t0
    prep = prepare(model, o)
    with num_threads(numba, o.threads, serial=model.n_elements < PARALLEL_MIN):
        return _loop(model, mod, prep, o, progress, compile_time, numba.get_num_threads())


def _loop(model, mod, prep: Prepared, o: NumbaOptions, progress, compile_time: float, threads: int) -> Result:
    end = float(model.end_time)
    tick = end / 100.0
    next_progress = tick
    fi = o.frame_interval
    frames = [(0.0, np.zeros_like(prep.nodes))] if fi else []
    states = [frame_state(prep, model)] if fi else []  # velocity, Prony state (user numbering)
    next_frame = fi if fi else math.inf
    chunks = []
    hist = np.zeros((4096, K.H_N))
    stop = "end_time"
    reported = 0.0
    ren = prep.ren
    # physics checks (cfm_core.simulation.checks), every ~1 % of the end time: the compiled
    # parallel scan reads the positions in the solver's numbering (no permuted copy) and names
    # nodes and elements in the user's (scan.py)
    from .scan import NumbaScan   # imports numba: only once a run has started

    monitor = Monitor(model, scan=functools.partial(NumbaScan, ren=ren))   # compiled in warm_up
    z = (lambda: float(prep.sc[K.S_Z])) if model.sphere is not None else (lambda: None)
    if model.sphere is not None and model.sphere.lateral:   # the whole reference point
        z = lambda: np.array([prep.sc[K.S_X], prep.sc[K.S_Y], prep.sc[K.S_Z]])   # noqa: E731
    start = time.perf_counter()
    while True:
        left = o.max_steps - int(prep.sc[K.S_STEPS])      # a full history chunk stops it: at max_steps exactly
        rows, code = advance(mod, prep, hist[:max(1, min(hist.shape[0], left))],
                             min(next_progress, next_frame, monitor.next))
        chunks.append(hist[:rows].copy())
        if code >= K.R_INVERTED:
            raise _error(code, prep, model)
        t = float(prep.sc[K.S_T])
        if monitor.due(t):
            monitor.check(t, prep.st[0], z())
        if fi and t >= next_frame:
            frames.append((t, ren.to_user_nodes(prep.st[0] - prep.nodes)))
            states.append(frame_state(prep, model))
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
        steps = int(prep.sc[K.S_STEPS])
        runaway = errors.pace(model, steps, t, o.max_steps)   # max_steps, or a pace that cannot reach the end
        if runaway is not None:
            raise runaway
    wall = time.perf_counter() - start
    monitor.final(t, prep.st[0], z())
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
                            info={"threads": threads, "compile_time": compile_time,
                                  "vector_width": numba_target.configure()})
