"""Which energy term failed: evaluate a material's terms one by one where its derivatives are not finite.

A backend that finds an inf or NaN energy derivative knows only the eigenvalues m_a of C at the
failing point. :func:`nonfinite_term` re-evaluates each of the material's own terms there, separately
(isochoric terms at the isochoric principal stretches l_a = sqrt(m_a) J^(-1/3), the volumetric term
at J = sqrt(m1 m2 m3)), value and first derivatives with numpy in float64, and names the first one
that is not finite, with its inputs. :func:`describe_nonfinite` turns that into the sentence every
backend puts in its :class:`~cfm_core.errors.NumericalError`. Used only on the error path.
"""

from __future__ import annotations

import functools

import numpy as np


@functools.lru_cache(maxsize=64)
def _term_functions(term):
    """(value, gradient) numpy functions of one term in its kinematic variables and parameters."""
    import sympy as sp  # deferred: only a failing run (the error path) needs it, every run imports this module

    names = [p.name for p in term.parameters]
    params = sp.symbols(names, real=True) if names else ()
    params = tuple(params) if isinstance(params, (list, tuple)) else (params,)
    if term.kind == "isochoric":
        kin = sp.symbols("l1 l2 l3", positive=True)
    else:
        kin = (sp.Symbol("J", positive=True),)
    expr = term.energy(*kin, *params)
    grad = [sp.diff(expr, k) for k in kin]
    value = sp.lambdify((*kin, *params), expr, modules="numpy")
    gradient = sp.lambdify((*kin, *params), grad, modules="numpy")
    return value, gradient


def term_inputs(m) -> dict:
    """Kinematic inputs of the energy terms at a point.

    Parameters
    ----------
    m : array_like, shape (3,)
        Eigenvalues of C (-).

    Returns
    -------
    dict
        ``J`` = sqrt(m1 m2 m3) (-) and ``stretches``: the isochoric principal stretches
        sqrt(m_a) J^(-1/3) (-), a 3-tuple.
    """
    m = np.asarray(m, dtype=np.float64).reshape(3)
    with np.errstate(all="ignore"):
        J = np.sqrt(m[0]) * np.sqrt(m[1]) * np.sqrt(m[2])
        lam = np.sqrt(m) * J ** (-1.0 / 3.0)  # numpy power: J = 0 gives inf, not a ZeroDivisionError
        J = float(J)
    return {"J": J, "stretches": tuple(float(v) for v in lam)}


def nonfinite_term(material, m):
    """The first term of ``material`` whose energy or first derivative is not finite at m.

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material (its spec's isochoric terms, then its volumetric term).
    m : array_like, shape (3,)
        Eigenvalues of C = F^T F (-) at the failing point.

    Returns
    -------
    tuple or None
        (term, inputs, what): the failing :class:`~cfm_core.material.spec.Term`, a dict of its
        kinematic inputs and parameter values (SI), and which quantity is not finite ("energy"
        or "derivative"); None when J is not a positive finite number (the failure lies in the
        kinematics, e.g. J = 0) or every term is finite there (then it lies in the sum of finite
        terms).
    """
    spec = getattr(material, "spec", None)
    if spec is None or not hasattr(material, "values"):
        return None  # not a Material made of declared terms (e.g. a test stand-in with its own code)
    inp = term_inputs(m)
    if not (0.0 < inp["J"] < np.inf):
        return None  # J = 0 (or inf, NaN): the kinematics failed before any term (describe_nonfinite says so)
    terms = list(spec.isochoric) + ([spec.volumetric] if spec.volumetric is not None else [])
    for term in terms:
        value, gradient = _term_functions(term)
        pvals = [float(material.values[p.name]) for p in term.parameters]
        kin = inp["stretches"] if term.kind == "isochoric" else (inp["J"],)
        with np.errstate(all="ignore"):
            try:
                e = np.asarray(value(*kin, *pvals), dtype=np.float64)
                g = np.asarray(gradient(*kin, *pvals), dtype=np.float64)
            except (OverflowError, ZeroDivisionError, ValueError):
                e, g = np.array(np.inf), np.array(np.inf)
        inputs = dict(zip(("l1", "l2", "l3") if term.kind == "isochoric" else ("J",), kin))
        inputs.update(zip([p.name for p in term.parameters], pvals))
        if not np.isfinite(e).all():
            return term, inputs, "energy"
        if not np.isfinite(g).all():
            return term, inputs, "derivative"
    return None


def describe_nonfinite(material, m) -> str:
    """One sentence naming the failing term of ``material`` at eigenvalues m (3,) of C and its inputs.

    Parameters
    ----------
    material : cfm_core.material.Material
        The bound material.
    m : array_like, shape (3,)
        Eigenvalues of C (-).

    Returns
    -------
    str
        E.g. "the volumetric term 'ogden-volumetric' of material 'cfm' is not finite (its
        derivative) at J = 1e-32 (kappa = 6.661e+05 Pa): ...". Without a failing term, the
        kinematic inputs and a note that the terms are finite there.
    """
    found = nonfinite_term(material, m)
    inp = term_inputs(m)
    ev = ", ".join(f"{v:.4g}" for v in np.asarray(m, dtype=np.float64).reshape(3))
    if found is None and not (0.0 < inp["J"] < np.inf):
        return (f"the eigenvalues of C = ({ev}) of material '{material.name}' give J = {inp['J']:.4g}: the point is "
                f"crushed to no volume (or C = F^T F lost its positive definiteness to underflow or round-off), so no "
                f"energy term can be evaluated; lower the load or check the deformation")
    if found is None:
        if getattr(material, "spec", None) is None:
            return (f"the energy derivatives of material '{material.name}' overflow (inf or NaN) at the "
                    f"eigenvalues of C = ({ev}), J = {inp['J']:.4g}; lower the load or check the parameters")
        return (f"every term of material '{material.name}' is finite at the eigenvalues of C = ({ev}), J = "
                f"{inp['J']:.4g}, but their combination is not (an overflow in J or the isochoric split J^(-1/3), "
                f"or in the sum of the terms)")
    term, inputs, what = found
    units = {p.name: p.unit for p in term.parameters}
    args = ", ".join(f"{k} = {v:.4g}" + (f" {units[k]}" if units.get(k) not in (None, "", "-") else "")
                     for k, v in inputs.items())
    hint = ("J -> 0 or J -> infinity makes a volumetric energy overflow: the element or point is crushed "
            "to (almost) no volume or blown up; lower the load or check the bulk modulus"
            if term.kind == "volumetric" else
            "an exponential or power of the stretches exceeds the float64 range (exp overflows above "
            "an argument of 709): lower the load or check the parameters")
    return (f"the {term.kind} term '{term.name}' of material '{material.name}' has a non-finite {what} at "
            f"{args} (eigenvalues of C = ({ev})): {hint}")
