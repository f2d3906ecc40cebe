"""The layer both explicit backends (numba, torch) share, numpy only.

- :mod:`.geometry`: reference hex8 geometry (volumes, mean gradients, hourglass vectors,
  characteristic lengths, lumped masses, incidence) and the model's constraint arrays;
- :mod:`.options`: the explicit-solver options, declared once (:class:`ExplicitOptions`);
- :mod:`.checks`: the model checks every explicit run makes before any work;
- :mod:`.errors`: the NumericalErrors of an explicit run (inversion, overflow, step collapse, ...);
- :mod:`.history`: the history columns of one step and the Result assembled from them.

Neither numba nor torch is imported here; ``cfm_backends.numba_explicit`` and
``cfm_backends.torch_explicit`` import this package and never each other (an import-linter
contract in pyproject.toml).
"""
