"""The discrete system of one model: dofs, masses, constraints, residual and tangent.

Unknowns q (m): nodal displacements (3 n, dof 3 node + axis) and, with a rigid impactor, the
displacements of its reference point along its free axes (``RigidSphere.moves``; z only by
default, then its z displacement w is the last dof). :meth:`System.evaluate` gives f_int(q),
the contact forces dPhi_c/dq and their tangent K_int + d2Phi_c/dq2 (contact: :mod:`.contact` for
the paper's hemisphere moving along z only, :mod:`.impactor` for every other shape or motion);
with several parts each part's material acts on its own elements (:mod:`.parts`). The time
integrator (:mod:`.stepper`) adds the inertia M a(q). M is the lumped (row-sum) mass of the nodes
(per-element density with parts) and the impactor's mass on each of its dofs (modelled part),
zero in quasi-static runs; f_ext is gravity on the impactor (|model.gravity| downwards,
as in the numba backend).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from cfm_core.errors import InputError

from . import contact, element, impactor
from .constitutive import Constitutive, History
from .discretization import discretize
from .linear import Pattern, assemble_vector
from .parts import PartElements, check_parts


@dataclass
class Evaluation:
    """Residual pieces at one iterate (modelled part, N): see :meth:`System.evaluate`."""

    f_int: np.ndarray
    f_c: np.ndarray
    K: np.ndarray | None  # CSR data (nnz,) in System.pattern (N/m), without mass and constraints
    history: History | None
    contact: contact.ContactState | None
    theta: np.ndarray


class System:
    """Everything of a model that does not change during the run."""

    def __init__(self, model, volumetric: str = "mean-dilatation", quasi_static: bool = False,
                 kernels: str = "numba"):
        self.model = model
        parts = model.part_list()
        self.parts = None  # PartElements with several parts; else the one-material path below
        self.volumetric = volumetric
        self.kernels = kernels
        self.compiled = None
        if len(parts) > 1:
            check_parts(model)
            density = model.element_density()
            self.disc = discretize(model.nodes, model.hexes, density if not quasi_static else 0.0)
            self.parts = PartElements(self.disc, parts, volumetric, kernels)
            self.mat = self.parts.mats[0]
        else:
            material = parts[0].material
            self.disc = discretize(model.nodes, model.hexes, parts[0].density if not quasi_static else 0.0)
            self.mat = Constitutive(material)
            if kernels == "numba":
                from .compiled import CompiledElements

                self.compiled = CompiledElements(self.disc, material, volumetric)
        #: the generated module whose scatter kernels assemble (None: numpy)
        self.scatter = self.compiled.mod if self.compiled is not None else (
            self.parts.mod if self.parts is not None else None)
        self.quasi_static = quasi_static
        nn = self.disc.n_nodes
        self.n_nodes = nn
        self.sphere = model.sphere
        self.has_w = self.sphere is not None
        self.warnings = impactor.check(self.sphere, model.name) if self.has_w else []
        #: the impactor's free axes (0, 1, 2 for x, y, z) and their dofs, after the nodes'
        self.axes = (np.flatnonzero(np.asarray(self.sphere.moves, dtype=bool)) if self.has_w
                     else np.zeros(0, np.int64))
        self.imp_dofs = 3 * nn + np.arange(self.axes.size)
        self.n = 3 * nn + self.axes.size
        self.w_dof = int(self.imp_dofs[list(self.axes).index(2)]) if self.has_w else -1
        #: the paper's hemisphere moving along z only keeps its own contact code (:mod:`.contact`)
        self.general_contact = self.has_w and (self.sphere.shape != "hemisphere" or self.axes.size != 1)
        mass = np.repeat(self.disc.mass, 3)
        if self.has_w:
            mass = np.append(mass, np.full(self.axes.size, 0.0 if quasi_static else float(self.sphere.mass)))
        self.mass = mass
        self.constrained = np.zeros(self.n, dtype=bool)
        fixed = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2)
        if fixed.size and (fixed[:, 0].max() >= nn or fixed[:, 0].min() < 0 or not np.isin(fixed[:, 1], (0, 1, 2)).all()):
            raise InputError(f"model '{model.name}': fixed_dofs must be (node, 0|1|2) pairs with nodes < {nn}.")
        self.constrained[3 * fixed[:, 0] + fixed[:, 1]] = True
        pr = model.prescribed
        self.presc_dofs = np.zeros(0, dtype=np.int64)
        if pr is not None:
            if pr.dof not in (0, 1, 2):
                raise InputError(f"model '{model.name}': prescribed dof = {pr.dof!r}; use 0, 1 or 2.")
            self.presc_dofs = 3 * np.asarray(pr.nodes, dtype=np.int64) + pr.dof
            self.constrained[self.presc_dofs] = True
        self.f_ext = np.zeros(self.n)
        if self.has_w and not quasi_static:
            self.f_ext[self.w_dof] = -float(self.sphere.mass) * abs(float(model.gravity))
        self.sphere_nodes = np.asarray(model.sphere_nodes, dtype=np.int64) if self.has_w else np.zeros(0, np.int64)
        extra = None
        if self.has_w and self.sphere_nodes.size:  # contact couples each candidate node with the impactor
            r = (3 * self.sphere_nodes[:, None] + np.arange(3)[None, :]).ravel()
            m = self.imp_dofs.size
            i, j = np.triu_indices(m, 1)  # couplings between the impactor's own dofs
            extra = (np.concatenate([np.repeat(r, m), self.imp_dofs[i]]),
                     np.concatenate([np.tile(self.imp_dofs, r.size), self.imp_dofs[j]]))
        self.pattern = Pattern(self.disc.edofs, self.n, extra)
        self.plane = model.plane
        self.plane_nodes = np.asarray(model.plane_nodes, dtype=np.int64) if self.plane is not None else np.zeros(0, np.int64)
        self.share_imp = self.share_plane = None
        if self.general_contact:  # each node's share of the modelled part (symmetry planes)
            self.share_imp = impactor.symmetry_share(model, self.sphere_nodes)
            self.share_plane = impactor.symmetry_share(model, self.plane_nodes)
        if self.parts is not None:
            self.kappa0 = self.parts.kappa0()  # the largest small-strain bulk modulus of the parts (Pa)
        else:
            _, _, d2U = self.mat.volumetric(np.ones(1))
            self.kappa0 = float(d2U[0])  # small-strain bulk modulus of the material (Pa)
        #: wall time (s) per phase, accumulated over the run: "element" (Gauss-point and element
        #: work), "assembly" (global vectors and matrix, contact, mass, constraints),
        #: "factorization" (direct factorisation or preconditioner set-up), "solve" (triangular solves or CG)
        self.times = {"element": 0.0, "assembly": 0.0, "factorization": 0.0, "solve": 0.0}
        self.counts = {"evaluations": 0, "factorizations": 0, "solves": 0}
        self.penalty = 0.0  # augmentation (penalty) stiffness k (N/m per node), set by the solver

    # ------------------------------------------------------------------ evaluation
    def displacement(self, q: np.ndarray) -> np.ndarray:
        return q[: 3 * self.n_nodes].reshape(-1, 3)

    def evaluate(self, q: np.ndarray, hist: History | None, dt: float, tangent: bool = True,
                 lam: tuple[np.ndarray, np.ndarray] | None = None, k: float | None = None) -> Evaluation:
        """Internal and contact forces (N) and tangent (N/m, without the mass term) at q for a step dt (s).

        lam: contact multipliers (N) of the sphere and plane candidate nodes (None: zero); k: contact
        stiffness (N/m per node; None: ``self.penalty``).
        Raises :class:`element.Inverted` (J <= 0) and NumericalError (non-finite material values).
        """
        u = self.displacement(q)
        tic = time.perf_counter()
        if self.parts is not None:
            ev = self.parts.evaluate(u, hist, dt, tangent=tangent)
        elif self.compiled is not None:
            ev = self.compiled.evaluate(u, hist, dt, tangent=tangent)
        else:
            ev = element.evaluate(self.disc, self.mat, u, hist, dt, tangent=tangent, volumetric=self.volumetric)
        toc = time.perf_counter()
        self.times["element"] += toc - tic
        self.counts["evaluations"] += 1
        nn3 = 3 * self.n_nodes
        f_int = np.zeros(self.n)
        if self.scatter is not None:
            self.scatter.scatter_vector(ev.force, self.disc.edofs, f_int)
        else:
            f_int[:nn3] = assemble_vector(self.disc.edofs, ev.force, nn3)
        f_c = np.zeros(self.n)
        cs = None
        K = None
        if self.has_w or (self.plane is not None and self.plane_nodes.size):
            lam_s, lam_p = lam if lam is not None else self.zero_multipliers()
            kk = self.penalty if k is None else k
            if self.general_contact:
                cs = impactor.evaluate(self.disc.nodes + u, self.impactor_displacement(q), self.sphere,
                                       self.sphere_nodes, self.plane, self.plane_nodes, kk, self.imp_dofs,
                                       self.axes, lam_s, lam_p, tangent=tangent, share_imp=self.share_imp,
                                       share_plane=self.share_plane)
            else:
                w = float(q[self.w_dof]) if self.has_w else 0.0
                cs = contact.evaluate(self.disc.nodes + u, w, self.sphere, self.sphere_nodes, self.plane,
                                      self.plane_nodes, kk, self.w_dof, lam_s, lam_p, tangent=tangent)
            for dofs, vals in cs.grad:
                np.add.at(f_c, dofs, vals)
        if tangent:
            K = np.zeros(self.pattern.nnz)
            if self.scatter is not None:
                self.scatter.scatter_matrix(ev.stiffness, self.pattern.map_el, K)
            else:
                K += np.bincount(self.pattern.map_el.ravel(), weights=ev.stiffness.ravel(), minlength=self.pattern.nnz)
            if cs is not None and cs.hess:
                rows = np.concatenate([h[0] for h in cs.hess])
                cols = np.concatenate([h[1] for h in cs.hess])
                vals = np.concatenate([h[2] for h in cs.hess])
                np.add.at(K, self.pattern.position(rows, cols), vals)
        self.times["assembly"] += time.perf_counter() - toc
        return Evaluation(f_int, f_c, K, ev.history, cs, ev.theta)

    def impactor_displacement(self, q: np.ndarray) -> np.ndarray:
        """(3,) displacement of the impactor's reference point (m; zero along held axes)."""
        W = np.zeros(3)
        if self.has_w:
            W[self.axes] = q[self.imp_dofs]
        return W

    def impactor_point(self, q: np.ndarray) -> np.ndarray | None:
        """(3,) current reference point of the impactor (m), None without one."""
        if not self.has_w:
            return None
        return np.asarray(self.sphere.center, dtype=np.float64) + self.impactor_displacement(q)

    def zero_multipliers(self) -> tuple[np.ndarray, np.ndarray]:
        """Contact multipliers (N) of the sphere and plane candidate nodes, all zero."""
        return np.zeros(self.sphere_nodes.size), np.zeros(self.plane_nodes.size)

    def relaxed_history(self):
        """The undeformed, relaxed Prony state of every Gauss point (None when elastic)."""
        if self.parts is not None:
            return self.parts.relaxed()
        if not self.mat.k:
            return None
        if self.compiled is not None:
            return self.compiled.relaxed()
        return History.relaxed(self.mat.k, self.disc.w.size)
