"""
The material-point driver
=========================

The CFM in uniaxial compression at two strain rates (SI units).

Uniaxial stress (lateral tractions zero, solved each step) at constant engineering strain rate to
a stretch of 0.7; the nominal stress at the end shows the rate dependence of the Prony series
(paper Eq. 8). Run: ``python docs/examples/point_driver.py``.
"""

import cfm_core as cfm
from cfm_core.simulation.point import uniaxial


def main(plot: bool = False) -> float:
    """Nominal stress (Pa) at stretch 0.7 and 100 /s; prints both rates."""
    material = cfm.make_material("cfm")  # Table 1 parameters, long-term moduli
    final, curves = {}, {}
    for rate in (1.0, 100.0):  # engineering strain rate, 1/s
        t, stretch, nominal, lateral = uniaxial(material, rate=rate, stretch=0.7, steps=100)
        final[rate], curves[rate] = nominal[-1], (stretch, nominal)
        print(f"rate {rate:5g} /s: nominal stress {nominal[-1]:9.1f} Pa at stretch {stretch[-1]:.2f} "
              f"(lateral stretch {lateral[-1]:.4f}) after {t[-1]:.3g} s")
    if plot:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
        for rate, (stretch, nominal) in curves.items():
            ax.plot(stretch, 1e-3 * nominal, label=f"{rate:g} 1/s")
        ax.set_xlabel("Stretch (-)")
        ax.set_ylabel("Nominal stress (kPa)")
        ax.set_title("CFM, Table 1, uniaxial compression")
        ax.legend(title="strain rate", loc="lower right", frameon=False)
    return float(final[100.0])


# %%
# Compression at 1 /s and 100 /s: the faster test meets the unrelaxed Prony terms.
if __name__ == "__main__":
    main(plot=True)
