"""A parameter sweep from Python: peak acceleration against specimen thickness (SI units).

Runs serially in this process (no Dask cluster) on a coarse mesh, and reads the table back with
pandas. ``cfm sweep --vary thickness=0.005,0.008 --out DIR`` does the same from the shell, on a
local Dask cluster. Run: ``python docs/examples/sweep.py OUT_DIR``.
"""

import sys
import tempfile

import pandas as pd

import cfm_core as cfm
from cfm_core.studies import sweep
from cfm_core.studies.dask_runner import SerialRunner


def main(out: str | None = None) -> float:
    """Ratio of the peak at 5 mm to the peak at 8 mm (-)."""
    out = out or tempfile.mkdtemp(prefix="cfm-sweep-")
    scene = cfm.builtin_scene("drop-test").with_overrides(element_size=0.002)
    axes = sweep.parse_vary(["thickness=0.005,0.008"], scene)
    sweep.run_sweep(scene, axes, out, backend="numba", runner=SerialRunner())
    table = pd.read_csv(f"{out}/sweep.csv", comment="#")
    print(table.filter(regex="thickness|peak_g"))
    peaks = table.set_index(table.filter(regex="^thickness").columns[0]).filter(regex="^peak_g").iloc[:, 0]
    return float(peaks.iloc[0] / peaks.iloc[1])


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
