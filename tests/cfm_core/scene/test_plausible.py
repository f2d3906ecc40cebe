"""Unit-slip warnings of the layers and parts of a specimen (cfm_core.scene.plausible)."""

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
