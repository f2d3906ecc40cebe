"""calculix backend without a build: names, the build lookup, and what a user is told (no ccx needed)."""

import json

import pytest

from cfm_backends.calculix.build import find, link_digest, linked_source, tag
from cfm_core.errors import InputError
from cfm_core.material import make_material
from cfm_core.material.cache import spec_fingerprint
from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene
from cfm_core.simulation.registry import get_backend


def test_tag_is_a_calculix_name():
    assert tag("neo-hookean") == "NEO_HOOKEAN"
    assert tag("cfm") == "CFM"


def _fake_build(root, material, definition):
    folder = root / "calculix" / "k1"
    folder.mkdir(parents=True)
    (folder / "ccx").write_text("")
    rec = {"ccx": str(folder / "ccx"), "key": "k1", "version": "2.20", "link": link_digest(),
           "materials": {material: {"tag": tag(material), "definition": definition}}}
    (folder / "build.json").write_text(json.dumps(rec))
    return rec


def test_find_wants_the_materials_current_definition(tmp_path, monkeypatch):
    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path))
    cfm = make_material("cfm")
    assert find() is None and find(cfm) is None
    _fake_build(tmp_path, "cfm", "an-older-definition")
    assert find() is not None
    assert find(cfm) is None  # a build of an older definition of the material is not used
    assert find(make_material("neo-hookean")) is None


def test_find_returns_the_build_with_the_material(tmp_path, monkeypatch):
    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path))
    cfm = make_material("cfm")
    rec = _fake_build(tmp_path, "cfm", spec_fingerprint(cfm.spec))
    assert find(cfm)["ccx"] == rec["ccx"]


def test_find_skips_a_build_linked_with_another_adaptor(tmp_path, monkeypatch):
    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path))
    cfm = make_material("cfm")
    rec = _fake_build(tmp_path, "cfm", spec_fingerprint(cfm.spec))
    path = tmp_path / "calculix" / "k1" / "build.json"
    path.write_text(json.dumps({**rec, "link": "an-older-adaptor"}))
    assert find(cfm) is None and find() is None
    path.write_text(json.dumps({k: v for k, v in rec.items() if k != "link"}))  # builds from before the field
    assert find(cfm) is None


def test_without_a_build_the_user_is_told_how_to_get_it(tmp_path, monkeypatch):
    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path))
    b = get_backend("calculix")
    ok, why = b.available()
    assert not ok and "cfm calculix build" in why
    with pytest.raises(InputError, match="cfm calculix build"):
        b.run(build_model(builtin_scene("single-element")))


def test_linked_source_dispatches_on_each_material():
    mats = [make_material("cfm"), make_material("neo-hookean")]
    text, names = linked_source(mats, {"cfm": "      subroutine umat(a)\n      end subroutine umat\n",
                                       "neo-hookean": "      subroutine umat(a)\n      end subroutine umat\n"})
    assert names["neo-hookean"]["tag"] == "NEO_HOOKEAN"
    assert "if (cmname(1:12) .eq. 'NEO_HOOKEAN ') then" in text and "call cfmu_2(" in text
    assert "subroutine cfmu_1(a)" in text and "end subroutine cfmu_2" in text
    assert "!     CFM-DISPATCH\n" not in text  # the marker line is replaced by the dispatch
    assert max(len(line) for line in text.splitlines()) <= 72  # fixed form


def test_adaptor_inverts_f_with_the_exports_own_routines():
    """No second hand-written 3x3 inverse: the adaptor's det3 and inv3 are the export's templates
    (the UMAT's {P}inv3, the kernel's {P}det3) with the prefix cfmad_."""
    from cfm_backends.calculix.build import ADAPTOR, _template_routine, adaptor_source
    from cfm_core.export import abaqus, fortran, kernel

    hand = ADAPTOR.read_text()
    assert "cfmad_inv3(a, b)" not in hand and "!     CFM-HELPERS\n" in hand
    text = adaptor_source()
    for template, kind, name in ((abaqus.UMAT, "subroutine", "inv3"), (kernel.CORE, "function", "det3")):
        routine = _template_routine(template, kind, name)
        assert routine.replace("{P}", "cfmad_").replace("{DP}", fortran.DP) in text
    assert "!     CFM-HELPERS\n" not in text and max(len(line) for line in text.splitlines()) <= 72
    with pytest.raises(InputError, match="no subroutine"):
        _template_routine(abaqus.UMAT, "subroutine", "nosuch")
