"""Histories of an implicit run, recorded at every accepted step, and the :class:`Result` made of them.

Forces, impulses, momenta and energies in the Result are for the full model (x
``model.symmetry_factor``), SI units. Energies are the work of each force over the accepted
steps (trapezoidal rule, exact for the integrator's energy identity): internal (N m = J, every
part's elements together), contact, external, and the integrator's numerical dissipation.

For an impactor free to move in x or y, ``Result.impactor_lateral`` holds force_x, force_y (N,
force of the specimen on the impactor), x, y (m, reference point), vx, vy (m/s); and
``info["momentum_x_drift"]`` / ``["momentum_y_drift"]`` the largest change of the total
momentum (specimen and impactor, kg m/s) along x and y, which no external force changes when
nothing holds the specimen laterally (a frictionless plate).

For a model with several parts, ``info["part_energies"]`` gives, per part name, the internal
energy (the work of that part's internal forces, J, full model) at the end ("internal") and its
largest value ("internal_max"); the parts' energies sum to the internal energy.
"""

from __future__ import annotations

import numpy as np

from cfm_core.errors import NumericalError
from cfm_core.simulation.result import Result

from .linear import dot
from .stepper import State
from .system import System


class Recorder:
    """Histories at every accepted step (full model: x symmetry factor)."""

    def __init__(self, sys_: System, model):
        self.sys = sys_
        self.factor = float(model.symmetry_factor)
        self.rows = []
        self.lateral = []  # fx, fy (N), x, y (m), vx, vy (m/s), momentum x, y (kg m/s); modelled part
        self.impulse = 0.0
        self.w_int = 0.0
        self.w_c = 0.0
        self.w_ext = 0.0
        self.diss = 0.0
        self.pen_s = 0.0
        self.pen_p = 0.0
        self.part_names = sys_.parts.names if sys_.parts is not None else []
        self.w_parts = np.zeros(len(self.part_names))
        self.part_rows = []
        self.with_lateral = sys_.has_w and bool(sys_.sphere.lateral)
        if self.with_lateral:
            n3 = 3 * sys_.n_nodes
            axis = np.full(sys_.n, -1)
            axis[:n3] = np.tile(np.arange(3), sys_.n_nodes)
            axis[sys_.imp_dofs] = sys_.axes
            self.axis_mass = [np.where(axis == j, sys_.mass, 0.0) for j in (0, 1)]

    def reaction(self, s: State) -> float:
        d = self.sys.presc_dofs
        return float(np.sum(s.f_int[d] + s.f_c[d])) if d.size else 0.0

    def record(self, s: State, prev: State | None, dt: float):
        sys_ = self.sys
        if prev is not None:
            dq = s.q - prev.q
            if sys_.has_w:  # the impactor's momentum change less that of gravity: exact for the integrator
                m_s = float(sys_.mass[sys_.w_dof])
                self.impulse += m_s * float(s.v[sys_.w_dof] - prev.v[sys_.w_dof]) - float(sys_.f_ext[sys_.w_dof]) * dt
            self.w_int += 0.5 * dot(prev.f_int + s.f_int, dq)
            if self.part_names:
                self.w_parts = self.w_parts + 0.5 * ((prev.f_parts + s.f_parts) @ dq)
            self.w_c += 0.5 * dot(prev.f_c + s.f_c, dq)
            self.diss += s.dissipation
            self.w_ext += 0.5 * dot(sys_.f_ext + sys_.f_ext, dq)
            d = sys_.presc_dofs
            if d.size:
                self.w_ext += 0.5 * (self.reaction(prev) + self.reaction(s)) * float(dq[d].mean())
        self.pen_s = max(self.pen_s, s.pen_sphere)
        self.pen_p = max(self.pen_p, s.pen_plane)
        ke = 0.5 * dot(sys_.mass, s.v * s.v)
        wz = s.q[sys_.w_dof] if sys_.has_w else 0.0
        zc = sys_.sphere.center[2] + wz if sys_.has_w else 0.0
        vz = s.v[sys_.w_dof] if sys_.has_w else 0.0
        self.rows.append((s.t, s.fz, self.impulse, zc, vz, self.reaction(s), ke, self.w_int,
                          self.w_c, self.w_ext, dt, self.diss))
        if self.part_names:
            self.part_rows.append(self.w_parts)
        if self.with_lateral:
            c = sys_.impactor_point(s.q)
            v = np.zeros(3)
            v[sys_.axes] = s.v[sys_.imp_dofs]
            self.lateral.append((s.fxy[0], s.fxy[1], c[0], c[1], v[0], v[1],
                                 dot(self.axis_mass[0], s.v), dot(self.axis_mass[1], s.v)))

    def result(self, model, steps: int, wall: float, frames, info) -> Result:
        h = np.array(self.rows, dtype=np.float64)
        if not np.isfinite(h).all():
            i = int(np.argmax(~np.isfinite(h).all(axis=1)))
            raise NumericalError(f"skfem backend: non-finite history at t = {h[i, 0]:.6g} s.",
                                 time=float(h[i, 0]), quantity="history")
        f = self.factor
        t = h[:, 0]
        dts = h[1:, 10]
        res = Result(t=t, backend="skfem", steps=steps, wall_time=wall,
                     energies={"kinetic": f * h[:, 6], "internal": f * h[:, 7],
                               "hourglass": np.zeros_like(t), "contact": f * h[:, 8],
                               "external": f * h[:, 9], "numerical_dissipation": f * h[:, 11]},
                     dt_min=float(dts.min()) if dts.size else float("nan"),
                     dt_max=float(dts.max()) if dts.size else float("nan"), frames=frames, info=info)
        if self.sys.has_w:
            res.contact_force = f * h[:, 1]
            res.impulse = f * h[:, 2]
            res.impactor_z = h[:, 3]
            res.impactor_v = h[:, 4]
            if model.mass_full:
                res.acceleration = res.contact_force / float(model.mass_full)
        if self.with_lateral:
            g = np.array(self.lateral, dtype=np.float64)
            res.impactor_lateral = {"force_x": f * g[:, 0], "force_y": f * g[:, 1], "x": g[:, 2], "y": g[:, 3],
                                    "vx": g[:, 4], "vy": g[:, 5]}
            for j, name in ((6, "momentum_x_drift"), (7, "momentum_y_drift")):
                res.info[name] = float(f * np.max(np.abs(g[:, j] - g[0, j])))
        if self.part_names:
            w = f * np.array(self.part_rows, dtype=np.float64)
            res.info["part_energies"] = {name: {"internal": float(w[-1, i]), "internal_max": float(w[:, i].max())}
                                         for i, name in enumerate(self.part_names)}
        if model.prescribed is not None:
            res.reaction_force = f * h[:, 5]
        return res
