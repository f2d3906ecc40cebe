"""Run a :class:`cfm_core.scene.Model` with torch: the explicit time loop (Python), vectorised steps.

One step is the numba backend's (kernels/step.py): element pass at x^n with the Prony factors of
dt_{n-1/2}; dt_{n+1/2} = min(safety min_e L_e / c_e, dt_max); central differences on the free
dofs; prescribed motion; kinematic contact with sphere and plane; energies; record of step n.
The element work is batched tensor ops on the run's device (``element``), the nodal sums an
``index_add_``; the scalar bookkeeping (time, impactor, energy sums, stop rule) is host
arithmetic in float64 with numba's formulas.

On CUDA a drop test (sphere, no prescribed motion, no frames) runs through the batched engine
with one run (``batch``), whose step has no host synchronisation and runs as a captured CUDA graph
(option ``cuda_graph``; True for any other model is an InputError). Otherwise, host
synchronisations per step (``info['host_syncs_per_step']``): one after the element pass
(min step, failures, work: the step size is needed on the host), one to select the nodes inside
the sphere, while some are: one to start the contact Newton iteration and one per
``newton_block`` iterations, and one at the end (contact results and energies: the history row).
About 3 + iterations per step on the CPU (block 1), 4-5 on CUDA (block 4). A step whose
eigen-decomposition needs the Jacobi fallback (round-off-isotropic C in the first steps) costs a
second element response. Forces, impulses and energies in the Result are of the full model.

Parts (``model.multi_material``): the renumbering groups the elements by part (each part one
contiguous range) and the element pass takes each part's material derivatives, Prony series and
density (:mod:`.parts`); a one-material model runs the pass unchanged. Impactors other than the
paper's hemisphere moving along z (another shape, or free in x or y) use :mod:`.impactor_contact`
with the reference point and velocity as 3-vectors over the free axes, and record the 23 history
columns (in-plane force, position, velocity and momenta); its Newton iteration checks convergence
every ``newton_block`` iterations like the hemisphere's; the frame state of a model with parts
holds the Prony state per part (:func:`.parts.frame_state_parts`).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from cfm_backends.explicit import errors, history, renumber
from cfm_backends.explicit.checks import check_model
from cfm_backends.explicit.history import BASE_COLUMNS, COLUMNS
from cfm_backends.explicit.options import step_cap
from cfm_backends.threads import num_threads
from cfm_core.errors import InputError, NumericalError
from cfm_core.simulation.checks import Monitor
from cfm_core.simulation.result import Result

from . import arrays as arr
from . import material as mat
from . import parts
from .frames import frame_state
from .options import PARALLEL_MIN, TorchOptions, resolve_device, resolve_dtype


def run_model(model, progress=None, **options) -> Result:
    """Run ``model``; see :class:`cfm_backends.torch_explicit.TorchExplicitBackend`."""
    import torch

    o = TorchOptions.from_mapping(options)
    device, dtype = resolve_device(o.device), resolve_dtype(o.dtype)
    if device.type == "cuda" and model.sphere is not None and model.prescribed is None and o.frame_interval is None:
        # a drop test on CUDA: the batched engine with one run, whose step has no host synchronisation
        from .batch import run_parsed

        return run_parsed([model], o, progress, True, True, device, dtype)[0]
    if o.cuda_graph:
        raise InputError(f"torch backend: option cuda_graph = True is not allowed for model '{model.name}': only a "
                         f"drop test (a rigid sphere, no prescribed motion, no frame_interval) on CUDA runs as a "
                         f"CUDA graph; use cuda_graph=None or False.")
    # the run uses a renumbered copy of the model for locality (cfm_backends.explicit.renumber);
    # frames, checks and errors are in the user's numbering
    ren = renumber.plan(*check_model(model), o.renumber, groups=model.element_part() if model.multi_material else None)
    if o.initial_velocity is not None and np.shape(o.initial_velocity) == (model.n_nodes, 3):
        o = replace(o, initial_velocity=ren.to_internal_nodes(np.asarray(o.initial_velocity, dtype=np.float64)))
    with num_threads(torch, o.threads, serial=device.type == "cpu" and model.n_elements < PARALLEL_MIN):
        with torch.inference_mode():
            return _Run(ren.model(model), o, device, dtype, progress, model, ren).loop()


class _Run:
    def __init__(self, model, o, device, dtype, progress, user, ren):
        import torch

        from . import element

        self.model, self.o, self.device, self.dtype, self.progress = model, o, device, dtype, progress
        self.user, self.ren = user, ren       # the user's model, the renumbering (model is ren.model(user))
        t0 = time.perf_counter()
        self.a, self.uv, k = arr.build(model, o, device, dtype)
        self.lay = None
        self.rho = float(model.density)
        if model.multi_material:    # parts: per-part derivatives, Prony series per element, density per element
            self.lay = lay = parts.layout(model)
            self.ghd, self.p = parts.composite(lay.ghd, lay.ranges), lay.params
            T = lambda x: torch.as_tensor(np.asarray(x), device=device)  # noqa: E731
            self.part_index = T(lay.part)
            self.ginf = T(lay.ginf).to(dtype).index_select(0, self.part_index)
            self.rho = T(lay.density).to(dtype)
        else:
            self.ghd = mat.grad_hess_diag(model.material)
            self.p = mat.parameters(model.material)
            self.gam, self.tau, self.ginf = mat.prony(model.material)
        self.general = model.sphere is not None and general_impactor(model.sphere)
        if self.general:
            from .batch_contact import BatchSphere

            sn = self.a.sphere
            s = sn.nodes.shape[0]
            self.bsphere = BatchSphere(sn.nodes, sn.X.view(3, 1, s), sn.mass.view(1, s), sn.free.view(3, 1, s))
            self.fmask = torch.tensor([float(m) for m in model.sphere.moves], dtype=dtype, device=device).view(3, 1)
        self.state = arr.initial_state(k, self.a.ne, dtype, device)
        self.flat = element.flat_index(self.a.idx, self.a.n)
        self.vold = torch.zeros((3, self.a.n), dtype=dtype, device=device)
        self.dvc = torch.zeros_like(self.vold)
        self.stages = element.Stages.make(o.compile)
        eps = torch.finfo(dtype).eps / torch.finfo(torch.float64).eps
        self.tol = 1e-16 * eps
        self.block = o.newton_block or (1 if device.type == "cpu" else 4)
        self.syncs = 0
        if o.warm_up:
            self._element_pass(0.0)        # pure: its result is dropped (compiles, warms caches)
        self.compile_time = time.perf_counter() - t0

    # ---- one element pass (pure), with the Jacobi fallback when flagged ----
    def _factors(self, dtp: float):
        import torch

        if self.lay is not None:
            return parts.factors(dtp, self.lay, self.part_index, self.dtype, self.device)
        decay, gain = mat.prony_factors(dtp, self.gam, self.tau)
        return torch.tensor([decay, gain], dtype=self.dtype).reshape(2, len(decay)).to(self.device, non_blocking=True)

    def _element_pass(self, dtp: float):
        """(kinematics, response, host summary) of all elements at the current state (one sync)."""
        from . import element
        from .eigen import patch_fallback

        a, o, st = self.a, self.o, self.stages
        factors = self._factors(dtp)
        kin, D = st.front(element.gather(self.uv, self.flat, a.ne), a.B, a.G, self.ghd, self.p)
        args = (self.state, factors, self.ginf, a.BV, a.G, a.L, a.V0, a.hgc, self.rho,
                0 if o.hourglass_wave == "shear" else 1)
        resp = element.response(kin, D, *args, stages=st)
        summary = resp.summary.tolist()
        self.syncs += 1
        if summary[4] > 0:   # some C need the Jacobi fallback: patch them, recompute the response
            m, Q = patch_fallback(kin.C, kin.m, kin.Q, kin.fallback)
            kin = kin._replace(m=m, Q=Q, fallback=kin.fallback & False)
            resp = element.response(kin, element.derivatives(self.ghd, self.p, kin.m), *args, stages=st)
            summary = resp.summary.tolist()
            self.syncs += 2
        return kin, resp, summary

    # ---- the time loop ----
    def loop(self) -> Result:
        import torch

        from .contact import plane_contact, sphere_contact
        from .element import scatter

        model, o, a = self.model, self.o, self.a
        end = float(model.end_time)
        sym = float(model.symmetry_factor)
        sph, pl, pr = model.sphere, model.plane, model.prescribed
        M = float(sph.mass) if sph is not None else 0.0
        grav = abs(float(model.gravity))
        mu = float(model.friction)
        u, v = self.uv[0:3], self.uv[3:6]
        ptimes = np.asarray(pr.times, dtype=np.float64) if pr is not None else None
        pvals = np.asarray(pr.values, dtype=np.float64) if pr is not None else None
        t = dtp = 0.0
        Z, V = (float(sph.center[2]), float(sph.velocity)) if sph is not None else (0.0, 0.0)
        IE = WINT = WHG = WC = WEXT = IMP = DT0 = SEPT = 0.0
        seen = False
        steps = 0
        dtmin, dtmax, maxpen = math.inf, 0.0, 0.0
        rows = []
        tick = end / 100.0
        next_progress = tick
        fi = o.frame_interval
        frames = [(0.0, np.zeros((a.n, 3)))] if fi else []
        to_user = self.ren.to_user_nodes
        states = [self._frame_state(v, 0.0)] if fi else []  # velocity, Prony state
        next_frame = fi if fi else math.inf
        reported = 0.0
        stop = "end_time"
        zero = torch.zeros((), dtype=self.dtype, device=self.device)
        self.syncs = 0
        # physics checks (cfm_core.simulation.checks), every ~1 % of the end time, in the user's numbering
        monitor = Monitor(self.user)
        cap = step_cap(o, self.user)  # dt_max, and the output interval: histories at least that often
        nodes0 = np.asarray(self.user.nodes, dtype=np.float64)
        positions = lambda: nodes0 + to_user(u.T.to("cpu", torch.float64).numpy())  # noqa: E731
        gen = self.general
        if gen:     # any shape, lateral motion: reference point and velocity as 3-vectors (free axes)
            from .impactor_contact import contact as general_contact

            C3 = [float(c) for c in sph.center]
            V3 = [float(x) * float(f) for x, f in zip(sph.velocity_vector, sph.moves)]
            Z, V = C3[2], V3[2]
            T1 = lambda x: torch.tensor(x, dtype=self.dtype).to(self.device, non_blocking=True)  # noqa: E731
            Mt, alive1 = T1([M]), torch.ones(1, dtype=torch.bool, device=self.device)
            shape, R, rr = sph.shape, float(sph.radius), float(sph.edge_radius)
        start = time.perf_counter()
        while True:
            # 1. elements at x^n (Prony factors of the previous step)
            kin, resp, (dmin, emin, nfailed, work, _) = self._element_pass(dtp)
            if nfailed > 0:
                raise self._element_error(resp, kin, t, DT0)
            IE += work
            # 2. stable step
            dtc = o.safety * dmin
            if DT0 == 0.0 and math.isfinite(dtc):
                DT0 = dtc
            dt = min(dtc, cap)
            if not (dt > 0.0 and math.isfinite(dt)) or dtc < o.collapse * DT0:
                raise self._collapse_error(t, int(emin), dtc, DT0)
            dtn = 0.5 * (dtp + dt)
            # 3. central differences
            nodal = scatter(resp.fe, a.idx, a.n)
            fint, fhg = nodal[0:3], nodal[3:6]
            self.vold.copy_(v)
            v.add_((fhg - fint) * (dtn / a.mass)).mul_(a.free)
            u.add_(v, alpha=dt)
            reaction = zero
            if pr is not None:
                d = int(pr.dof)
                target = arr.interp(t + dt, ptimes, pvals)
                old = u[d].index_select(0, a.pnodes)
                v[d].index_copy_(0, a.pnodes, (target - old) / dt)
                u[d].index_fill_(0, a.pnodes, target)
                reaction = (fint[d] - fhg[d]).index_select(0, a.pnodes).sum()
            Zn, Vo = Z, V
            Vs = Vo - dtn * grav
            Zs = Zn + dt * Vs
            # 4. contact
            self.dvc.zero_()
            dZ = dV = pen = zero
            if gen:
                Vs3 = [V3[0], V3[1], V3[2] - dtn * grav]
                Cs3 = [C3[i] + dt * Vs3[i] for i in range(3)]
                dC3, dV3, pen, checks, unconv = general_contact(
                    u, v, self.dvc, self.bsphere, shape, R, rr, self.fmask, T1(Cs3).view(3, 1), T1(Vs3).view(3, 1),
                    Mt, mu, T1([dt]), alive1, self.tol, self.block)
                self.syncs += checks
                dZ = torch.cat([dC3.view(3), dV3.view(3), unconv.to(self.dtype)])
                pen = pen[0]
            elif sph is not None:
                out, checks = sphere_contact(u, v, self.dvc, a.sphere, float(sph.center[0]), float(sph.center[1]),
                                             Zs, Vs, float(sph.radius), M, mu, dt, self.block, self.tol)
                self.syncs += checks
                if out is not None:
                    dZ, dV, pen = out
            if pl is not None:
                plane_contact(u, v, self.dvc, a.plane, float(pl.z), mu, dt)
            # 5. energies and the record of step n (one transfer)
            en = _energies(a.mass, v, self.vold, nodal, self.dvc, a.pmask, dtn, lateral=gen)
            if gen:
                rec = torch.cat([en, dZ.to(en.dtype), torch.stack([pen, reaction]).to(en.dtype)]).tolist()
                ke, ai, bi, ah, bh, ac, bc, ax, bx, pz, px, py = rec[:12]
                dC_, dV_3, unc, (pen_, reac) = rec[12:15], rec[15:18], rec[18], rec[19:21]
                if unc:
                    raise NumericalError(f"contact Newton iteration of the {shape} impactor did not converge at "
                                         f"t = {t:.6g} s", time=t, quantity="contact")
            else:
                rec = torch.cat([en, torch.stack([dZ, dV, pen, reaction]).to(en.dtype)]).tolist()
                ke, ai, bi, ah, bh, ac, bc, ax, bx, pz, dZ_, dV_, pen_, reac = rec
            self.syncs += 1
            force = 0.0
            Vf = Vo
            if gen:
                Co3 = C3
                C3 = [Cs3[i] + dC_[i] for i in range(3)]
                Vn3 = [Vs3[i] + dV_3[i] for i in range(3)]
                f3 = [M * x / dtn for x in dV_3]
                force, Zs, Vs = f3[2], C3[2], Vn3[2]
                Vf3 = [V3[i] + dtp / (dtp + dt) * (Vn3[i] - V3[i]) for i in range(3)]
                Vf = Vf3[2]
                ke += 0.5 * M * sum(V3[i] * Vn3[i] for i in range(3))
                ac += 0.5 * M * sum(dV_3[i] * V3[i] for i in range(3))
                bc += 0.5 * M * sum(dV_3[i] * Vn3[i] for i in range(3))
                fg = -0.5 * dtn * M * grav
                ax += fg * V3[2]
                bx += fg * Vn3[2]
                pz, px, py = pz + M * Vn3[2], px + M * Vn3[0], py + M * Vn3[1]
                V3 = Vn3
                lateral = (f3[0] * sym, f3[1] * sym, Co3[0], Co3[1], Vf3[0], Vf3[1], px * sym, py * sym)
            elif sph is not None:
                Zs += dZ_
                Vs += dV_
                force = M * dV_ / dtn
                Vf = Vo + dtp / (dtp + dt) * (Vs - Vo)
                ke += 0.5 * M * Vo * Vs
                fs = 0.5 * M * dV_
                ac += fs * Vo
                bc += fs * Vs
                fg = -0.5 * dtn * M * grav
                ax += fg * Vo
                bx += fg * Vs
                pz += M * Vs
            row = (t, force * sym, (IMP + 0.5 * dtp * force) * sym, Zn, Vf, reac * sym, ke * sym, IE * sym,
                   -(WHG + ah) * sym, -(WC + ac) * sym, (WEXT + ax) * sym, (WINT + ai) * sym, dt, pen_, pz * sym)
            rows.append(row + lateral if gen else row)
            WINT += ai + bi
            WHG += ah + bh
            WC += ac + bc
            WEXT += ax + bx
            IMP += force * dtn
            Z, V = Zs, Vs
            t_n, t = t, t + dt
            dtp = dt
            steps += 1
            dtmin, dtmax, maxpen = min(dtmin, dt), max(dtmax, dt), max(maxpen, pen_)
            self.state = resp.state
            if not math.isfinite(ke + pz + Zs):
                raise errors.state(model, t_n)
            done = t_n >= end
            if not done and sph is not None and model.stop_after_separation:
                if force > 0.0:
                    seen, SEPT = True, 0.0
                elif seen and Vf > 0.0:
                    SEPT += dt
                    if SEPT >= o.separation_time:
                        stop = "separated"
                        done = True
                else:
                    SEPT = 0.0
            if fi and t >= next_frame:
                frames.append((t, to_user(u.T.to("cpu", torch.float64).numpy())))
                states.append(self._frame_state(v, dtp))
                next_frame = (math.floor(t / fi) + 1) * fi
            if t >= next_progress:
                if self.progress is not None and min(t, end) > reported:
                    reported = min(t, end)
                    self.progress(reported)
                next_progress = (math.floor(t / tick) + 1) * tick
            if monitor.due(t):
                monitor.check(t, positions(), self._ref(Z, C3 if gen else None))
            if done:
                break
            runaway = errors.pace(model, steps, t, o.max_steps)   # max_steps, or a pace that cannot reach the end
            if runaway is not None:
                raise runaway
        wall = time.perf_counter() - start
        monitor.final(t, positions(), self._ref(Z, C3 if gen else None))
        h = np.array(rows, dtype=np.float64).reshape(-1, len(COLUMNS) if gen else BASE_COLUMNS)
        res = self._result(h, wall, steps, DT0, dtmin, dtmax, maxpen, frames, stop)
        res.info["checks"] = monitor.report()
        res.frame_state = states
        return res

    def _ref(self, Z, C3):
        """What the monitor checks the impactor at: its z (hemisphere along z) or reference point (3,)."""
        if self.model.sphere is None:
            return None
        return Z if C3 is None else np.asarray(C3, dtype=np.float64)

    def _frame_state(self, v, dt: float) -> dict:
        """A frame's velocity and Prony state in the user's numbering (per part with parts)."""
        if self.lay is not None:
            return parts.frame_state_parts(self.user, self.ren, v, self.state, dt)
        return self.ren.frame_state_to_user(frame_state(v, self.state, dt, self.a.ne))

    # ---- errors ----
    def _element_error(self, resp, kin, t: float, dt0: float):
        import torch

        from .element import inverted

        e = int(torch.nonzero(resp.failed)[0, 0])      # the first failed element (solver's numbering)
        J = float(kin.J[e])
        m = [float(x) for x in kin.m[:, e].tolist()]
        eu = self.ren.user_element(e)
        if bool(inverted(kin.J[e])):
            return errors.inverted(self.user, eu, t, J, dt0)
        material = self.user.part_list()[int(self.user.element_part()[eu])].material
        return errors.nonfinite(material, f"element {eu} at t = {t:.6g} s", m, J, t, eu,
                                float32=self.dtype == torch.float32)

    def _collapse_error(self, t: float, e: int, dtc: float, dt0: float):
        return errors.collapse(self.user, t, self.ren.user_element(e), dtc, dt0, self.o.collapse)

    # ---- result ----
    def _result(self, h, wall, steps, dt0, dtmin, dtmax, maxpen, frames, stop) -> Result:
        import torch

        o = self.o
        return history.assemble(
            self.model, h, backend="torch", steps=steps, wall=wall, dt0=dt0, dtmin=dtmin, dtmax=dtmax,
            maxpen=maxpen, frames=frames, stop=stop, options=o,
            info={"device": str(self.device), "dtype": str(self.dtype).replace("torch.", ""),
                  "threads": torch.get_num_threads(), "compile": o.compile, "compile_time": self.compile_time,
                  "host_syncs_per_step": self.syncs / max(steps, 1)})


def general_impactor(sphere) -> bool:
    """True when the impactor needs the contact of any shape (:mod:`.impactor_contact`): not the
    paper's hemisphere moving along z only, which keeps its own contact (:mod:`.contact`)."""
    return not (sphere.shape == "hemisphere" and tuple(bool(m) for m in sphere.moves) == (False, False, True))


def _energies(mass, v, vold, nodal, dvc, pmask, dtn: float, lateral: bool = False):
    """(10,) tensor: kinetic energy at t^n, A and B work halves of the internal, hourglass, contact and
    external forces around t^n (see numba's ``energy_pass``), z momentum at n+1/2 (modelled part);
    ``lateral``: (12,), the x and y momenta appended.

    nodal (6, n): internal and hourglass nodal forces. The force-velocity products are one matrix
    product (force rows x (v^{n-1/2}, v^{n+1/2})), the same sums as numba's node loop.
    """
    import torch

    h = 0.5 * dtn
    rows = [nodal.view(2, -1), ((0.5 * mass) * dvc).view(1, -1)]
    if pmask is not None:
        fx = pmask * ((0.5 * mass) * (v - vold) - (h * (nodal[3:6] - nodal[0:3]) + (0.5 * mass) * dvc))
        rows.append(fx.view(1, -1))
    AB = torch.cat(rows) @ torch.stack([vold.reshape(-1), v.reshape(-1)], dim=1)      # (3 or 4, 2)
    scale = torch.tensor([-h, h, 1.0, 1.0][:AB.shape[0]], dtype=AB.dtype, device=AB.device)[:, None]
    AB = (AB * scale).reshape(-1)
    if pmask is None:
        AB = torch.cat([AB, torch.zeros(2, dtype=AB.dtype, device=AB.device)])
    ke = 0.5 * (mass * (vold * v).sum(0)).sum()
    if lateral:
        return torch.cat([ke[None], AB, (mass * v[[2, 0, 1]]).sum(1)])
    return torch.cat([ke[None], AB, (mass * v[2]).sum()[None]])
