"""Options of the skfem backend's ``run``, their defaults and checks (InputError on a bad one)."""

from __future__ import annotations

import math

from cfm_core.errors import InputError

DEFAULTS = {
    "quasi_static": None,        # None: model.meta["quasi_static"]; True: no inertia; False: Newmark
    "volumetric": "mean-dilatation",  # locking-free element; "full": U(J) at every Gauss point
    "rho_inf": 0.0,              # generalized-alpha spectral radius at infinite frequency (-);
                                 # 1: Newmark average acceleration (trapezoidal rule, no damping),
                                 # which chatters and gains energy with stiff penalty contact
    "dt": None,                  # first step (s); None: dt_max / 10 (dynamic) or segment / segment_steps
    "dt_min": None,              # smallest step (s) before giving up; None: 1e-5 x dt_max
    "dt_max": None,              # largest step (s); None: the model's output_interval
    "segment_steps": 50,         # at least this many steps per moving segment of a prescribed motion
    "grow": 1.5,                 # step growth factor after a fast Newton convergence (-)
    "grow_iterations": 4,        # ... i.e. in at most this many iterations
    "cut": 0.5,                  # step reduction factor after a failed step (-)
    "max_iterations": 15,        # Newton iterations per step before the step is cut
    "rtol": None,                # residual tolerance relative to the largest force term (-); None:
                                 # 1e-6 for dynamic runs (forces to 1 ppm), 1e-9 quasi-static
    "atol": None,                # absolute residual tolerance (N); None: 1e-10 kappa0 h^2
    "contact": "augmented",      # "augmented" (multipliers updated every step) or "penalty" (plain)
    "penalty": None,             # contact augmentation / penalty stiffness (N/m per node); None: penalty_factor kappa0 h
    "penalty_factor": 100.0,     # (-), see penalty (measured: 2.2-2.5 Newton iterations per step at 100, 3.4 at 1e3)
    "error_tol": 2e-3,           # local error tolerance of a dynamic step (-, relative to the step's
                                 # displacement increment); None: steps set by Newton only (grow/cut)
    "linear_solver": "auto",     # "pardiso", "superlu", "direct" (pardiso if installed, else superlu),
                                 # "cg" (compiled block-Jacobi CG) or "auto"
    "direct_limit": 6000,        # "auto": direct below this many dofs (or for quasi-static runs), else cg
    "cg_rtol": 1e-8,             # CG: relative residual of each linear solve (-)
    "cg_maxiter": 400,           # CG: iterations before falling back to the direct solver
    "kernels": "numba",          # element and Gauss-point work: "numba" (compiled) or "numpy" (reference)
    "separation_time": 2e-4,     # s after the impactor left the specimen before stopping
    "frame_interval": None,      # s; store (t, displacement (n, 3)) frames this often
    "max_steps": 1_000_000,      # guard against runaway runs
    "record_newton": False,      # keep every step's residual sequence in info["newton"]
}

_CHOICES = {"volumetric": ("mean-dilatation", "full"), "contact": ("augmented", "penalty"),
            "linear_solver": ("auto", "direct", "pardiso", "superlu", "cg"),
            "kernels": ("numba", "numpy")}


def _positive(o, key, allow_none=False, unit="s"):
    v = o[key]
    if v is None and allow_none:
        return
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise InputError(f"skfem backend: {key} = {v!r} {unit} must be a finite number > 0"
                         f"{' or None (automatic)' if allow_none else ''}.")


def check_options(options: dict) -> dict:
    """Options merged over DEFAULTS; unknown names and bad values raise InputError."""
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise InputError(f"skfem backend: unknown option(s) {', '.join(sorted(unknown))}; "
                         f"allowed: {', '.join(DEFAULTS)}.")
    o = {**DEFAULTS, **options}
    for key, allowed in _CHOICES.items():
        if o[key] not in allowed:
            raise InputError(f"skfem backend: {key} = {o[key]!r}; use one of {', '.join(map(repr, allowed))}.")
    for key in ("dt", "dt_min", "dt_max", "frame_interval"):
        _positive(o, key, allow_none=True)
    _positive(o, "penalty", allow_none=True, unit="N/m")
    _positive(o, "atol", allow_none=True, unit="N")
    _positive(o, "error_tol", allow_none=True, unit="(-)")
    _positive(o, "rtol", allow_none=True, unit="(-)")
    for key in ("penalty_factor", "separation_time", "cg_rtol"):
        _positive(o, key, unit="" if key != "separation_time" else "s")
    r = o["rho_inf"]
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not 0.0 <= r <= 1.0:
        raise InputError(f"skfem backend: rho_inf = {r!r} (-) must be in [0, 1] (1: Newmark average "
                         f"acceleration, no numerical damping; 0: strongest damping of the highest modes).")
    if not (1.0 < o["grow"] <= 4.0 and 0.0 < o["cut"] < 1.0):
        raise InputError(f"skfem backend: grow = {o['grow']!r} must be in (1, 4] and cut = {o['cut']!r} in (0, 1).")
    for key in ("segment_steps", "grow_iterations", "max_iterations", "max_steps", "direct_limit", "cg_maxiter"):
        v = o[key]
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise InputError(f"skfem backend: {key} = {v!r} must be an integer >= 1.")
    if o["quasi_static"] not in (None, True, False):
        raise InputError(f"skfem backend: quasi_static = {o['quasi_static']!r} must be True, False or None.")
    return o
