"""Issue 21 end to end: the layered-tissue and flat-impactor built-in scenes on the backends, an
off-centre oblique impact on a user's gmsh mesh with two named parts, and the full deformed
specimen with its fields and the impactor in the VTU output.

The backends' own tests check the pieces (parts equal to the one-material run, shapes against the
reference gap, symmetry "none" against the quarter, momentum); here the user's paths are run.
"""

import json

import meshio
import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.runs import drop_test
from cfm_core.scene.mesh import structured_hex_mesh
from cfm_core.scene.scene import builtin_scene

# the built-in scenes with 2 mm elements (full 50 mm width: a narrower block folds under them)
LAYERED = builtin_scene("layered-tissue").with_overrides(element_size=0.002)
FLAT = builtin_scene("flat-impactor").with_overrides(element_size=0.002)


def _peak(outcome) -> float:
    return float(outcome.peak_g)


@pytest.mark.parametrize("scene", [pytest.param(LAYERED, marks=pytest.mark.slow), FLAT],
                         ids=["layered-tissue", "flat-impactor"])
def test_new_scenes_agree_on_numba_and_torch(scene):
    """Explicit against explicit on the same mesh: the issue's 1 % on the filtered peak; the same
    element, step rule and contact leave only summation order (so far tighter: 1e-9). Measured
    (2 mm): layered 16.981 g on both, flat 79.323 g on both; the layered torch run takes about a
    minute on 2 cores, so it runs with --runslow."""
    pytest.importorskip("numba")
    pytest.importorskip("torch")
    a, b = drop_test(scene, backend="numba"), drop_test(scene, backend="torch")
    assert a.result.info["stop_reason"] == "separated" and b.result.info["stop_reason"] == "separated"
    assert abs(_peak(a) - _peak(b)) <= 1e-9 * _peak(a)
    assert a.result.info["energy_error"] < 0.01


@pytest.mark.slow
@pytest.mark.parametrize("scene", [LAYERED, FLAT], ids=["layered-tissue", "flat-impactor"])
def test_new_scenes_agree_on_skfem_and_numba(scene):
    """Implicit against explicit on the same mesh: the issue's 3 % on the filtered peak. Measured
    (2 mm): layered 17.250 g (skfem) against 16.981 g (numba), 1.6 %; flat 78.295 g against
    79.323 g, 1.3 % (4 and 1 minutes of skfem on 2 cores)."""
    pytest.importorskip("skfem")
    a, b = drop_test(scene, backend="numba"), drop_test(scene, backend="skfem")
    assert abs(_peak(a) - _peak(b)) <= 0.03 * _peak(a), (_peak(a), _peak(b))


def _two_part_mesh(tmp_path):
    """A full 24 x 24 x 6 mm block, 2 mm elements, centred at x = y = 0: "fat" below 4 mm, "skin"
    above, as gmsh physical groups."""
    nodes, hexes = structured_hex_mesh(0.024, 0.024, 0.006, 12, 12, 3, (-0.012, -0.012, 0.0))
    tags = np.where(nodes[hexes, 2].mean(axis=1) < 0.004, 1, 2)
    path = tmp_path / "block.msh"
    meshio.write(path, meshio.Mesh(nodes, [("hexahedron", hexes)],
                                   cell_data={"gmsh:physical": [tags], "gmsh:geometrical": [tags]},
                                   field_data={"fat": np.array([1, 3]), "skin": np.array([2, 3])}),
                 file_format="gmsh22", binary=False)
    return path, hexes.shape[0]


def test_oblique_off_centre_impact_on_a_gmsh_mesh_with_two_parts(tmp_path, capsys):
    pytest.importorskip("numba")
    mesh, n_el = _two_part_mesh(tmp_path)
    scene = tmp_path / "scene.toml"
    scene.write_text(f"""
[scene]
type = "drop-test"
name = "oblique"
end_time = 0.004

[specimen]
mesh = "{mesh.name}"

[parts.fat]
material = "cfm"

[parts.skin]
material = "neo-hookean"
density = 1100.0
[parts.skin.parameters]
mu = 4.0e4
kappa = 2.0e6

[impactor]
shape = "sphere"
radius = 0.02
mass = 0.05
velocity = 1.0
angle = 20.0
azimuth = 30.0
offset = [0.003, 0.002]
""")
    out = tmp_path / "out"
    assert main(["run", "--scene", str(scene), "--backend", "numba", "--vtu", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["symmetry"] == "none"
    assert [(p["name"], p["material"]) for p in summary["parts"]] == [("fat", "cfm"), ("skin", "neo-hookean")]
    assert sum(p["elements"] for p in summary["parts"]) == n_el
    assert summary["peak_g"] > 0.0
    prov = summary["provenance"]
    assert prov["parts"][1]["material"]["name"] == "neo-hookean"
    vtus = sorted(out.glob("specimen_*.vtu"))
    assert vtus, "no frames written"
    last = meshio.read(vtus[-1])
    names = set(last.cell_data)
    assert any(n.startswith("part") for n in names) and any(n.startswith("cauchy_stress") for n in names)
    part = np.concatenate(last.cell_data[next(n for n in names if n.startswith("part"))]).ravel()
    assert set(np.unique(part)) == {0.0, 1.0}


def test_layered_run_writes_the_full_deformed_specimen_and_the_impactor(tmp_path):
    """--vtu --full on the quarter model: the mirrored specimen (4 x the modelled elements) with
    stress and the part of each element, read back with meshio; the impactor as its own file."""
    pytest.importorskip("numba")
    out = tmp_path / "lay"
    scene = tmp_path / "lay.toml"
    from cfm_core.scene.scene import scene_to_toml

    scene.write_text(scene_to_toml(LAYERED.with_overrides(end_time=0.004)))
    assert main(["run", "--scene", str(scene), "--backend", "numba", "--vtu", "--full", "--out", str(out)]) == 0
    modelled = json.loads((out / "summary.json").read_text())["elements_modelled"]
    frames = sorted(out.glob("specimen_*.vtu"))
    mesh = meshio.read(frames[-1])
    n_cells = sum(len(c.data) for c in mesh.cells)
    assert n_cells == 4 * modelled
    part_key = next(n for n in mesh.cell_data if n.startswith("part"))
    assert set(np.unique(np.concatenate(mesh.cell_data[part_key]))) == {0.0, 1.0, 2.0}
    stress_key = next(n for n in mesh.cell_data if n.startswith("cauchy_stress"))
    sigma = np.concatenate(mesh.cell_data[stress_key])
    assert sigma.shape[0] == n_cells and np.isfinite(sigma).all() and np.abs(sigma).max() > 0.0
    assert sorted(out.glob("impactor*.vt*")), "the impactor surface is not written"
