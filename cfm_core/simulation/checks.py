"""Physics checks of a run: every backend calls the same monitor, the pipeline checks the Result.

A run that ends with a summary must be one whose physics held (docs/conventions.md section 5).
Two parts, both numpy only and backend-neutral:

- :class:`Monitor`: created by a backend's run loop from the model, called every ~1 % of the
  end time (at most 25 output intervals apart: 0.5 ms at 50 kHz) with the current nodal positions and impactor centre (``due`` / ``check``) and once
  at the end (``final``). It stops the run with a :class:`~cfm_core.errors.NumericalError`
  naming the node or element, the time (s) and the quantity when

  * a node lies behind the rigid plate (z < plate - tol) or inside the rigid sphere
    (distance to its centre < radius - tol);
  * a node has crossed a symmetry plane (a plane of nodes whose normal displacement is fixed)
    by more than tol;
  * the impactor reached the plate: the sphere's lowest point at or below the plate + tol
    (bottoming out: the specimen is crushed through);
  * an element is folded: the Jacobian det(dx/dxi) at one of its 8 corners is <= 0 (the
    explicit backends integrate at the centre only, whose J stays positive while a corner folds).

  In the homogeneous scenes (single-element, relaxation: :data:`HOMOGENEOUS_SCENES`) it also
  follows each element's volume ratio J at its centre (:class:`VolumeWatch`) and records where
  the material's volumetric energy is not convex there (the point driver's check,
  :func:`cfm_core.simulation.point.volumetric_convex_at`); :func:`check_result` warns about it.
  During the prescribed ramp these scenes are checked at least 100 times over the ramp (a
  relaxation's 1 ms ramp before a 30 s hold).

  ``tol`` defaults to 5 % of the smallest reference edge length (m); the scene's
  ``[scene] penetration_tolerance`` (m) sets it.

  The monitor only words the messages: one pass over the state (a *scan*,
  :mod:`cfm_core.simulation.scan`; the numba backend brings a parallel one of its own
  numbering) gives it the extremes, each with its node or element.

- :func:`check_result`: end-of-run checks on the :class:`~cfm_core.simulation.result.Result`,
  run by :mod:`cfm_core.runs.pipeline` for every backend. Returns warnings (text) and raises
  NumericalError when a stop limit is passed:

  * hourglass energy over internal energy > 10 % warns (LS-DYNA / OpenRadioss practice), above
    ``[scene] hourglass_limit`` (-) it stops;
  * energy-balance error > 1 % warns, above ``[scene] energy_limit`` (-) it stops;
  * the impactor history reaching the plate stops (also between two monitor calls);
  * a single-element run (prescribed motion, with inertia) whose kinetic energy exceeds 0.1 % of
    its internal energy warns that inertia matters (soft materials: the explicit reaction force
    was 5-60 % above the uniaxial-stress solution, where KE / IE was 0.5-3 %; the CFM: 0.02 %);
  * the run ending at its end time while still in contact: it stops when the end time was
    automatic (a generous bound, so still being in contact means the impactor never came back:
    bottoming out), and warns when the user chose the end time (the pulse is cut short);
  * a homogeneous scene (single-element, relaxation) whose element reached a J where the
    volumetric energy is not convex (the Ogden term: J > 1.29, e.g. stiff fibres pulled far)
    warns, naming the element, the time and J (the monitor's record in ``info["checks"]``), as
    the point driver's uniaxial path does: the state there is not a physical one;
  * the backend's own accuracy warnings, ``result.info["solver_warnings"]`` (text; e.g. skfem's
    Newton stopped by round-off, with the force balance it attained), are passed on first.

Limits travel from the scene to the model as ``model.meta["checks"]`` (a dict of the keys above).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import NumericalError
from .scan import Extremes, Scan, corner_volumes  # noqa: F401  (corner_volumes: its public home was here)

HOURGLASS_WARN = 0.10   # (-) hourglass / internal energy above which a run warns
ENERGY_WARN = 0.01      # (-) energy-balance error above which a run warns
TOLERANCE_FRACTION = 0.05  # (-) default penetration tolerance as a fraction of the smallest edge
CHECKS_PER_RUN = 100    # monitor calls over the end time at least (plus the final state)
OUTPUTS_PER_CHECK = 25  # and at least one every 25 output intervals (0.5 ms at 50 kHz)
INERTIA_WARN = 1e-3     # (-) kinetic / internal energy above which a single-element run is not quasi-static
#: Scene types with homogeneous deformation whose elements' J the monitor follows (volumetric convexity).
HOMOGENEOUS_SCENES = ("single-element", "relaxation")
#: Time steps (-) over the contact below which an impact is not resolved in time: a 10 ug impactor on a
#: 4 mm specimen took 17 steps of 37 us for its whole run, and its contact came out 0.42 ms long against
#: 0.20 ms with steps of 1 us (the paper's drop test: about 1 600 steps in contact).
CONTACT_STEPS_WARN = 20
RINGING_WARN = 0.01     # (-) RMS of a single element's reaction force about its trend, over its peak, above which
                        # it rings (kappa = 1e12 Pa: +-1.8 N about -1.1 N, the final value 71 % off, unwarned;
                        # kappa = 1e8 Pa: 1.2 %, final value 2.4 % off; Table 1: 0.12 %)


@dataclass(frozen=True)
class Limits:
    """Limits of the run checks (SI units).

    Attributes
    ----------
    tolerance : float or None
        Allowed penetration behind a rigid surface or across a symmetry plane (m); None for 5 %
        of the smallest element edge.
    hourglass_limit : float or None
        Hourglass / internal energy above which the run stops (-); None: warn only (above 0.10).
    energy_limit : float or None
        Energy-balance error above which the run stops (-); None: warn only (above 0.01).
    """

    tolerance: float | None = None
    hourglass_limit: float | None = None
    energy_limit: float | None = None

    @classmethod
    def of(cls, model) -> "Limits":
        """The limits a model carries.

        Parameters
        ----------
        model : cfm_core.scene.Model
            Its ``meta["checks"]`` (from the scene's [scene] section) holds the limits.

        Returns
        -------
        Limits
            Those limits; defaults where the model has none.
        """
        d = dict(getattr(model, "meta", {}).get("checks") or {})
        return cls(tolerance=d.get("penetration_tolerance"), hourglass_limit=d.get("hourglass_limit"),
                   energy_limit=d.get("energy_limit"))


def smallest_edge(nodes: np.ndarray, hexes: np.ndarray) -> float:
    """Smallest edge length of the hexahedra (the 12 edges of each element).

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Node coordinates (m).
    hexes : ndarray, shape (e, 8)
        Connectivity, VTK hexahedron order.

    Returns
    -------
    float
        The smallest edge (m); 0 without elements.
    """
    x = np.asarray(nodes, dtype=np.float64)[np.asarray(hexes)]
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                      [0, 4], [1, 5], [2, 6], [3, 7]])
    lengths = np.linalg.norm(x[:, pairs[:, 1]] - x[:, pairs[:, 0]], axis=2)
    return float(lengths.min()) if lengths.size else 0.0


def tolerance(model, limits: Limits | None = None) -> float:
    """Penetration tolerance of a model: the scene's, or 5 % of the smallest edge.

    Parameters
    ----------
    model : cfm_core.scene.Model
        The model (reference mesh in m, ``meta["checks"]``).
    limits : Limits, optional
        Its limits (default: :meth:`Limits.of` the model).

    Returns
    -------
    float
        Tolerance (m).
    """
    limits = limits or Limits.of(model)
    if limits.tolerance is not None:
        return float(limits.tolerance)
    return TOLERANCE_FRACTION * smallest_edge(model.nodes, model.hexes)


def symmetry_planes(model) -> list[tuple[int, float, float]]:
    """The planes of fixed normal displacement (symmetry planes, clamped faces) of a model.

    A fixed dof d counts when all nodes fixed in d share one coordinate x_d = c and the whole
    mesh lies on one side of it; side is the sign of that side.

    Parameters
    ----------
    model : cfm_core.scene.Model
        Reference nodes (n, 3) in m and fixed_dofs (k, 2) pairs (node, dof).

    Returns
    -------
    list of tuple
        (axis 0-2, coordinate (m), side +1.0 or -1.0) per plane.
    """
    fixed = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2)
    nodes = np.asarray(model.nodes, dtype=np.float64)
    if nodes.size == 0:
        return []
    size = float(np.ptp(nodes, axis=0).max()) or 1.0
    planes = []
    for d in range(3):
        idx = fixed[fixed[:, 1] == d, 0]
        if idx.size == 0:
            continue
        c = nodes[idx, d]
        if np.ptp(c) > 1e-9 * size:
            continue
        rel = nodes[:, d] - float(c[0])
        if rel.min() >= -1e-9 * size and rel.max() > 0:
            planes.append((d, float(c[0]), 1.0))
        elif rel.max() <= 1e-9 * size and rel.min() < 0:
            planes.append((d, float(c[0]), -1.0))
    return planes


class Monitor:
    """Checks a running model's state; see the module docstring.

    Parameters
    ----------
    model : cfm_core.scene.Model
        The model being run (reference nodes (n, 3) in m, hexes (e, 8), sphere, plane, fixed dofs).
    checks : int
        Number of checks over the end time (default 100), plus the final state.
    scan : callable, optional
        ``scan(model, tol, planes)`` -> the scan of this run's states
        (:class:`cfm_core.simulation.scan.Scan`'s interface: called with the positions the
        backend passes and the impactor's reference point, it returns the
        :class:`~cfm_core.simulation.scan.Extremes` in the user's numbering; ``position(x, node)``
        gives a node's position for the messages), for a backend with a compiled one (the numba
        backend's parallel scan of its own numbering, ``cfm_backends.numba_explicit.scan``);
        default: the numpy :class:`~cfm_core.simulation.scan.Scan`.
    contact_hint : str, optional
        Appended to a penetration failure (a node behind the plate or inside the impactor): what
        the backend's contact adds to the cause (skfem: a penalty stiffness that follows kappa0).

    Raises
    ------
    NumericalError
        From :meth:`check` / :meth:`final`, naming the node or element, the time (s) and the
        quantity ("penetration", "symmetry", "bottoming out", "corner Jacobian").
    """

    def __init__(self, model, checks: int = CHECKS_PER_RUN, scan=None, contact_hint: str = ""):
        self.model = model
        self.contact_hint = contact_hint
        self.limits = Limits.of(model)
        self.tol = tolerance(model, self.limits)
        self.planes = symmetry_planes(model)
        self.hexes = np.asarray(model.hexes, dtype=np.int64)
        self.scan = (scan or Scan)(model, self.tol, self.planes)
        self.interval = float(model.end_time) / max(int(checks), 1)
        if float(model.output_interval) > 0.0:
            self.interval = min(self.interval, OUTPUTS_PER_CHECK * float(model.output_interval))
        self.volumes = None
        self.ramp_end, self.ramp_interval = 0.0, math.inf
        if (getattr(model, "meta", None) or {}).get("scene_type") in HOMOGENEOUS_SCENES and model.material is not None:
            self.volumes = VolumeWatch(model)
            pres = model.prescribed
            if pres is not None and len(pres.times) > 1:
                moving = np.flatnonzero(np.diff(np.asarray(pres.values, dtype=np.float64)) != 0.0)
                if moving.size:
                    self.ramp_end = float(pres.times[moving[-1] + 1])
                    self.ramp_interval = self.ramp_end / max(int(checks), 1)
        self.next = self._next_after(0.0)
        self.calls = 0
        self.worst = {"plate": 0.0, "sphere": 0.0, "symmetry": 0.0, "corner_jacobian_ratio": 1.0}

    def _next_after(self, t: float) -> float:
        """The next check time (s) after t: on the grid of ``interval``, and during the prescribed
        ramp of a homogeneous scene also on the grid of ``ramp_interval``."""
        nxt = (math.floor(t / self.interval) + 1) * self.interval if self.interval > 0 else math.inf
        if t < self.ramp_end and self.ramp_interval > 0:
            nxt = min(nxt, (math.floor(t / self.ramp_interval) + 1) * self.ramp_interval)
        return nxt

    def due(self, t: float) -> bool:
        """Whether a check is due.

        Parameters
        ----------
        t : float
            Simulated time (s).

        Returns
        -------
        bool
            True once t has reached the next check time (``self.next``, s).
        """
        return t >= self.next

    def check(self, t: float, x: np.ndarray, impactor_z: float | None = None) -> None:
        """Check the state and schedule the next check.

        Parameters
        ----------
        t : float
            Simulated time (s).
        x : ndarray, shape (n, 3)
            Current nodal positions (m) of the modelled part.
        impactor_z : float or array_like of shape (3,), optional
            Current z of the impactor's reference point (m), or the whole point for an impactor
            that moves in x or y, for models with an impactor.

        Raises
        ------
        NumericalError
            Penetration, symmetry plane crossed, bottoming out or a folded corner (see the module
            docstring), naming node or element, time and quantity.
        """
        self.calls += 1
        self.next = self._next_after(t)
        self.inspect(t, x, impactor_z)

    def inspect(self, t: float, x: np.ndarray, impactor_z: float | None = None) -> None:
        """The checks of :meth:`check` without the bookkeeping of when the next one is due.

        Parameters
        ----------
        t, x, impactor_z
            As for :meth:`check` (s, m, m).

        Raises
        ------
        NumericalError
            As for :meth:`check`.
        """
        m, tol = self.model, self.tol
        sph, plane = m.sphere, m.plane
        c = impactor_position(sph, impactor_z) if sph is not None and impactor_z is not None else None
        found: Extremes = self.scan(x, c)
        if found.nonfinite >= 0:
            raise NumericalError(f"node {found.nonfinite} has a non-finite position at t = {t:.6g} s in model "
                                 f"'{m.name}'.", time=t, element=None, quantity="position")
        if found.plate is not None:
            depth, i = found.plate
            self.worst["plate"] = max(self.worst["plate"], depth)
            if depth > tol:
                raise self._error(t, f"node {i} is {_mm(depth)} behind the rigid plate z = {plane.z:g} m "
                                     f"(reference position {_pos(m.nodes[i])}, now {_pos(self.scan.position(x, i))})",
                                  "penetration of the rigid plate", node=i)
        if c is not None:
            if found.impactor is not None:
                depth, i = found.impactor
                self.worst["sphere"] = max(self.worst["sphere"], depth)
                if depth > tol:
                    size = f"radius {sph.radius:g} m" if sph.shape != "plane" else "a plane"
                    raise self._error(t, f"node {i} is {_mm(depth)} inside the rigid impactor ({sph.shape}, "
                                         f"{size}, reference point {_pos(c)}; node now at "
                                         f"{_pos(self.scan.position(x, i))})",
                                      "penetration of the rigid impactor", node=i)
            if plane is not None:
                self._bottoming(t, float(c[2]), x)
        for (axis, c_plane, _), (depth, i) in zip(self.planes, found.symmetry):
            self.worst["symmetry"] = max(self.worst["symmetry"], depth)
            if depth > tol:
                name = "xyz"[axis]
                raise self._error(t, f"node {i} has crossed the symmetry plane {name} = {c_plane:g} m by {_mm(depth)} "
                                     f"(now at {_pos(self.scan.position(x, i))}): the specimen folds through a plane "
                                     f"it may only slide on", "symmetry plane crossed", node=i)
        if found.corner is not None:
            ratio, e, corner = found.corner
            self.worst["corner_jacobian_ratio"] = min(self.worst["corner_jacobian_ratio"], ratio)
            if not ratio > 0.0:
                raise NumericalError(
                    f"element {e} is folded at t = {t:.6g} s: the Jacobian at its corner node "
                    f"{int(self.hexes[e, corner])} (local corner {corner}) is {ratio:.3g} times its "
                    f"reference value (<= 0) in model '{m.name}'. The centre-point integration of the explicit "
                    f"solvers cannot see this; the mesh cannot follow the deformation: lower the load, refine the "
                    f"mesh or check the impactor mass and the material's stiffness (units).",
                    time=t, element=e, quantity="corner Jacobian")
        if self.volumes is not None:
            self.volumes.see(t, x, self.scan.position)

    def final(self, t: float, x: np.ndarray, impactor_z: float | None = None) -> None:
        """The check of the last state (always run).

        Parameters
        ----------
        t, x, impactor_z
            As for :meth:`check` (s, m, m).

        Raises
        ------
        NumericalError
            As for :meth:`check`.
        """
        self.check(t, x, impactor_z)

    def report(self) -> dict:
        """What the monitor saw, for ``Result.info["checks"]``.

        Returns
        -------
        dict
            monitor_calls (-), tolerance (m), worst_plate / worst_sphere / worst_symmetry (largest
            depths seen, m) and worst_corner_jacobian_ratio (smallest ratio to the reference, -);
            in a homogeneous scene also ``volume_ratio`` (:meth:`VolumeWatch.report`).
        """
        out = {"monitor_calls": self.calls, "tolerance": self.tol,
               **{f"worst_{k}": v for k, v in self.worst.items()}}
        if self.volumes is not None:
            out["volume_ratio"] = self.volumes.report()
        return out

    def _bottoming(self, t: float, z: float, x=None) -> None:
        m = self.model
        gap = z - m.sphere.bottom - float(m.plane.z)
        if gap <= self.tol:
            cause = ("The specimen is crushed through: the impactor is too heavy or too fast for this specimen "
                     "(check the units: mass in kg, velocity in m/s) or the material too soft.")
            if x is not None and _uncrushed(m, x, self.scan.position):
                if any(float(v) != 0.0 for v in m.sphere.velocity_xy):
                    cause = ("The specimen is not crushed (its top surface is still above half its thickness): the "
                             "impactor came down beside it. An oblique impact at this angle slides off the specimen; "
                             "give a smaller angle, a wider specimen or an earlier end time.")
                else:
                    cause = (f"The specimen is not crushed (its top surface is still above half its thickness), and "
                             f"the impact is straight down: the impactor passed between the specimen's nodes, where "
                             f"contact is checked (top-surface nodes up to {_mm(_top_spacing(m))} apart against "
                             f"an impactor radius of {_mm(m.sphere.radius)}); refine the mesh.")
            raise NumericalError(
                f"the impactor reached the rigid plate at t = {t:.6g} s: its lowest point is {_mm(gap)} above "
                f"the plate z = {m.plane.z:g} m (bottoming out) in model '{m.name}'. {cause}", time=t,
                quantity="bottoming out")

    def _error(self, t: float, what: str, quantity: str, node: int) -> NumericalError:
        err = NumericalError(
            f"{what} at t = {t:.6g} s in model '{self.model.name}' (tolerance {_mm(self.tol)}): the run "
            f"cannot be trusted. The load is too large for this specimen (check the units: impactor mass in "
            f"kg, velocity in m/s, moduli in Pa), or the mesh too coarse."
            + (self.contact_hint if quantity.startswith("penetration") else ""), time=t, quantity=quantity)
        err.node = node
        return err


class VolumeWatch:
    """The volume ratio J at each element's centre over a run, and where the volumetric energy of the
    element's material is not convex there (the point driver's check,
    :func:`cfm_core.simulation.point.volumetric_convex_at`). For the small homogeneous models: it
    reads every node's position at each check.

    Parameters
    ----------
    model : cfm_core.scene.Model
        The model (reference nodes (n, 3) in m, hexes (e, 8), parts with their materials).
    """

    def __init__(self, model):
        from ..scene.mesh import HEX_REFERENCE

        self.hexes = np.asarray(model.hexes, dtype=np.int64)
        self.signs = HEX_REFERENCE                       # (8, 3) natural coordinates of the corners
        self.ref = self._centre_det(np.asarray(model.nodes, dtype=np.float64)[self.hexes])
        self.parts = [(p.material, np.asarray(p.elements, dtype=np.int64)) for p in model.part_list()]
        self.n = int(model.nodes.shape[0])
        self.first = None        # (t_before, t, element, J, material): the first check that found U'' < 0
        self.extreme = None      # (t, element, J): the J farthest from 1 (in |ln J|) seen where U'' < 0
        self.last_t = 0.0        # time of the previous check (s)
        self.range = [1.0, 1.0]  # smallest and largest J seen (-)
        self.crushed = None      # (t, element, J): the first check that found J below point.CRUSHED_J
        self.smallest = None     # (t, element, J): the smallest J seen

    def _centre_det(self, X):
        """8 det(dx/dxi) at the centre of each element, X (e, 8, 3) its corner positions (m^3)."""
        return np.linalg.det(np.einsum("eai,aj->eij", X, self.signs))

    def see(self, t: float, x, position) -> None:
        """Record the J of every element in the state x at time t (s).

        Parameters
        ----------
        t : float
            Simulated time (s).
        x : ndarray, shape (n, 3)
            Positions (m) as the backend passes them.
        position : callable
            position(x, node) -> (3,) position (m) of the user's node (the scan's: a backend may
            pass its own numbering).
        """
        from .point import CRUSHED_J as crushed_below, volumetric_convex_at  # deferred: only these scenes need it

        xu = np.array([position(x, i) for i in range(self.n)], dtype=np.float64)
        J = self._centre_det(xu[self.hexes]) / self.ref
        if np.isfinite(J).all():
            self.range = [min(self.range[0], float(J.min())), max(self.range[1], float(J.max()))]
            k = int(np.argmin(J))
            if self.smallest is None or J[k] < self.smallest[2]:
                self.smallest = (float(t), k, float(J[k]))
            if self.crushed is None and J[k] < crushed_below:
                self.crushed = self.smallest
        for material, elements in self.parts:
            if not elements.size:
                continue
            try:
                convex = volumetric_convex_at(material, J[elements])
            except NumericalError:   # the volumetric term itself is not finite there: the backend stops on it
                continue
            for k in np.flatnonzero(~convex):
                e, Je = int(elements[k]), float(J[elements[k]])
                if self.first is None:
                    self.first = (self.last_t, float(t), e, Je, material)
                if self.extreme is None or abs(math.log(Je)) > abs(math.log(self.extreme[2])):
                    self.extreme = (float(t), e, Je)
        self.last_t = float(t)

    def report(self) -> dict:
        """What was seen, JSON-able.

        Returns
        -------
        dict
            ``min`` and ``max``: the smallest and largest J seen (-); ``nonconvex``: None, or where
            U'' < 0 was first found: ``t`` (s, the check that found it), ``t_before`` (s, the check
            before), ``element``, ``J`` (-), ``material`` (name), ``text`` (the warning,
            :func:`nonconvex_warning`); ``crushed``: None, or the warning (text) for a J below
            :data:`cfm_core.simulation.point.CRUSHED_J` (:func:`crushed_warning`).
        """
        out = {"min": self.range[0], "max": self.range[1], "nonconvex": None,
               "crushed": crushed_warning(self.crushed, self.smallest) if self.crushed is not None else None}
        if self.first is not None:
            t0, t1, e, Je, material = self.first
            out["nonconvex"] = {"t_before": t0, "t": t1, "element": e, "J": Je, "material": material.name,
                                "text": nonconvex_warning(self.first, self.extreme)}
        return out


def crushed_warning(first, smallest) -> str:
    """The warning of a homogeneous scene whose element's J fell below
    :data:`cfm_core.simulation.point.CRUSHED_J` (the point driver's words,
    :func:`cfm_core.simulation.point.crushed_volume`).

    Parameters
    ----------
    first, smallest : tuple
        (time (s), element, J (-)) of the first check below the limit and of the smallest J seen.

    Returns
    -------
    str
        Names the element and time of both.
    """
    from .point import CRUSHED_J, crushed_volume

    t0, e0, J0 = first
    ts, es, Js = smallest
    return (f"element {e0} reached J = {J0:.4g} by t = {t0:.4g} s (below {CRUSHED_J:g}); the smallest, in element "
            f"{es} at t = {ts:.4g} s, is {crushed_volume(Js)}")


def nonconvex_warning(first, extreme) -> str:
    """The warning of a homogeneous scene whose element reached a J where U''(J) < 0.

    Parameters
    ----------
    first : tuple
        (time of the check before (s), time of the check that found it (s), element, J (-), material).
    extreme : tuple
        (time (s), element, J (-)) of the J farthest from 1 seen where U''(J) < 0.

    Returns
    -------
    str
        Names the element, the time, J, and the farthest J with its time.
    """
    from .point import nonconvex_volumetric

    t0, t1, e, Je, material = first
    when = f"t = {t1:.4g} s" + (f" (the check before, at t = {t0:.4g} s, found none)" if 0.0 < t0 < t1 else "")
    tx, ex, Jx = extreme
    return (f"element {e} reached J = {Je:.4g} by {when}, where {nonconvex_volumetric(material)}: the bulk modulus "
            f"cannot hold the volume, and the stresses and reaction force from there on are not those of a physical "
            f"state (J reaches {Jx:.4g} in element {ex} at t = {tx:.4g} s); lower the stretch or the fibre stiffness "
            f"(k1, k2), or raise kappa.")


def impactor_position(sph, z) -> np.ndarray:
    """(3,) current reference point (m) of the impactor ``sph`` from its z (m; x and y its
    initial ones) or from the whole point (array_like (3,))."""
    z = np.asarray(z, dtype=np.float64)
    if z.size == 3:
        return z.reshape(3)
    return np.array([sph.center[0], sph.center[1], float(z)])


def _mm(x: float) -> str:
    return f"{1e3 * x:.4g} mm"


def _pos(x) -> str:
    return "(" + ", ".join(f"{1e3 * v:.4g}" for v in x) + ") mm"


def check_result(model, result) -> list[str]:
    """End-of-run checks of a Result (see the module docstring); returns the warnings.

    Parameters
    ----------
    model : cfm_core.scene.Model
        The model that was run (sphere, plane, end_time in s, meta["checks"] limits).
    result : cfm_core.simulation.result.Result
        Its histories: t (s), contact_force (N), impactor_z (m), energies (J).

    Returns
    -------
    list of str
        Warnings (the backend's ``info["solver_warnings"]``, hourglass energy, energy balance, a
        J where the volumetric energy is not convex in a homogeneous scene, inertia and ringing of a
        single element, end in contact with a user end time, an impact whose contact spans fewer than
        :data:`CONTACT_STEPS_WARN` time steps).

    Raises
    ------
    NumericalError
        Bottoming out, end in contact with an automatic end time, or a stop limit passed.
    """
    limits = Limits.of(model)
    warnings: list[str] = [str(w) for w in (result.info or {}).get("solver_warnings", [])]
    t = np.asarray(result.t, dtype=np.float64)
    sph, plane = model.sphere, model.plane
    if sph is not None and plane is not None and result.impactor_z is not None and t.size:
        low = np.asarray(result.impactor_z) - sph.bottom - float(plane.z)
        i = int(np.argmin(low))
        if low[i] <= tolerance(model, limits):
            cause = ("The specimen is crushed through: the impactor is too heavy or too fast for this specimen "
                     "(check the units: mass in kg, velocity in m/s) or the material too soft.")
            raise NumericalError(
                f"the impactor reached the rigid plate at t = {t[i]:.6g} s: its lowest point came within "
                f"{_mm(low[i])} of the plate z = {plane.z:g} m (bottoming out) in model '{model.name}'. {cause}",
                time=float(t[i]), quantity="bottoming out")
    if result.energies and t.size:
        hg = result.hourglass_ratio()
        # a scene's stop limit applies at any level, also below the warning threshold (hourglass_limit =
        # 0.001 was ignored at 1.3 %)
        if math.isfinite(hg) and limits.hourglass_limit is not None and hg > limits.hourglass_limit:
            raise NumericalError(f"hourglass energy is {100 * hg:.3g} % of the internal energy, above the scene's stop "
                                 f"limit hourglass_limit = {limits.hourglass_limit:g}, in model '{model.name}': the "
                                 f"zero-energy modes carry part of the deformation; refine the mesh or lower the load.",
                                 time=float(t[-1]), quantity="hourglass energy")
        if math.isfinite(hg) and hg > HOURGLASS_WARN:
            warnings.append(f"hourglass energy is {100 * hg:.3g} % of the internal energy (above "
                            f"{100 * HOURGLASS_WARN:g} %): the zero-energy modes carry a large part of the deformation "
                            f"and the stresses are not reliable; refine the mesh or lower the load.")
        err = result.energy_error()
        if math.isfinite(err) and limits.energy_limit is not None and err > limits.energy_limit:
            raise NumericalError(f"energy-balance error is {100 * err:.3g} %, above the scene's stop limit "
                                 f"energy_limit = {limits.energy_limit:g}, in model '{model.name}': energy is created "
                                 f"or lost by the integration; lower the time step or check the contact.",
                                 time=float(t[-1]), quantity="energy balance")
        if math.isfinite(err) and err > ENERGY_WARN:
            warnings.append(f"energy-balance error is {100 * err:.3g} % (above {100 * ENERGY_WARN:g} %): energy is "
                            f"created or lost by the integration; lower the time step or check the contact.")
    volume = ((result.info or {}).get("checks") or {}).get("volume_ratio") or {}
    if volume.get("nonconvex"):
        warnings.append(volume["nonconvex"]["text"])
    if volume.get("crushed"):
        warnings.append(volume["crushed"])
    if model.meta.get("scene_type") == "single-element" and result.energies and t.size:
        ke = float(np.max(np.abs(result.energies["kinetic"])))
        ie = float(np.max(np.abs(result.energies["internal"])))
        if ie > 0.0 and ke > INERTIA_WARN * ie:
            warnings.append(
                f"inertia matters in this single-element run: the kinetic energy reaches {100 * ke / ie:.3g} % of "
                f"the internal energy (above {100 * INERTIA_WARN:g} %), so the reaction force carries inertial "
                f"(wave) forces and is not the quasi-static uniaxial response (a soft material or a high rate); "
                f"lower the rate, or run the quasi-static 'relaxation' scene with the skfem backend.")
    if model.meta.get("scene_type") == "single-element" and result.reaction_force is not None:
        ringing = _ringing(np.asarray(result.reaction_force, dtype=np.float64))
        if ringing > RINGING_WARN:
            warnings.append(
                f"the reaction force rings: it oscillates about its trend by {100 * ringing:.3g} % of its peak (RMS; "
                f"above {100 * RINGING_WARN:g} %), an undamped vibration of the element (the volumetric mode of a "
                f"nearly incompressible material rings at a frequency the output samples poorly), so its values are "
                f"not the quasi-static uniaxial response; run the 'relaxation' scene with the skfem backend "
                f"(quasi-static), or lower the rate.")
    if sph is not None and result.contact_force is not None and t.size:
        f = np.asarray(result.contact_force, dtype=np.float64)
        peak = float(np.max(np.abs(f))) if f.size else 0.0
        ended = t[-1] >= float(model.end_time) * (1.0 - 1e-9)
        if ended and peak > 0.0 and f[-1] > 1e-6 * peak:
            automatic = bool(model.meta.get("end_time_automatic", False))
            text = (f"the run ended at its end time t = {t[-1]:.6g} s while the impactor was still in contact "
                    f"(force {f[-1]:.4g} N, {100 * f[-1] / peak:.3g} % of the peak)")
            if automatic:
                raise NumericalError(
                    f"{text} in model '{model.name}', although the automatic end time allows ten times the "
                    f"thickness over the velocity: the impactor never came back (bottoming out or a far too "
                    f"soft specimen; check the units of mass, velocity and moduli).",
                    time=float(t[-1]), quantity="contact at the end time")
            warnings.append(text + "; the pulse is cut short, so its duration and later metrics are not those "
                                   "of the full impact (raise [scene] end_time).")
        on = np.flatnonzero(f > 1e-3 * peak) if peak > 0.0 else np.empty(0, dtype=np.int64)
        if on.size and result.steps and t[-1] > 0.0:
            contact = float(t[on[-1]] - t[on[0]])
            dt = float(t[-1]) / int(result.steps)   # the mean step (s)
            if contact < CONTACT_STEPS_WARN * dt:
                warnings.append(
                    f"the impact is not resolved in time: its contact ({1e3 * contact:.3g} ms) spans about "
                    f"{contact / dt:.3g} time steps of {dt:.3g} s on average (fewer than {CONTACT_STEPS_WARN}), so "
                    f"the peak and the contact time depend on the step; lower the largest step (the backend's "
                    f"dt_max option, 'cfm backends --options') to about {contact / 100:.2g} s, or check the "
                    f"impactor's mass and speed (SI units: kg, m/s).")
    return warnings


def _ringing(force: np.ndarray) -> float:
    """RMS of a history about its running mean over 9 samples, over its largest |value| (-); 0 for fewer
    than 30 samples or a zero history. A smooth loading curve leaves ~1e-4 (its curvature over the
    window); a vibration sampled at the output rate leaves its amplitude."""
    n = force.size
    peak = float(np.max(np.abs(force))) if n else 0.0
    if n < 30 or not peak > 0.0 or not np.all(np.isfinite(force)):
        return 0.0
    w = 9
    trend = np.convolve(force, np.ones(w) / w, mode="valid")
    rest = force[w // 2: n - w // 2] - trend
    return float(np.sqrt(np.mean(rest ** 2)) / peak)



def _top_spacing(model) -> float:
    """The longest element edge (m) in the specimen's top surface (reference configuration)."""
    ref = np.asarray(model.nodes)
    hexes = np.asarray(model.hexes)
    top = ref[:, 2].max()
    on_top = np.abs(ref[:, 2] - top) <= 1e-9 * max(top - ref[:, 2].min(), 1e-12)
    longest = 0.0
    for a, b in ((4, 5), (5, 6), (6, 7), (7, 4), (0, 1), (1, 2), (2, 3), (3, 0)):
        both = on_top[hexes[:, a]] & on_top[hexes[:, b]]
        if both.any():
            longest = max(longest, float(np.linalg.norm(ref[hexes[both, a]] - ref[hexes[both, b]], axis=1).max()))
    return longest


def _uncrushed(model, x, position) -> bool:
    """Whether every node of the specimen's top surface (in the reference configuration) is still above
    half the specimen's thickness in the state x (m): the specimen is not crushed, so an impactor at the
    plate came down beside it. position(x, node): the user's node's (3,) position in x (the scan's
    mapping: a backend may hold x in its own node order)."""
    ref = np.asarray(model.nodes)
    bottom, top = float(ref[:, 2].min()), float(ref[:, 2].max())
    upper = np.flatnonzero(ref[:, 2] >= top - 1e-9 * max(top - bottom, 1e-12))
    return bool(min(float(position(x, i)[2]) for i in upper) > bottom + 0.5 * (top - bottom))
