"""The generated-code cache is keyed by content: every ingredient of the generated source changes
its key, and a changed ingredient makes the next use generate again (old key: the generator's one
file and each energy's own file, so an edit of a helper module or of the symbolic layer was served
the stale code)."""

import shutil
import sys
import textwrap
import uuid

import pytest

from cfm_core import fingerprint
from cfm_core.material import cache
from cfm_core.material.registry import get_material

HELPERS = "def shape(x):\n    return x**2\n"
TERM = textwrap.dedent('''
    from cfm_core.material.parameters import positive
    from cfm_core.material.terms import isochoric
    from cfm_plugins.volumetric import quadratic_volumetric

    from . import helpers


    @isochoric(positive("a", "Pa", 1.0), name="helper-term")
    def energy(l1, l2, l3, a):
        return a * (helpers.shape(l1) + helpers.shape(l2) + helpers.shape(l3) - 3)


    SPEC = (energy & quadratic_volumetric).named("helper-material")
''')


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A plugin package whose energy calls a helper of another of its modules."""
    name = f"cachetest_{uuid.uuid4().hex[:8]}"
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helpers.py").write_text(HELPERS)
    (pkg / "term.py").write_text(TERM)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("CFM_NO_CODEGEN_CACHE", raising=False)
    module = __import__(f"{name}.term", fromlist=["SPEC"])
    yield pkg, module.SPEC
    for key in [k for k in sys.modules if k.startswith(name)]:
        del sys.modules[key]


def _cached(spec, calls):
    def generate():
        calls.append(1)
        return f"# generated {len(calls)}\n"

    return cache.codegen_cache(spec, "math", generate)


def test_each_ingredient_changes_the_key_and_the_rerun_generates_again(plugin, tmp_path, monkeypatch):
    pkg, spec = plugin
    calls = []
    first = _cached(spec, calls)
    assert _cached(spec, calls) == first and len(calls) == 1          # cached: not generated again

    # the helper module the energy calls (a module imported by another)
    (pkg / "helpers.py").write_text(HELPERS.replace("x**2", "x**2 + 0"))
    assert _cached(spec, calls) != first and len(calls) == 2
    assert _cached(spec, calls) and len(calls) == 2

    # the energy's own file
    (pkg / "term.py").write_text(TERM + "\n# an edit\n")
    _cached(spec, calls)
    assert len(calls) == 3

    # the generator: any module of cfm_core.material (sym.py here), the project's version, sympy's
    copy = tmp_path / "material"
    shutil.copytree(cache.CODEGEN_FILE.parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(cache, "CODEGEN_FILE", copy / "codegen.py")
    cache.generator_digest.cache_clear()
    _cached(spec, calls)
    assert len(calls) == 3                                               # same text: same key
    (copy / "sym.py").write_text((copy / "sym.py").read_text() + "\n# an edit\n")
    cache.generator_digest.cache_clear()
    _cached(spec, calls)
    assert len(calls) == 4
    monkeypatch.setattr(fingerprint, "package_version", lambda: "99.0")
    cache.generator_digest.cache_clear()
    _cached(spec, calls)
    assert len(calls) == 5
    cache.generator_digest.cache_clear()
    assert str(pkg / "helpers.py") in cache.dependency_files(spec.isochoric[0].energy)


def test_the_cfm_material_depends_on_the_neo_hookean_file_its_lipid_term_calls():
    files = {f.replace("\\", "/").rsplit("/", 1)[-1] for t in get_material("cfm").isochoric
             for f in cache.dependency_files(t.energy)}
    assert {"cfm.py", "neo_hookean.py", "sym.py"} <= files


def test_the_key_is_the_same_in_every_process_and_closures_count_by_content():
    """cfm-septa's energy captures numpy arrays (the sphere rule): hashed by content, not by a
    truncated or address-bearing repr, so another process finds the same key."""
    import subprocess

    code = ("from cfm_core.material.registry import get_material\n"
            "from cfm_core.material.cache import spec_fingerprint\n"
            "print(spec_fingerprint(get_material('cfm-septa')))")
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert other == cache.spec_fingerprint(get_material("cfm-septa"))
    from cfm_plugins.septa import septa_term
    from cfm_plugins.volumetric import ogden_volumetric

    assert cache.spec_fingerprint(septa_term(15) & ogden_volumetric) != cache.spec_fingerprint(
        septa_term(17) & ogden_volumetric)


def test_an_interactive_energy_is_never_cached(monkeypatch):
    from cfm_core.material.parameters import positive
    from cfm_core.material.terms import isochoric
    from cfm_plugins.volumetric import quadratic_volumetric

    namespace = {}
    exec("def energy(l1, l2, l3, a):\n    return a * (l1**2 + l2**2 + l3**2 - 3)\n", namespace)
    term = isochoric(positive("a", "Pa", 1.0), name="typed")(namespace["energy"])
    assert cache.spec_fingerprint(term & quadratic_volumetric) is None


def test_a_helper_module_beside_a_single_file_plugin_is_followed(tmp_path, monkeypatch):
    """A plugin file (not a package) whose energy calls a function of another top-level module in its
    folder: an edit of the helper kept the key, and cfm reused the stale derivatives and kernels
    (s11 -26400.8 Pa for -26802.0)."""
    name = f"cachehelp_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{name}_helper.py").write_text("def scale():\n    return 1.0\n")
    (tmp_path / f"{name}.py").write_text(TERM.replace("from . import helpers", f"import {name}_helper as helpers")
                                         .replace("helpers.shape(l1) + helpers.shape(l2) + helpers.shape(l3) - 3",
                                                  "helpers.scale() * (l1**2 + l2**2 + l3**2 - 3)"))
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        spec = __import__(name).SPEC
        first = cache.spec_fingerprint(spec)
        assert str(tmp_path / f"{name}_helper.py") in cache.dependency_files(spec.isochoric[0].energy)
        (tmp_path / f"{name}_helper.py").write_text("def scale():\n    return 2.0\n")
        assert cache.spec_fingerprint(spec) != first
    finally:
        for key in [k for k in sys.modules if k.startswith(name)]:
            del sys.modules[key]


@pytest.mark.parametrize("value, edited", [("1.0", "3.0"), ("{'s': 1.0}", "{'s': 3.0}")])
def test_a_value_imported_by_name_from_a_helper_module_counts(tmp_path, monkeypatch, value, edited):
    """``from consts import SCALE``: the value lives in the plugin's namespace, its file is the
    helper's. Editing SCALE kept the key, and the code caches returned the old energy's stresses
    (uniaxial -11829.3 Pa for -35226.4) and the sweep reused the old runs."""
    name = f"cacheconst_{uuid.uuid4().hex[:8]}"
    use = "SCALE" if value[0] != "{" else "SCALE['s']"
    (tmp_path / f"{name}_consts.py").write_text(f"SCALE = {value}\n")
    (tmp_path / f"{name}.py").write_text(TERM.replace("from . import helpers", f"from {name}_consts import SCALE")
                                         .replace("helpers.shape(l1) + helpers.shape(l2) + helpers.shape(l3) - 3",
                                                  f"{use} * (l1**2 + l2**2 + l3**2 - 3)"))
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        spec = __import__(name).SPEC
        first, defined = cache.spec_fingerprint(spec), cache.definition_digest(spec)
        assert cache.spec_fingerprint(spec) == first  # stable
        sys.modules[name].SCALE = eval(edited)  # what a new process reading the edited helper sees
        assert cache.spec_fingerprint(spec) != first
        assert cache.definition_digest(spec) != defined  # provenance and the sweep's run key see it too
    finally:
        for key in [k for k in sys.modules if k.startswith(name)]:
            del sys.modules[key]


def test_installed_libraries_are_not_followed():
    """numpy, sympy and the standard library are not the user's code: their files stay out of the key."""
    import numpy

    assert cache._user_module_file(numpy) is None and cache._user_module_file(textwrap.dedent) is None


def test_the_definition_digest_tells_prony_defaults_and_moduli_apart():
    """Two plugins with the same terms and other Prony defaults had one digest: the sweep cache served the
    first one's results to the second (67.3 g for 170.0 g)."""
    from cfm_core.material.prony import PronySeries
    from cfm_plugins.cfm import circular_fibers, lipid
    from cfm_plugins.volumetric import ogden_volumetric

    def spec(g1, moduli="long-term"):
        s = (lipid & circular_fibers & ogden_volumetric & PronySeries(((g1, 1e-3), (0.435, 0.1)))).named("p")
        return s if moduli == "long-term" else type(s)(**{**s.__dict__, "default_moduli": moduli})

    a, b, c = spec(0.45), spec(0.0), spec(0.45, "instantaneous")
    assert cache.spec_fingerprint(a) == cache.spec_fingerprint(b)      # the same code
    assert len({cache.definition_digest(x) for x in (a, b, c)}) == 3     # other definitions
    assert cache.definition_digest(spec(0.45)) == cache.definition_digest(a)
