"""Volumetric terms U(J) (energy per reference volume, Pa)."""

from cfm_core.material.parameters import positive
from cfm_core.material.sym import log
from cfm_core.material.terms import volumetric

KAPPA = positive("kappa", "Pa", 666.1e3, "bulk modulus (paper Table 1: 666.1 kPa)")


@volumetric(KAPPA, name="ogden-volumetric")
def ogden_volumetric(J, kappa):
    """Ogden (1972) with beta = 9 (paper Eq. 7): kappa/81 (9 ln J + J^-9 - 1)."""
    return kappa / 81 * (9 * log(J) + J**-9 - 1)


@volumetric(KAPPA, name="quadratic-volumetric")
def quadratic_volumetric(J, kappa):
    """Quadratic penalty kappa/2 (J - 1)^2."""
    return kappa / 2 * (J - 1) ** 2
