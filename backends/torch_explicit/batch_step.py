"""One step of the batched drop-test engine (:mod:`.batch`) on buffers allocated before the first step.

Everything a step carries to the next (per-run time, step, impactor, energy sums, stop and failure
flags, the element state, displacements and velocities) lives in a :class:`Carry` allocated once
and is updated in place (``copy_``); the step's history row and live-run mask are written into
(CHUNK, B, columns) and (CHUNK, B) device buffers at the row index ``pos``, itself a device
tensor incremented by the step. With ``sync_free`` the step so reads nothing back to the host,
branches on no tensor value, has no data-dependent shape, and every tensor that outlives it keeps
its address: the conditions for capturing it as a CUDA graph and replaying it (:class:`CudaGraph`).
Its temporaries are allocated per step (in the graph's own memory pool when captured). The
arithmetic is the earlier loop's, op for op: the histories are the same to the bit
(tests/backends/test_torch_batch_graph.py).
"""

from __future__ import annotations

import math
from types import SimpleNamespace

from .batch_checks import COLLAPSE, FALLBACK, INVERTED, NEWTON, NONFINITE, OK, STATE

WARM_STEPS = 3        # eager steps (on a side stream) before a CUDA graph is captured
CARRIED = ("t", "dtp", "Z", "V", "IE", "WINT", "WHG", "WC", "WEXT", "IMP", "DT0", "SEPT", "seen", "alive", "steps",
           "dtmin", "dtmax", "maxpen", "separated", "C", "Vv")


def carry(bt, chunk: int) -> SimpleNamespace:
    """The step's persistent tensors for batch ``bt`` (a :class:`.batch._Batch`); ``chunk`` rows of history.

    Per-run (B,) float64 unless said: t, dtp (s), Z, V (m, m/s), energy sums (J), DT0, SEPT (s),
    seen, alive, separated (bool), steps (int64), dtmin, dtmax (s), maxpen (m), code (int64), err
    (B, 7); C, Vv (3, B) for a general impactor; vold, dvc (3, B n); rows (chunk, B, columns)
    float64, masks (chunk, B) bool, pos (1,) int64.
    """
    import torch

    B, N, dev, m0 = bt.B, bt.N, bt.device, bt.models[0]
    f64 = dict(dtype=torch.float64, device=dev)
    z = lambda: torch.zeros(B, **f64)  # noqa: E731
    s = SimpleNamespace()
    s.t, s.dtp, s.Z, s.V = z(), z(), bt.Z0.clone(), bt.V0s.clone()
    s.IE, s.WINT, s.WHG, s.WC, s.WEXT, s.IMP, s.DT0, s.SEPT = (z() for _ in range(8))
    s.seen, s.alive, s.separated = (torch.zeros(B, dtype=torch.bool, device=dev),
                                    torch.ones(B, dtype=torch.bool, device=dev),
                                    torch.zeros(B, dtype=torch.bool, device=dev))
    s.steps = torch.zeros(B, dtype=torch.int64, device=dev)
    s.dtmin, s.dtmax, s.maxpen = torch.full((B,), math.inf, **f64), z(), z()
    s.code = torch.zeros(B, dtype=torch.int64, device=dev)
    s.err = torch.zeros((B, 7), **f64)       # element, t, value, m0, m1, m2, dt0
    u = bt.uv[0:3]
    s.vold, s.dvc = torch.zeros_like(u), torch.zeros_like(u)
    s.C = bt.C0.clone() if bt.general else torch.zeros((3, B), **f64)
    s.Vv = bt.Vv0.clone() if bt.general else torch.zeros((3, B), **f64)
    s.ez = torch.tensor([0.0, 0.0, 1.0], **f64).view(3, 1)
    s.ar = torch.arange(N, device=dev)
    s.bN = torch.arange(B, device=dev) * N
    s.rows = torch.zeros((chunk, B, 23 if bt.general else 15), **f64)
    s.masks = torch.zeros((chunk, B), dtype=torch.bool, device=dev)
    s.pos = torch.zeros(1, dtype=torch.int64, device=dev)
    # host constants of the step (Python numbers: no transfer inside the step)
    sp = m0.sphere
    s.sym, s.grav, s.mu = float(m0.symmetry_factor), abs(float(m0.gravity)), float(m0.friction)
    s.cx, s.cy, s.R = float(sp.center[0]), float(sp.center[1]), float(sp.radius)
    return s


def tensors(bt, s) -> dict:
    """Name -> tensor of everything the step reads across steps or writes (for the capture-safety checks)."""
    import torch

    out = {k: v for k, v in vars(s).items() if isinstance(v, torch.Tensor)}
    out.update({f"state.{k}": v for k, v in bt.state._asdict().items()})
    out["uv"] = bt.uv
    return out


def step(bt, s) -> None:
    """One step of every run of batch ``bt`` on carry ``s`` (in place); the earlier loop's body."""
    import torch

    from . import batch_contact, element, impactor_contact
    from .contact import plane_contact
    from .element import scatter

    o, B, N, n = bt.o, bt.B, bt.N, bt.n
    m0 = bt.models[0]
    F = lambda x: x.to(bt.dtype)  # noqa: E731  (a per-run float64 scalar where it meets the fields)
    z = lambda: torch.zeros(B, dtype=torch.float64, device=bt.device)  # noqa: E731
    sym, grav, mu, M, gen, sph = s.sym, s.grav, s.mu, bt.M, bt.general, m0.sphere
    u, v, vold, dvc = bt.uv[0:3], bt.uv[3:6], s.vold, s.dvc
    # the carried tensors, bound to locals: reassigned below (new tensors), copied back at the end
    t, dtp, Z, V, C, Vv = s.t, s.dtp, s.Z, s.V, s.C, s.Vv
    IE, WINT, WHG, WC, WEXT, IMP, DT0, SEPT = s.IE, s.WINT, s.WHG, s.WC, s.WEXT, s.IMP, s.DT0, s.SEPT
    seen, alive, steps, separated = s.seen, s.alive, s.steps, s.separated
    dtmin, dtmax, maxpen, code, err = s.dtmin, s.dtmax, s.maxpen, s.code, s.err
    flag = bt._flag
    # 1. elements at x^n
    kin, resp, overflow = bt._element_pass(dtp, alive)
    first_bad = torch.where(resp.failed.view(B, N), s.ar, N).amin(1)
    failed = alive & (first_bad < N)
    fb = first_bad.clamp(max=N - 1)
    ge = s.bN + fb
    Jb = kin.J.index_select(0, ge)
    kind = torch.where(element.inverted(Jb), INVERTED, NONFINITE)
    flag(code, err, failed, kind, fb, t, Jb, kin.m.index_select(1, ge), DT0)
    if overflow is not None:
        flag(code, err, alive & overflow, FALLBACK, fb * 0, t, t, kin.m[:, :B], DT0)
    alive = alive & ~failed
    IE = IE + resp.work_e.view(B, N).sum(1).double()
    # 2. stable step per run
    dmin, emin = resp.dte.view(B, N).min(1)
    dtc = o.safety * dmin.double()
    DT0 = torch.where((DT0 == 0.0) & torch.isfinite(dtc), dtc, DT0)
    dt = torch.clamp(dtc, max=bt.step_cap)  # dt_max and the output intervals (explicit.options.step_cap)
    coll = alive & (~((dt > 0.0) & torch.isfinite(dt)) | (dtc < o.collapse * DT0))
    flag(code, err, coll, COLLAPSE, emin, t, dtc, kin.m[:, :B], DT0)
    alive = alive & ~coll
    dt = torch.where(alive, dt, torch.where(dtp > 0.0, dtp, 1.0))
    dtn = 0.5 * (dtp + dt)
    # 3. central differences
    nodal = scatter(resp.fe, bt.idx, B * n)
    fint, fhg = nodal[0:3], nodal[3:6]
    vold.copy_(v)
    v.view(3, B, n).add_((fhg - fint).view(3, B, n) * (F(dtn)[:, None] / bt.mass.view(B, n))).mul_(
        bt.free.view(3, B, n))
    u.view(3, B, n).add_(v.view(3, B, n) * F(dt)[:, None])
    if gen:     # any shape, lateral motion (impactor_contact); z as the hemisphere's below
        Vo3, Co3 = Vv, C
        Vs3 = Vo3 - (dtn * grav) * s.ez
        Cs3 = Co3 + dt * Vs3
        dvc.zero_()
        dC, dV3, pen, checks, unconv = impactor_contact.contact(
            u, v, dvc, bt.sphere, sph.shape, s.R, float(sph.edge_radius), bt.fmask, F(Cs3), F(Vs3), F(M),
            mu, F(dt), alive, bt.tol, bt.block)
        dC, dV3, pen = dC.double(), dV3.double(), pen.double()
        Cs3, Vs3 = Cs3 + dC, Vs3 + dV3
        Vo, Zn, Vs, Zs, dV = Vo3[2], Co3[2], Vs3[2], Cs3[2], dV3[2]
    else:
        Vo, Zn = V, Z
        Vs = Vo - dtn * grav
        Zs = Zn + dt * Vs
        # 4. contact
        dvc.zero_()
        dZ, dV, pen, checks, unconv = batch_contact.sphere_contact(
            u, v, dvc, bt.sphere, s.cx, s.cy, F(Zs), F(Vs), s.R, F(M), mu, F(dt), alive, bt.tol, bt.block)
        dZ, dV, pen = dZ.double(), dV.double(), pen.double()
    bt.syncs += checks
    flag(code, err, alive & unconv, NEWTON, emin * 0, t, dt, kin.m[:, :B], DT0)
    if bt.plane is not None:
        plane_contact(u, v, dvc, bt.plane, float(m0.plane.z), mu, F(dt).repeat_interleave(bt.p_count))
    if not gen:
        Zs = Zs + dZ
        Vs = Vs + dV
    force = M * dV / dtn
    Vf = Vo + dtp / (dtp + dt) * (Vs - Vo)
    # 5. energies and the record of step n
    en = bt._energies(v, vold, nodal, dvc, F(dtn), gen).double()
    ke, ai, bi, ah, bh, ac, bc, pz = en[:8].unbind(0)
    fg = -0.5 * dtn * M * grav
    if gen:
        ke = ke + 0.5 * M * (Vo3 * Vs3).sum(0)
        ac = ac + 0.5 * M * (dV3 * Vo3).sum(0)
        bc = bc + 0.5 * M * (dV3 * Vs3).sum(0)
    else:
        ke = ke + 0.5 * M * Vo * Vs
        fs = 0.5 * M * dV
        ac = ac + fs * Vo
        bc = bc + fs * Vs
    ax, bx = fg * Vo, fg * Vs
    pz = pz + M * Vs
    row = [t, force * sym, (IMP + 0.5 * dtp * force) * sym, Zn, Vf, z(), ke * sym, IE * sym,
           -(WHG + ah) * sym, -(WC + ac) * sym, (WEXT + ax) * sym, (WINT + ai) * sym, dt, pen, pz * sym]
    if gen:
        f3 = M * dV3 / dtn
        Vf3 = Vo3 + dtp / (dtp + dt) * (Vs3 - Vo3)
        pxy = en[8:10] + M * Vs3[0:2]
        row += [f3[0] * sym, f3[1] * sym, Co3[0], Co3[1], Vf3[0], Vf3[1], pxy[0] * sym, pxy[1] * sym]
        C, Vv = torch.where(alive, Cs3, C), torch.where(alive, Vs3, Vv)
    s.rows.index_copy_(0, s.pos, torch.stack(row, dim=1)[None])
    s.masks.index_copy_(0, s.pos, alive[None])
    WINT, WHG, WC, WEXT = WINT + ai + bi, WHG + ah + bh, WC + ac + bc, WEXT + ax + bx
    IMP = IMP + force * dtn
    nonfin = alive & ~torch.isfinite(ke + pz + Zs)
    t_n = t
    Z, V = torch.where(alive, Zs, Z), torch.where(alive, Vs, V)
    t = torch.where(alive, t + dt, t)
    dtp = torch.where(alive, dt, dtp)
    steps = steps + alive.to(torch.int64)
    dtmin = torch.where(alive, torch.minimum(dtmin, dt), dtmin)
    dtmax = torch.where(alive, torch.maximum(dtmax, dt), dtmax)
    maxpen = torch.where(alive, torch.maximum(maxpen, pen), maxpen)
    flag(code, err, nonfin, STATE, emin * 0, t_n, t_n, kin.m[:, :B], DT0)   # as the single run: t^n
    alive = alive & ~nonfin
    done = t_n >= bt.end
    if m0.stop_after_separation:
        pos = force > 0.0
        up = seen & (Vf > 0.0) & ~pos
        SEPT = torch.where(pos, 0.0, torch.where(up, SEPT + dt, 0.0))
        seen = seen | pos
        sep = alive & ~done & up & (SEPT >= o.separation_time)
        separated = separated | sep
        done = done | sep
    alive = alive & ~done
    # write back: every value above is computed, so no copy below overwrites a tensor still to be read
    for a, b in zip(bt.state, resp.state):
        a.copy_(b)
    new = dict(t=t, dtp=dtp, Z=Z, V=V, IE=IE, WINT=WINT, WHG=WHG, WC=WC, WEXT=WEXT, IMP=IMP, DT0=DT0, SEPT=SEPT,
               seen=seen, alive=alive, steps=steps, dtmin=dtmin, dtmax=dtmax, maxpen=maxpen, separated=separated,
               C=C, Vv=Vv)
    for name in CARRIED:
        getattr(s, name).copy_(new[name])
    s.pos.add_(1)


class CudaGraph:
    """Runs a step function: :data:`WARM_STEPS` eager calls on a side stream (lazy initialisation,
    the cached constants, the allocator's state), then one call captured as a ``torch.cuda.CUDAGraph``
    (recorded, not run) and replayed, and every later call a replay. ``used``: a graph was captured.
    """

    def __init__(self, device):
        import torch

        self.device = device
        self.side = torch.cuda.Stream(device)
        self.graph = None
        self.calls = 0

    @property
    def used(self) -> bool:
        return self.graph is not None

    def __call__(self, fn) -> None:
        import torch

        main = torch.cuda.current_stream(self.device)
        if self.graph is None and self.calls >= WARM_STEPS:
            main.wait_stream(self.side)
            self.graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(self.graph):
                fn()
        if self.graph is not None:
            self.graph.replay()
        else:
            self.side.wait_stream(main)
            with torch.cuda.stream(self.side):
                fn()
            main.wait_stream(self.side)
        self.calls += 1


__all__ = ["CARRIED", "OK", "WARM_STEPS", "CudaGraph", "carry", "step", "tensors"]
