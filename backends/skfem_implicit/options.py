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
    "rtol": 1e-9,                # residual tolerance relative to the largest force term (-)
    "atol": None,                # absolute residual tolerance (N); None: 1e-10 kappa0 h^2
    "penalty": None,             # contact penalty (N/m per node); None: penalty_factor kappa0 h
    "penalty_factor": 1e4,       # (-), see penalty
    "penalty_gap": 1e-3,         # (-) x h: the penalty force is C^1, quadratic over this first gap
    "linear_solver": "auto",     # "direct" (SuperLU), "cg" (block-Jacobi CG) or "auto"
    "direct_limit": 6000,        # "auto": direct below this many dofs (or for quasi-static runs)
    "separation_time": 2e-4,     # s after the impactor left the specimen before stopping
    "frame_interval": None,      # s; store (t, displacement (n, 3)) frames this often
    "max_steps": 1_000_000,      # guard against runaway runs
    "record_newton": False,      # keep every step's residual sequence in info["newton"]
}

_CHOICES = {"volumetric": ("mean-dilatation", "full"), "linear_solver": ("auto", "direct", "cg")}


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
    if isinstance(o["penalty_gap"], bool) or not isinstance(o["penalty_gap"], (int, float)) or not 0.0 <= o["penalty_gap"] < 0.1:
        raise InputError(f"skfem backend: penalty_gap = {o['penalty_gap']!r} (-, fraction of the element size) "
                         f"must be in [0, 0.1); 0 gives the plain (C^0) penalty law.")
    for key in ("penalty_factor", "rtol", "separation_time"):
        _positive(o, key, unit="" if key != "separation_time" else "s")
    r = o["rho_inf"]
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not 0.0 <= r <= 1.0:
        raise InputError(f"skfem backend: rho_inf = {r!r} (-) must be in [0, 1] (1: Newmark average "
                         f"acceleration, no numerical damping; 0: strongest damping of the highest modes).")
    if not (1.0 < o["grow"] <= 4.0 and 0.0 < o["cut"] < 1.0):
        raise InputError(f"skfem backend: grow = {o['grow']!r} must be in (1, 4] and cut = {o['cut']!r} in (0, 1).")
    for key in ("segment_steps", "grow_iterations", "max_iterations", "max_steps", "direct_limit"):
        v = o[key]
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise InputError(f"skfem backend: {key} = {v!r} must be an integer >= 1.")
    if o["quasi_static"] not in (None, True, False):
        raise InputError(f"skfem backend: quasi_static = {o['quasi_static']!r} must be True, False or None.")
    return o
