"""The drop test as a CalculiX deck: specimen, rigid impactor cap, rigid plate, frictionless contact.

Lessons of the hand-built deck (issue 22): the impactor is a rigid body (``*RIGID BODY``) whose
mass is carried as the density of a meshed spherical cap (a ``*MASS`` element on the reference
node made ccx's impact rules cut every increment to the minimum); contact is frictionless
``SURFACE TO SURFACE`` with a linear penalty (``NODE TO SURFACE`` crashed); the specimen is C3D8R
(C3D8I went unstable past ~50 % compression); the plate is a contact surface that allows
lift-off (a fixed support raised the peak and added a 1 kHz ring), here one flat hexahedron
(:data:`PLATE_CELLS`) with every node fixed.

Found when it was wired in (with the CFM's 25 state variables):

- ``*DYNAMIC`` first computes the initial accelerations with C3D8R integrated at 8 points
  (``resultsmech.f``, ``intscheme = 1``), reading states and stresses ccx never initialised
  there (the failures "at the first call", error 1 or 2 varying from build to build). The
  adaptor (:file:`adaptor.f`) answers that call from the undeformed, unloaded state; the plate
  is C3D8 (fully integrated, all its nodes fixed, so its element type changes nothing) so that
  ccx's state array has room for 8 points per element and that call stays inside it.
- The penalty: with 1e10 Pa/m (enough for a neo-Hookean specimen) the CFM's peak came out 4.8 %
  low and its contact 4.3 % long against numba on the same mesh; 1e11 Pa/m (:data:`PENALTY`)
  agrees to 0.03 % and 0.2 %, at about 30 % more increments.
- Fixed increments (``DIRECT``) stop at the first increment ("solution seems to diverge"):
  ccx's impact rules want a smaller one. Automatic increments (:data:`MIN_INCREMENT` up to the
  largest increment, 50 us by default) run, and a UMAT error in a Newton iterate (J <= 0 far
  from the solution) cuts the increment back through PNEWDT instead of stopping ccx.

Made faster (issue 22: 1450 s for the 2 mm drop test on one thread): ccx spends a Newton
iteration (0.2-0.3 s here) mostly in SPOOLES's reordering and factorisation, the element
stiffnesses and the contact search, whatever the mesh's 2801 equations; the time goes with the
number of iterations. The plate is one hexahedron (fewer contact points, :data:`PLATE_CELLS`),
a chattering contact increment is given up after 20 iterations
(:data:`CONTACT_ITERATIONS`), and the adaptor halves a refused increment instead of quartering it
(ccx's impact rules regrow it by 10 % per increment only).
"""

from __future__ import annotations

import math

import numpy as np

from cfm_core.errors import InputError

from .deck import _int_lines, material_card

#: Penalty stiffness of the contact (Pa/m), ``PRESSURE-OVERCLOSURE=LINEAR``. The hand-built
#: neo-Hookean deck of issue 22 used about 1e10; with the CFM, whose force rises steeply near the
#: peak, 1e10 Pa/m put the 8 mm peak 4.8 % below numba's (2 mm mesh) and 1e11 within 0.03 %.
PENALTY = 1e11
#: Thickness of the impactor cap and of the plate layer, relative to the element size (-).
LAYER = 1.0
#: Hexahedra along each side of the plate (flat, so any count is exact). ccx's surface-to-surface
#: contact cuts each slave face by the master triangles it overlaps and puts 7 points in each
#: piece: with a plate meshed like the cap (not aligned with the specimen) ccx generated about
#: 38 000 candidate points per increment in the 2 mm drop test, with one plate face 23 600.
PLATE_CELLS = 1
#: ``*CONTROLS, PARAMETERS=CONTACT`` delcon: the relative change of the number of contact
#: elements between two Newton iterations below which ccx may call the increment converged (the
#: force and correction criteria hold as well): ccx's default, 0.001. A looser 0.05 saved about a
#: fifth of the 2 mm drop test's iterations, but on the 4 mm mesh a contact set accepted too early
#: led to inverted iterates and ccx stopped with "too many cutbacks" (0.001: 56.90 g, as before).
CONTACT_DELCON = 0.001
#: ``*CONTROLS, PARAMETERS=CONTACT`` itf2f: Newton iterations of a surface-to-surface contact
#: increment before ccx gives it up and reattempts it (ccx's default 60). Converging increments
#: of the drop test took at most 15; the ones that reached 60 were chattering (the force residual
#: alternating between two values with the contact elements unchanged) and were reattempted
#: anyway: 20 gives the same increments and histories (0-1 ms: 287 iterations against 367).
CONTACT_ITERATIONS = 20
#: Smallest automatic increment (s) before ccx gives up (then a NumericalError).
MIN_INCREMENT = 1e-8
#: Largest increment (s) of the drop test when none is given (issue 22: 50 us resolved the CFC 600 band).
DROP_INCREMENT = 5e-5
#: The energies printed at every increment, as totals (:func:`.dropread.read_energies`): the
#: specimen's internal energy (ccx integrates S : dE of each point, so the Prony series' dissipated
#: work is in it) and kinetic energy, the rigid cap's kinetic energy, and the elastic energy of
#: every penalty contact element (both pairs). ccx computes them in every implicit dynamic run
#: (``dynamics.f`` sets them on), so printing them changes nothing in the solution.
ENERGY_PRINTS = ["*EL PRINT, ELSET=ESPEC, TOTALS=ONLY", "ELSE, ELKE", "*EL PRINT, ELSET=ECAP, TOTALS=ONLY", "ELKE",
                 "*CONTACT PRINT, TOTALS=ONLY", "CELS"]


def _grid(n_x: int, extent: float) -> np.ndarray:
    return np.linspace(0.0, extent, n_x + 1)


def _hex_block(coords_bottom, coords_top, n: int, first_node: int, first_elem: int):
    """Nodes and hexahedra of one layer on an (n+1) x (n+1) grid: bottom face then top face."""
    nodes = np.concatenate([coords_bottom, coords_top])
    m = (n + 1) * (n + 1)
    elems = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            quad = [a, a + 1, a + n + 2, a + n + 1]
            elems.append([first_node + q for q in quad] + [first_node + m + q for q in quad])
    ids = np.arange(first_elem, first_elem + len(elems))
    return nodes, np.array(elems), ids


def drop_deck_lines(model, dt: float, end_time: float, native: bool = False,
                    penalty: float | None = None, plate_cells: int | None = None) -> list[str]:
    """Deck lines of a quarter (or full) drop-test model.

    Parameters
    ----------
    model : Model
        A drop-test model (a hemisphere impactor moving along z, a plane, frictionless).
    dt : float
        Largest (and first) time increment (s); ccx's automatic incrementation may cut it.
    end_time : float
        End of the step (s).
    native : bool
        CalculiX's own neo-Hookean material (:func:`.deck.material_card`).
    penalty : float, optional
        Contact penalty stiffness (Pa/m) of both contact pairs; default :data:`PENALTY`.
    plate_cells : int, optional
        Hexahedra along each side of the (flat, fixed) plate; default :data:`PLATE_CELLS`.

    Returns
    -------
    list of str
        The deck; node sets ``NREF`` (impactor reference node), surfaces ``STOP``/``SCAP``
        (specimen top / impactor) and ``SBOT``/``SPLATE``.

    Raises
    ------
    InputError
        Friction (only frictionless contact is written), gravity, several parts, or an impactor
        other than the hemisphere moving along z.
    """
    if model.friction != 0.0 or model.gravity != 0.0:
        raise InputError(f"calculix backend: the drop test is written frictionless and without gravity; the scene "
                         f"has friction = {model.friction:g}, gravity = {model.gravity:g} m/s^2.")
    sph = model.sphere
    if sph is None or model.plane is None:
        raise InputError(f"calculix backend: the drop-test deck needs an impactor and a plate; scene '{model.name}' "
                         f"lacks one.")
    if getattr(sph, "shape", "hemisphere") != "hemisphere" or getattr(sph, "lateral", False):
        raise InputError(f"calculix backend: the drop test is written for the hemisphere moving along z (the "
                         f"paper's); scene '{model.name}' has impactor shape '{sph.shape}'"
                         f"{' moving in x or y' if sph.lateral else ''}.")
    if getattr(model, "multi_material", False):
        raise InputError(f"calculix backend: one material per specimen so far; scene '{model.name}' has parts "
                         f"{[p.name for p in model.part_list()]}.")
    x = model.nodes
    h = float(np.min(np.linalg.norm(x[model.hexes[:, 1]] - x[model.hexes[:, 0]], axis=1)))
    quarter = model.symmetry_factor > 1.0
    lo = x.min(axis=0)
    hi = x.max(axis=0)
    n_spec = x.shape[0]
    out = ["*HEADING", f"cfm drop test {model.name} (SI units: m, s, kg, Pa)", "*NODE, NSET=NALL"]
    out += [f"{i + 1}, {a:.14g}, {b:.14g}, {c:.14g}" for i, (a, b, c) in enumerate(x)]
    # impactor cap: a layer over the specimen's footprint, outer face on the sphere
    span = max(hi[0] - lo[0], hi[1] - lo[1]) * 1.04
    n = max(2, int(math.ceil(span / h)))
    g = _grid(n, span) if quarter else np.linspace(-span / 2, span / 2, n + 1)
    X, Y = np.meshgrid(g, g)
    X, Y = X.ravel(), Y.ravel()
    c = np.array(sph.center)
    r2 = sph.radius ** 2 - (X - c[0]) ** 2 - (Y - c[1]) ** 2
    if np.any(r2 <= 0):
        raise InputError("calculix backend: the specimen is wider than the impactor; the cap cannot cover it.")
    outer = np.stack([X, Y, c[2] - np.sqrt(r2)], axis=1)
    t_cap = LAYER * h
    inner = c + (outer - c) * (sph.radius - t_cap) / sph.radius
    cap_nodes, cap_elems, cap_ids = _hex_block(outer, inner, n, n_spec + 1, model.n_elements + 1)
    # plate: a layer below z = plane.z, every node fixed, PLATE_CELLS hexahedra a side (it is flat)
    npl = int(PLATE_CELLS if plate_cells is None else plate_cells)
    gp = _grid(npl, span) if quarter else np.linspace(-span / 2, span / 2, npl + 1)
    PX, PY = (a.ravel() for a in np.meshgrid(gp, gp))
    p0 = np.stack([PX, PY, np.full_like(PX, model.plane.z - LAYER * h)], axis=1)
    p1 = np.stack([PX, PY, np.full_like(PX, model.plane.z)], axis=1)
    first_plate = n_spec + 1 + cap_nodes.shape[0]
    plate_nodes, plate_elems, plate_ids = _hex_block(p0, p1, npl, first_plate, cap_ids[-1] + 1)
    ref = first_plate + plate_nodes.shape[0]
    rot = ref + 1
    out += [f"{first_node}, {a:.14g}, {b:.14g}, {cc:.14g}"
            for first_node, (a, b, cc) in zip(range(n_spec + 1, n_spec + 1 + len(cap_nodes)), cap_nodes)]
    out += [f"{k}, {a:.14g}, {b:.14g}, {cc:.14g}"
            for k, (a, b, cc) in zip(range(first_plate, first_plate + len(plate_nodes)), plate_nodes)]
    out += [f"{ref}, {c[0]:.14g}, {c[1]:.14g}, {c[2]:.14g}", f"{rot}, {c[0]:.14g}, {c[1]:.14g}, {c[2]:.14g}"]
    out.append("*ELEMENT, TYPE=C3D8R, ELSET=ESPEC")
    out += [f"{e + 1}, " + ", ".join(str(int(v) + 1) for v in hx) for e, hx in enumerate(model.hexes)]
    out.append("*ELEMENT, TYPE=C3D8, ELSET=ECAP")  # rigid; its mass integrated exactly (2x2x2)
    out += [f"{e}, " + ", ".join(str(int(v)) for v in hx) for e, hx in zip(cap_ids, cap_elems)]
    out.append("*ELEMENT, TYPE=C3D8, ELSET=EPLATE")  # see the module docstring
    out += [f"{e}, " + ", ".join(str(int(v)) for v in hx) for e, hx in zip(plate_ids, plate_elems)]
    out.append("*NSET, NSET=NCAP")
    out += _int_lines(range(n_spec + 1, n_spec + 1 + len(cap_nodes)))
    out.append("*NSET, NSET=NPLATE")
    out += _int_lines(range(first_plate, first_plate + len(plate_nodes)))
    out += ["*NSET, NSET=NREF", str(ref)]
    # surfaces: specimen top (S2) and bottom (S1) faces, cap outer face (S1), plate top (S2)
    top = np.isin(model.hexes[:, 4:], model.sphere_nodes).all(axis=1)
    bot = np.isin(model.hexes[:, :4], model.plane_nodes).all(axis=1)
    out.append("*SURFACE, NAME=STOP, TYPE=ELEMENT")
    out += [f"{e + 1}, S2" for e in np.flatnonzero(top)]
    out.append("*SURFACE, NAME=SBOT, TYPE=ELEMENT")
    out += [f"{e + 1}, S1" for e in np.flatnonzero(bot)]
    out.append("*SURFACE, NAME=SCAP, TYPE=ELEMENT")
    out += [f"{e}, S1" for e in cap_ids]
    out.append("*SURFACE, NAME=SPLATE, TYPE=ELEMENT")
    out += [f"{e}, S2" for e in plate_ids]
    mat = material_card(model.material, native)
    out += mat + ["*DENSITY", f"{model.density:.14g}"]
    out.append(f"*SOLID SECTION, ELSET=ESPEC, MATERIAL={mat[0].split('=')[1]}")
    volume = _cap_volume(cap_nodes, cap_elems - (n_spec + 1))
    out += ["*MATERIAL, NAME=RIGIDCAP", "*ELASTIC", "1e9, 0.3", "*DENSITY", f"{sph.mass / volume:.14g}",
            "*SOLID SECTION, ELSET=ECAP, MATERIAL=RIGIDCAP",
            "*MATERIAL, NAME=PLATE", "*ELASTIC", "1e9, 0.3", "*DENSITY", "1000.",
            "*SOLID SECTION, ELSET=EPLATE, MATERIAL=PLATE",
            f"*RIGID BODY, ELSET=ECAP, REF NODE={ref}, ROT NODE={rot}"]
    out += ["*SURFACE INTERACTION, NAME=SI", "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", f"{PENALTY if penalty is None else penalty:.6g}, 0.1",
            "*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE", "STOP, SCAP",
            "*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE", "SBOT, SPLATE"]
    out.append("*BOUNDARY")
    out += [f"{int(a) + 1}, {int(d) + 1}, {int(d) + 1}" for a, d in np.asarray(model.fixed_dofs)]
    out += ["NPLATE, 1, 3", f"{ref}, 1, 2", f"{rot}, 1, 3"]
    out.append("*INITIAL CONDITIONS, TYPE=VELOCITY")
    out += ["NCAP, 3, " + f"{sph.velocity:.14g}", f"{ref}, 3, {sph.velocity:.14g}"]
    if not (dt > 0.0 and end_time > 0.0):
        raise InputError(f"calculix backend: increment and end time must be > 0 s; got {dt!r}, {end_time!r}.")
    dt = min(dt, end_time)
    steps = int(math.ceil(end_time / dt - 1e-9))
    out += [f"*STEP, NLGEOM, INC={100 * steps + 1000}", "*CONTROLS, PARAMETERS=CONTACT",
            f"{CONTACT_DELCON:g}, 0.1, 100, {CONTACT_ITERATIONS}",  # alea 0.1 and kscalemax 100: ccx's defaults
            "*DYNAMIC",
            f"{dt:.14g}, {end_time:.14g}, {min(MIN_INCREMENT, dt):.14g}, {dt:.14g}",
            "*NODE PRINT, NSET=NREF", "U, V", "*CONTACT PRINT, SLAVE=STOP, MASTER=SCAP", "CF"]
    out += ENERGY_PRINTS + ["*END STEP"]
    return out


def _cap_volume(nodes, elems, order: int = 2) -> float:
    """Volume (m^3) of the cap's trilinear hexahedra: Gauss-Legendre (``order`` per direction) of det J.

    det J of a trilinear map is of degree 2 in each reference coordinate, so 2 points per
    direction integrate it exactly, as ccx does for the C3D8 cap's mass (2 x 2 x 2 points).

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Node coordinates (m).
    elems : ndarray, shape (e, 8)
        Hexahedra (C3D8 node order), indices into ``nodes``.
    order : int
        Gauss points per direction (>= 2 is exact).

    Returns
    -------
    float
        The volume (m^3).
    """
    xg, wg = np.polynomial.legendre.leggauss(order)
    sign = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
    p = np.asarray(nodes, dtype=float)[np.asarray(elems)]  # (e, 8, 3)
    vol = 0.0
    for a, wa in zip(xg, wg):
        for b, wb in zip(xg, wg):
            for c, wc in zip(xg, wg):
                q = np.array([a, b, c])
                # dN_k/dxi_j = s_kj / 8 * prod_{m != j} (1 + s_km q_m)
                grad = np.empty((8, 3))
                for j in range(3):
                    others = [m for m in range(3) if m != j]
                    grad[:, j] = sign[:, j] / 8.0 * np.prod(1.0 + sign[:, others] * q[others], axis=1)
                jac = np.einsum("eki,kj->eij", p, grad)
                vol += wa * wb * wc * float(np.abs(np.linalg.det(jac)).sum())
    return vol
