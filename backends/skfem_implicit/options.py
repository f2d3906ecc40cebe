"""Options of the skfem backend's ``run``: one typed declaration (unit, default, range, meaning).

:class:`SkfemOptions` is a frozen dataclass of :func:`cfm_core.simulation.options.option` fields;
constructing it checks every value (InputError naming the option, the value, its unit and what is
allowed). :func:`check_options` returns the checked options as a dict for the solver.
"""

from __future__ import annotations

from dataclasses import dataclass

from cfm_core.simulation.options import Options, document, option

#: Smallest time step an option may set (s): below it 1 / (beta dt^2) overflows or underflows to 0.
MIN_STEP = 1e-12

@document
@dataclass(frozen=True)
class SkfemOptions(Options):
    """Options of the implicit scikit-fem backend (SI units)."""

    owner = "skfem backend"

    quasi_static: bool = option(None, "-", "no inertia (True) or generalized-alpha dynamics (False)", kind="bool",
                                none="from the model's meta['quasi_static']")
    volumetric: str = option("mean-dilatation", "-", "volumetric treatment: locking-free mean dilatation, or "
                             "U(J) at every Gauss point", choices=("mean-dilatation", "full"))
    kernels: str = option("numba", "-", "Gauss-point and element work: compiled (numba) or the numpy reference",
                          choices=("numba", "numpy"))
    rho_inf: float = option(0.0, "-", "generalized-alpha spectral radius at infinite frequency (1: Newmark "
                            "average acceleration, no damping; 0: strongest damping of the highest modes)",
                            low=0.0, high=1.0)
    error_tol: float = option("auto", "-", "local error tolerance of a dynamic step (Zienkiewicz-Xie estimate, "
                              "mass-weighted RMS relative to the displacement); 'auto': 2e-3 for impact scenes "
                              "(rigid impactor), None for the others", kind="float", choices=("auto",), low=0.0,
                              low_open=True,
                              none="steps set by Newton only (grow / cut)")
    dt: float = option(None, "s", "first step", kind="float", low=MIN_STEP,
                       none="output interval / 10 (dynamic) or segment / segment_steps")
    dt_min: float = option(None, "s", "smallest step before giving up", kind="float", low=MIN_STEP, none="1e-5 dt_max")
    dt_max: float = option(None, "s", "largest step", kind="float", low=MIN_STEP,
                           none="2.5 output intervals with error control, else one output interval")
    segment_steps: int = option(50, "-", "at least this many steps per moving segment of a prescribed motion", low=1)
    grow: float = option(1.5, "-", "step growth after a fast Newton convergence (error_tol None)", low=1.0,
                         high=4.0, low_open=True)
    grow_iterations: int = option(4, "-", "'fast' means at most this many Newton iterations", low=1)
    cut: float = option(0.5, "-", "step reduction after a failed step", low=0.0, high=1.0, low_open=True,
                        high_open=True)
    max_iterations: int = option(15, "-", "Newton iterations per step before the step is cut", low=1)
    rtol: float = option(None, "-", "Newton residual tolerance relative to the largest force term of the iterate "
                         "(internal forces with the reactions, inertia, contact, external; invariant to the "
                         "stiffness scale; at most 1e-3: above it the step is accepted before the force balance "
                         "is solved)", kind="float", low=0.0, low_open=True, high=1e-3,
                         none="1e-6 for impact scenes (rigid impactor), 1e-9 for the others")
    atol: float = option(None, "N", "absolute Newton residual tolerance added to rtol's", kind="float", low=0.0,
                         low_open=True, high=1e-3,
                         none="0: rtol only; a step whose Newton stagnates at the round-off floor (~eps kappa0 "
                              "h^2) is accepted with the force balance it reached, which the run reports (a "
                              "warning above 10 rtol, an error above 1e-3)")
    contact: str = option("augmented", "-", "contact: augmented Lagrangian (multipliers updated every step) or "
                          "plain penalty", choices=("augmented", "penalty"))
    penalty: float = option(None, "N/m", "contact augmentation (penalty) stiffness per node", kind="float", low=0.0,
                            low_open=True, none="penalty_factor x kappa0 x h")
    penetration_tol: float = option(0.01, "-", "augmented contact: largest penetration (fraction of the element "
                                    "size) before the multipliers are updated again within a step", low=0.0,
                                    low_open=True)
    penalty_factor: float = option(100.0, "-", "penalty in units of kappa0 h (kappa0 small-strain bulk modulus, "
                                   "h element size)", low=0.0, low_open=True)
    linear_solver: str = option("auto", "-", "linear solver ('direct': pardiso if installed, else superlu; "
                                "'auto': cg for dynamic runs, direct for quasi-static ones)",
                                choices=("auto", "direct", "pardiso", "superlu", "cg"))
    cg_rtol: float = option(1e-4, "-", "CG: largest relative residual of a linear solve (smaller near Newton "
                            "convergence: at most 0.1 x the Newton tolerance)", low=0.0, high=1.0, low_open=True,
                            high_open=True)
    cg_maxiter: int = option(400, "-", "CG iterations before the direct solver takes over", low=1)
    separation_time: float = option(2e-4, "s", "time after the impactor left the specimen before stopping",
                                    low=0.0, low_open=True)
    frame_interval: float = option(None, "s", "store (t, displacement) frames this often", kind="float", low=0.0,
                                   low_open=True, none="no frames")
    max_steps: int = option(1_000_000, "-", "guard against runaway runs", low=1, high=1e12)
    record_newton: bool = option(False, "-", "keep every step's residual sequence in info['newton']")


DEFAULTS = {name: getattr(SkfemOptions, name) for name in SkfemOptions.specs()}


def _check_error_tol(value):
    """error_tol: 'auto', None or a number > 0 (InputError otherwise)."""
    if value is None or value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0.0 < value < float("inf")):
        from cfm_core.errors import InputError

        raise InputError(f"skfem backend: option error_tol = {value!r} (-) is not allowed; expected 'auto', None "
                         f"(steps set by Newton only) or a number in (0, inf) (local error tolerance of a "
                         f"dynamic step).")
    return float(value)


def check_options(options: dict) -> dict:
    """The checked options as a dict (name -> value), defaults filled in.

    Raises
    ------
    InputError
        An unknown option (the allowed names are listed) or a value outside its declaration (the
        option, its value, unit and the allowed values are named).
    """
    o = SkfemOptions.from_mapping(options).as_dict()
    o["error_tol"] = _check_error_tol(o["error_tol"])
    return o
