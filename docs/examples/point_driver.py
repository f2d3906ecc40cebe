"""Material-point driver: the CFM in uniaxial compression at two strain rates (SI units).

Uniaxial stress (lateral tractions zero, solved each step) at constant engineering strain rate
to a stretch of 0.7; the nominal stress at the end shows the rate dependence of the Prony series
(paper Eq. 8). Run: ``python docs/examples/point_driver.py``.
"""

import cfm_core as cfm
from cfm_core.simulation.point import uniaxial


def main() -> float:
    """Nominal stress (Pa) at stretch 0.7 and 100 /s; prints both rates."""
    material = cfm.make_material("cfm")  # Table 1 parameters, long-term moduli
    final = {}
    for rate in (1.0, 100.0):  # engineering strain rate, 1/s
        t, stretch, nominal, lateral = uniaxial(material, rate=rate, stretch=0.7, steps=100)
        final[rate] = nominal[-1]
        print(f"rate {rate:5g} /s: nominal stress {nominal[-1]:9.1f} Pa at stretch {stretch[-1]:.2f} "
              f"(lateral stretch {lateral[-1]:.4f}) after {t[-1]:.3g} s")
    return float(final[100.0])


if __name__ == "__main__":
    main()
