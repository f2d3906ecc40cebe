"""Options of the numba backend: the shared explicit-solver options and the thread count."""

from __future__ import annotations

from dataclasses import dataclass

from cfm_backends.explicit.options import ExplicitOptions
from cfm_core.simulation.options import document, option

PARALLEL_MIN = 1000  # below this many elements, thread start-up costs more than it saves


@document
@dataclass(frozen=True)
class NumbaOptions(ExplicitOptions):
    """Options of the numba backend (``NumbaExplicitBackend.run(model, **options)``)."""

    owner = "numba backend"
    threads: int = option(None, "-", "numba threads for this run", kind="int", low=1,
                          none=f"the cores free to this process (affinity, less cores busy with other processes, a "
                          f"Dask worker's share), 1 below {PARALLEL_MIN} elements")
