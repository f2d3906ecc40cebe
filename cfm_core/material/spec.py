"""Material declarations: energy terms (:class:`Term`) and their composition (:class:`MaterialSpec`).

A term is an author's energy function of the isochoric principal stretches (``isochoric``) or of J
(``volumetric``) with its parameter declarations; a spec is isochoric terms + at most one
volumetric term + an optional Prony series, composed with ``&`` (FElupe style). A spec is traced
symbolically once (:mod:`cfm_core.material.codegen`) and checked (isotropy, stress-free reference)
when it is registered or first used. Binding values gives a :class:`~cfm_core.material.Material`.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
from dataclasses import dataclass
from typing import Callable

import numpy as np
import sympy as sp

from ..errors import InputError
from . import codegen
from .cache import codegen_cache
from .material import Material
from .parameters import Parameter
from .prony import PronySeries

MODULI = ("instantaneous", "long-term")
_RESERVED = {"m1", "m2", "m3", "p", "J", "s_iso", "zero_", "math", "numpy", "torch"}


@dataclass(frozen=True)
class Term:
    """One energy term.

    kind: "isochoric" (energy of l1, l2, l3) or "volumetric" (energy of J).
    energy: the author's function; called once with sympy symbols.
    parameters: declarations of the keyword arguments after the kinematic ones.
    """

    name: str
    kind: str
    energy: Callable
    parameters: tuple[Parameter, ...]
    description: str = ""

    def __post_init__(self):
        if self.kind not in ("isochoric", "volumetric"):
            raise InputError(f"term '{self.name}': kind must be 'isochoric' or 'volumetric', got {self.kind!r}.")
        n_kin = 3 if self.kind == "isochoric" else 1
        sig = inspect.signature(self.energy).parameters
        if any(a.kind is inspect.Parameter.VAR_POSITIONAL for a in sig.values()):
            return  # f(l1, l2, l3, *params): parameters passed by position in declaration order
        args = list(sig)
        declared = [p.name for p in self.parameters]
        if args[n_kin:] != declared:
            expected = "(l1, l2, l3, ...)" if n_kin == 3 else "(J, ...)"
            raise InputError(
                f"term '{self.name}': the energy function's arguments {args} must be the kinematic "
                f"arguments {expected} followed by the declared parameters {declared} in the same order."
            )

    def __and__(self, other):
        return MaterialSpec.compose(self.name, (self,)) & other


@dataclass(frozen=True)
class MaterialSpec:
    """Declaration of a material: energy terms, Prony series and defaults (no values bound)."""

    name: str
    isochoric: tuple = ()
    volumetric: object = None
    prony: PronySeries | None = None
    description: str = ""
    default_moduli: str = "long-term"

    @classmethod
    def compose(cls, name, terms, prony=None, description=""):
        """Build a spec from a sequence of terms (at most one volumetric)."""
        spec = cls(name=name, description=description, prony=prony)
        for t in terms:
            spec = spec & t
        return spec

    def __and__(self, other):
        if isinstance(other, PronySeries):
            if self.prony is not None:
                raise InputError(f"material '{self.name}' already has a Prony series.")
            return _replace(self, prony=other)
        if isinstance(other, Term):
            if other.kind == "isochoric":
                return _replace(self, isochoric=self.isochoric + (other,))
            if self.volumetric is not None:
                raise InputError(
                    f"material '{self.name}' already has the volumetric term '{self.volumetric.name}'; "
                    f"cannot add '{other.name}' (one volumetric term per material)."
                )
            return _replace(self, volumetric=other)
        raise InputError(f"cannot compose material '{self.name}' with {other!r}: expected a Term or PronySeries.")

    def named(self, name: str, description: str = "") -> "MaterialSpec":
        """The same spec under another name (and description)."""
        return _replace(self, name=name, description=description or self.description)

    @functools.cached_property
    def energy_parameters(self) -> tuple[Parameter, ...]:
        """Parameters of the energy terms, each name once, in order of appearance."""
        seen: dict[str, Parameter] = {}
        for term in self.isochoric + ((self.volumetric,) if self.volumetric else ()):
            for p in term.parameters:
                if p.name in _RESERVED:
                    raise InputError(f"term '{term.name}': parameter name '{p.name}' is reserved; rename it.")
                if p.name in seen and seen[p.name] != p:
                    raise InputError(
                        f"material '{self.name}': parameter '{p.name}' is declared twice with different "
                        f"unit, default or range ({seen[p.name]} vs {p}); give one of them another name."
                    )
                seen[p.name] = p
        return tuple(seen.values())

    @property
    def parameters(self) -> tuple[Parameter, ...]:
        """All parameters: energy terms first, then the Prony series (g1, tau1, ...)."""
        return self.energy_parameters + (self.prony.parameters if self.prony else ())

    def bind(self, parameters: dict | None = None, moduli: str | None = None, elastic: bool = False) -> "Material":
        """A :class:`Material` with defaults overridden by ``parameters`` (name -> value, SI units)."""
        moduli = self.default_moduli if moduli is None else moduli
        if moduli not in MODULI:
            raise InputError(f"moduli = {moduli!r} is not allowed; use one of {', '.join(MODULI)}.")
        decl = {p.name: p for p in self.parameters}
        values = {p.name: p.default for p in self.parameters}
        for key, value in (parameters or {}).items():
            if key not in decl:
                raise InputError(
                    f"material '{self.name}' has no parameter '{key}' (given {value!r}); "
                    f"its parameters are: {', '.join(decl) or 'none'}."
                )
            values[key] = decl[key].check(value, context=f"material '{self.name}' parameter")
        return Material(self, values, moduli, bool(elastic) or self.prony is None)

    @functools.cached_property
    def symbolic(self):
        """(psi_iso, psi_vol, parameter names) as sympy expressions in m1, m2, m3."""
        names = [p.name for p in self.energy_parameters] + ["s_iso"]
        syms = {n: sp.Symbol(n, real=True) for n in names}
        iso, vol = codegen.energies(self.isochoric, self.volumetric, syms)
        return iso, vol, names

    @functools.cached_property
    def derivatives(self):
        """Dict of generated-function name -> sympy expressions (see :mod:`cfm_core.material.codegen`)."""
        iso, vol, _ = self.symbolic
        return codegen.derivative_table(iso, vol)

    @functools.lru_cache(maxsize=None)
    def source(self, dialect: str) -> str:
        """Generated module source for ``dialect`` ("math", "numpy" or "torch").

        Sources are cached on disk (see :mod:`cfm_core.material.cache`) under a fingerprint of the terms'
        code, so sympy differentiates a material once per machine, not once per run.
        """
        return codegen_cache(self, dialect, lambda: codegen.module_source(self.derivatives, self.symbolic[2], dialect))

    @functools.lru_cache(maxsize=None)
    def kernels(self, dialect: str):
        """Namespace with psi_energy, psi_grad, psi_hess_diag, psi_hess compiled from ``source``."""
        src = self.source(dialect)
        namespace: dict = {}
        code = compile(src, f"<cfm material {self.name} ({dialect})>", "exec")
        exec(code, namespace)  # generated from the symbolic energy only
        kernels = _Kernels(namespace)
        if dialect == "numpy":
            check_spec(self, kernels)
        return kernels

    def fingerprint(self) -> str:
        """Hash of the generated scalar code (identifies compiled kernels in caches)."""
        return hashlib.sha256(self.source("math").encode()).hexdigest()[:16]

    def __hash__(self):
        return hash((self.name, id(self)))

    def __eq__(self, other):
        return self is other


@dataclass(frozen=True)
class _Kernels:
    namespace: dict

    def __getattr__(self, item):
        try:
            return self.namespace[item]
        except KeyError:
            raise AttributeError(item) from None


def check_spec(spec: MaterialSpec, kernels) -> None:
    """Check a spec against what every backend assumes: isotropy and a stress-free reference.

    The energy must be symmetric in the principal stretches, and its gradient must vanish at
    C = I for the default parameters. Raises InputError naming the material.
    """
    p = np.array([q.default for q in spec.energy_parameters] + [1.0])
    m = np.array([[1.3, 0.8, 1.1], [0.7, 1.2, 0.95]])
    with np.errstate(all="ignore"):
        base = np.stack(kernels.psi_energy(m[:, 0], m[:, 1], m[:, 2], p))
        for perm in ((1, 0, 2), (0, 2, 1), (2, 1, 0)):
            other = np.stack(kernels.psi_energy(m[:, perm[0]], m[:, perm[1]], m[:, perm[2]], p))
            if not np.allclose(base, other, rtol=1e-9, atol=1e-12 * np.abs(base).max()):
                raise InputError(
                    f"material '{spec.name}': the energy is not symmetric in the principal stretches "
                    f"(swapping stretches {perm} changes it); isotropic terms must treat l1, l2, l3 alike.")
        one = np.ones(1)
        g = np.stack(kernels.psi_grad(one, one, one, p))
        h = np.stack(kernels.psi_hess(one, one, one, p))
    if not np.isfinite(g).all() or np.abs(g).max() > 1e-8 * max(np.abs(h).max(), 1.0):
        raise InputError(
            f"material '{spec.name}': the reference state C = I is not stress-free (d psi / d m = "
            f"{g.ravel().tolist()} Pa); a volumetric term needs U'(1) = 0.")


def _replace(spec: MaterialSpec, **changes) -> MaterialSpec:
    fields = dict(name=spec.name, isochoric=spec.isochoric, volumetric=spec.volumetric,
                  prony=spec.prony, description=spec.description, default_moduli=spec.default_moduli)
    fields.update(changes)
    return MaterialSpec(**fields)


