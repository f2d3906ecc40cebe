"""What a fresh user gets wrong: values in mm where the product reads m, a mistyped command, option
or scene key ("did you mean ...?") refused before anything runs (exit 2, one paragraph, no
traceback); values in g or mm/s where it reads kg and m/s (shared case units-mass-in-grams) warned
before the run, which the run checks then stop (exit 3); and ``cfm --version``."""

import subprocess
import sys
import time
from importlib import metadata

import pytest

from cfm_core.errors import InputError
from cfm_core.scene.plausible import check_plausible
from cfm_core.scene.scene import builtin_scene


def cfm(*args, timeout=120):
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "cfm_core.cli", *args], capture_output=True, text=True,
                         timeout=timeout)
    return run.returncode, run.stdout, run.stderr, time.perf_counter() - start


def _one_paragraph(err):
    assert "Traceback" not in err and "usage:" not in err
    assert err.strip() and "\n" not in err.strip(), err


@pytest.mark.parametrize("option, value, expected", [
    ("--radius", "55", "[impactor] radius = 55.0 m is out of range"),
    ("--radius", "5", "[impactor] radius = 5.0 m is out of range"),
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
    slip = f"{value} mm"
    si = f"{float(value) / 1000:g}"
    assert f"did you mean {si} " in err and f"({slip})?" in err and f"{option} {si}" in err
    assert not out.exists()


@pytest.mark.parametrize("key, value, slip, what", [
    ("mass", "220.0", "did you mean 0.22 kg (220 g)?", "impactor mass"),
    ("velocity", "1000.0", "did you mean 1 m/s (1000 mm/s)?", "impact speed"),
])
def test_mass_or_speed_in_g_or_mm_per_s_warned_first_then_stopped_by_the_run_checks(tmp_path, key, value, slip, what):
    """The shared case (mass = 220.0 read as 220 kg; 1000 for 1000 mm/s): a warning naming the slip
    before the run, then exit 3 from the run checks (no summary.json), never a finished run."""
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[scene]\ntype = "drop-test"\n[specimen]\nelement_size = 0.002\n[impactor]\n{key} = {value}\n')
    out = tmp_path / "o"
    code, _, err, _ = cfm("run", "--scene", str(scene), "--out", str(out), "--quiet")
    first = err.strip().splitlines()[0]
    assert first.startswith("warning:") and f"not a plausible {what}" in first and slip in first
    assert code == 3 and "Traceback" not in err
    assert not (out / "summary.json").exists()


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


@pytest.mark.parametrize("over", [{"radius": 1.01}, {"width": 1.01}])
def test_just_above_the_bounds_is_refused(over):
    with pytest.raises(InputError, match="out of range"):
        check_plausible(builtin_scene("drop-test").with_overrides(**over))


@pytest.mark.parametrize("over", [{"mass": 100.5}, {"velocity": 101.0}])
def test_mass_and_speed_above_the_slip_bound_are_warned_as_slips_not_refused(over):
    notes = check_plausible(builtin_scene("drop-test").with_overrides(**over))
    assert len(notes) == 1 and "almost surely a unit slip" in notes[0] and "It runs as given" in notes[0]


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


@pytest.mark.parametrize("args", [
    ["point", "--uniaxial", "--rate", "100", "--stretch", "0.7"],
    ["drop-test", "--element-size", "0.002", "--no-plot", "--quiet"],
    ["run", "--scene", "single-element", "--no-plot", "--quiet"],
])
@pytest.mark.parametrize("g1", ["0.471", "0.47099999999999986"])
def test_prony_coefficients_summing_to_one_within_rounding_are_refused(tmp_path, args, g1):
    """Shared case prony-sum-rounding: g1 = 0.471 with Table 1's g2, g3 sums to 1 exactly (naive float sum
    0.9999999999999999): was a ZeroDivisionError traceback (exit 1); g_inf = 1.1e-16 ran to 4.8 GPa."""
    out = tmp_path / ("o.csv" if args[0] == "point" else "o")
    code, _, err, _ = cfm(*args, "--param", f"g1={g1}", "--out", str(out))
    assert code == 2 and "gamma_inf = 1 - (g1 + g2 + g3) =" in err and "at least 1e-06" in err
    _one_paragraph(err)
    assert not out.exists()


def test_a_modulus_in_kpa_is_warned_about_before_the_drop_test_runs(tmp_path):
    """--param k1=1.32 (kPa typed for Pa) ran to a plausible, wrong peak with no warning."""
    code, out, err, _ = cfm("drop-test", "--element-size", "0.002", "--param", "k1=1.32", "--quiet", "--no-plot",
                            "--out", str(tmp_path / "o"))
    first = err.strip().splitlines()[0]
    assert code == 0 and first.startswith("warning: [material] k1 = 1.32 Pa is 1,000x below the typical 1320 Pa")
    assert "Was it kPa? Write k1 = 1320 (--param k1=1320)" in first


def test_an_output_rate_writing_a_huge_csv_is_refused_before_running(tmp_path):
    """output_rate = 1e9 Hz ran and wrote a 568 MB CSV."""
    scene = tmp_path / "scene.toml"
    scene.write_text('[scene]\ntype = "drop-test"\noutput_rate = 1e9\n[specimen]\nelement_size = 0.002\n')
    out = tmp_path / "o"
    code, _, err, elapsed = cfm("run", "--scene", str(scene), "--out", str(out), "--quiet")
    assert code == 2 and "[scene] output_rate = 1e+09 Hz" in err and "MB" in err and "output_rate <= " in err
    _one_paragraph(err)
    assert not out.exists()


def test_material_unit_slip_warned_by_reaction_runs_and_cfm_point(tmp_path):
    """A modulus typed in kPa is named with the likely slip before the run, by `cfm run` on a
    reaction scene and by `cfm point`, and it lands in the summary's warnings."""
    import json
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "cfm_core.cli", "run", "--scene", "single-element", "--param",
                          "kappa=666.1", "--out", str(tmp_path / "se"), "--quiet", "--no-plot"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "kappa = 666.1 Pa" in run.stderr and "Was it kPa?" in run.stderr
    summary = json.loads((tmp_path / "se" / "summary.json").read_text())
    assert any("Was it kPa?" in w for w in summary["warnings"])
    point = subprocess.run([sys.executable, "-m", "cfm_core.cli", "point", "--uniaxial", "--rate", "1", "--stretch",
                            "0.9", "--param", "k1=1.32", "--no-plot", "--out", str(tmp_path / "p.csv")],
                           capture_output=True, text=True)
    assert point.returncode == 0, point.stderr
    assert "k1 = 1.32 Pa" in point.stderr and "Was it kPa?" in point.stderr


@pytest.mark.parametrize("command", [["export", "cfm", "--to", "abaqus-umat"], ["fit", "--test", "{test}", "--fit", "k2"]])
def test_a_modulus_in_kpa_is_warned_about_by_export_and_fit(tmp_path, command):
    """cfm export wrote a card with k1 = 1.32 Pa and cfm fit fitted around it, both silently (drop-test and
    point warned)."""
    test = tmp_path / "u.csv"
    t = [0.01 * i for i in range(11)]
    test.write_text("t,stretch,stress\n" + "".join(f"{x},{1 - x},{-2000 * x}\n" for x in t))
    args = [a.format(test=f"{test}:uniaxial:1") for a in command]
    code, out, err, _ = cfm(*args, "--param", "k1=1.32", "--out", str(tmp_path / "o"), timeout=300)
    assert code == 0, err
    assert "warning: [material] k1 = 1.32 Pa is 1,000x below the typical 1320 Pa" in err


def test_a_lab_test_stress_column_in_kpa_is_named_as_the_likely_cause():
    """A uniaxial curve in kPa read as Pa: the fit ended with k1 and k2 on their lower bounds and a
    143 % misfit, with no hint at the unit."""
    import numpy as np

    from cfm_core.studies.fit import stress_scale_warnings
    from cfm_core.studies.lab_tests import LabTest

    t = np.linspace(0.0, 0.3, 31)
    sim = -25_000.0 * t / 0.3                                 # the starting material's P (Pa)
    kpa = LabTest("c1", "c1.csv", "uniaxial", 1.0, 1.0, t, 1.0 - t, sim / 1e3)
    pa = LabTest("c2", "c2.csv", "uniaxial", 1.0, 1.0, t, 1.0 - t, 1.7 * sim)
    (note,) = stress_scale_warnings([kpa, pa], [sim, sim])
    assert note.startswith("test 'c1' (c1.csv): its measured stresses") and "Is its stress column in kPa?" in note
    assert "MPa" in stress_scale_warnings([LabTest("c3", "c3.csv", "uniaxial", 1.0, 1.0, t, 1.0 - t, sim / 1e6)],
                                          [sim])[0]


def test_more_input_slips_get_a_clear_word(tmp_path):
    """An unreadable mesh said "could not be read by meshio: 1." (meshio's sys.exit); --velocity 0 got the
    hint "did you mean 0 m/s (0 mm/s)"; a layer's element_size 0.02 got "did you mean 2e-05 m"; --hold -1
    ran as 0 and --hold inf ended as a numerical failure; a strain column read as stretch showed a numpy
    repr; an element wider than the specimen ran silently."""
    from cfm_core.scene.plausible import unit_hint

    (tmp_path / "bad.msh").write_text("garbage\n")
    code, _, err, _ = cfm("drop-test", "--mesh", str(tmp_path / "bad.msh"), "--out", str(tmp_path / "o"))
    assert code == 2 and "could not be read by meshio (Couldn't read file" in err and ": 1." not in err
    _one_paragraph(err)
    assert unit_hint("velocity", 0.0, "m/s", 0.0, 100.0) == ""
    assert unit_hint("element_size", 0.02, "m", 0.0, 0.002) == ""
    assert "did you mean 0.002 m" in unit_hint("element_size", 2.0, "m", 0.0, 0.004)
    for hold in ("-1", "inf", "nan"):
        code, _, err, _ = cfm("point", "--uniaxial", "--rate", "1", "--stretch", "0.8", "--hold", hold, "--no-plot",
                              "--out", str(tmp_path / "p.csv"))
        assert code == 2 and "hold =" in err and "finite hold time >= 0" in err
    strain = tmp_path / "strain.csv"
    strain.write_text("t,stretch,stress\n" + "".join(f"{0.01 * i},{-0.01 * i},{-100.0 * i}\n" for i in range(11)))
    from cfm_core.studies.fit import read_tests

    with pytest.raises(InputError, match=r"stretch = -0.0 is outside .*a strain column") as e:
        read_tests([f"{strain}:uniaxial:1"])
    assert "np.float64" not in str(e.value)
    notes = check_plausible(builtin_scene("drop-test").with_overrides(element_size=0.002, width=0.001))
    assert any("larger than half the width" in n for n in notes)


def test_a_parameter_or_option_given_twice_is_refused_and_repeated_fits_add_up(tmp_path):
    """`--param k1=1e3 --param k1=2e3` ran with the last value, `--dtype float32 --option dtype=float64`
    ran in float32, and `cfm fit --fit k1 --fit k2` fitted k2 alone, each with exit 0 and no word."""
    from cfm_core.cli import main

    out = str(tmp_path / "o")
    for args, said in [
        (["--param", "k1=1e3", "--param", "k1=2e3"], "--param k1 is given twice, as 1000.0 and 2000.0"),
        (["--option", "hourglass=0.1", "--option", "hourglass=0.05"], "--option hourglass is given twice"),
        (["--backend", "torch", "--dtype", "float32", "--option", "dtype=float64"],
         "--dtype float32 and --option dtype=float64 disagree"),
    ]:
        code, _, err, _ = cfm("drop-test", "--element-size", "0.002", *args, "--no-plot", "--quiet", "--out", out)
        assert code == 2 and said in err, err
        _one_paragraph(err)
    lab = tmp_path / "comp.csv"
    assert main(["point", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--steps", "20", "--no-plot",
                 "--out", str(lab)]) == 0
    assert main(["fit", "--test", f"{lab}:uniaxial:100", "--fit", "k1", "--fit", "k2", "--max-evaluations", "3",
                 "--quiet", "--out", str(tmp_path / "fit")]) == 0
    import json

    assert json.loads((tmp_path / "fit" / "fit.json").read_text())["names"] == ["k1", "k2"]


def test_built_in_scene_names_work_wherever_a_drop_test_scene_is_taken(tmp_path):
    """`cfm drop-test --scene flat-impactor` (and sweep, calibrate) said "cannot be read: No such file"
    while `cfm run --scene flat-impactor` ran; and `cfm fit --scene` took a single-element scene for the
    drop-test scene its fitted-scene.toml is based on."""
    import json

    from cfm_core.cli import main
    from cfm_core.cli.options import scene_named

    assert main(["drop-test", "--scene", "flat-impactor", "--element-size", "0.002", "--width", "0.02",
                 "--thickness", "0.004", "--quiet", "--no-plot", "--out", str(tmp_path / "o")]) == 0
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["scene"]["impactor"]["shape"] == "flat"
    assert scene_named("layered-tissue").specimen.layers
    code, _, err, _ = cfm("sweep", "--scene", "nope", "--vary", "k1=1000", "--serial", "--out", str(tmp_path / "s"))
    assert code == 2 and "not a built-in scene (built-in: drop-test, flat-impactor, layered-tissue" in err
    _one_paragraph(err)
    (tmp_path / "one.toml").write_text('[scene]\ntype = "single-element"\n')
    (tmp_path / "c.csv").write_text("t,stretch,nominal_stress\n0,1,0\n0.001,0.9,-100\n")
    code, _, err, _ = cfm("fit", "--test", f"{tmp_path / 'c.csv'}:uniaxial:100", "--fit", "k1", "--scene",
                          str(tmp_path / "one.toml"), "--out", str(tmp_path / "f"))
    assert code == 2 and "a 'single-element' scene; fitted-scene.toml is a drop-test scene" in err
    _one_paragraph(err)


def test_an_empty_backend_name_is_refused_not_taken_for_the_default(tmp_path):
    code, _, err, _ = cfm("drop-test", "--element-size", "0.002", "--backend", "", "--out", str(tmp_path / "o"))
    assert code == 2 and "--backend '' is empty; give a backend name" in err and not (tmp_path / "o").exists()
    _one_paragraph(err)


def test_wrong_paths_and_files_are_named_for_what_they_are(tmp_path):
    """A folder that does not exist was "not a directory" (compare) or "no specimen.pvd" (fields); random bytes
    were "encoded as UTF-16 or UTF-32"; `--material neo-hookean` on a cfm run's scene.toml blamed the user for the
    file's own c ("material 'neo-hookean' has no parameter 'c' (given ...)")."""
    import os

    from cfm_core.cli import main

    code, _, err, _ = cfm("compare", str(tmp_path / "nope1"), str(tmp_path / "nope2"))
    assert code == 2 and "nope1: no such folder" in err
    code, _, err, _ = cfm("fields", str(tmp_path / "nope"), "--at", "0.001", "--field", "J", "--png", str(tmp_path / "f.png"))
    assert code == 2 and "nope: no such folder" in err
    (tmp_path / "x.csv").write_bytes(os.urandom(3000).replace(b"\x00", b"\x01") + b"\x00" * 3)
    code, _, err, _ = cfm("point", "--history", str(tmp_path / "x.csv"), "--out", str(tmp_path / "o.csv"))
    assert code == 2 and "is not a text file" in err and "UTF-16" in err   # named as binary, not as UTF-16
    (tmp_path / "u.csv").write_bytes("t,F11\n0,1\n".encode("utf-16-le"))
    code, _, err, _ = cfm("point", "--history", str(tmp_path / "u.csv"), "--out", str(tmp_path / "o.csv"))
    assert code == 2 and "is encoded as UTF-16 or UTF-32" in err
    first = tmp_path / "first"
    assert main(["run", "--scene", "single-element", "--quiet", "--no-plot", "--out", str(first)]) == 0
    code, _, err, _ = cfm("run", "--scene", str(first / "scene.toml"), "--material", "neo-hookean", "--quiet",
                          "--no-plot", "--out", str(tmp_path / "nh"))
    assert code == 0 and "has no parameter" not in err
    assert "its parameters c, g1, g2, g3, k1, k2, tau1, tau2, tau3, which neo-hookean does not have, are left out" in err


@pytest.mark.parametrize("kind, over, reached", [("single-element", {"end_time": 0.001}, "0.9"),
                                                  ("relaxation", {"end_time": 5e-4}, "0.85")])
def test_an_end_time_before_the_ramp_ends_is_warned_with_the_stretch_reached(kind, over, reached):
    """single-element, end_time = 1 ms before its 5 ms ramp to 0.5: the run stopped at 0.9 with exit 0 and no word."""
    (w,) = [w for w in check_plausible(builtin_scene(kind).with_overrides(**over)) if "ramp" in w]
    assert f"the run stops at the stretch {reached}" in w and "never reached" in w
    assert not [w for w in check_plausible(builtin_scene(kind)) if "ramp" in w]   # automatic end time


def test_a_run_too_long_to_record_names_what_made_its_end_time_not_the_disk(tmp_path):
    """A single element at a rate of 1e-6 1/s was refused as "the output needs about 2.48e+06 MiB but only ... are
    free", and a drop test at 0.001 m/s only blamed output_rate: the automatic end time (5e5 s, 80 s) is the cause."""
    (tmp_path / "slow.toml").write_text('[scene]\ntype = "single-element"\n[element]\nrate = 1e-6\n')
    code, _, err, _ = cfm("run", "--scene", str(tmp_path / "slow.toml"), "--out", str(tmp_path / "o"))
    assert code == 2 and "(automatic: the ramp of 500000 s to the stretch 0.5 and the hold of 0 s)" in err
    assert "MiB" not in err
    _one_paragraph(err)
    code, _, err, _ = cfm("drop-test", "--velocity", "0.001", "--out", str(tmp_path / "d"))
    assert code == 2 and "automatic: 10 x the thickness 0.008 m over the impact speed 0.001 m/s" in err
