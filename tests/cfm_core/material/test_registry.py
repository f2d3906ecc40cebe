"""Registries: fake entry points, broken plugins, duplicates, runtime registration, lazy imports."""

import subprocess
import sys
import warnings
from importlib.metadata import EntryPoint

import numpy as np
import pytest

from cfm_core import (InputError, MaterialSpec, isochoric, make_material, positive, register_material, plugins,
                      volumetric)
from cfm_core import get_backend, get_material
from cfm_core.material import reference as ref


@pytest.fixture
def fake_entry_points(monkeypatch):
    """Replace installed entry points by a table the test controls."""
    table = {}

    def fake(group):
        return table.get(group, [])

    monkeypatch.setattr(plugins, "_iter_entry_points", fake)
    plugins.refresh()
    yield table
    plugins.refresh()


def test_broken_plugin_is_reported_and_skipped(fake_entry_points):
    fake_entry_points["cfm.materials"] = [
        EntryPoint("good", "cfm_plugins.neo_hookean:NEO_HOOKEAN", "cfm.materials"),
        EntryPoint("broken", "no_such_module_xyz:THING", "cfm.materials"),
        EntryPoint("wrongtype", "math:pi", "cfm.materials"),
    ]
    with pytest.warns(RuntimeWarning) as record:
        entries = plugins.entries("materials")
    messages = " ".join(str(w.message) for w in record)
    assert "'broken' is skipped" in messages and "'wrongtype' is skipped" in messages
    assert entries["good"][1] is None
    assert "No module named 'no_such_module_xyz'" in entries["broken"][1]
    assert "not a MaterialSpec" in entries["wrongtype"][1]
    assert get_material("good").name == "neo-hookean"
    with pytest.raises(InputError, match="could not be used"):
        get_material("broken")


def test_duplicate_names_warn_and_keep_the_first(fake_entry_points):
    fake_entry_points["cfm.materials"] = [
        EntryPoint("dup", "cfm_plugins.neo_hookean:NEO_HOOKEAN", "cfm.materials"),
        EntryPoint("dup", "cfm_plugins.cfm:CFM", "cfm.materials"),
    ]
    with pytest.warns(RuntimeWarning, match="keeping the first"):
        spec = get_material("dup")
    assert spec.name == "neo-hookean"


def test_unknown_name_lists_what_exists(fake_entry_points):
    fake_entry_points["cfm.backends"] = [EntryPoint("numpy", "cfm_core.reference_backend:NumpyReferenceBackend", "cfm.backends")]
    with pytest.raises(InputError, match=r"unknown backend 'gpu'; available: numpy"):
        get_backend("gpu")


def test_runtime_registration_of_a_ten_line_material():
    @isochoric(positive("c10", "Pa", 200.0), positive("c01", "Pa", 50.0))
    def my_mooney_rivlin(l1, l2, l3, c10, c01):
        i1 = l1**2 + l2**2 + l3**2
        i2 = (l1 * l2) ** 2 + (l2 * l3) ** 2 + (l1 * l3) ** 2
        return c10 * (i1 - 3) + c01 * (i2 - 3)

    @volumetric(positive("K", "Pa", 1e5))
    def my_volume(J, K):
        return K / 2 * (J - 1) ** 2

    register_material(my_mooney_rivlin & my_volume, name="my-mr")
    try:
        mat = make_material("my-mr", {"c10": 300.0})
        # small-strain shear modulus of Mooney-Rivlin: 2 (c10 + c01)
        CC = ref.tangent(mat, np.eye(3))[0]
        assert CC[0, 1, 0, 1] == pytest.approx(2 * (300.0 + 50.0), rel=1e-10)
        with pytest.raises(InputError, match="already registered"):
            register_material(my_mooney_rivlin & my_volume, name="my-mr")
    finally:
        plugins.unregister("materials", "my-mr")


def test_term_signature_is_checked_against_declaration():
    with pytest.raises(InputError, match="must be the kinematic arguments"):
        @isochoric(positive("mu", "Pa", 1.0))
        def bad(l1, l2, l3, not_mu):
            return not_mu * l1

    assert isinstance(MaterialSpec(name="x"), MaterialSpec)


def test_importing_core_and_listing_backends_imports_no_heavy_library():
    code = (
        "import sys, warnings\n"
        "warnings.simplefilter('ignore')\n"
        "import cfm_core\n"
        "from cfm_core import plugins\n"
        "plugins.entries('backends'); plugins.entries('materials')\n"
        "from cfm_core.cli import main\n"
        "main(['backends'])\n"
        "heavy = [m for m in ('numba', 'torch', 'skfem') if m in sys.modules]\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)


def test_warnings_are_clean_for_installed_plugins():
    plugins.refresh()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        entries = plugins.entries("materials")
    assert {"cfm", "neo-hookean", "ogden", "mooney-rivlin"} <= set(entries)


def test_plugin_breaking_the_specification_is_rejected_with_its_name():
    @isochoric(positive("a", "Pa", 1.0))
    def lopsided(l1, l2, l3, a):
        return a * (l1**2 - 1) ** 2

    @volumetric(positive("K", "Pa", 1.0))
    def prestressed(J, K):
        return K * (J - 1)

    with pytest.raises(InputError, match="'anisotropic'.*not symmetric"):
        (lopsided & prestressed).named("anisotropic").bind().kernels("numpy")

    @isochoric(positive("a", "Pa", 1.0))
    def fine(l1, l2, l3, a):
        return a * (l1**2 + l2**2 + l3**2 - 3)

    with pytest.raises(InputError, match="'prestressed-material'.*not stress-free"):
        (fine & prestressed).named("prestressed-material").bind().kernels("numpy")


@pytest.mark.parametrize("body, words", [
    ("a * math.exp(l1**2 + l2**2 + l3**2 - 3)", "cannot be traced symbolically"),
    ("a * np.exp(l1**2 + l2**2 + l3**2 - 3)", "cannot be traced symbolically"),
    ("a * (l1 - 1) if l1 > 1 else 0", "Python if/else"),
])
def test_energy_written_with_math_or_numpy_is_refused_at_registration_with_a_hint(body, words):
    import math  # noqa: F401  (used by the energy bodies)

    from cfm_plugins.volumetric import ogden_volumetric

    namespace = {"math": math, "np": np}
    exec(f"def energy(l1, l2, l3, a):\n    return {body}\n", namespace)
    term = isochoric(positive("a", "Pa", 1.0), name="traced")(namespace["energy"])
    with pytest.raises(InputError, match=words) as err:
        register_material((term & ogden_volumetric).named("untraceable"))
    assert "cfm.sym.exp" in str(err.value) and "'traced'" in str(err.value)
    assert "untraceable" not in plugins.names("materials")


def test_asymmetric_energy_is_refused_at_registration_not_first_use():
    from cfm_plugins.volumetric import ogden_volumetric

    @isochoric(positive("a", "Pa", 1.0))
    def lopsided(l1, l2, l3, a):
        return a * (l1**2 - 1) ** 2

    with pytest.raises(InputError, match="not symmetric in the principal stretches"):
        register_material((lopsided & ogden_volumetric).named("lopsided"))
    assert "lopsided" not in plugins.names("materials")


def test_range_errors_name_the_unit_and_leave_dimensionless_values_bare():
    """'k2' = -1.0 is outside ... (no stray '-' for the dimensionless unit); Pa values keep theirs."""
    with pytest.raises(InputError) as err:
        make_material("cfm", {"k2": -1.0})
    text = str(err.value)
    assert "'k2' = -1.0 is outside the allowed range (0, inf) (" in text and " - " not in text
    with pytest.raises(InputError, match=r"'k1' = -3.0 Pa is outside the allowed range \(0, inf\) Pa"):
        make_material("cfm", {"k1": -3.0})
