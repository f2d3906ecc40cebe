"""
A new material in ten lines
===========================

A Yeoh term with the Ogden volumetric term (SI units).

The energy is written once with the symbolic helpers of :mod:`cfm_core.material.sym` (here plain
arithmetic is enough); stress and tangent come from exact derivatives, on every backend.
Run: ``python docs/examples/new_material.py``.
"""

import numpy as np

import cfm_core as cfm
from cfm_core.material import reference
from cfm_plugins.volumetric import ogden_volumetric


@cfm.isochoric(cfm.positive("c1", "Pa", 500.0, "initial shear modulus / 2"),
               cfm.nonnegative("c2", "Pa", 50.0, "second Yeoh coefficient"))
def yeoh(l1, l2, l3, c1, c2):
    i1 = l1**2 + l2**2 + l3**2  # first invariant of the isochoric C
    return c1 * (i1 - 3) + c2 * (i1 - 3) ** 2


def main() -> float:
    """Cauchy stress sigma_11 (Pa) of the Yeoh material at F = diag(0.8, 1.1, 1.1)."""
    cfm.register_material((yeoh & ogden_volumetric).named("yeoh-example", "Yeoh + Ogden volumetric"),
                          overwrite=True)
    material = cfm.make_material("yeoh-example", {"c1": 400.0})
    sigma = reference.cauchy(material, np.diag([0.8, 1.1, 1.1]))[0]  # a batch of one: (1, 3, 3) -> (3, 3)
    print(f"sigma_11 = {sigma[0, 0]:.2f} Pa, sigma_22 = {sigma[1, 1]:.2f} Pa")
    return float(sigma[0, 0])


# %%
# Register the material and evaluate its Cauchy stress at one deformation:
if __name__ == "__main__":
    main()
