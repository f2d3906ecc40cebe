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

from ..errors import InputError
from .cache import codegen_cache
from .material import Material
from .parameters import Parameter
from .prony import PronySeries

MODULI = ("instantaneous", "long-term")
_RESERVED = {"m1", "m2", "m3", "p", "J", "s_iso", "zero_", "math", "numpy", "torch"}


@dataclass(frozen=True)
class Term:
    """One energy term (made by the ``@isochoric`` / ``@volumetric`` decorators).

    Terms compose with ``&`` into a :class:`MaterialSpec` (``lipid & circular_fibers``).

    Parameters
    ----------
    name : str
        Registry name, e.g. ``"lipid"``.
    kind : {"isochoric", "volumetric"}
        "isochoric": energy of the isochoric principal stretches l1, l2, l3 (-); "volumetric":
        energy of J (-).
    energy : callable
        The author's function ``f(l1, l2, l3, *params)`` or ``U(J, *params)`` returning the
        energy per reference volume (Pa); called once with sympy symbols.
    parameters : tuple of Parameter
        Declarations of the arguments after the kinematic ones, in the same order.
    description : str
        One line for ``cfm materials``.

    Raises
    ------
    InputError
        ``kind`` is neither "isochoric" nor "volumetric", or the energy's arguments are not the
        kinematic ones followed by the declared parameters in order (unless it takes ``*params``).
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
    """Declaration of a material: energy terms, Prony series and defaults (no values bound).

    Built by composing with ``&`` (a Term, another term, a :class:`PronySeries`); composing a
    second volumetric term or a second Prony series raises InputError. Two specs are equal only
    if they are the same object.

    Parameters
    ----------
    name : str
        Registry name, e.g. ``"cfm"``.
    isochoric : tuple of Term
        Isochoric terms, summed (W in psi = W + U).
    volumetric : Term or None
        At most one volumetric term U(J).
    prony : PronySeries or None
        Viscoelasticity on the isochoric stress (docs/conventions.md section 2).
    description : str
        One line for ``cfm materials``.
    default_moduli : {"long-term", "instantaneous"}
        Moduli convention used when :meth:`bind` is given none.
    """

    name: str
    isochoric: tuple = ()
    volumetric: object = None
    prony: PronySeries | None = None
    description: str = ""
    default_moduli: str = "long-term"

    @classmethod
    def compose(cls, name, terms, prony=None, description=""):
        """Build a spec from a sequence of terms (at most one volumetric).

        Parameters
        ----------
        name : str
            Registry name of the spec.
        terms : iterable of Term or PronySeries
            Composed in order with ``&``.
        prony : PronySeries, optional
            Prony series of the spec.
        description : str
            One line for ``cfm materials``.

        Returns
        -------
        MaterialSpec
            The composed spec (not yet traced or checked).

        Raises
        ------
        InputError
            Two volumetric terms, two Prony series, or an object that is neither a Term nor a
            PronySeries.
        """
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
        """The same spec under another name (and description).

        Parameters
        ----------
        name : str
            New name.
        description : str
            New description; empty keeps the current one.

        Returns
        -------
        MaterialSpec
            A new spec with the same terms and Prony series.
        """
        return _replace(self, name=name, description=description or self.description)

    @functools.cached_property
    def energy_parameters(self) -> tuple[Parameter, ...]:
        """Parameters of the energy terms, each name once, in order of appearance (the order of
        the parameter vector ``p`` of the generated code, before s_iso).

        Raises
        ------
        InputError
            A parameter name is reserved by the generated code (``m1``, ``J``, ``p``, ``s_iso``,
            ...), or one name is declared by two terms with different unit, default or range.
        """
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
        """A :class:`Material` with defaults overridden by ``parameters`` (name -> value, SI units).

        Parameters
        ----------
        parameters : dict of str to float, optional
            Overrides in SI units (Pa, s, -); the other parameters keep their defaults.
        moduli : {"long-term", "instantaneous"}, optional
            Moduli convention (docs/conventions.md section 2); default ``default_moduli``.
        elastic : bool
            Switch the Prony series off; always True for a spec without one.

        Returns
        -------
        Material
            The bound material.

        Raises
        ------
        InputError
            ``moduli`` not allowed, an unknown parameter name (the message lists the spec's
            parameters), a value outside its range, or Prony coefficients summing to 1 or more.
        """
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
        """(psi_iso, psi_vol, parameter names): the energies (Pa) as sympy expressions in m1, m2,
        m3 and the names of the parameter vector (energy parameters, then ``s_iso``); traced once
        per spec (:func:`cfm_core.material.codegen.energies`, InputError if untraceable)."""
        import sympy  # deferred (with codegen): needed only to trace an energy whose generated code is not cached

        from . import codegen

        names = [p.name for p in self.energy_parameters] + ["s_iso"]
        syms = {n: sympy.Symbol(n, real=True) for n in names}
        iso, vol = codegen.energies(self.isochoric, self.volumetric, syms)
        return iso, vol, names

    @functools.cached_property
    def derivatives(self):
        """Dict of generated-function name -> sympy expressions, Pa (see
        :func:`cfm_core.material.codegen.derivative_table`)."""
        from . import codegen  # deferred: imports sympy, needed only when the generated code is not cached

        iso, vol, _ = self.symbolic
        return codegen.derivative_table(iso, vol)

    @functools.lru_cache(maxsize=None)
    def source(self, dialect: str) -> str:
        """Generated module source for ``dialect`` ("math", "numpy" or "torch").

        Sources are cached on disk (see :mod:`cfm_core.material.cache`) under a fingerprint of the terms'
        code, so sympy differentiates a material once per machine, not once per run.

        Parameters
        ----------
        dialect : {"math", "numpy", "torch"}
            Target of the generated code.

        Returns
        -------
        str
            Module source defining psi_energy, psi_grad, psi_hess_diag, psi_hess and
            psi_grad_hess_diag (see :mod:`cfm_core.material.codegen`).

        Raises
        ------
        InputError
            An energy cannot be traced symbolically (names the term).
        """
        return codegen_cache(self, dialect, lambda: _generate(self, dialect))

    @functools.lru_cache(maxsize=None)
    def kernels(self, dialect: str):
        """Namespace with psi_energy, psi_grad, psi_hess_diag, psi_hess compiled from ``source``.

        Parameters
        ----------
        dialect : {"math", "numpy", "torch"}
            Target of the generated code; the first "numpy" compilation also runs
            :func:`check_spec`.

        Returns
        -------
        namespace
            Attribute access to the generated functions ``f(m1, m2, m3, p)`` (also
            psi_grad_hess_diag), cached per spec and dialect.

        Raises
        ------
        InputError
            An energy cannot be traced, or (numpy) the spec is not isotropic or its reference
            state is not stress-free.
        """
        src = self.source(dialect)
        namespace: dict = {}
        code = compile(src, f"<cfm material {self.name} ({dialect})>", "exec")
        exec(code, namespace)  # generated from the symbolic energy only
        kernels = _Kernels(namespace)
        if dialect == "numpy":
            check_spec(self, kernels)
        return kernels

    def fingerprint(self) -> str:
        """Hash of the generated scalar code (identifies compiled kernels in caches).

        Returns
        -------
        str
            16 hexadecimal characters (SHA-256 prefix of ``source("math")``).
        """
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

    The energy must be symmetric in the principal stretches (checked by swapping them at two
    sample states), and its gradient must vanish at C = I for the default parameters (below 1e-8
    times the largest Hessian entry there, or 1e-8 Pa).

    Parameters
    ----------
    spec : MaterialSpec
        The spec to check (its default parameter values, s_iso = 1).
    kernels : namespace
        Its numpy kernels (psi_energy, psi_grad, psi_hess).

    Raises
    ------
    InputError
        The energy changes when two stretches are swapped (not isotropic), or d psi / d m at
        C = I is not zero or not finite (a volumetric term needs U'(1) = 0); names the material.
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


def _generate(spec: MaterialSpec, dialect: str) -> str:
    """Generate the module source of ``spec`` for ``dialect`` (the cache-miss path of ``source``)."""
    from . import codegen  # deferred: imports sympy, needed only when the generated code is not cached

    return codegen.module_source(spec.derivatives, spec.symbolic[2], dialect)


def _replace(spec: MaterialSpec, **changes) -> MaterialSpec:
    fields = dict(name=spec.name, isochoric=spec.isochoric, volumetric=spec.volumetric,
                  prony=spec.prony, description=spec.description, default_moduli=spec.default_moduli)
    fields.update(changes)
    return MaterialSpec(**fields)


