"""Batched drop tests on torch: one simulation advances B runs that share a mesh.

The B runs may differ in material parameter values (same material definition, same number of
Prony terms, per part), impact velocity, impactor mass and start height, and end time; they share the mesh,
parts (elements, densities, material definitions), constraints, contact node sets, impactor shape,
radius and free axes, and friction. A model with parts runs renumbered as the single run is (each
part one contiguous element range, ``renumber.plan(..., o.renumber, groups)``); the results, checks
and messages are in the user's numbering. A one-material batch keeps the mesh's numbering (its
results stay those of earlier versions to the bit). The batch is one mesh of B
disconnected copies: elements (B N) and nodes (B n), run b's at b N + e and b n + i, so the
element pass (``element``) is the single run's, unchanged; every per-run quantity (time t, step dt,
sphere height and velocity, energy sums, stop rule, failure) is a (B,) tensor on the device. Each
run takes its own stable step and keeps its own time, so each result equals the same run done alone
to round-off (relative L2 of the filtered acceleration < 1e-10 in float64,
tests/backends/test_torch_batch.py). A run that has stopped (end time, separation, failure) keeps
being computed with the others until all have stopped; its records are dropped.

Host synchronisations: none inside a step when ``sync_free`` (default on CUDA): the eigen
fallback (C isotropic to round-off) takes m = diag C, Q = I under a mask
(``eigen.patch_fallback_isotropic``), the contact Newton iteration runs a fixed number of
iterations, and failures, unconverged contacts and stops are flags read once per chunk of
``CHUNK`` steps together with the history rows. The step (:mod:`.batch_step`) works on buffers
allocated before the first step (carried tensors updated in place, history rows written into a
(CHUNK, B, columns) device buffer at a row index held on the device), so that it can be captured:
on CUDA with ``cuda_graph`` (default on for the sync-free step without ``torch.compile``) three
eager warm-up steps run on a side stream, then one step is captured as a ``torch.cuda.CUDAGraph``
and replayed (``info['cuda_graph']``). Capture-safety is tested on the CPU
(tests/backends/test_torch_batch_graph.py); the capture itself has not yet run on a GPU (none
was lent). On the CPU (default ``sync_free=False``) a step reads
whether any eigen fallback is needed (then Jacobi, as a single run) and whether every run has
stopped, and the Newton iteration checks convergence every ``newton_block`` iterations;
``info['host_syncs_per_step']`` counts them.
"""

from __future__ import annotations

import contextlib
import math
import time

import numpy as np

from cfm_backends.explicit import errors, history, renumber
from cfm_backends.explicit.options import step_cap
from cfm_backends.threads import num_threads
from cfm_core.errors import InputError, NumericalError
from cfm_core.simulation.checks import Monitor

from . import arrays as arr
from . import material as mat
from . import parts
from .options import PARALLEL_MIN, TorchOptions, check_cuda_graph, resolve_device, resolve_dtype

CHUNK = 32            # steps between host reads of the history rows and the run flags

from .batch_checks import (COLLAPSE, FALLBACK, INVERTED, NEWTON, NONFINITE, OK, STATE,  # noqa: F401
                           check_batch, run_error)


def run_batch(models, progress=None, raise_errors: bool = True, sync_free: bool | None = None, **options):
    """Run drop tests sharing a mesh as one batch; list of Results (or NumericalErrors).

    See :meth:`cfm_backends.torch_explicit.TorchExplicitBackend.run_batch`.
    """
    return run_parsed(models, TorchOptions.from_mapping(options), progress, raise_errors, sync_free)


def run_parsed(models, o: TorchOptions, progress=None, raise_errors: bool = True, sync_free: bool | None = None,
               device=None, dtype=None):
    """:func:`run_batch` with its options already parsed (``o``); ``device`` and ``dtype``: the torch
    device and dtype ``o`` names, when the caller has resolved them already."""
    import torch

    if o.frame_interval is not None:
        raise InputError("torch batch: frame_interval is not supported in batched runs; run the model alone.")
    check_batch(models)
    if device is None or dtype is None:
        device, dtype = resolve_device(o.device), resolve_dtype(o.dtype)
    if sync_free is None:
        sync_free = device.type == "cuda"
    graph = cuda_graph(o, device, bool(sync_free))
    serial = device.type == "cpu" and models[0].n_elements * len(models) < PARALLEL_MIN
    on_device = torch.cuda.device(device) if graph else contextlib.nullcontext()   # capture on the run's GPU
    with num_threads(torch, o.threads, serial=serial), torch.inference_mode(), on_device:
        out = _Batch(models, o, device, dtype, progress, bool(sync_free), graph).loop()
    if raise_errors:
        for r in out:
            if isinstance(r, NumericalError):
                raise r
    return out


def cuda_graph(o: TorchOptions, device, sync_free: bool) -> bool:
    """Whether the batch's step runs as a captured CUDA graph: the option ``cuda_graph``, by
    default on for a sync-free step on CUDA without ``torch.compile``; InputError where it cannot."""
    if o.cuda_graph is None:
        return device.type == "cuda" and sync_free and o.compile is False
    check_cuda_graph(o.cuda_graph, str(device), o.compile)     # the resolved device (o.device may be 'auto')
    if o.cuda_graph and not sync_free:
        raise InputError("torch backend: option cuda_graph = True is not allowed with sync_free=False (a step "
                         "that reads values back to the host cannot be captured); use sync_free=True (the "
                         "default on CUDA) or cuda_graph=False.")
    return bool(o.cuda_graph)


class _Batch:
    def __init__(self, models, o: TorchOptions, device, dtype, progress, sync_free: bool, graph: bool = False):
        import torch

        from . import element
        from .batch_contact import BatchSphere
        from .contact import PlaneNodes

        t0 = time.perf_counter()
        self.models, self.o, self.device, self.dtype, self.progress = models, o, device, dtype, progress
        self.step_cap = step_cap(o, list(models))  # the largest step (s): dt_max and the output intervals
        self.sync_free, self.cuda_graph, self.graph_used = sync_free, graph, False
        B = self.B = len(models)
        # parts: the models renumbered as the single run is (each part one contiguous element range, the
        # renumber option's order within it); runs, monitors and messages stay in the user's numbering
        self.ren = None
        if models[0].multi_material:
            self.ren = renumber.plan(models[0].nodes, models[0].hexes, o.renumber, groups=models[0].element_part())
        self.imodels = [self.ren.model(m) for m in models] if self.ren is not None else list(models)
        m0 = self.imodels[0]
        a, uv, k = arr.build(m0, o, device, dtype)
        n, N = a.n, a.ne
        self.n, self.N, self.k = n, N, k
        T = lambda x: torch.as_tensor(np.asarray(x, dtype=np.float64), dtype=dtype, device=device)  # noqa: E731
        rep = lambda x: x.repeat(*([1] * (x.dim() - 1)), B)  # noqa: E731  (last axis tiled B times)
        offs = torch.arange(B, device=device, dtype=torch.int64)
        self.idx = (a.idx.view(8, 1, N) + (offs * n).view(1, B, 1)).reshape(-1)
        self.flat = element.flat_index(self.idx, B * n)
        self.Bm, self.BV, self.G = rep(a.B), rep(a.BV), rep(a.G)
        self.L, self.V0, self.hgc = rep(a.L), rep(a.V0), rep(a.hgc)
        self.mass, self.free = rep(a.mass), rep(a.free)
        self.uv = rep(uv).contiguous()
        sn = a.sphere
        s = sn.nodes.shape[0]
        self.sphere = BatchSphere((sn.nodes.view(1, s) + (offs * n).view(B, 1)).reshape(-1),
                                  sn.X.view(3, 1, s).repeat(1, B, 1), sn.mass.view(1, s).repeat(B, 1),
                                  sn.free.view(3, 1, s).repeat(1, B, 1))
        self.plane = None
        if a.plane is not None:
            pl = a.plane
            self.p_count = pl.nodes.shape[0]
            self.plane = PlaneNodes((pl.nodes.view(1, -1) + (offs * n).view(B, 1)).reshape(-1), rep(pl.Xz),
                                    rep(pl.free))
        # per-run material and impactor
        T64 = lambda x: torch.as_tensor(np.asarray(x, dtype=np.float64), dtype=torch.float64, device=device)  # noqa: E731
        self.lay, self.rho = None, float(m0.density)
        if m0.multi_material:       # per part: derivatives, Prony series (padded to k), density
            lays = [parts.layout(m) for m in self.imodels]
            self.lay = lay = lays[0]
            self.ghd = parts.composite(lay.ghd, lay.ranges)
            self.p = [[T(np.array([ly.params[i][j] for ly in lays])).view(B, 1) for j in range(len(lay.params[i]))]
                      for i in range(len(lay.ranges))]
            self.gam = T64(np.stack([ly.gam for ly in lays]))                       # (B, P, k)
            self.tau = T64(np.stack([ly.tau for ly in lays]))
            self.part_index = torch.as_tensor(lay.part, device=device)
            self.ginf = T(np.stack([ly.ginf[ly.part] for ly in lays])).reshape(-1)
            self.rho = rep(T(lay.density))
        else:
            self.ghd = mat.grad_hess_diag(m0.material)
            P = np.array([mat.parameters(m.material) for m in models])              # (B, P)
            self.p = [T(P[:, j]).view(B, 1) for j in range(P.shape[1])]
            pr = [mat.prony(m.material) for m in models]
            self.gam = T64([g for g, _, _ in pr]).view(B, k)
            self.tau = T64([t for _, t, _ in pr]).view(B, k)
            self.ginf = T([gi for _, _, gi in pr]).repeat_interleave(N)
        from .solver import general_impactor

        self.general = general_impactor(m0.sphere)
        if self.general:            # any shape, lateral motion: reference point and velocity (3, B)
            self.C0 = T64([list(m.sphere.center) for m in models]).T.contiguous()
            self.Vv0 = T64([(m.sphere.velocity_vector * np.asarray(m.sphere.moves, dtype=float)).tolist()
                            for m in models]).T.contiguous()
            self.fmask = torch.tensor([float(f) for f in m0.sphere.moves], dtype=dtype, device=device).view(3, 1)
        # per-run scalars (time, step, impactor, energy sums) are float64 whatever the field dtype,
        # as the single run's host arithmetic
        self.M = T64([m.sphere.mass for m in models])
        self.Z0 = T64([m.sphere.center[2] for m in models])
        self.V0s = T64([m.sphere.velocity for m in models])
        self.end = T64([m.end_time for m in models])
        self.state = arr.initial_state(k, B * N, dtype, device)
        self.stages = element.Stages.make(o.compile)
        self.tol = 1e-16 * torch.finfo(dtype).eps / torch.finfo(torch.float64).eps
        self.block = 0 if sync_free else (o.newton_block or 1)
        self.syncs = 0
        if o.warm_up:
            self._element_pass(torch.zeros(B, dtype=torch.float64, device=device), torch.ones(B, dtype=torch.bool,
                                                                                         device=device))
        self.syncs = 0
        self.compile_time = time.perf_counter() - t0

    def _ghd(self, m1, m2, m3, p):
        B = self.B
        return [x.reshape(-1) for x in self.ghd(m1.view(B, -1), m2.view(B, -1), m3.view(B, -1), p)]

    def _factors(self, dtp):
        """Prony (decay, gain) of each run's previous step, per element: (2, k, B N); numba's formulas."""
        import torch

        if self.k == 0:
            return torch.zeros((2, 0, 1), dtype=self.dtype, device=self.device)
        if self.lay is not None:    # (B, P, k) series: per run and part, then per element
            x = dtp[:, None, None] / self.tau
            small = x < 1e-8
            decay = torch.where(small, 1.0 - x, torch.exp(-x))
            gain = self.gam * torch.where(small, 1.0 - 0.5 * x, -torch.expm1(-x) / torch.where(small, 1.0, x))
            f = torch.stack([decay, gain]).permute(0, 3, 1, 2).to(self.dtype)       # (2, k, B, P)
            return f.index_select(3, self.part_index).reshape(2, self.k, -1)
        x = dtp[:, None] / self.tau
        small = x < 1e-8
        decay = torch.where(small, 1.0 - x, torch.exp(-x))
        gain = self.gam * torch.where(small, 1.0 - 0.5 * x, -torch.expm1(-x) / torch.where(small, 1.0, x))
        f = torch.stack([decay, gain]).permute(0, 2, 1).to(self.dtype)              # (2, k, B)
        return f[:, :, :, None].expand(2, self.k, self.B, self.N).reshape(2, self.k, -1)

    def _element_pass(self, dtp, alive):
        """(kin, resp, unsafe-fallback flag) of all runs (no host sync when sync_free)."""
        from . import element
        from .eigen import patch_fallback, patch_fallback_isotropic

        st = self.stages
        kin, D = st.front(element.gather(self.uv, self.flat, self.B * self.N), self.Bm, self.G, self._ghd, self.p)
        alive_e = alive[:, None].expand(self.B, self.N).reshape(-1)
        fb = kin.fallback & alive_e
        overflow = None
        patched = False
        if self.sync_free:
            m, Q, overflow = patch_fallback_isotropic(kin.C, kin.m, kin.Q, fb)
            patched = True
        else:
            self.syncs += 1
            if bool(fb.any()):
                m, Q = patch_fallback(kin.C, kin.m, kin.Q, fb)
                patched = True
        if patched:
            kin = kin._replace(m=m, Q=Q, fallback=kin.fallback & False)
            D = element.derivatives(self._ghd, self.p, kin.m)
        args = (self.state, self._factors(dtp), self.ginf, self.BV, self.G, self.L, self.V0, self.hgc,
                self.rho, 0 if self.o.hourglass_wave == "shear" else 1)
        return kin, element.response(kin, D, *args, stages=st), overflow

    def loop(self):
        import torch

        from . import batch_step

        o, B = self.o, self.B
        gen = self.general
        s = self.carry = batch_step.carry(self, CHUNK)
        chunks = []
        tick = float(max(m.end_time for m in self.models)) / 100.0
        next_progress = tick
        total = flushed = 0
        # physics checks of every run (cfm_core.simulation.checks), at the chunk reads below
        self.monitors = [Monitor(m) for m in self.models]
        self.nodes0 = np.asarray(self.models[0].nodes, dtype=np.float64)
        self.check_errors: dict = {}
        # CUDA graph: WARM_STEPS eager steps on a side stream, then one step captured and replayed
        graph = batch_step.CudaGraph(self.device) if self.cuda_graph else None
        start = time.perf_counter()
        while True:
            if graph is None:
                batch_step.step(self, s)
            else:
                graph(lambda: batch_step.step(self, s))
            total += 1
            if not self.sync_free:          # CPU: stop as soon as every run has (one cheap read)
                self.syncs += 1
                if not bool(s.alive.any()):
                    break
            if total % CHUNK == 0 or total >= o.max_steps:
                chunks.append(self._rows(s, total - flushed))
                flushed = total
                self.syncs += 1
                if not bool(s.alive.any()):
                    break
                self._monitor(s.alive, s.t, self.uv[0:3], s.C if gen else s.Z)
                if total >= errors.PROJECT_AFTER:
                    self._pace(s)
                tmin = float(torch.where(s.alive, s.t, math.inf).min())
                if self.progress is not None and tmin >= next_progress:
                    self.progress(min(tmin, tick * 100.0))
                    next_progress = (math.floor(tmin / tick) + 1) * tick
                if total >= o.max_steps:
                    break
        if total > flushed:
            chunks.append(self._rows(s, total - flushed))
        wall = time.perf_counter() - start
        self.graph_used = graph is not None and graph.used
        self._monitor(s.alive, s.t, self.uv[0:3], s.C if gen else s.Z, final=True,
                      ok=(s.code == OK).to("cpu").numpy())
        host = [x.to("cpu") for x in (s.steps, s.DT0, s.dtmin, s.dtmax, s.maxpen, s.code, s.err, s.separated,
                                      s.alive, s.t)]
        self.memory = self._memory(s.vold, s.dvc, s.rows, s.masks)
        return self._results(chunks, wall, total, *host)

    @staticmethod
    def _rows(s, count: int):
        """The first ``count`` history rows and live-run masks on the host (copies), the row index reset."""
        import torch

        out = (s.rows[:count].to("cpu", torch.float64, copy=True), s.masks[:count].to("cpu", copy=True))
        s.pos.zero_()
        return out

    def _pace(self, s) -> None:
        """Stop the runs whose pace cannot reach their end time within max_steps, with the single
        runs' error (:func:`cfm_backends.explicit.errors.pace`; mu = 1e306 Pa: a stable step of
        1e-155 s); the others go on. One read of the runs' steps and times."""
        import torch

        self.syncs += 1
        steps, t = s.steps.to("cpu").numpy(), s.t.to("cpu", torch.float64).numpy()
        alive = s.alive.to("cpu").numpy()
        for b, model in enumerate(self.models):
            if alive[b] and b not in self.check_errors:
                runaway = errors.pace(model, int(steps[b]), float(t[b]), self.o.max_steps)
                if runaway is not None:
                    self.check_errors[b] = runaway
                    s.alive[b] = False

    def _monitor(self, alive, t, u, Z, final: bool = False, ok=None) -> None:
        """Run the physics checks of the runs that are due (``final``: every run that finished
        without a failure, ``ok`` (B,) bool); a run whose check fails stops here (its entry
        becomes the NumericalError) and the others go on."""
        import torch

        th, al = t.to("cpu", torch.float64).numpy(), alive.to("cpu").numpy()
        runs = [b for b in range(self.B) if b not in self.check_errors
                and ((final and not al[b] and ok[b]) or (not final and al[b] and self.monitors[b].due(float(th[b]))))]
        if not runs:
            return
        uh = u.to("cpu", torch.float64).view(3, self.B, self.n).numpy()
        zh = Z.to("cpu", torch.float64).numpy()      # (B,) heights or (3, B) reference points
        nodes = self.nodes0
        for b in runs:
            check = self.monitors[b].final if final else self.monitors[b].check
            ub = uh[:, b].T if self.ren is None else self.ren.to_user_nodes(uh[:, b].T)
            try:
                check(float(th[b]), nodes + ub, float(zh[b]) if zh.ndim == 1 else zh[:, b].copy())
            except NumericalError as exc:
                self.check_errors[b] = exc
                alive[b] = False

    def _memory(self, *extra) -> dict:
        """Bytes per run: the persistent tensors (geometry, state), and the device's peak on CUDA."""
        import torch

        tensors = [self.idx, self.Bm, self.BV, self.G, self.L, self.V0, self.hgc, self.mass, self.free, self.uv,
                   self.ginf, *self.state, *self.sphere, *extra]
        if self.plane is not None:
            tensors += list(self.plane)
        out = {"tensor_bytes_per_run": sum(t.numel() * t.element_size() for t in tensors) / self.B}
        if self.device.type == "cuda":
            out["peak_device_bytes_per_run"] = torch.cuda.max_memory_allocated(self.device) / self.B
        return out

    @staticmethod
    def _flag(code, err, where, kind, element, t, value, m, dt0):
        """Record the first failure of each run in ``where`` (device ops only)."""
        import torch

        new = where & (code == OK)
        code.copy_(torch.where(new, kind, code))          # kind: a Python int or a (B,) tensor (no copy to the device)
        vals = torch.stack([element.to(err.dtype), t.to(err.dtype), value.to(err.dtype),
                            m[0].to(err.dtype), m[1].to(err.dtype), m[2].to(err.dtype), dt0.to(err.dtype)], dim=1)
        err.copy_(torch.where(new[:, None], vals, err))

    def _energies(self, v, vold, nodal, dvc, dtn, lateral: bool = False):
        """(8, B): kinetic energy, A/B work halves of internal, hourglass, contact forces, z momentum;
        ``lateral``: (10, B), the x and y momenta appended."""
        import torch

        B, n = self.B, self.n
        h = 0.5 * dtn
        mh = (0.5 * self.mass) * dvc
        prods = torch.stack([nodal[0:3] * vold, nodal[0:3] * v, nodal[3:6] * vold, nodal[3:6] * v, mh * vold,
                             mh * v, self.mass * (vold * v)]).view(7, 3, B, n).sum((1, 3))
        pz = (self.mass * v[2]).view(B, n).sum(1)
        out = [0.5 * prods[6], -h * prods[0], -h * prods[1], h * prods[2], h * prods[3], prods[4], prods[5], pz]
        if lateral:
            out += list((self.mass * v[0:2]).view(2, B, n).sum(2).unbind(0))
        return torch.stack(out)

    def _results(self, chunks, wall, total, steps, DT0, dtmin, dtmax, maxpen, code, err, separated, alive, t):
        import torch

        rows = torch.cat([c[0] for c in chunks]).numpy()          # (steps, B, 15)
        masks = torch.cat([c[1] for c in chunks]).numpy()         # (steps, B)
        out = []
        for b, model in enumerate(self.models):
            c = int(code[b])
            e = err[b].tolist()
            if b in self.check_errors:
                out.append(self.check_errors[b])
                continue
            if c != OK:
                out.append(run_error(b, model, c, e, self.ren, self.dtype, self.o.collapse, self.general))
                continue
            if bool(alive[b]):
                out.append(errors.max_steps(model, int(steps[b]), float(t[b])))
                continue
            h = rows[masks[:, b], b, :]
            res = history.assemble(
                model, h, backend="torch", steps=int(steps[b]), wall=wall / self.B, dt0=float(DT0[b]),
                dtmin=float(dtmin[b]), dtmax=float(dtmax[b]), maxpen=float(maxpen[b]), frames=[],
                stop="separated" if bool(separated[b]) else "end_time", options=self.o,
                info={"device": str(self.device), "dtype": str(self.dtype).replace("torch.", ""),
                      "threads": torch.get_num_threads(), "compile": self.o.compile,
                      "compile_time": self.compile_time / self.B, "batch_size": self.B, "batch_index": b,
                      "batch_wall_time": wall, "batch_steps": total, "sync_free": self.sync_free,
                      "cuda_graph": self.graph_used, **self.memory,
                      "host_syncs_per_step": self.syncs / max(total, 1)})
            res.info["checks"] = self.monitors[b].report()
            out.append(res)
        return out
