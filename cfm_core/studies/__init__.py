"""Studies built on many runs: parameter sweeps (sweep.py), calibration of material parameters to
measured drop-test curves (calibrate.py), on a Dask cluster or serially (dask_runner.py)."""
