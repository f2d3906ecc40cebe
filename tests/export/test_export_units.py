"""Consistent unit systems of other solvers (docs/user/export.md, "Units of other solvers"): the table's
factors are those dimensional analysis gives from length, time and mass, and the generated routines, given
constants and times converted with them, return the SI stress times the stress factor (the sources hold no
dimensional constant). The docs had no such table: a user converting by hand had no check."""

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import uniaxial

from cfm_core.export import layout
from cfm_core.export.harness import run_lsdyna, run_umat, run_vumat

PAGE = Path(__file__).resolve().parents[2] / "docs" / "user" / "export.md"
#: Factor from the SI unit of length, time and mass to each system's (m -> mm: 1e3).
SYSTEMS = {"mm-s-tonne": {"m": 1e3, "s": 1.0, "kg": 1e-3}, "mm-ms-kg": {"m": 1e3, "s": 1e3, "kg": 1.0}}
#: SI unit -> its exponents of length, time, mass.
DIMENSIONS = {"m": (1, 0, 0), "s": (0, 1, 0), "kg": (0, 0, 1), "kg/m^3": (-3, 0, 1), "Pa": (-1, -2, 1),
              "N": (1, -2, 1), "m/s": (1, -1, 0), "J": (2, -2, 1), "J/kg": (2, -2, 0), "-": (0, 0, 0)}


def factor(system: str, unit: str) -> float:
    """The factor from the SI unit to the system's, from those of length, time and mass."""
    base = SYSTEMS[system]
    length, time, mass = DIMENSIONS[unit]
    return base["m"] ** length * base["s"] ** time * base["kg"] ** mass


def table_rows() -> list[list[str]]:
    """The rows of the page's unit table (cells stripped), header and separator left out."""
    text = PAGE.read_text()
    section = text.split("## Units of other solvers", 1)[1].split("\n## ", 1)[0]
    lines = [line for line in section.splitlines() if line.startswith("|")]
    assert lines[0].startswith("| quantity |") and "mm-s-tonne" in lines[0] and "mm-ms-kg" in lines[0]
    return [[c.strip() for c in line.strip("|").split("|")] for line in lines[2:]]


def test_the_unit_table_gives_the_factors_of_dimensional_analysis():
    rows = table_rows()
    assert {r[2] for r in rows} == {"m", "s", "kg", "kg/m^3", "Pa", "N", "m/s", "J", "-"}
    for quantity, _, si, _, f1, _, f2 in rows:
        for system, given in (("mm-s-tonne", f1), ("mm-ms-kg", f2)):
            assert float(given) == pytest.approx(factor(system, si), rel=1e-12), (quantity, system)


def test_the_examples_under_the_table_are_the_cards_values_converted(cfm):
    text = " ".join(PAGE.read_text().split("## Units of other solvers", 1)[1].split("\n## ", 1)[0].split())
    number = r"([0-9.e+-]+)"
    found = re.findall(rf"c = {number}, k1 = {number}, kappa = {number} \((MPa|GPa)\), tau1, tau2, tau3 = {number}, "
                       rf"{number}, {number} \((s|ms)\), density {number} \((tonne/mm\^3|kg/mm\^3)\)", text)
    assert [f[3] for f in found] == ["MPa", "GPa"]
    v = cfm.values
    for system, (c, k1, kappa, _, t1, t2, t3, _, rho, _) in zip(SYSTEMS, found):
        p, s = factor(system, "Pa"), factor(system, "s")
        got = [float(x) for x in (c, k1, kappa, t1, t2, t3, rho)]
        want = [v["c"] * p, v["k1"] * p, v["kappa"] * p, v["tau1"] * s, v["tau2"] * s, v["tau3"] * s,
                950.0 * factor(system, "kg/m^3")]
        assert got == pytest.approx(want, rel=1e-12), system


def _converted(material, system: str, lsdyna: bool = False) -> np.ndarray:
    entries = layout.constants(material.spec, lsdyna, material)
    return np.array([e.default * factor(system, e.unit) for e in entries])


@pytest.mark.parametrize("system", list(SYSTEMS))
def test_the_routines_run_in_every_consistent_unit_system(libs, cfm, nstate, system):
    """Compression at 100/s, then held: the Prony terms relax (dt / tau), so times matter as well as moduli."""
    t, F = uniaxial(100.0, 0.6, hold=0.05)
    ts, ps = t * factor(system, "s"), factor(system, "Pa")
    si = run_umat(libs["abaqus-umat"], layout.props(cfm), t, F, nstate)
    other = run_umat(libs["abaqus-umat"], _converted(cfm, system), ts, F, nstate)
    scale = np.abs(si["stress"]).max()
    np.testing.assert_allclose(other["stress"], si["stress"] * ps, rtol=1e-12, atol=1e-12 * scale * ps)
    np.testing.assert_allclose(other["ddsdde"], si["ddsdde"] * ps, rtol=1e-12,
                               atol=1e-12 * np.abs(si["ddsdde"]).max() * ps)
    si = run_lsdyna(libs["lsdyna-umat"], layout.props(cfm, lsdyna=True), t, F, nstate)
    other = run_lsdyna(libs["lsdyna-umat"], _converted(cfm, system, lsdyna=True), ts, F, nstate)
    np.testing.assert_allclose(other["stress"], si["stress"] * ps, rtol=1e-12, atol=1e-12 * scale * ps)
    rho = 950.0
    si = run_vumat(libs["abaqus-vumat"], layout.props(cfm), t, F[:, None], nstate, density=rho)
    other = run_vumat(libs["abaqus-vumat"], _converted(cfm, system), ts, F[:, None], nstate,
                      density=rho * factor(system, "kg/m^3"))
    np.testing.assert_allclose(other["stress"], si["stress"] * ps, rtol=1e-12, atol=1e-12 * scale * ps)
    energy = factor(system, "J/kg")  # the specific internal energy, stress power / density
    np.testing.assert_allclose(other["ener_intern"], si["ener_intern"] * energy, rtol=1e-10,
                               atol=1e-12 * np.abs(si["ener_intern"]).max() * energy)
