"""The circular fiber model (CFM) of Lanzl et al. for subcutaneous adipose tissue.

The energy::

    Psi = W_lipid + W_RBM + U(J)                                      (paper Eq. 1, 7)
    W_lipid = c/2 (l1^2 + l2^2 + l3^2 - 3)                            (Eq. 2)
    W_RBM = sum over (a,b) in (1,2), (2,3), (1,3) of
            k1/(2 k2) [exp(k2 (x_ab - 1)^2) - 1]  if x_ab >= 1, else 0  (Eq. 3-6)
    x_ab = (l_a^2 + l_b^2)/2, l_a the isochoric principal stretches

with the Ogden volumetric term (beta = 9) and a three-term Prony series on the isochoric part.
Defaults: Table 1 of the paper in SI units (c = 10 Pa, k1 = 1320 Pa, k2 = 1.66, kappa = 666.1 kPa,
(g, tau) = (0.45, 1 ms), (0.435, 0.1 s), (0.094, 10 s)).
"""

from cfm_core.material.parameters import positive
from cfm_core.material.prony import PronySeries
from cfm_core.material.sym import exp, where
from cfm_core.material.terms import isochoric

from .neo_hookean import neo_hookean
from .volumetric import ogden_volumetric


@isochoric(positive("c", "Pa", 10.0, "lipid modulus (Table 1: 0.01 kPa)"), name="lipid")
def lipid(l1, l2, l3, c):
    """Neo-Hookean lipid of the adipocytes (paper Eq. 2).

    W_lipid = c/2 (l1^2 + l2^2 + l3^2 - 3).

    Parameters
    ----------
    l1, l2, l3 : sympy.Expr
        Isochoric principal stretches (-), symbols when traced.
    c : sympy.Expr
        Lipid modulus (Pa); Table 1: 10 Pa.

    Returns
    -------
    sympy.Expr
        Energy per reference volume (Pa).
    """
    return neo_hookean.energy(l1, l2, l3, c)  # the Neo-Hookean energy with c as its modulus


def fibre_family(x, k1, k2):
    """One tension-only circular fibre family of squared-stretch measure x (paper Eq. 3-6).

    k1/(2 k2) [exp(k2 (x - 1)^2) - 1] for x >= 1, else 0 (C^1 at x = 1; docs/conventions.md
    section 2).

    Parameters
    ----------
    x : sympy.Expr
        Squared-stretch measure (l_a^2 + l_b^2) / 2 of a stretch pair (-).
    k1 : sympy.Expr
        Reinforced basement membrane stiffness (Pa); Table 1: 1320 Pa.
    k2 : sympy.Expr
        Fibre stiffening exponent (-); Table 1: 1.66.

    Returns
    -------
    sympy.Piecewise
        Energy per reference volume (Pa).
    """
    return where(x >= 1, k1 / (2 * k2) * (exp(k2 * (x - 1) ** 2) - 1), 0)


@isochoric(positive("k1", "Pa", 1320.0, "reinforced basement membrane stiffness (Table 1: 1.32 kPa)"),
           positive("k2", "-", 1.66, "fibre stiffening exponent (Table 1)"), name="circular-fibers")
def circular_fibers(l1, l2, l3, k1, k2):
    """Three circular fibre families of the reinforced basement membrane (paper Eq. 3-6).

    W_RBM = sum over the stretch pairs (1, 2), (2, 3), (1, 3) of :func:`fibre_family` of
    x_ab = (l_a^2 + l_b^2) / 2.

    Parameters
    ----------
    l1, l2, l3 : sympy.Expr
        Isochoric principal stretches (-), symbols when traced.
    k1 : sympy.Expr
        Reinforced basement membrane stiffness (Pa); Table 1: 1320 Pa.
    k2 : sympy.Expr
        Fibre stiffening exponent (-); Table 1: 1.66.

    Returns
    -------
    sympy.Expr
        Energy per reference volume (Pa).
    """
    pairs = ((l1, l2), (l2, l3), (l1, l3))
    return sum(fibre_family((a**2 + b**2) / 2, k1, k2) for a, b in pairs)


TABLE1_PRONY = PronySeries(((0.45, 1e-3), (0.435, 0.1), (0.094, 10.0)))

CFM = (lipid & circular_fibers & ogden_volumetric & TABLE1_PRONY).named(
    "cfm", "circular fiber model for adipose tissue (Lanzl et al.): lipid + 3 circular fibre families "
    "+ Ogden volumetric + 3-term Prony series, Table 1 defaults")
