"""Unit-slip warnings of the layers and parts of a specimen (cfm_core.scene.plausible)."""

import pytest

from cfm_core.scene.plausible import check_plausible
from cfm_core.scene.scene import builtin_scene, load_scene


LAYERED = """
[scene]
type = "drop-test"
[specimen]
width = 0.03
element_size = 0.002
[[specimen.layers]]
name = "muscle"
thickness = 0.004
material = "neo-hookean"
density = 1060.0
[specimen.layers.parameters]
mu = 15600.0
kappa = {kappa}
[[specimen.layers]]
name = "fat"
thickness = 0.004
[[specimen.layers]]
name = "skin"
thickness = 0.002
material = "neo-hookean"
[specimen.layers.parameters]
mu = 400000.0
kappa = 20000000.0
"""


def test_a_kpa_slip_under_a_layer_is_warned_naming_the_layer(tmp_path):
    """kappa = 666.1 (kPa meant) under a layer's parameters ran silently (peak 36.3 g instead of 33.3 g)
    while the same value in [material] was warned about; a stiff skin layer is not a slip."""
    path = tmp_path / "layers.toml"
    path.write_text(LAYERED.format(kappa=666.1))
    warnings = check_plausible(load_scene(path))
    assert len(warnings) == 1
    assert warnings[0].startswith("[[specimen.layers]] 1 (muscle) kappa = 666.1 Pa is 1,000x below")
    path.write_text(LAYERED.format(kappa=666100.0))
    assert check_plausible(load_scene(path)) == []
    assert check_plausible(builtin_scene("layered-tissue")) == []   # skin mu = 4e5 Pa: no warning


def test_values_no_layer_uses_are_refused_not_swept(tmp_path, capsys):
    """Every layer with its own material and density: a sweep of k1 or density ran identical runs labelled
    1000 and 2000 Pa (the same 34.41 g), and --density was noted as applied while no part took it."""
    from cfm_core.cli import main
    from cfm_core.errors import InputError
    from cfm_core.studies.sweep import parse_vary

    text = LAYERED.format(kappa=666100.0).replace('name = "fat"\nthickness = 0.004\n',
                                                   'name = "fat"\nthickness = 0.004\nmaterial = "cfm"\n')
    text = text.replace('thickness = 0.002\n', 'thickness = 0.002\ndensity = 1100.0\n').replace(
        'name = "fat"\n', 'name = "fat"\ndensity = 950.0\n')
    path = tmp_path / "own.toml"
    path.write_text(text)
    scene = load_scene(path)
    for vary in ("k1=1000,2000", "density=900,1000"):
        with pytest.raises(InputError, match="no layer of the specimen uses"):
            parse_vary([vary], scene)
    assert main(["drop-test", "--scene", str(path), "--density", "2000", "--out", str(tmp_path / "o")]) == 2
    assert "--density: no layer of the specimen uses [specimen] density" in capsys.readouterr().err
    # the template's fat layer takes [material]: its k1 is swept
    assert [a.name for a in parse_vary(["k1=1000,2000"], load_scene(_write(tmp_path, LAYERED)))] == ["k1"]


def _write(tmp_path, template):
    path = tmp_path / "inherit.toml"
    path.write_text(template.format(kappa=666100.0))
    return path


def test_a_part_density_slip_is_fixed_in_its_table_not_with_the_specimen_flag():
    """The hint for [parts.part_1] density = 1.1 said "(--density 1100)", which sets [specimen] density."""
    import types

    from cfm_core.scene.plausible import _density_warnings

    scene = types.SimpleNamespace(specimen=types.SimpleNamespace(density=950.0, layers=()), element=None,
                                  parts=(types.SimpleNamespace(name="part_1", density=1.1),))
    (text,) = _density_warnings(scene)
    assert "Write density = 1100 in [parts.part_1]" in text and "--density" not in text


@pytest.mark.parametrize("key, value, meant", [("mass", 0.00022, "0.22 kg"), ("velocity", 0.001, "1 m/s")])
def test_a_value_converted_twice_is_warned(key, value, meant):
    """A 220 g impactor written 0.00022 kg ran a 0.22 g one without a word."""
    scene = builtin_scene("drop-test").with_overrides(**{key: value})
    text = [w for w in check_plausible(scene) if f"[impactor] {key} = {value:g}" in w]
    assert len(text) == 1 and f"({meant} meant)" in text[0]
    assert not any(f"[impactor] {key}" in w for w in check_plausible(builtin_scene("drop-test")))


def test_a_flat_impactor_without_edge_radius_is_checked_with_its_default_rim():
    """[impactor] shape = "flat" without edge_radius: TypeError traceback (float(None)) before any run; and the rim
    warning came for a rim outside the specimen too."""
    base = builtin_scene("drop-test").with_overrides(width=0.03, element_size=0.0025, shape="flat")
    small = [w for w in check_plausible(base.with_overrides(radius=0.01)) if "edge_radius" in w]
    assert len(small) == 1 and "edge_radius = 0.001 m" in small[0]         # the default min(1 mm, radius / 2)
    assert not [w for w in check_plausible(base.with_overrides(radius=0.05)) if "edge_radius" in w]  # rim outside


@pytest.mark.parametrize("flag, key, own", [(["--moduli", "long-term"], "moduli", 'moduli = "instantaneous"\n'),
                                            (["--elastic"], "elastic", "elastic = false\n")])
def test_moduli_and_elastic_no_layer_uses_are_refused(tmp_path, capsys, flag, key, own):
    """The only layer taking [material] gives its own moduli (or elastic): --moduli long-term ran
    byte for byte as without it, and summary.json said "long-term" for a layer that ran instantaneous."""
    from cfm_core.cli import main

    path = tmp_path / "own.toml"
    path.write_text(LAYERED.format(kappa=666100.0).replace('name = "fat"\n', f'name = "fat"\n{own}'))
    assert main(["drop-test", "--scene", str(path), *flag, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{flag[0]}: no layer of the specimen uses [material] {key}" in err and "fat" in err
    assert not (tmp_path / "o").exists()
    # a layer taking [material] whole: the flag applies, nothing refused
    from cfm_core.scene.layers import unused_by_layers

    assert unused_by_layers(load_scene(_write(tmp_path, LAYERED)), ["moduli", "elastic", "material"]) == {}
    assert unused_by_layers(load_scene(path), ["material"]) == {}  # the fat layer still takes [material]'s name
