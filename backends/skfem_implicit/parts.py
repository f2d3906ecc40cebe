"""Models with several parts: each part's material evaluated on its own elements, per Gauss point.

A part (:class:`cfm_core.scene.model.Part`) is a set of elements with its own material (its own
generated kernels, parameters and Prony series) and density. :class:`PartElements` evaluates each
part with the one-material evaluator (:class:`.compiled.CompiledElements`, or the numpy reference
:func:`.element.evaluate`) on the sub-discretisation of the part's elements, and writes element
forces (N), stiffnesses (N/m) and volume ratios into arrays in the model's element order: assembly,
contact and time stepping are the same as for one material. The Prony state is a tuple with one
entry per part (None for an elastic part). Element indices in errors are the model's.

The lumped mass with per-element density is :func:`.discretization.discretize` with the density
array (kg/m^3) of :meth:`cfm_core.scene.model.Model.element_density`.
"""

from __future__ import annotations

import numpy as np

from cfm_core.errors import InputError, NumericalError

from . import element
from .constitutive import Constitutive, History
from .discretization import Discretization
from .element import ElementState, Inverted


def subset(disc: Discretization, elements: np.ndarray) -> Discretization:
    """The discretisation of the elements ``elements`` (k,) of ``disc`` (same nodes; lumped masses unused)."""
    e = np.asarray(elements, dtype=np.int64)
    return Discretization(nodes=disc.nodes, conn=np.ascontiguousarray(disc.conn[e]),
                          dN=np.ascontiguousarray(disc.dN[e]), w=np.ascontiguousarray(disc.w[e]),
                          volume=disc.volume[e], mass=disc.mass, edofs=np.ascontiguousarray(disc.edofs[e]),
                          size=disc.size)


def check_parts(model) -> None:
    """InputError unless the model's parts have distinct names and cover every element exactly once
    with a density >= 0 (kg/m^3)."""
    names = [p.name for p in model.part_list()]
    if len(set(names)) != len(names):
        raise InputError(f"model '{model.name}': part names must differ; got {names}.")
    count = np.zeros(model.n_elements, dtype=np.int64)
    for p in model.part_list():
        idx = np.asarray(p.elements, dtype=np.int64).reshape(-1)
        if idx.size == 0 or idx.min() < 0 or idx.max() >= model.n_elements:
            raise InputError(f"model '{model.name}': part '{p.name}' must list element indices in "
                             f"0..{model.n_elements - 1} (got {idx.size} indices).")
        if not (float(p.density) >= 0.0 and np.isfinite(float(p.density))):
            raise InputError(f"model '{model.name}': part '{p.name}' density = {p.density!r} kg/m^3 must be "
                             f"finite and >= 0.")
        np.add.at(count, idx, 1)
    if not (count == 1).all():
        e = int(np.argmax(count != 1))
        raise InputError(f"model '{model.name}': element {e} belongs to {int(count[e])} parts; every element "
                         f"must belong to exactly one part.")


class PartElements:
    """All elements of a model with several parts (same results, per element, as one material each).

    Parameters
    ----------
    disc : Discretization
        The whole mesh.
    parts : sequence of Part
        The model's parts (:meth:`cfm_core.scene.model.Model.part_list`).
    volumetric : str
        "mean-dilatation" or "full" (:mod:`.element`).
    kernels : str
        "numba" (compiled, one generated module per material) or "numpy" (the reference).
    """

    def __init__(self, disc: Discretization, parts, volumetric: str = "mean-dilatation", kernels: str = "numba"):
        self.disc = disc
        self.names = [p.name for p in parts]
        self.index = [np.asarray(p.elements, dtype=np.int64).reshape(-1) for p in parts]
        self.mats = [Constitutive(p.material) for p in parts]
        self.subs = [subset(disc, i) for i in self.index]
        self.volumetric = volumetric
        self.compiled = None
        self.mod = None  # a generated module: its scatter kernels serve every part
        if kernels == "numba":
            from .compiled import CompiledElements

            self.compiled = [CompiledElements(s, p.material, volumetric) for s, p in zip(self.subs, parts)]
            self.mod = self.compiled[0].mod
        E = disc.n_elements
        self.fe = np.zeros((E, 24))
        self.Ke = np.zeros((E, 24, 24))

    @property
    def viscous(self) -> bool:
        """True when some part has a Prony series."""
        return any(m.k for m in self.mats)

    def kappa0(self) -> float:
        """Largest small-strain bulk modulus of the parts' materials (Pa)."""
        return max(float(m.volumetric(np.ones(1))[2][0]) for m in self.mats)

    def relaxed(self) -> tuple | None:
        """The undeformed, relaxed Prony state of every part (None for an elastic part; None when all are)."""
        if not self.viscous:
            return None
        out = []
        for i, m in enumerate(self.mats):
            if not m.k:
                out.append(None)
            elif self.compiled is not None:
                out.append(self.compiled[i].relaxed())
            else:
                out.append(History.relaxed(m.k, self.subs[i].w.size))
        return tuple(out)

    def nodal_forces(self, n: int) -> np.ndarray:
        """(parts, n) internal forces (N) of each part's elements from the last :meth:`evaluate`,
        assembled into vectors of n dofs (the nodes' first): the rows sum to f_int."""
        out = np.zeros((len(self.index), n))
        for i, idx in enumerate(self.index):
            m = 3 * self.disc.n_nodes
            out[i, :m] = np.bincount(self.disc.edofs[idx].ravel(), weights=self.fe[idx].ravel(), minlength=m)
        return out

    def evaluate(self, u: np.ndarray, hist: tuple | None, dt: float, *, tangent: bool = True) -> ElementState:
        """Element forces (E, 24) in N and stiffness (E, 24, 24) in N/m of every part at u (n, 3) in m.

        ``hist``: the tuple of :meth:`relaxed` (or a later one). The force and stiffness arrays are
        buffers reused by the next call. Raises :class:`.element.Inverted` or NumericalError with
        the model's element index.
        """
        hist = hist if hist is not None else (None,) * len(self.index)
        theta = np.empty(self.disc.n_elements)
        new = []
        for i, idx in enumerate(self.index):
            try:
                if self.compiled is not None:
                    ev = self.compiled[i].evaluate(u, hist[i], dt, tangent=tangent)
                else:
                    ev = element.evaluate(self.subs[i], self.mats[i], u, hist[i], dt, tangent=tangent,
                                          volumetric=self.volumetric)
            except Inverted as exc:
                raise Inverted(int(idx[exc.element]), exc.value) from None
            except NumericalError as exc:
                g = int(idx[exc.element]) if exc.element is not None else None
                raise NumericalError(f"{exc} [part '{self.names[i]}': its element {exc.element} is the model's "
                                     f"element {g}]", time=exc.time, element=g, quantity=exc.quantity) from None
            self.fe[idx] = ev.force
            if tangent:
                self.Ke[idx] = ev.stiffness
            theta[idx] = ev.theta
            new.append(ev.history)
        history = tuple(new) if self.viscous else None
        return ElementState(force=self.fe, stiffness=self.Ke if tangent else None, history=history, theta=theta)
