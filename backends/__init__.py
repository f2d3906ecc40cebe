"""Solver backends shipped with the project (import name ``cfm_backends``).

Each backend is registered through the ``cfm.backends`` entry-point group and imports its heavy
library (numba, torch, scikit-fem) only when it runs.
"""
