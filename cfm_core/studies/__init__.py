"""Studies built on many runs: parameter sweeps (sweep.py, files in sweep_output.py), calibration of
material parameters to measured drop-test curves (calibrate.py), fits to laboratory tests (fit.py),
on a Dask cluster or serially (dask_runner.py). The Python API (``cfm.sweep``, ``cfm.calibrate``,
``cfm.fit``, ``cfm.uniaxial``) is in api.py; the outcomes it returns in outcomes.py."""
