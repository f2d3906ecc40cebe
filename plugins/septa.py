"""Septa fibres: the isotropic collagen network between the fat lobules (paper, section 5 outlook).

The paper's CFM leaves out the septa, "a three-dimensional network of collagen fibers with no
preferred orientation", and expects them to matter at large deformation. Here they are
tension-only fibres whose directions n are spread uniformly over the unit sphere, each with the
exponential (HGO-type) law of the CFM's own fibres, averaged over all directions:

    W_septa = < f(I4(n)) >,   < . > = 1/(4 pi) int_{S^2} . dOmega              (energy, Pa)
    f(I4) = k1s / (2 k2s) [exp(k2s (I4 - 1)^2) - 1]   if I4 >= 1, else 0      (tension only)
    I4(n) = sum_a l_a^2 n_a^2,   I4 - 1 = sum_a n_a^2 (l_a^2 - 1)

with l_a the isochoric principal stretches and n written in the principal frame. Because the
distribution is isotropic, the mean is a symmetric function of (l1, l2, l3), so the term is an
ordinary isochoric term and runs on every backend. The mean is computed with an octahedrally
symmetric sphere rule of stated degree (:mod:`cfm_plugins.sphere_quadrature`, default degree 17,
110 directions, 19 distinct squared directions): permutation-closed with equal weights, so the
sum is symmetric in the stretches. The squared components are rounded to 40-bit dyadic numbers
summing to exactly 1, so that I4 - 1 is exactly 0 in floating point at the reference state, where every fibre sits on the switch (as in the CFM, the active side
is taken at I4 = 1: value and slope of f vanish there, its second derivative jumps from 0 to k1s).

Small-strain stiffness: with all fibres counted active, the initial shear modulus of the term is
4 k1s <n1^2 n2^2> = 4 k1s / 15; a real small deformation stretches half of the fibres, so it is
k1s * 2/15 in effect. The quadrature error comes from the switch (the integrand is C^1 across the
cone I4 = 1, not a polynomial): measured against an adaptive integration split at the cone in
``tests/plugins/test_septa.py``.

Parameters (SI): k1s (Pa, > 0, default 17970) fibre stiffness, k2s (-, > 0, default 1.80)
stiffening exponent; the defaults are the fit of the two parameters to the paper's two peaks
(docs/user/septa.md): matched, not confirmed, and the early loading of the drop test is then too stiff.
Under the "long-term" moduli convention they are relaxed values, like c and k1 (the Prony series
acts on the whole isochoric energy).
"""

from fractions import Fraction

from cfm_core.material.parameters import positive
from cfm_core.material.sym import exp, where
from cfm_core.material.terms import isochoric

from .cfm import TABLE1_PRONY, circular_fibers, lipid
from .sphere_quadrature import POINTS, squared_directions
from .volumetric import ogden_volumetric

#: Degree of the default sphere rule (110 directions on the sphere).
DEGREE = 17
#: Squared direction components are rounded to multiples of 2^-BITS (moments move by ~1e-12): sympy
#: expands a (l1^2 - 1) + b (l2^2 - 1) + c (l3^2 - 1) into a l1^2 + b l2^2 + c l3^2 - (a + b + c), and
#: only with exactly representable a, b, c summing to 1 (passed as exact fractions, so that the
#: generated code prints them exactly) is I4 - 1 exactly 0 at the reference state (every fibre
#: then takes the active side of the switch, as the CFM's fibres do).
BITS = 40
#: Defaults: the calibration to the paper's two peaks (80.7 g at 5 mm, 52.5 g at 8 mm) with the CFM part at
#: Table 1 (docs/user/septa.md, docs/septa/calibration.json). Two numbers for two parameters: matched, not confirmed.
K1S = positive("k1s", "Pa", 17970.0, "septa fibre stiffness, tension only (default: fitted to the paper's two peaks)")
K2S = positive("k2s", "-", 1.80, "septa fibre stiffening exponent (default: fitted to the paper's two peaks)")


def septa_term(degree: int = DEGREE):
    """The septa-fibre isochoric term integrated with the sphere rule of ``degree``.

    Parameters
    ----------
    degree : int
        Degree of the octahedral sphere rule, 11, 15 or 17 (50, 86 or 110 directions).

    Returns
    -------
    Term
        Isochoric term named ``septa-fibers`` (degree 17) or ``septa-fibers-<degree>``, parameters
        k1s (Pa) and k2s (-); energy in Pa (module docstring).
    """
    weights, squares = squared_directions(degree, bits=BITS)

    def energy(l1, l2, l3, k1s, k2s):
        """Mean tension-only exponential fibre energy over the rule's directions.

        Parameters
        ----------
        l1, l2, l3 : sympy expression
            Isochoric principal stretches (-).
        k1s : sympy expression
            Fibre stiffness (Pa).
        k2s : sympy expression
            Stiffening exponent (-).

        Returns
        -------
        sympy expression
            Energy per reference volume (Pa).
        """
        total = 0
        for w, row in zip(weights, squares):
            a, b, c = (Fraction(float(x)) for x in row)  # exact: printed as p/q, not as 15 digits
            e = a * (l1**2 - 1) + b * (l2**2 - 1) + c * (l3**2 - 1)  # I4 - 1 of this direction
            total += float(w) * where(e >= 0, k1s / (2 * k2s) * (exp(k2s * e**2) - 1), 0)
        return total

    name = "septa-fibers" if degree == DEGREE else f"septa-fibers-{degree}"
    return isochoric(K1S, K2S, name=name,
                     description=f"isotropic tension-only septa fibres, exponential law, sphere rule of degree "
                                 f"{degree} ({POINTS[degree]} directions)")(energy)


septa_fibers = septa_term()

CFM_SEPTA = (lipid & circular_fibers & septa_fibers & ogden_volumetric & TABLE1_PRONY).named(
    "cfm-septa", "CFM + isotropic tension-only septa fibres (exponential law, 110-direction sphere rule of "
    "degree 17); Table 1 for the CFM part, septa fitted to the paper's two drop-test peaks")
