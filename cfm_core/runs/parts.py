"""What a run reports about a model's parts and symmetry: summary entries and the printed line.

A one-material model adds nothing (its summary.json is as before); a model with several parts
lists each (name, material, density, element count, parameters, definition digest).
"""

from __future__ import annotations

from ..post.vtu import symmetry_of
from .provenance import part_records


def parts_info(model) -> dict:
    """Summary entries of a model with several parts; empty for one material (summary as before).

    Parameters
    ----------
    model : Model
        The model that ran.

    Returns
    -------
    dict
        ``parts``: one entry per part (``name``, ``material``, ``moduli``, ``elastic``,
        ``density`` kg/m^3, ``elements`` modelled, ``parameters`` SI, ``definition_digest``);
        ``material``: the part materials joined (``"neo-hookean + cfm"``); ``parameters``: part
        name -> its values; ``density``: None (each part has its own); and their ``units``.
    """
    if not model.multi_material:
        return {}
    rows = [{"name": r["name"], "material": r["material"]["name"], "moduli": r["material"]["moduli"],
             "elastic": r["material"]["elastic"], "density": r["density"], "elements": r["elements"],
             "parameters": r["material"]["parameters"], "definition_digest": r["material"]["definition_digest"]}
            for r in part_records(model.part_list())]
    names = list(dict.fromkeys(r["material"] for r in rows))
    return {"parts": rows, "material": " + ".join(names), "parameters": {r["name"]: r["parameters"] for r in rows},
            "density": None, "elastic": all(r["elastic"] for r in rows),
            "units": {"parts": "name, material, moduli, elastic; density kg/m^3; elements (modelled) -; parameters SI "
                               "(Pa, s, -); definition_digest of the material definition",
                      "parameters": "SI (Pa, s, -), per part", "density": "kg/m^3 (null: per part, see parts)"}}


def describe_model(model) -> str:
    """One line naming the symmetry and the parts of a model, printed before a drop test runs.

    Returns
    -------
    str
        E.g. ``"model: half symmetry (plane y = 0), 2 parts: skin (neo-hookean, 1000 kg/m^3, 72
        elements), fat (cfm, 900 kg/m^3, 288 elements); flat impactor"``.
    """
    planes = {"quarter": " (planes x = 0 and y = 0)", "half": " (plane y = 0)", "none": " (whole specimen)"}
    sym = symmetry_of(model)
    parts = model.part_list()
    text = ", ".join(f"{p.name} ({p.material.name}, {float(p.density):g} kg/m^3, {len(p.elements)} elements)"
                     for p in parts)
    imp = f"; {model.sphere.shape} impactor" if model.sphere is not None else ""
    word = "no" if sym == "none" else sym
    return f"model: {word} symmetry{planes.get(sym, '')}, {len(parts)} part{'s' if len(parts) > 1 else ''}: {text}{imp}"

