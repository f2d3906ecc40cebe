"""Options of the explicit solver shared by the numba and torch backends (declared once).

The backends extend :class:`ExplicitOptions` with their own (threads, device, dtype, ...); the
names, defaults and meaning of the shared ones are the same on both, so that both run the same
algorithm with the same numbers (docs/conventions.md section 5). ``cfm backends --options``
lists them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cfm_core.errors import InputError
from cfm_core.simulation.options import Options, document, option


@document
@dataclass(frozen=True)
class ExplicitOptions(Options):
    """Options of the explicit solver (central differences, kinematic contact)."""

    owner = "explicit backend"
    hourglass: float = option(0.1, "-", "viscous hourglass coefficient Q_hg in c_hg = Q_hg rho c V0^(2/3) / 4 "
                              "(typical 0.05-0.15; at most 1; not in the stable step, so above 0.15 a run can go unstable)",
                              low=0.0, high=1.0)
    hourglass_wave: str = option("shear", "-", "wave speed c of the hourglass viscosity: 'shear' from the "
                                 "isochoric modulus, 'longitudinal' from the full one",
                                 choices=("shear", "longitudinal"))
    safety: float = option(0.9, "-", "time-step safety factor: dt = safety min_e L_e / c_e",
                           low=0.0, high=1.0, low_open=True)
    dt_max: float = option(math.inf, "s", "upper bound of the time step", low=0.0, low_open=True)
    collapse: float = option(1e-4, "-", "stop with an error when dt falls below this fraction of the first step",
                             low=0.0, high=1.0, high_open=True)
    separation_time: float = option(2e-4, "s", "with model.stop_after_separation, stop this long after the "
                                    "impactor left the specimen", low=0.0)
    initial_velocity: object = option(None, "m/s", "(n, 3) nodal velocities at t = 0", kind="any",
                                      none="at rest")
    frame_interval: float = option(None, "s", "store (t, displacement) frames this often", kind="float",
                                   low=0.0, low_open=True, none="no frames")
    max_steps: int = option(50_000_000, "-", "stop with an error after this many steps (runaway guard)", low=1,
                            high=1e12)
    renumber: str = option("morton", "-", "element order the solver uses internally for memory locality "
                           "(outputs stay in the mesh's numbering): 'morton' along a space-filling curve over the "
                           "element centroids, 'rcm' reverse Cuthill-McKee, 'none' the mesh's own; nodes follow "
                           "in first-touch order", choices=("morton", "rcm", "none"))
    warm_up: bool = option(True, "-", "compile / warm the kernels before the clock starts, so that wall_time "
                           "excludes it (reported in info['compile_time'])")


def initial_velocity(o: ExplicitOptions, n: int, free, backend: str):
    """The (n, 3) initial nodal velocities (m/s) on free dofs, or None (at rest).

    Raises
    ------
    InputError
        ``initial_velocity`` not of shape (n, 3).
    """
    if o.initial_velocity is None:
        return None
    v0 = np.asarray(o.initial_velocity, dtype=np.float64)
    if v0.shape != (n, 3):
        raise InputError(f"{backend} backend: initial_velocity must have shape ({n}, 3), got {v0.shape}.")
    return v0 * free


def document_run(backend_class, options_class) -> None:
    """Append the options table of ``options_class`` to the docstring of ``backend_class.run``
    and set ``backend_class.options_class`` (the options are declared once, listed everywhere)."""
    table = "\n".join("            " + line for line in options_class.table().splitlines())
    run = backend_class.run
    run.__doc__ = (run.__doc__ or "").rstrip() + "\n\n        Options (name, default, unit, meaning; allowed)::\n\n" + table + "\n"
    backend_class.options_class = options_class


def step_cap(o: ExplicitOptions, models) -> float:
    """The largest time step a run may take (s): the option ``dt_max`` and, for a prescribed-motion
    model, its output interval (``1 / [scene] output_rate``), so that its reaction history, written
    a row per step, is recorded at least that often, as the scenes promise. Without it a model whose
    stable step exceeded its load time (a 1 m single element: size given in mm) ran in one step,
    past its end time, and wrote two rows. A drop test's history is resampled onto the output grid
    from the impulse (:func:`cfm_core.post.resample_acceleration`), so its step stays the stable one.

    Parameters
    ----------
    o : ExplicitOptions
        The run's options.
    models : Model or sequence of Model
        The model, or the models of a batch (the smallest interval caps them all).

    Returns
    -------
    float
        min(dt_max, the output intervals of the prescribed-motion models) (s).
    """
    models = models if isinstance(models, (list, tuple)) else (models,)
    intervals = [float(m.output_interval) for m in models
                 if getattr(m, "prescribed", None) is not None and float(m.output_interval) > 0.0]
    return min([float(o.dt_max), *intervals])
