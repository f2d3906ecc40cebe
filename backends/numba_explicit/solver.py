"""Run a :class:`cfm_core.scene.Model` with the numba kernels: set-up, time loop, Result.

Python prepares the arrays (geometry, masses, constraints), then calls the compiled time loop
``advance`` in chunks (about 1 % of the end time each, or up to the next frame), reports
progress between chunks and turns failure codes into :class:`cfm_core.errors.NumericalError`.
Histories are recorded at every step. Forces, impulses and energies in the Result are for the
full model (times ``model.symmetry_factor``); SI units throughout.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np

from cfm_core.errors import InputError, NumericalError
from cfm_core.material.diagnose import describe_nonfinite
from cfm_core.simulation.checks import Monitor
from cfm_core.simulation.result import Result

from . import codegen, geometry
from .kernels import layout as K

DEFAULTS = {
    "hourglass": 0.1,            # Q_hg (-), viscous hourglass coefficient
    "hourglass_wave": "shear",   # "shear": isochoric wave speed; "longitudinal": full one
    "safety": 0.9,               # dt = safety * min_e L_e / c_e
    "dt_max": math.inf,          # upper bound of the step (s)
    "collapse": 1e-4,            # time-step collapse below this fraction of the first step
    "separation_time": 2e-4,     # stop this long (s) after the impactor left the specimen
    "initial_velocity": None,    # (n, 3) nodal velocities at t = 0 (m/s)
    "frame_interval": None,      # store (t, displacement) every this many seconds
    "threads": None,             # numba threads (None: numba's default, 1 below PARALLEL_MIN elements)
    "max_steps": 50_000_000,     # guard against runaway runs
    "warm_up": True,             # compile on a 1-element model first, to time compilation apart
}


PARALLEL_MIN = 1000  # below this many elements, thread start-up costs more than it saves


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


def check_options(options: dict, defaults: dict = DEFAULTS, backend: str = "numba") -> dict:
    """Options merged over ``defaults``; unknown names and bad values of the explicit-solver
    options shared by the numba and torch backends raise InputError naming ``backend``."""
    unknown = set(options) - set(defaults)
    if unknown:
        raise InputError(f"{backend} backend: unknown option(s) {', '.join(sorted(unknown))}; "
                         f"allowed: {', '.join(defaults)}.")
    o = {**defaults, **options}
    if not (o["hourglass"] >= 0.0):
        raise InputError(f"{backend} backend: hourglass = {o['hourglass']!r} (-) must be >= 0 (typical 0.05-0.15).")
    if o["hourglass_wave"] not in ("shear", "longitudinal"):
        raise InputError(f"{backend} backend: hourglass_wave = {o['hourglass_wave']!r}; use 'shear' or 'longitudinal'.")
    if not (0.0 < o["safety"] <= 1.0):
        raise InputError(f"{backend} backend: safety = {o['safety']!r} (-) must be in (0, 1].")
    if not (o["dt_max"] > 0.0):
        raise InputError(f"{backend} backend: dt_max = {o['dt_max']!r} s must be > 0.")
    if not (0.0 <= o["collapse"] < 1.0):
        raise InputError(f"{backend} backend: collapse = {o['collapse']!r} (-) must be in [0, 1).")
    if o["frame_interval"] is not None and not (o["frame_interval"] > 0.0):
        raise InputError(f"{backend} backend: frame_interval = {o['frame_interval']!r} s must be > 0 or None.")
    return o


def prepare(model, o: dict) -> Prepared:
    """Build all arrays of a run from the model and checked options."""
    nodes = np.ascontiguousarray(model.nodes, dtype=np.float64)
    hexes = np.ascontiguousarray(model.hexes, dtype=np.int64)
    n, ne = nodes.shape[0], hexes.shape[0]
    if nodes.ndim != 2 or nodes.shape[1] != 3 or hexes.ndim != 2 or hexes.shape[1] != 8:
        raise InputError(f"model '{model.name}': nodes must be (n, 3) and hexes (e, 8); got {nodes.shape}, {hexes.shape}.")
    if ne == 0 or hexes.min() < 0 or hexes.max() >= n:
        raise InputError(f"model '{model.name}': hexes must index nodes 0..{n - 1} (and there must be at least one).")
    rho = float(model.density)
    if not (rho > 0.0):
        raise InputError(f"model '{model.name}': density = {rho!r} kg/m^3 must be > 0.")
    V0, B, G, L = geometry.hex_geometry(nodes, hexes)
    mass = geometry.lumped_mass(hexes, V0, rho, n)
    ptr, inc = geometry.incidence(hexes, n)
    free = np.ones((n, 3))
    free[mass <= 0.0] = 0.0
    mass = np.where(mass > 0.0, mass, 1.0)
    fixed = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2)
    free[fixed[:, 0], fixed[:, 1]] = 0.0
    pmask = np.zeros((n, 3))
    pr = model.prescribed
    if pr is not None:
        pnodes = np.ascontiguousarray(pr.nodes, dtype=np.int64)
        if pr.dof not in (0, 1, 2):
            raise InputError(f"model '{model.name}': prescribed dof = {pr.dof!r}; use 0, 1 or 2.")
        free[pnodes, pr.dof] = 0.0
        pmask[pnodes, pr.dof] = 1.0
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
    par[K.P_HG] = o["hourglass"]
    par[K.P_SAFETY] = o["safety"]
    par[K.P_DTMAX] = o["dt_max"]
    par[K.P_COLLAPSE] = o["collapse"]
    par[K.P_MU] = float(model.friction)
    par[K.P_GRAV] = abs(float(model.gravity))
    par[K.P_SYM] = float(model.symmetry_factor)
    par[K.P_TEND] = float(model.end_time)
    par[K.P_SEPTIME] = o["separation_time"]
    par[K.P_GINF] = 1.0 - math.fsum(gam.tolist())
    ipar[K.I_HGWAVE] = 0 if o["hourglass_wave"] == "shear" else 1
    ipar[K.I_STOPSEP] = int(bool(model.stop_after_separation))
    sph = model.sphere
    if sph is not None:
        if not (sph.radius > 0.0 and sph.mass > 0.0):
            raise InputError(f"model '{model.name}': sphere radius {sph.radius!r} m and mass {sph.mass!r} kg must be > 0.")
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

    v = np.zeros((n, 3))
    if o["initial_velocity"] is not None:
        v0 = np.asarray(o["initial_velocity"], dtype=np.float64)
        if v0.shape != (n, 3):
            raise InputError(f"numba backend: initial_velocity must have shape ({n}, 3), got {v0.shape}.")
        v = v0 * free
    snodes = np.ascontiguousarray(model.sphere_nodes if sph is not None else [], dtype=np.int64)
    plnodes = np.ascontiguousarray(model.plane_nodes if model.plane is not None else [], dtype=np.int64)
    geo = (hexes, B, G, V0, L, rho * V0 ** (2.0 / 3.0) / 4.0, mass, free, pmask, ptr, inc)
    fe = np.zeros((ne, 8, 6))
    st = (nodes.copy(), np.ascontiguousarray(v), np.zeros((n, 3)), np.zeros((ne, k, 6)),
          np.zeros((ne, 6)), np.zeros((ne, 6)), np.zeros((ne, 6)), fe, fe.reshape(ne * 8, 6),
          np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
          np.zeros(ne), np.zeros(ne, dtype=np.int64), np.zeros((ne, 4)))
    cnt = (snodes, plnodes, np.zeros((max(len(snodes), 1), 9)))
    return Prepared(geo, (p, gam, tau), par, ipar, sc, st, cnt, presc, nodes)


def _error(code: int, prep: Prepared, model) -> NumericalError:
    sc = prep.sc
    t, e = float(sc[K.S_T]), int(sc[K.S_ERRE])
    name = model.material.name
    if code == K.R_INVERTED:
        return NumericalError(
            f"element {e} inverted at t = {t:.6g} s (J = det F = {sc[K.S_ERRV]:.4g} <= 0) in model "
            f"'{model.name}': the mesh cannot follow this deformation; refine the mesh, lower the load "
            f"or raise the hourglass coefficient.", time=t, element=e, quantity="J")
    if code == K.R_NONFINITE:
        m = (sc[K.S_ERRM0], sc[K.S_ERRM1], sc[K.S_ERRM2])
        return NumericalError(
            f"non-finite stress in element {e} at t = {t:.6g} s (J = {sc[K.S_ERRV]:.4g}): "
            f"{describe_nonfinite(model.material, m)}.", time=t, element=e,
            quantity=f"non-finite energy derivative of material '{name}'")
    if code == K.R_COLLAPSE and not math.isfinite(sc[K.S_ERRV]):
        return NumericalError(
            f"no finite stable time step at t = {t:.6g} s in model '{model.name}': every element has zero "
            f"stiffness (material '{name}'); give the option dt_max (s).", time=t, quantity="time step")
    if code == K.R_COLLAPSE:
        return NumericalError(
            f"time-step collapse at t = {t:.6g} s: the stable step of element {e} fell to "
            f"{sc[K.S_ERRV]:.3g} s, below {prep.par[K.P_COLLAPSE]:g} x the first step "
            f"{sc[K.S_DT0]:.3g} s (element crushed or material stiffening without bound).",
            time=t, element=e, quantity="time step")
    return NumericalError(f"non-finite kinematic state at t = {t:.6g} s in model '{model.name}'.",
                          time=t, quantity="state")


def advance(mod, prep: Prepared, hist: np.ndarray, t_stop: float):
    """One call of the compiled loop: (rows, code)."""
    return mod.advance(prep.geo, prep.mat, prep.par, prep.ipar, prep.sc, prep.st, prep.cnt,
                       prep.presc, hist, t_stop)


_WARM: set = set()


def warm_up(mod, material) -> float:
    """Compile (or load from the cache) every kernel on a 1-element model; seconds spent."""
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
    prep = prepare(model, check_options({}))
    advance(mod, prep, np.zeros((4, K.H_N)), 1e-9)
    out = np.zeros((1, 6))
    gam, tau = prep.mat[1], prep.mat[2]
    mod.point_history(np.zeros(1), np.eye(3)[None].copy(), prep.mat[0], gam, tau, 1.0, out)
    _WARM.add(id(mod))
    return time.perf_counter() - start


def run_model(model, progress=None, **options) -> Result:
    """Run ``model``; see :class:`cfm_backends.numba_explicit.NumbaExplicitBackend`."""
    o = check_options(options)
    # Worker threads that sleep at the end of a parallel loop instead of spinning: on a 2-core
    # machine where another process held one core, spinning OpenMP threads made 2 threads about
    # 10x slower than one, sleeping ones about as fast as one. Set before numba starts its threads
    # (no effect afterwards); a value the user chose is kept.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    import numba

    old_threads = numba.get_num_threads()
    threads = o["threads"]
    if threads is None and model.n_elements < PARALLEL_MIN:
        threads = 1
    if threads is not None:
        numba.set_num_threads(int(threads))
    try:
        t0 = time.perf_counter()
        mod = codegen.load(model.material)
        if o["warm_up"]:
            warm_up(mod, model.material)
        compile_time = time.perf_counter() - t0
        prep = prepare(model, o)
        return _loop(model, mod, prep, o, progress, compile_time, numba.get_num_threads())
    finally:
        numba.set_num_threads(old_threads)


def _loop(model, mod, prep: Prepared, o: dict, progress, compile_time: float, threads: int) -> Result:
    end = float(model.end_time)
    if not (end > 0.0):
        raise InputError(f"model '{model.name}': end_time = {end!r} s must be > 0.")
    tick = end / 100.0
    next_progress = tick
    fi = o["frame_interval"]
    frames = [(0.0, np.zeros_like(prep.nodes))] if fi else []
    next_frame = fi if fi else math.inf
    chunks = []
    hist = np.zeros((4096, K.H_N))
    stop = "end_time"
    reported = 0.0
    monitor = Monitor(model)  # physics checks (cfm_core.simulation.checks), every ~1 % of the end time
    z = (lambda: float(prep.sc[K.S_Z])) if model.sphere is not None else (lambda: None)
    start = time.perf_counter()
    while True:
        rows, code = advance(mod, prep, hist, min(next_progress, next_frame, monitor.next))
        chunks.append(hist[:rows].copy())
        if code >= K.R_INVERTED:
            raise _error(code, prep, model)
        t = float(prep.sc[K.S_T])
        if monitor.due(t):
            monitor.check(t, prep.st[0], z())
        if fi and t >= next_frame:
            frames.append((t, prep.st[0] - prep.nodes))
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
        if prep.sc[K.S_STEPS] >= o["max_steps"]:
            raise NumericalError(f"model '{model.name}': {int(prep.sc[K.S_STEPS])} steps reached at "
                                 f"t = {t:.6g} s before the end time {end:g} s (option max_steps).",
                                 time=t, quantity="steps")
    wall = time.perf_counter() - start
    monitor.final(t, prep.st[0], z())
    h = np.concatenate(chunks)
    res = _result(model, prep, h, wall, compile_time, threads, frames, stop, o)
    res.info["checks"] = monitor.report()
    return res


def _result(model, prep, h, wall, compile_time, threads, frames, stop, o) -> Result:
    sc = prep.sc
    steps = int(sc[K.S_STEPS])
    ne = model.n_elements
    sphere = model.sphere is not None
    mass_full = model.mass_full if model.mass_full else (model.sphere.mass * model.symmetry_factor if sphere else None)
    energies = {"kinetic": h[:, K.H_KE], "internal": h[:, K.H_IE], "hourglass": h[:, K.H_HG],
                "contact": h[:, K.H_C], "external": h[:, K.H_EXT]}
    dt0 = float(sc[K.S_DT0])
    duration = float(h[-1, K.H_T]) if len(h) else 0.0
    pz = h[:, K.H_PZ]
    res = Result(
        t=h[:, K.H_T], backend="numba", steps=steps, wall_time=wall,
        contact_force=h[:, K.H_F] if sphere else None,
        impulse=h[:, K.H_IMP] if sphere else None,
        acceleration=h[:, K.H_F] / mass_full if sphere else None,
        impactor_z=h[:, K.H_Z] if sphere else None,
        impactor_v=h[:, K.H_V] if sphere else None,
        reaction_force=h[:, K.H_R] if model.prescribed is not None else None,
        energies=energies, dt_min=float(sc[K.S_DTMIN]), dt_max=float(sc[K.S_DTMAX]), frames=frames,
        info={
            "n_elements": ne, "n_nodes": model.n_nodes, "material": model.material.name,
            "hourglass": o["hourglass"], "hourglass_wave": o["hourglass_wave"], "safety": o["safety"],
            "threads": threads, "compile_time": compile_time, "stop_reason": stop,
            "dt_first": dt0, "steps_at_first_dt": int(math.ceil(duration / dt0)) if dt0 > 0 else None,
            "ns_per_element_cycle": wall / max(steps * ne, 1) * 1e9,
            "max_sphere_penetration": float(sc[K.S_MAXPEN]),
            "internal_force_work": float(h[-1, K.H_WINT]) if len(h) else 0.0,
            "momentum_z_drift": float(np.max(np.abs(pz - pz[0]))) if len(h) else 0.0,
            "prony_terms": int(prep.mat[1].shape[0]),
        },
    )
    res.info["energy_error"] = res.energy_error()
    res.info["hourglass_ratio"] = res.hourglass_ratio()
    return res
