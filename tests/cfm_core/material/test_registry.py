"""Registries: fake entry points, broken plugins, duplicates, runtime registration, lazy imports."""

import subprocess
import sys
import warnings
from importlib.metadata import EntryPoint
from types import SimpleNamespace

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


def _ep(name, value, group, dist=None, version="1.0"):
    """A fake entry point of a fake distribution (importlib attaches the real one the same way)."""
    ep = EntryPoint(name, value, group)
    return ep._for(SimpleNamespace(name=dist, version=version)) if dist else ep


BUILTIN_CFM = ("cfm", "cfm_plugins.cfm:CFM", "cfm.materials", "cfm-materials", "0.2.0")
IMPOSTOR = ("cfm", "cfm_plugins.neo_hookean:NEO_HOOKEAN", "cfm.materials", "cfm-impostor", "9.9")


def test_a_plugin_reusing_a_builtin_name_is_refused_naming_both_distributions(fake_entry_points, monkeypatch):
    """Old code: the first entry point on the path won with a RuntimeWarning (here the paper's model
    would silently become neo-Hookean if the impostor came first)."""
    monkeypatch.delenv(plugins.PREFER_ENV, raising=False)
    fake_entry_points["cfm.materials"] = [_ep(*IMPOSTOR), _ep(*BUILTIN_CFM),
                                          _ep("ogden", "cfm_plugins.ogden:OGDEN", "cfm.materials", "cfm-materials")]
    with pytest.raises(InputError) as err:
        get_material("cfm")
    text = str(err.value)
    for words in ("cfm-materials 0.2.0", "cfm = cfm_plugins.cfm:CFM, the built-in", "cfm-impostor 9.9",
                  "cfm = cfm_plugins.neo_hookean:NEO_HOOKEAN", "reuses a built-in's name",
                  'CFM_PLUGIN_PREFER="materials:cfm=DISTRIBUTION"'):
        assert words in text, (words, text)
    assert "\n" not in text
    with pytest.raises(InputError, match="cfm-impostor"):
        plugins.origin("materials", "cfm")
    # listing still works and shows the conflict; the other names are usable
    with pytest.warns(RuntimeWarning, match="'cfm' is skipped"):
        entries = plugins.entries("materials")
    assert entries["cfm"][0] is None and "cfm-impostor" in entries["cfm"][1]
    assert entries["ogden"][1] is None and get_material("ogden").name == "ogden"
    assert plugins.names("materials") == ["cfm", "ogden"]


@pytest.mark.parametrize("prefer, expected, dist", [
    ("materials:cfm=cfm-materials", "cfm", "cfm-materials"),
    ("cfm=cfm_Impostor", "neo-hookean", "cfm-impostor"),           # any kind; names compared as pip does
    ("backends:numba=x, materials:cfm=cfm-impostor", "neo-hookean", "cfm-impostor"),
])
def test_the_user_chooses_a_distribution_explicitly_and_origin_names_it(fake_entry_points, monkeypatch, prefer,
                                                                        expected, dist):
    monkeypatch.setenv(plugins.PREFER_ENV, prefer)
    fake_entry_points["cfm.materials"] = [_ep(*IMPOSTOR), _ep(*BUILTIN_CFM)]
    assert get_material("cfm").name == expected
    where = plugins.origin("materials", "cfm")
    assert where["distribution"] == dist and where["version"] == ("0.2.0" if dist == "cfm-materials" else "9.9")


def test_a_preference_naming_neither_distribution_or_malformed_is_an_input_error(fake_entry_points, monkeypatch):
    fake_entry_points["cfm.materials"] = [_ep(*IMPOSTOR), _ep(*BUILTIN_CFM)]
    monkeypatch.setenv(plugins.PREFER_ENV, "materials:cfm=somebody-else")
    with pytest.raises(InputError, match="prefers distribution 'somebody-else', which declares no material 'cfm'"):
        get_material("cfm")
    monkeypatch.setenv(plugins.PREFER_ENV, "cfm")
    with pytest.raises(InputError, match=r"CFM_PLUGIN_PREFER item 'cfm' is not '\[kind:\]name=distribution'"):
        get_material("cfm")


def test_two_plugins_with_one_name_are_refused_and_one_distribution_found_twice_is_not(fake_entry_points,
                                                                                       monkeypatch):
    """Old code: a RuntimeWarning and the first one kept."""
    monkeypatch.delenv(plugins.PREFER_ENV, raising=False)
    fake_entry_points["cfm.materials"] = [
        _ep("dup", "cfm_plugins.neo_hookean:NEO_HOOKEAN", "cfm.materials", "dist-a"),
        _ep("dup", "cfm_plugins.cfm:CFM", "cfm.materials", "dist-b"),
        _ep("twice", "cfm_plugins.ogden:OGDEN", "cfm.materials", "dist-a"),
        _ep("twice", "cfm_plugins.ogden:OGDEN", "cfm.materials", "dist_A"),  # the same install seen twice
    ]
    with pytest.raises(InputError, match=r"dist-a 1.0 \(entry point dup = cfm_plugins.neo_hookean:NEO_HOOKEAN\) and "
                                         r"dist-b 1.0 \(entry point dup = cfm_plugins.cfm:CFM\): two plugins share"):
        get_material("dup")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert get_material("twice").name == "ogden"
    monkeypatch.setenv(plugins.PREFER_ENV, "dup=dist-b")
    assert get_material("dup").name == "cfm"


def test_an_explicit_runtime_registration_still_shadows_an_entry_point(fake_entry_points):
    fake_entry_points["cfm.materials"] = [_ep(*BUILTIN_CFM)]
    from cfm_plugins.neo_hookean import NEO_HOOKEAN

    with pytest.raises(InputError, match="already registered"):
        register_material(NEO_HOOKEAN, name="cfm")
    register_material(NEO_HOOKEAN, name="cfm", overwrite=True)
    try:
        assert "mu" in [q.name for q in get_material("cfm").parameters]
        assert plugins.origin("materials", "cfm")["distribution"] is None
    finally:
        plugins.unregister("materials", "cfm")


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


def test_a_distributions_name_and_version_are_read_once():
    """plugins._dist_of reads a distribution's metadata (name, version) once per distribution
    object: each read parses its metadata file again (about 2 ms; a drop test asked 38 times)."""
    from cfm_core import plugins

    class Dist:
        reads = 0

        @property
        def name(self):
            Dist.reads += 1
            return "cfm-acme"

        @property
        def version(self):
            Dist.reads += 1
            return "1.2"

    ep = type("EP", (), {})()
    ep.dist = Dist()
    assert plugins._dist_of(ep) == ("cfm-acme", "1.2") and Dist.reads == 2
    assert plugins._dist_of(ep) == ("cfm-acme", "1.2") and Dist.reads == 2
    other = type("EP", (), {})()
    other.dist = Dist()
    assert plugins._dist_of(other) == ("cfm-acme", "1.2") and Dist.reads == 4
    assert plugins._dist_of(type("EP", (), {"dist": None})()) == (None, None)
