"""Volumetric terms U(J) (energy per reference volume, Pa)."""

from cfm_core.material.parameters import positive
from cfm_core.material.sym import log
from cfm_core.material.terms import volumetric

KAPPA = positive("kappa", "Pa", 666.1e3, "bulk modulus (paper Table 1: 666.1 kPa)")


@volumetric(KAPPA, name="ogden-volumetric")
def ogden_volumetric(J, kappa):
    """Ogden (1972) with beta = 9 (paper Eq. 7): kappa/81 (9 ln J + J^-9 - 1).

    U(1) = U'(1) = 0, U''(1) = kappa; not convex for J > 10^(1/9) (docs/conventions.md section 2).

    Parameters
    ----------
    J : sympy.Expr
        Volume ratio det F (-).
    kappa : sympy.Expr
        Bulk modulus (Pa); Table 1: 666.1 kPa.

    Returns
    -------
    sympy.Expr
        Energy per reference volume (Pa).
    """
    return kappa / 81 * (9 * log(J) + J**-9 - 1)


@volumetric(KAPPA, name="quadratic-volumetric")
def quadratic_volumetric(J, kappa):
    """Quadratic penalty kappa/2 (J - 1)^2.

    Parameters
    ----------
    J : sympy.Expr
        Volume ratio det F (-).
    kappa : sympy.Expr
        Bulk modulus (Pa); default 666.1 kPa.

    Returns
    -------
    sympy.Expr
        Energy per reference volume (Pa).
    """
    return kappa / 2 * (J - 1) ** 2
