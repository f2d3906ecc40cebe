"""``cfm export --density``: the unit hints of a density in the model units of docs/user/export.md's table,
the value as typed where it overflows, and the warning for a density unusual for tissue (as scenes warn)."""

import pytest

from cfm_core.cli import main
from cfm_core.scene.plausible import DENSITY_USUAL, density_warning, unit_hint

SMALL = ["--thickness", "0.005", "--element-size", "0.0025", "--no-plot", "--quiet"]


def test_a_density_in_kg_per_cubic_millimetre_gets_the_hint_in_export(tmp_path, capsys):
    """9.5e-7 (kg/mm^3, an mm-ms-kg model's density, export.md's table) was refused with no hint, while 9.5e-10
    (tonne/mm^3) and 0.95 (g/cm^3) had one."""
    assert main(["export", "cfm", "--to", "abaqus-vumat", "--density", "9.5e-7", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--density 9.5e-07 kg/m^3 is not allowed" in err or "--density 9.5e-7 kg/m^3 is not allowed" in err
    assert "did you mean 950 kg/m^3 (9.5e-07 kg/mm^3)? Give --density 950" in err and err.count("\n") == 1, err
    assert not (tmp_path / "x").exists()


def test_a_scene_density_in_kg_per_cubic_millimetre_gets_the_hint_too(tmp_path, capsys):
    assert main(["drop-test", *SMALL, "--density", "9.5e-7", "--out", str(tmp_path / "o")]) == 2
    assert "did you mean 950 kg/m^3 (9.5e-07 kg/mm^3)? Write density = 950 (--density 950)" in capsys.readouterr().err


def test_the_unit_slips_tell_tonne_from_kilogram_per_cubic_millimetre():
    lo, hi = DENSITY_USUAL
    assert "(9.2e-10 tonne/mm^3)" in unit_hint("density", 9.2e-10, "kg/m^3", lo, hi)
    assert "(9.2e-07 kg/mm^3)" in unit_hint("density", 9.2e-7, "kg/m^3", lo, hi)
    assert "(0.92 g/cm^3)" in unit_hint("density", 0.92, "kg/m^3", lo, hi)


@pytest.mark.parametrize("typed", ["1e400", "-1e400", "1" + "0" * 400])
def test_a_density_beyond_the_float_range_is_shown_as_typed(tmp_path, capsys, typed):
    """--density 1e400 was answered "--density inf kg/m^3 is not allowed": not what was typed."""
    assert main(["export", "cfm", "--to", "abaqus-vumat", f"--density={typed}", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    shown = typed if len(typed) < 20 else "1000...0 (an integer of 401 digits)"
    assert f"--density {shown} kg/m^3 is not allowed" in err and "inf" in err and err.count("\n") == 1, err
    assert "Traceback" not in err and not (tmp_path / "x").exists()


@pytest.mark.parametrize("rho, warned", [(100000.0, True), (4000.0, True), (400.0, True), (950.0, False),
                                         (2000.0, False)])
def test_export_warns_of_a_density_unusual_for_tissue_as_scenes_do(tmp_path, capsys, rho, warned):
    """--density 100000 was written onto the card without a word, while a scene's warns above 3000 kg/m^3."""
    assert main(["export", "cfm", "--to", "abaqus-vumat", "--density", f"{rho:g}", "--out", str(tmp_path / "x")]) == 0
    captured = capsys.readouterr()
    assert ("unusual for tissue" in captured.err) is warned, captured.err
    assert "unusual" not in captured.out
    assert (tmp_path / "x" / "material.inp").is_file()  # warned, not refused
    if warned:
        assert f"--density {rho:g} kg/m^3 is unusual for tissue" in captured.err


def test_the_density_warning_is_one_check_for_scenes_and_export():
    assert density_warning("[specimen] density", 5000.0) == ("[specimen] density = 5000 kg/m^3 is unusual for tissue "
                                                           "(soft tissue 900-1100, bone up to ~2000 kg/m^3); it runs "
                                                           "as given.")
    assert density_warning("--density", 5000.0, as_given="the card holds it as given").endswith(
        "; the card holds it as given.")
    assert density_warning("[specimen] density", 1000.0) is None
    slip = density_warning("--density", 1.06, option="--density", as_given="the card holds it as given")
    assert "(1.06 g/cm^3)? Give --density 1060" in slip and slip.endswith(" The card holds it as given.")
