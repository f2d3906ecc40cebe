"""A run repeated from the scene.toml it wrote is the same run: backend, options, dtype (issue 20).

Each repeat is compared byte for byte with the first run; a run without the option (or on the
default backend) is compared too, so that a repeat that lost the option cannot pass.
"""

import json
import re

import meshio
import pytest

import cfm_core as cfm
from cfm_core.cli import main
from cfm_core.scene.mesh import structured_hex_mesh
from fixtures.inp_meshes import write_inp_with_included_nodes

# a small quarter specimen (5 x 5 x 2 elements of 2 mm): a run takes about a second
SMALL = ["--element-size", "0.002", "--width", "0.02", "--thickness", "0.004", "--quiet", "--no-plot"]


def _csv(folder):
    return (folder / "acceleration.csv").read_bytes()


def _summary(folder):
    return json.loads((folder / "summary.json").read_text())


def test_numba_option_is_repeated_byte_for_byte_and_overridden_with_a_note(tmp_path, capsys):
    hg, again, default, over = (tmp_path / n for n in ("hg", "again", "default", "over"))
    assert main(["drop-test", *SMALL, "--option", "hourglass=0.05", "--out", str(hg)]) == 0
    assert main(["drop-test", *SMALL, "--out", str(default)]) == 0
    assert _csv(hg) != _csv(default)  # the option changes the history, so a lost option shows
    capsys.readouterr()
    assert main(["run", "--scene", str(hg / "scene.toml"), "--quiet", "--no-plot", "--out", str(again)]) == 0
    assert _csv(again) == _csv(hg)
    assert "overrides" not in capsys.readouterr().err
    # a command-line value overrides the file's, and the run says so
    assert main(["run", "--scene", str(hg / "scene.toml"), "--option", "hourglass=0.1", "--quiet", "--no-plot",
                 "--out", str(over)]) == 0
    assert "--option hourglass=0.1 overrides scene.toml [run] hourglass = 0.05" in capsys.readouterr().err
    assert _csv(over) == _csv(default)
    prov = _summary(hg)["provenance"]
    assert prov["backend"]["options"]["hourglass"] == 0.05 and prov["backend"]["name"] == "numba"
    assert prov["code"]["version"] == cfm.__version__ and "commit" in prov["code"] and "dirty" in prov["code"]
    assert re.fullmatch(r"[0-9a-f]{8,}", prov["material"]["definition_digest"])


def test_torch_float32_is_repeated_as_torch_float32(tmp_path):
    pytest.importorskip("torch")
    t32, again, numba = (tmp_path / n for n in ("t32", "again", "numba"))
    assert main(["drop-test", *SMALL, "--backend", "torch", "--dtype", "float32", "--out", str(t32)]) == 0
    assert main(["run", "--scene", str(t32 / "scene.toml"), "--quiet", "--no-plot", "--out", str(again)]) == 0
    assert main(["drop-test", *SMALL, "--out", str(numba)]) == 0
    assert _csv(again) == _csv(t32) != _csv(numba)
    for s in (_summary(t32), _summary(again)):
        assert (s["backend"], s["dtype"], s["device"]) == ("torch", "float32", "cpu")
        assert s["provenance"]["backend"]["dtype"] == "float32"


def test_python_api_keeps_the_run_settings_of_a_loaded_scene(tmp_path, capsys):
    hg = tmp_path / "hg"
    assert main(["drop-test", *SMALL, "--option", "hourglass=0.05", "--out", str(hg)]) == 0
    scene = cfm.load_scene(hg / "scene.toml")
    assert scene.run.backend == "numba" and scene.run.option_dict["hourglass"] == 0.05
    capsys.readouterr()
    outcome = cfm.drop_test(scene)
    outcome.save(tmp_path / "py", plot=False)
    assert _csv(tmp_path / "py") == _csv(hg)
    cfm.drop_test(scene, hourglass=0.1)
    assert "hourglass=0.1 overrides the scene's [run] hourglass = 0.05" in capsys.readouterr().err


@pytest.mark.parametrize("run, match", [
    ('backend = "nubma"', r"scene.toml \[run\] backend = 'nubma'"),
    ('backend = "numba"\n[run.options]\nhourglas = 0.1', r"scene.toml \[run\] options.hourglas = 0.1: backend 'numba' "
                                                          r"has no option of that name"),
    ('backend = "numba"\ndtype = "float32"', r"scene.toml \[run\] dtype = 'float32': backend 'numba' has no choice"),
    ('backend = "numba"\n[run.options]\nhourglass = -1.0', r"option hourglass = -1.0 is not allowed"),
])
def test_a_bad_run_section_is_an_input_error_naming_it(tmp_path, capsys, run, match):
    (tmp_path / "scene.toml").write_text(f'[scene]\ntype = "drop-test"\n[run]\n{run}\n')
    out = tmp_path / "out"
    assert main(["run", "--scene", str(tmp_path / "scene.toml"), "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err) and "Traceback" not in err and not out.exists()


def _write_mesh(path, thickness):
    nodes, hexes = structured_hex_mesh(0.01, 0.01, thickness, 5, 5, 2)
    meshio.write(path, meshio.Mesh(nodes, [("hexahedron", hexes)]))


def test_a_changed_mesh_is_named_with_both_digests_when_repeating(tmp_path, capsys):
    mesh = tmp_path / "specimen.vtu"
    _write_mesh(mesh, 0.004)
    first = tmp_path / "first"
    assert main(["drop-test", "--mesh", str(mesh), "--quiet", "--no-plot", "--out", str(first)]) == 0
    recorded = "sha256:" + cfm.fingerprint.file_digest(mesh)
    assert _summary(first)["provenance"]["input_files"] == {str(mesh): recorded}
    assert f'"{mesh}" = "{recorded}"' in (first / "scene.toml").read_text()
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot",
                 "--out", str(tmp_path / "same")]) == 0
    assert "changed since" not in capsys.readouterr().err
    _write_mesh(mesh, 0.005)
    now = "sha256:" + cfm.fingerprint.file_digest(mesh)
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot",
                 "--out", str(tmp_path / "again")]) == 0
    err = capsys.readouterr().err
    assert f"mesh file {mesh} changed since the run" in err and recorded in err and now in err
    assert any("changed since" in w for w in _summary(tmp_path / "again")["warnings"])


def test_a_changed_file_that_an_inp_mesh_includes_is_named_when_repeating(tmp_path, capsys):
    """The included file is part of the mesh: recorded with its digest, compared on the repeat."""
    mesh = write_inp_with_included_nodes(tmp_path, 0.004)
    first = tmp_path / "first"
    assert main(["drop-test", "--mesh", str(mesh), "--quiet", "--no-plot", "--out", str(first)]) == 0
    nodes = tmp_path / "nodes.inp"
    recorded = "sha256:" + cfm.fingerprint.file_digest(nodes)
    assert _summary(first)["provenance"]["input_files"] == {
        str(mesh): "sha256:" + cfm.fingerprint.file_digest(mesh), str(nodes): recorded}
    main_bytes = mesh.read_bytes()
    write_inp_with_included_nodes(tmp_path, 0.005)
    assert mesh.read_bytes() == main_bytes          # only the included file changed
    now = "sha256:" + cfm.fingerprint.file_digest(nodes)
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot",
                 "--out", str(tmp_path / "again")]) == 0
    err = capsys.readouterr().err
    assert f"file {nodes} (included by the mesh {mesh}) changed since the run" in err
    assert recorded in err and now in err
    assert _summary(tmp_path / "again")["peak_g"] != _summary(first)["peak_g"]


def test_a_changed_material_definition_is_named_with_both_digests_when_repeating(tmp_path, capsys):
    """A user material's code (or a constant it imports) edited between a run and its repeat: the
    repeat gave other values without a word (35.4 against 52.3 g)."""
    first = tmp_path / "first"
    assert main(["drop-test", *SMALL, "--out", str(first)]) == 0
    from cfm_core.material.cache import definition_digest

    text = (first / "scene.toml").read_text()
    digest = re.search(r'^\[run\.materials\][^\n]*\ncfm = "([0-9a-f]{24})"', text, re.M).group(1)
    assert digest == definition_digest(cfm.get_material("cfm"))
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot",
                 "--out", str(tmp_path / "same")]) == 0
    assert "defined differently" not in capsys.readouterr().err
    (tmp_path / "edited.toml").write_text(text.replace(digest, "0" * 24))  # what an edit of the code gives
    assert main(["run", "--scene", str(tmp_path / "edited.toml"), "--quiet", "--no-plot",
                 "--out", str(tmp_path / "again")]) == 0
    err = capsys.readouterr().err
    assert f"material 'cfm' is defined differently from the run that wrote this scene" in err
    assert "0" * 24 in err and digest in err
    assert any("defined differently" in w for w in _summary(tmp_path / "again")["warnings"])


def test_another_backend_on_the_command_line_drops_the_files_backend_options():
    from cfm_core.runs.settings import plan_run
    from cfm_core.scene.run_section import RunSettings

    scene = cfm.builtin_scene("drop-test").with_run(RunSettings("torch", "float32", "cpu", {"hourglass": 0.05}))
    plan = plan_run(scene, "numba", {}, given_as={"backend": "--backend numba"}, where="scene.toml [run]")
    assert (plan.backend, plan.options) == ("numba", {})
    assert plan.notes == ["--backend numba overrides scene.toml [run] backend = torch (its options are not used)"]
    same = plan_run(scene, None, {"dtype": "float64"})
    assert same.backend == "torch" and same.options == {"hourglass": 0.05, "dtype": "float64", "device": "cpu"}
    assert same.notes == ["dtype=float64 overrides the scene's [run] dtype = float32"]
    assert plan_run(cfm.builtin_scene("drop-test")).options == {}  # no [run]: the defaults, as before


def test_a_sweep_from_a_written_scene_runs_with_its_backend_and_options(tmp_path, capsys):
    """cfm sweep --scene OUT/scene.toml took numba with its default options whatever the file's [run]
    said (the sweep's --backend defaulted to numba): a sweep of one value equal to the run's gave another
    history. Now the file's backend and options apply, and --option overrides them with a note."""
    hg, sweep, over = (tmp_path / n for n in ("hg", "sweep", "over"))
    assert main(["drop-test", *SMALL, "--option", "hourglass=0.05", "--out", str(hg)]) == 0
    capsys.readouterr()
    scene = str(hg / "scene.toml")
    assert main(["sweep", "--scene", scene, "--vary", "k2=1.66", "--serial", "--quiet", "--out", str(sweep)]) == 0
    assert "overrides" not in capsys.readouterr().err
    run = next((sweep / "runs").iterdir())
    first, repeat = (cfm.tables.read_table(f / "acceleration.csv", ["t", "a_raw", "a_cfc600"]).data
                     for f in (hg, run))
    assert (repeat == first).all()                       # the same run, to the bit
    assert main(["sweep", "--scene", scene, "--vary", "k2=1.66", "--serial", "--quiet", "--option", "hourglass=0.1",
                 "--out", str(over)]) == 0
    assert "--option hourglass=0.1 overrides scene.toml [run] hourglass = 0.05" in capsys.readouterr().err
    assert _summary(next((over / "runs").iterdir()))["provenance"]["backend"]["options"]["hourglass"] == 0.1


def test_the_fitted_scene_records_the_backend_and_options_the_fit_ran_with():
    """calibrate's fitted-scene.toml copied the input scene's [run] (or had none) instead of the fit's own
    backend and options: repeating the fitted curve from it gave another history."""
    from types import SimpleNamespace

    from cfm_core.studies.calibrate_output import fitted_scene

    scene = cfm.builtin_scene("drop-test")
    result = SimpleNamespace(final=SimpleNamespace(params={"k2": 1.7}),
                             problem=SimpleNamespace(backend="numba", options={"hourglass": 0.05, "safety": 0.8}))
    fitted = fitted_scene(scene, result)
    assert dict(fitted.material.parameters)["k2"] == 1.7
    assert fitted.run.backend == "numba" and fitted.run.option_dict["hourglass"] == 0.05
    assert fitted.run.option_dict["safety"] == 0.8
    from cfm_core.scene.scene import scene_to_toml

    text = scene_to_toml(fitted)
    assert "[run.options]" in text and "hourglass = 0.05" in text


def test_a_vtu_run_is_repeated_with_its_frames_and_overrides_are_named(tmp_path, capsys):
    """The repeat of a --vtu run stored frames ([run] frame_interval) but wrote no VTU; --param and scene
    overrides of a written scene.toml were applied without a word (only --option got a note)."""
    vtu, again, over = (tmp_path / n for n in ("vtu", "again", "over"))
    assert main(["drop-test", *SMALL, "--vtu", "--out", str(vtu)]) == 0
    capsys.readouterr()
    assert main(["run", "--scene", str(vtu / "scene.toml"), "--quiet", "--no-plot", "--out", str(again)]) == 0
    assert "written as VTU" in capsys.readouterr().err
    assert sorted(p.name for p in again.glob("specimen_*.vtu")) == sorted(p.name for p in vtu.glob("specimen_*.vtu"))
    assert _csv(again) == _csv(vtu)
    assert main(["drop-test", "--scene", str(vtu / "scene.toml"), "--param", "k2=2.5", "--thickness", "0.005",
                 "--quiet", "--no-plot", "--out", str(over)]) == 0
    err = capsys.readouterr().err
    assert "--param k2=2.5 overrides scene.toml [material.parameters] k2 = 1.66" in err
    assert "--thickness 0.005 overrides scene.toml [specimen] thickness = 0.004" in err


def test_vtu_keeps_a_frame_interval_given_as_an_option(tmp_path):
    """--vtu replaced --option frame_interval=... by its 0.2 ms, and so also let invalid values through."""
    out = tmp_path / "o"
    assert main(["drop-test", *SMALL, "--vtu", "--option", "frame_interval=0.001", "--out", str(out)]) == 0
    assert "frame_interval = 0.001" in (out / "scene.toml").read_text()
    assert main(["drop-test", *SMALL, "--vtu", "--option", "frame_interval=-1", "--out", str(tmp_path / "bad")]) == 2


def test_a_vtu_run_is_repeated_with_its_fields_and_mirroring(tmp_path, capsys):
    """--fields part --full: the repeat wrote quarter-model frames with every field; neither scene.toml nor
    summary.json recorded them."""
    first, again = tmp_path / "first", tmp_path / "again"
    assert main(["drop-test", *SMALL, "--vtu", "--fields", "part", "--full", "--out", str(first)]) == 0
    text = (first / "scene.toml").read_text()
    assert 'fields = "part"' in text and "full = true" in text
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot", "--out", str(again)]) == 0
    assert "with the fields part, mirrored into the whole specimen" in capsys.readouterr().err
    assert (again / "fields.json").read_bytes() == (first / "fields.json").read_bytes()
    for frame in sorted(first.glob("specimen_*.vtu"))[:3]:
        assert (again / frame.name).read_bytes() == frame.read_bytes()


def test_a_param_over_a_default_of_the_scene_file_is_noted(tmp_path, capsys):
    """--param k2=2.5 on a scene file without [material.parameters] changed the run without a note."""
    path = tmp_path / "plain.toml"
    path.write_text(cfm.scene.scene.scene_to_toml(cfm.builtin_scene("drop-test")))
    assert main(["drop-test", "--scene", str(path), *SMALL, "--param", "k2=2.5", "--out", str(tmp_path / "o")]) == 0
    assert "--param k2=2.5 overrides the default k2 = 1.66 that plain.toml runs with" in capsys.readouterr().err


def test_an_option_set_to_none_against_a_default_is_repeated_as_none(tmp_path):
    """skfem's error_tol = None (steps by Newton only) against its default 'auto': the [run] section
    left None out, so the repeat ran 'auto' (70 steps and 6.95 g for 154 steps and 6.80 g)."""
    import dataclasses

    from cfm_core.runs.settings import plan_run, run_record
    from cfm_core.scene.run_section import RunSettings, run_toml
    from cfm_core.scene.scene import builtin_scene

    scene = builtin_scene("drop-test")
    rec = run_record(scene, "skfem", {"error_tol": None})
    assert rec.option_dict["error_tol"] == "none" and "dt" not in rec.option_dict  # dt's default is None
    assert 'error_tol = "none"' in run_toml(rec)
    again = plan_run(dataclasses.replace(scene, run=RunSettings.from_table(rec.as_dict())))
    assert again.options["error_tol"] is None and again.options.get("dt") is None
    assert plan_run(dataclasses.replace(scene, run=RunSettings.from_table(
        run_record(scene, "skfem", {}).as_dict()))).options["error_tol"] == "auto"


def test_a_text_choice_named_none_is_given_on_the_command_line(tmp_path):
    """renumber's choices are 'morton', 'rcm' and 'none': `--option renumber=none` was read as None
    and refused; a scene file's renumber = "none" worked."""
    first, again = tmp_path / "first", tmp_path / "again"
    assert main(["drop-test", *SMALL, "--option", "renumber=none", "--out", str(first)]) == 0
    assert _summary(first)["provenance"]["backend"]["options"]["renumber"] == "none"
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot", "--out", str(again)]) == 0
    assert _csv(again) == _csv(first)
