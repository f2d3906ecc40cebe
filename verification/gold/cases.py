"""The named gold cases: scenes x materials x backends, coarse enough for the default test command.

A :class:`Case` names a builtin scene ("point" for a material-point history) with overrides, the
backend, backend options, and the independent check (:mod:`.checks`) run when its reference is
written. Drop tests use a 20 x 20 mm specimen with 2 mm hexahedra unless stated (numba: about
0.05-0.5 s each); ``paper-8mm-numba`` is the paper's 8 mm drop test at full size (50 mm, 1 mm
hexahedra, about 3 s on numba). skfem cases are few and cheap: that backend is being rewritten for
speed and its references will be regenerated (``python -m cfm_verification.gold --update --only skfem``).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Case:
    """One gold case. scene: "point" or a builtin scene name; overrides: scene overrides (SI) or,
    for "point", {"material", "history", "elastic", "moduli"}; check: name in :data:`.checks.CHECKS`."""

    name: str
    scene: str
    backend: str
    overrides: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)
    check: str = ""
    slow: bool = False


SMALL = {"width": 0.02, "element_size": 0.002}
#: Elastic single elements ring at 100 1/s (the shear wave of a 1 kPa solid crosses 1 mm in ~1 ms);
#: a 950 times lighter cube (1 kg/m^3, the smallest allowed) is quasi-static, so the uniaxial solution is its truth.
LIGHT = {"density": 1.0}
#: Other materials run on torch (numba would compile its kernels for each material, ~1 min each),
#: neo-hookean and mooney-rivlin 20 times stiffer than their defaults (at 1 kPa the impactor sinks
#: through the specimen over 65 ms and 10^5 steps).
COARSE = {"element_size": 0.003, "width": 0.024}
#: ... and at 0.5 m/s: at 1 m/s the run checks stop them (the impactor presses nodes of the two
#: element layers 0.2-0.4 mm into itself and folds corners), which is the checks working, not a reference.
SOFT = {**COARSE, "velocity": 0.5}


def _point(name, backend, material="cfm", history="uniaxial compression", elastic=False, moduli="long-term"):
    check = "truth-point" if material == "cfm" else "energy-fd" if elastic else "prony-energy-fd"
    return Case(name, "point", backend, {"material": material, "history": history, "elastic": elastic,
                                         "moduli": moduli}, check=check)


def _drop(name, backend="numba", check="energy-momentum", options=None, **kw):
    return Case(name, "drop-test", backend, {**SMALL, "thickness": 0.006, **kw}, options or {}, check)


def _single(name, backend="numba", material="cfm", **kw):
    check = "truth-uniaxial" if material == "cfm" else "uniaxial-reference"
    return Case(name, "single-element", backend, {"material": material, **kw}, check=check)


CASES = [
    # material points: every backend, cfm elastic and viscoelastic, the other materials
    _point("point-cfm-visco-uniaxial-numpy", "numpy"),
    _point("point-cfm-visco-uniaxial-numba", "numba"),
    _point("point-cfm-visco-uniaxial-torch", "torch"),
    _point("point-cfm-visco-uniaxial-skfem", "skfem"),
    _point("point-cfm-elastic-shear-numpy", "numpy", history="simple shear", elastic=True),
    _point("point-cfm-elastic-shear-numba", "numba", history="simple shear", elastic=True),
    _point("point-cfm-visco-random-numba", "numba", history="random smooth"),
    _point("point-cfm-visco-random-torch", "torch", history="random smooth"),
    _point("point-cfm-visco-repeated-numpy", "numpy", history="repeated stretches"),
    _point("point-cfm-instantaneous-uniaxial-numba", "numba", moduli="instantaneous"),
    _point("point-neo-hookean-shear-numpy", "numpy", material="neo-hookean", history="simple shear", elastic=True),
    _point("point-neo-hookean-uniaxial-torch", "torch", material="neo-hookean", elastic=True),
    _point("point-ogden-random-torch", "torch", material="ogden", history="random smooth", elastic=True),
    _point("point-ogden-uniaxial-numpy", "numpy", material="ogden", elastic=True),
    _point("point-mooney-rivlin-repeated-torch", "torch", material="mooney-rivlin", history="repeated stretches",
           elastic=True),
    _point("point-mooney-rivlin-shear-numpy", "numpy", material="mooney-rivlin", history="simple shear", elastic=True),
    # the septa material with its Prony series (composed without it, this case fails)
    _point("point-cfm-septa-visco-uniaxial-numpy", "numpy", material="cfm-septa"),
    # single element (uniaxial stress at 100 1/s) and relaxation (quasi-static, implicit only)
    _single("single-cfm-visco-numba"),
    _single("single-cfm-visco-torch", "torch"),
    _single("single-cfm-visco-skfem", "skfem"),
    _single("single-cfm-elastic-numba", elastic=True, **LIGHT),
    _single("single-cfm-tension-numba", stretch=1.5, **LIGHT),
    _single("single-cfm-hold-numba", hold=0.002),
    _single("single-cfm-rate-200-numba", rate=200.0, **LIGHT),
    _single("single-cfm-instantaneous-numba", moduli="instantaneous", **LIGHT),
    Case("relaxation-cfm-free-skfem", "relaxation", "skfem", {"hold": 1.0}, check="truth-relaxation"),
    Case("relaxation-cfm-confined-skfem", "relaxation", "skfem", {"hold": 1.0, "lateral": "confined"},
         check="truth-relaxation"),
    # drop tests: thickness, speed, moduli, materials, meshes, friction, backends
    _drop("drop-cfm-4mm-numba", thickness=0.004),
    _drop("drop-cfm-6mm-numba"),
    _drop("drop-cfm-8mm-numba", thickness=0.008),
    _drop("drop-cfm-0.5ms-numba", velocity=0.5),
    _drop("drop-cfm-2ms-numba", velocity=2.0),
    _drop("drop-cfm-instantaneous-numba", moduli="instantaneous"),
    _drop("drop-cfm-elastic-numba", elastic=True),
    _drop("drop-cfm-k2-5-numba", parameters={"k2": 5.0}),
    _drop("drop-neo-hookean-torch", "torch", material="neo-hookean", parameters={"mu": 2e4}, **SOFT),
    _drop("drop-ogden-torch", "torch", material="ogden", **SOFT),
    _drop("drop-mooney-rivlin-torch", "torch", material="mooney-rivlin", parameters={"c10": 6e3, "c01": 2e3},
          **SOFT),
    _drop("drop-cfm-mesh-1mm-numba", element_size=0.001),
    _drop("drop-cfm-mesh-3mm-numba", element_size=0.003, width=0.024),
    _drop("drop-cfm-friction-0.3-numba", friction=0.3),
    _drop("drop-cfm-safety-0.5-numba", options={"safety": 0.5}),
    _drop("drop-cfm-6mm-torch", "torch", check="cross-backend"),
    Case("paper-8mm-numba", "drop-test", "numba", {"thickness": 0.008}, check="paper-table"),
]
