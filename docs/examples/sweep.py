"""
A parameter sweep
=================

Peak acceleration against specimen thickness, from Python (SI units).

``cfm.sweep`` runs serially in this process (no Dask cluster) on a coarse mesh and returns the
table (``to_dataframe()``, units in the column names); with ``out`` it also writes the files of
``cfm sweep`` there, read back here with pandas. ``cfm sweep --vary thickness=0.005,0.008 --out
DIR`` does the same from the shell, on a local Dask cluster. Run: ``python docs/examples/sweep.py
OUT_DIR``.
"""

import sys
import tempfile

import pandas as pd

import cfm_core as cfm


def main(out: str | None = None, plot: bool = False) -> float:
    """Ratio of the peak at 5 mm to the peak at 8 mm (-)."""
    out = out or tempfile.mkdtemp(prefix="cfm-sweep-")
    scene = cfm.builtin_scene("drop-test").with_overrides(element_size=0.002)
    study = cfm.sweep(scene, vary={"thickness": [0.005, 0.008]}, out=out)
    print(study.to_dataframe()[["thickness [m]", "peak_g [g]", "run_time [s]"]])
    table = pd.read_csv(f"{out}/sweep.csv", comment="#")
    peaks = table.set_index("thickness [m]")["peak_g [g]"]
    if plot:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
        ax.plot(1e3 * peaks.index, peaks.values, "o-", label="simulated (2 mm hexahedra)")
        ax.plot([5.0, 8.0], [80.7, 52.5], "s--", label="experiment (paper, section 4)")
        ax.set_xlabel("Specimen thickness (mm)")
        ax.set_ylabel("Peak acceleration, CFC 600 (g)")
        ax.set_title("Peak against thickness, 1 m/s, 220 g, numba")
        ax.legend(frameon=False)
    return float(peaks[0.005] / peaks[0.008])


# %%
# Two drop tests, 5 mm and 8 mm, and their peaks beside the experiment's:
if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None, plot=True)
