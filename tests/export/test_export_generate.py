"""``cfm export``: the files it writes (source, card, manifest), what they say, and that the
sources of other materials compile warning-free and agree with the reference too."""

import json

import numpy as np
import pytest
from conftest import uniaxial

from cfm_core.cli.app import main
from cfm_core.errors import InputError
from cfm_core.export import TARGETS, expected, export, layout
from cfm_core.export.harness import ABAQUS_STANDARD, run_umat
from cfm_core.fingerprint import package_version
from cfm_core.material import make_material
from cfm_core.material.cache import spec_fingerprint

TABLE1 = {"c": 10.0, "k1": 1320.0, "k2": 1.66, "kappa": 666.1e3, "g1": 0.45, "tau1": 1e-3, "g2": 0.435,
          "tau2": 0.1, "g3": 0.094, "tau3": 10.0, "moduli": 1.0}


@pytest.mark.parametrize("target", list(TARGETS))
def test_cli_writes_source_card_and_manifest(tmp_path, capsys, target, cfm):
    assert main(["export", "cfm", "--to", target, "--out", str(tmp_path / "x")]) == 0
    info = TARGETS[target]
    manifest = json.loads((tmp_path / "x" / "manifest.json").read_text())
    consts = {c["name"]: c["value"] for c in manifest["constants"]}
    assert {k: consts[k] for k in TABLE1} == TABLE1
    assert [c["index"] for c in manifest["constants"]] == list(range(1, len(consts) + 1))
    assert len(manifest["state_variables"]) == 25 and manifest["state_variables"][-1]["name"] == "error"
    assert manifest["generated_by"]["definition_hash"] == spec_fingerprint(cfm.spec)
    source = (tmp_path / "x" / info["source"]).read_text()
    assert f"cfm-materials {package_version()}" in source and spec_fingerprint(cfm.spec) in source
    assert all(len(line) <= 72 for line in source.splitlines())  # fixed form
    assert "not run in the commercial solver" in source
    card = (tmp_path / "x" / info["card"]).read_text()
    if target == "lsdyna-umat":
        assert "IHYPER" in card and "        25" in card.splitlines()[card.splitlines().index(
            "$      MID        RO        MT       LMC       NHV    IORTHO     IBULK        IG") + 1]
    else:
        assert "*USER MATERIAL, CONSTANTS=11" in card and "*DEPVAR\n25" in card
        assert "10.0, 1320.0, 1.66, 666100.0, 0.45, 0.001, 0.435, 0.1" in card
    assert "wrote" in capsys.readouterr().out


def test_card_takes_parameters_and_errors_are_one_paragraph(tmp_path, capsys):
    assert main(["export", "cfm", "--to", "abaqus-umat", "--out", str(tmp_path / "a"), "--param", "c=20",
                 "--moduli", "instantaneous"]) == 0
    consts = {c["name"]: c["value"] for c in json.loads((tmp_path / "a" / "manifest.json").read_text())["constants"]}
    assert consts["c"] == 20.0 and consts["moduli"] == 0.0
    (tmp_path / "file").write_text("")
    assert main(["export", "cfm", "--to", "abaqus-umat", "--out", str(tmp_path / "file")]) == 2
    assert main(["export", "cfm", "--to", "abaqus-umat", "--out", str(tmp_path / "b"), "--param", "c=-1"]) == 2
    assert "Traceback" not in capsys.readouterr().err
    with pytest.raises(InputError, match="abaqus-umat"):
        export(make_material("cfm"), "calculix", tmp_path / "c")


def test_compiles_warning_free(libs):
    assert {k: lib.warnings for k, lib in libs.items()} == {k: "" for k in libs}


@pytest.mark.parametrize("name", ["neo-hookean", "ogden"])
def test_other_materials(compiled, name):
    """A material without a Prony series and one with another term compile warning-free and agree."""
    material = make_material(name)
    lib = compiled(material, "abaqus-umat")
    assert lib.warnings == ""
    t, F = uniaxial(100.0, 0.6, n=20)
    sigma, _ = expected.history(material, t, F)
    out = run_umat(lib, layout.props(material), t, F, len(layout.state_variables(material.spec)))
    ref = expected.to_order(sigma, ABAQUS_STANDARD)
    assert (np.abs(out["stress"] - ref).max(axis=1) <= 1e-10 * np.abs(ref).max(axis=1) + 1e-8).all()


def test_umat_cost_is_measured_in_fortran(libs, cfm):
    from cfm_core.export.cost import umat_cost

    seconds = umat_cost(cfm, calls=2000)
    assert 1e-8 < seconds < 1e-3
