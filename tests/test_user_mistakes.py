"""What a fresh user gets wrong, answered before anything runs (exit 2, one paragraph, no traceback):
values in g, mm or mm/s where the product reads kg, m and m/s (shared case units-mass-in-grams), a
mistyped command, option or scene key ("did you mean ...?"); and ``cfm --version``."""

import subprocess
import sys
import time
from importlib import metadata

import pytest

from cfm_core.errors import InputError
from cfm_core.runs.pipeline import drop_tests
from cfm_core.scene.plausible import check_plausible
from cfm_core.scene.scene import builtin_scene, load_scene


def cfm(*args, timeout=120):
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "cfm_core.cli", *args], capture_output=True, text=True,
                         timeout=timeout)
    return run.returncode, run.stdout, run.stderr, time.perf_counter() - start


def _one_paragraph(err):
    assert "Traceback" not in err and "usage:" not in err
    assert err.strip() and "\n" not in err.strip(), err


@pytest.mark.parametrize("option, value, expected", [
    ("--mass", "220", "[impactor] mass = 220 kg is not a plausible impactor mass"),
    ("--radius", "55", "[impactor] radius = 55.0 m is out of range"),
    ("--radius", "5", "[impactor] radius = 5.0 m is out of range"),
    ("--velocity", "1000", "[impactor] velocity = 1000 m/s is not a plausible impact speed"),
    ("--width", "5", "[specimen] width = 5.0 m is out of range"),
    ("--thickness", "8", "[specimen] thickness = 8.0 m is out of range"),
    ("--element-size", "2", "[specimen] element_size = 2.0 m is out of range"),
])
def test_unit_slips_are_refused_before_running_with_the_likely_mistake(tmp_path, option, value, expected):
    out = tmp_path / "o"
    code, _, err, _ = cfm("drop-test", option, value, "--out", str(out), "--quiet", "--no-plot")
    assert code == 2
    _one_paragraph(err)
    assert expected in err
    slip = {"--mass": "220 g", "--velocity": "1000 mm/s"}.get(option, f"{value} mm")
    si = f"{float(value) / 1000:g}"
    assert f"did you mean {si} " in err and f"({slip})?" in err and f"{option} {si}" in err
    assert not out.exists()


def test_mass_in_grams_in_a_scene_file_is_refused_at_once_on_cfm_run(tmp_path):
    """The shared case's scene (mass = 220.0) no longer runs for seconds: refused (exit 2) in well under
    the ~7 s its failing run took, naming the slip."""
    scene = tmp_path / "scene_mass_g.toml"
    scene.write_text('[scene]\ntype = "drop-test"\n[specimen]\nelement_size = 0.002\n[impactor]\nmass = 220.0\n')
    code, out, err, took = cfm("run", "--scene", str(scene), "--out", str(tmp_path / "o"), "--quiet")
    assert code == 2 and "did you mean 0.22 kg (220 g)?" in err and out == ""
    _one_paragraph(err)
    result = drop_tests([load_scene(scene)], "numba")[0]  # a sweep records it as a failed run, unrun
    assert isinstance(result, InputError) and "220 kg" in str(result)


@pytest.mark.parametrize("over, warned", [
    ({"mass": 20.0}, False), ({"mass": 50.0}, True), ({"mass": 100.0}, True),  # heavy impactors run
    ({"velocity": 20.0}, False), ({"velocity": 60.0}, True), ({"radius": 0.25}, False), ({"radius": 0.8}, True),
    ({"width": 0.5}, False), ({"width": 0.9}, True), ({}, False),
])
def test_legitimate_heavy_or_large_values_run_with_at_most_a_warning(over, warned):
    notes = check_plausible(builtin_scene("drop-test").with_overrides(**over))
    assert len(notes) == int(warned)
    if warned:
        key, value = next(iter(over.items()))
        assert f"{key} = {value:g} " in notes[0] and "it runs as given" in notes[0]


@pytest.mark.parametrize("over", [{"mass": 100.5}, {"velocity": 101.0}, {"radius": 1.01}, {"width": 1.01}])
def test_just_above_the_bounds_is_refused(over):
    with pytest.raises(InputError, match="refused as a unit slip|out of range"):
        check_plausible(builtin_scene("drop-test").with_overrides(**over))


@pytest.mark.parametrize("args, hint", [
    (["drop-tset"], "Did you mean 'drop-test'?"),
    (["drop-test", "--thicknesss", "0.005", "--out", "o"], "--thicknesss: did you mean '--thickness'?"),
    (["drop-test", "--thikness=0.005", "--out", "o"], "--thikness: did you mean '--thickness'?"),
    (["drop-test", "--moduli", "longterm", "--out", "o"], "Did you mean 'long-term'?"),
    (["sweep", "--vary", "k1=1", "--out", "o", "--workrs", "2"], "--workrs: did you mean '--workers'?"),
])
def test_typos_get_the_closest_names(tmp_path, args, hint):
    code, _, err, _ = cfm(*args)
    assert code == 2 and hint in err
    _one_paragraph(err)
    assert not (tmp_path / "o").exists()


def test_a_mistyped_scene_key_gets_the_closest_key(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[scene]\ntype = "drop-test"\n[specimen]\nthicknes = 0.005\n')
    code, _, err, _ = cfm("drop-test", "--scene", str(path), "--out", str(tmp_path / "o"))
    assert code == 2 and "unknown key 'thicknes' in [specimen] of a drop-test scene (did you mean 'thickness'?)" in err
    _one_paragraph(err)


def test_version_names_the_package_version_and_the_backends():
    code, out, err, _ = cfm("--version")
    assert code == 0 and err == ""
    first, *rest = out.splitlines()
    assert first.startswith(f"cfm-materials {metadata.version('cfm-materials')} (Python ")
    backends = {line.split()[0] for line in rest[1:]}
    assert rest[0] == "backends:" and {"numba", "skfem", "torch"} <= backends
    assert all("available" in line or "BROKEN" in line for line in rest[1:])


def test_a_mesh_in_millimetres_is_refused_with_a_hint_to_scale_it(tmp_path):
    import meshio

    from cfm_core.scene.mesh import structured_hex_mesh

    nodes, hexes = structured_hex_mesh(25.0, 25.0, 8.0, 5, 5, 2, (0.0, 0.0, 0.0))  # a quarter, in mm
    path = tmp_path / "quarter_mm.vtu"
    meshio.write(path, meshio.Mesh(nodes, [("hexahedron", hexes)]))
    with pytest.raises(InputError) as err:
        builtin_scene("drop-test").with_overrides(mesh=str(path))
    text = str(err.value)
    assert "width = 50.0 m is out of range" in text and "did you mean 0.05 m (50 mm)?" in text
    assert "Scale the mesh's coordinates to m" in text and "Write width" not in text
