"""CalculiX input decks (``.inp``) from the project's :class:`cfm_core.scene.Model` (SI units: m, s, kg, Pa).

What the deck says (and so what is CalculiX's): C3D8R hexahedra (the model's connectivity, whose
meshio/VTK order is CalculiX's C3D8 order), ``*BOUNDARY`` for the fixed dofs (symmetry planes,
clamps), ``*AMPLITUDE`` + ``*BOUNDARY`` for prescribed motion, ``*STATIC`` (quasi-static) or
``*DYNAMIC`` (CalculiX's alpha method) with fixed increments (``DIRECT``) no longer than the
output interval, ``NLGEOM``, and the material as ``*USER MATERIAL`` named ``ABAQUS<TAG>`` (ccx's
ABAQUS user-material interface, the generated UMAT through :file:`adaptor.f`) with the material's
constants in the UMAT's order (:func:`cfm_core.export.layout.props`), or CalculiX's own
``*HYPERELASTIC, NEO HOOKE`` (``native=True``, the neo-Hookean material only) for the comparison
of the export path against a native implementation.
"""

from __future__ import annotations

import numpy as np

from cfm_core.errors import InputError

from .build import tag

#: Node sets whose reaction force is printed (``*NODE PRINT``, totals).
PRESCRIBED_SET = "NPRESC"


def _lines(values, per_line: int = 8) -> list[str]:
    vals = [f"{v:.14g}" for v in values]
    return [", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line)]


def material_card(material, native: bool = False) -> list[str]:
    """The ``*MATERIAL`` block of ``material`` (name ``M``-prefixed by the interface, SI units).

    Parameters
    ----------
    material : Material
        A bound material.
    native : bool
        Write CalculiX's own ``*HYPERELASTIC, NEO HOOKE`` (C10 = mu / 2, D1 = 2 / kappa) instead of
        the generated UMAT; only the (elastic) neo-Hookean material has a native twin.

    Returns
    -------
    list of str
        Deck lines (``*MATERIAL`` ... ``*DEPVAR``), without ``*DENSITY``.

    Raises
    ------
    InputError
        ``native`` for a material other than the elastic neo-Hookean one.
    """
    from cfm_core.export import layout
    from cfm_core.export.generate import sizes

    name = material.spec.name
    if native:
        vals = dict(material.values) if hasattr(material, "values") else {}
        if name != "neo-hookean" or any(k.startswith("g") and v for k, v in vals.items()):
            raise InputError(f"CalculiX's native material is '*HYPERELASTIC, NEO HOOKE' only: material '{name}' "
                             f"has no native twin (use the generated UMAT, native=False).")
        mu, kappa = _neo_hookean_moduli(material)
        return ["*MATERIAL, NAME=NATIVE", "*HYPERELASTIC, NEO HOOKE", f"{mu / 2:.14g}, {2.0 / kappa:.14g}"]
    props = layout.props(material)
    lines = [f"*MATERIAL, NAME=ABAQUS{tag(name)}", f"*USER MATERIAL, CONSTANTS={len(props)}"]
    lines += _lines(props)
    lines += ["*DEPVAR", str(sizes(material.spec)["NS"])]
    return lines


def _neo_hookean_moduli(material) -> tuple[float, float]:
    v = material.values
    mu = float(v.get("mu", v.get("G", np.nan)))
    kappa = float(v.get("kappa", v.get("K", np.nan)))
    if not (np.isfinite(mu) and np.isfinite(kappa)):
        raise InputError(f"neo-hookean material: expected parameters 'mu' and 'kappa' (Pa), got {sorted(v)}.")
    return mu, kappa


def increments(model, max_increment: float) -> list[tuple[float, float]]:
    """Steps of the deck: (end time (s), fixed increment (s)), breaking at the prescribed breakpoints.

    Parameters
    ----------
    model : Model
        The model; its prescribed breakpoints (if any) and output interval set the increments.
    max_increment : float
        Largest increment (s).

    Returns
    -------
    list of (float, float)
        Each step's end time (total time, s) and increment (s), at least 20 increments per
        prescribed segment and none longer than the output interval.
    """
    dt_out = min(float(model.output_interval), max_increment)
    cuts = [0.0]
    if model.prescribed is not None:
        cuts += [float(x) for x in model.prescribed.times if 0.0 < x < model.end_time]
    cuts.append(float(model.end_time))
    steps = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        seg = b - a
        in_ramp = model.prescribed is not None and b <= float(model.prescribed.times[-1])
        dt = min(dt_out, seg / 20.0) if in_ramp else dt_out
        n = max(1, int(np.ceil(seg / dt - 1e-9)))
        steps.append((b, seg / n))
    return steps


def write_deck(model, path, max_increment: float = np.inf, native: bool = False,
               penalty: float | None = None) -> None:
    """Write the CalculiX input deck of ``model`` to ``path``.

    Parameters
    ----------
    model : Model
        A prescribed-motion model (single element, relaxation), or a drop test (written by
        :func:`.drop.drop_deck_lines`, automatic increments up to ``max_increment``, 50 us when
        infinite, to the model's end time).
    path : path-like
        The ``.inp`` file.
    max_increment : float
        Largest time increment (s).
    native : bool
        CalculiX's own neo-Hookean material instead of the UMAT (:func:`material_card`).
    penalty : float, optional
        Drop test: contact penalty stiffness (Pa/m); default :data:`.drop.PENALTY`.

    Raises
    ------
    InputError
        The model has neither prescribed motion nor an impactor, or a drop test the deck cannot
        write (:func:`.drop.drop_deck_lines`).
    """
    if model.sphere is not None or model.plane is not None:
        from .drop import DROP_INCREMENT, drop_deck_lines

        dt = DROP_INCREMENT if not np.isfinite(max_increment) else float(max_increment)
        with open(path, "w") as f:
            f.write("\n".join(drop_deck_lines(model, dt, float(model.end_time), native=native,
                                                penalty=penalty)) + "\n")
        return
    if model.prescribed is None:
        raise InputError(f"calculix backend: the scene '{model.name}' has no prescribed motion.")
    dynamic = not model.meta.get("quasi_static") and model.density > 0.0
    out = ["*HEADING", f"cfm model {model.name} (SI units: m, s, kg, Pa)", "*NODE, NSET=NALL"]
    out += [f"{i + 1}, {x:.14g}, {y:.14g}, {z:.14g}" for i, (x, y, z) in enumerate(model.nodes)]
    out.append("*ELEMENT, TYPE=C3D8R, ELSET=EALL")
    out += [f"{e + 1}, " + ", ".join(str(int(n) + 1) for n in hexa) for e, hexa in enumerate(model.hexes)]
    p = model.prescribed
    out.append(f"*NSET, NSET={PRESCRIBED_SET}")
    out += _int_lines(np.asarray(p.nodes) + 1)
    mat = material_card(model.material, native)
    out += mat
    if dynamic:
        out += ["*DENSITY", f"{model.density:.14g}"]
    out.append(f"*SOLID SECTION, ELSET=EALL, MATERIAL={mat[0].split('=')[1]}")
    out.append("*AMPLITUDE, NAME=APRESC, TIME=TOTAL TIME")
    pts = [v for tv in zip(p.times, p.values) for v in tv]
    if float(p.times[-1]) < model.end_time:
        pts += [float(model.end_time) * 1.001, float(p.values[-1])]
    out += _lines(pts)
    out.append("*BOUNDARY")
    out += [f"{int(n) + 1}, {int(d) + 1}, {int(d) + 1}" for n, d in np.asarray(model.fixed_dofs)]
    start = 0.0
    for k, (end, dt) in enumerate(increments(model, max_increment)):
        proc = "*DYNAMIC, DIRECT" if dynamic else "*STATIC, DIRECT"
        out += [f"*STEP, NLGEOM, INC={int(round((end - start) / dt)) + 10}", proc, f"{dt:.14g}, {end - start:.14g}"]
        if k == 0:
            out.append("*BOUNDARY, AMPLITUDE=APRESC")
            out += [f"{int(n) + 1}, {p.dof + 1}, {p.dof + 1}, 1." for n in p.nodes]
        out += [f"*NODE PRINT, NSET={PRESCRIBED_SET}, TOTALS=ONLY", "RF", "*END STEP"]
        start = end
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def _int_lines(values, per_line: int = 16) -> list[str]:
    vals = [str(int(v)) for v in values]
    return [", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line)]
