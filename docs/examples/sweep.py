"""A parameter sweep from Python: peak acceleration against specimen thickness (SI units).

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


def main(out: str | None = None) -> float:
    """Ratio of the peak at 5 mm to the peak at 8 mm (-)."""
    out = out or tempfile.mkdtemp(prefix="cfm-sweep-")
    scene = cfm.builtin_scene("drop-test").with_overrides(element_size=0.002)
    study = cfm.sweep(scene, vary={"thickness": [0.005, 0.008]}, out=out)
    print(study.to_dataframe()[["thickness [m]", "peak_g [g]", "run_time [s]"]])
    table = pd.read_csv(f"{out}/sweep.csv")
    peaks = table.set_index("thickness [m]")["peak_g [g]"]
    return float(peaks[0.005] / peaks[0.008])


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
