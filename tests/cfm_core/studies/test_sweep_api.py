"""cfm.sweep: the Python API, content-keyed run ids (each ingredient invalidates), values checked before
any run, an earlier sweep's files never left looking current, the run count and --yes."""

import json

import meshio
import numpy as np
import pytest

import cfm_core as cfm
from cfm_core import fingerprint
from cfm_core.cli import main
from cfm_core.errors import InputError
from cfm_core.scene.scene import scene_to_toml
from cfm_core.studies import outcomes
from cfm_core.studies import sweep

pytest.importorskip("numba")




def _write_mesh(path, thickness: float, h: float = 0.0025, half: float = 0.015) -> None:
    """A structured quarter specimen (hexahedra, VTK node order), ``half`` x ``half`` x thickness (m)."""
    n, nz = round(half / h), max(2, round(thickness / h))
    xs, zs = np.linspace(0.0, half, n + 1), np.linspace(0.0, thickness, nz + 1)
    X, Y, Z = np.meshgrid(xs, xs, zs, indexing="ij")
    idx = lambda i, j, k: (i * (n + 1) + j) * (nz + 1) + k  # noqa: E731
    cells = [[idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k), idx(i, j, k + 1),
              idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)]
             for i in range(n) for j in range(n) for k in range(nz)]
    points = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    meshio.write(str(path), meshio.Mesh(points, [("hexahedron", np.array(cells))]))


def test_api_returns_a_table_with_units_and_saves_the_cli_files(scene, tmp_path):
    result = cfm.sweep(scene, vary={"k2": [1.6, 1.8]}, progress=False)
    df = result.to_dataframe()
    assert list(df.columns[:4]) == ["run_id", "k2 [-]", "status", "error"] and "peak_g [g]" in df.columns
    assert list(df["k2 [-]"]) == [1.6, 1.8] and list(df["status"]) == ["ok", "ok"]
    assert df["peak_g [g]"].iloc[1] > df["peak_g [g]"].iloc[0]  # stiffer fibres, higher peak
    # the same run through cfm.drop_test: the sweep's table holds exactly its peak
    single = cfm.drop_test(scene.with_overrides(parameters={"k2": 1.8}))
    assert df["peak_g [g]"].iloc[1] == single.peak_g
    out = result.save(tmp_path / "saved")
    names = {p.name for p in out.iterdir()}
    assert {"sweep.csv", "sweep.json", "peaks.png", "runs", ".cfm-output.json"} <= names
    for rid in df["run_id"]:
        assert json.loads((out / "runs" / rid / "summary.json").read_text())["run_id"] == rid
    # saved runs are a cache: the same sweep into that folder computes nothing
    again = cfm.sweep(scene, vary={"k2": [1.6, 1.8]}, out=out, progress=False)
    assert again.executed == 0 and again.skipped == 2
    assert again.to_dataframe()["peak_g [g]"].tolist() == df["peak_g [g]"].tolist()


# ----------------------------------------------------------------------------- run ids, ingredient by ingredient
def test_run_id_changes_with_each_ingredient_and_only_then(scene, tmp_path, monkeypatch):
    mesh = tmp_path / "specimen.vtu"
    _write_mesh(mesh, 0.005)
    toml = tmp_path / "scene.toml"
    toml.write_text('[scene]\ntype = "drop-test"\n[specimen]\nmesh = "specimen.vtu"\n')
    base = cfm.load_scene(toml)
    case = {"k2": 1.8}
    ref = sweep.run_id(sweep.run_key(base, "numba"), case)
    assert sweep.run_id(sweep.run_key(cfm.load_scene(toml), "numba"), dict(case)) == ref  # same: reused
    # another specimen in the same file: the path is unchanged, the content is not
    _write_mesh(mesh, 0.0075)
    moved = sweep.run_id(sweep.run_key(cfm.load_scene(toml), "numba"), case)
    assert moved != ref
    _write_mesh(mesh, 0.005)  # the first specimen back: its id again
    assert sweep.run_id(sweep.run_key(cfm.load_scene(toml), "numba"), case) == ref
    # a backend option, given or changed
    assert sweep.run_id(sweep.run_key(base, "numba", {"hourglass": 0.05}), case) != ref
    # a default written out explicitly is the same run
    default = sweep.run_key(base, "numba")["options"]["hourglass"]
    assert sweep.run_id(sweep.run_key(base, "numba", {"hourglass": default}), case) == ref
    # the case's values
    assert sweep.run_id(sweep.run_key(base, "numba"), {"k2": 1.81}) != ref
    # the material's definition
    monkeypatch.setattr(sweep, "definition_digest", lambda spec: "another definition")
    assert sweep.run_id(sweep.run_key(base, "numba"), case) != ref
    monkeypatch.undo()
    # the code
    monkeypatch.setattr(fingerprint, "source_digest", lambda: "0" * 24)
    assert sweep.run_id(sweep.run_key(base, "numba"), case) != ref


def test_run_id_changes_with_a_file_that_an_inp_mesh_includes(tmp_path):
    """main.inp the same bytes, its *NODE, INPUT= file another specimen: another run (not a stale reuse)."""
    from fixtures.inp_meshes import write_inp_with_included_nodes

    mesh = write_inp_with_included_nodes(tmp_path, 0.004)
    toml = tmp_path / "scene.toml"
    toml.write_text(f'[scene]\ntype = "drop-test"\n[specimen]\nmesh = "{mesh.name}"\n')
    case = {"k2": 1.8}
    ref = sweep.run_id(sweep.run_key(cfm.load_scene(toml), "numba"), case)
    write_inp_with_included_nodes(tmp_path, 0.005)
    assert sweep.run_id(sweep.run_key(cfm.load_scene(toml), "numba"), case) != ref
    write_inp_with_included_nodes(tmp_path, 0.004)
    assert sweep.run_id(sweep.run_key(cfm.load_scene(toml), "numba"), case) == ref


def test_rerun_after_the_mesh_file_changed_recomputes(tmp_path):
    """The issue's case: replace the mesh by another specimen under the same path and rerun."""
    mesh = tmp_path / "specimen.vtu"
    _write_mesh(mesh, 0.005)
    toml = tmp_path / "scene.toml"
    toml.write_text('[scene]\ntype = "drop-test"\n[specimen]\nmesh = "specimen.vtu"\n')
    out = tmp_path / "out"
    first = cfm.sweep(str(toml), vary={"velocity": [1.0]}, out=out, progress=False)
    assert first.executed == 1
    same = cfm.sweep(str(toml), vary={"velocity": [1.0]}, out=out, progress=False)
    assert same.executed == 0 and same.skipped == 1
    _write_mesh(mesh, 0.0075)
    changed = cfm.sweep(str(toml), vary={"velocity": [1.0]}, out=out, progress=False)
    assert changed.executed == 1 and changed.skipped == 0  # not the stale 5 mm result
    thick, thin = changed.rows[0]["peak_g"], first.rows[0]["peak_g"]
    assert thick < 0.8 * thin  # a thicker specimen: a softer impact
    assert json.loads((out / "runs" / changed.rows[0]["run_id"] / "summary.json").read_text())["thickness"] == 0.0075


def test_rerun_with_other_code_or_options_recomputes(scene, tmp_path, monkeypatch):
    out = tmp_path / "out"
    assert cfm.sweep(scene, vary={"k2": [1.7]}, out=out, progress=False).executed == 1
    assert cfm.sweep(scene, vary={"k2": [1.7]}, out=out, progress=False).executed == 0
    assert cfm.sweep(scene, vary={"k2": [1.7]}, out=out, progress=False, options={"hourglass": 0.05}).executed == 1
    monkeypatch.setattr(fingerprint, "source_digest", lambda: "f" * 24)  # an edit of the code
    assert cfm.sweep(scene, vary={"k2": [1.7]}, out=out, progress=False).executed == 1


# ----------------------------------------------------------------------------- inputs, before any run
@pytest.mark.parametrize("vary, message", [
    ({"k2": [1.6, float("nan")]}, "k2: value nan is not a finite number"),
    (["k2=1.6,inf"], "k2: value inf is not a finite number"),
    ({"k1": [1000, -5]}, "--vary k1: value -5(.0)? Pa is not allowed, so no run was started"),
    ({"thickness": [0.005, -0.001]}, "--vary thickness: value -0.001 m is not allowed"),
    ({"g1": [0.3, 0.46], "g2": [0.1, 0.45]}, "the combination g1=0.46 g2=0.45 is not allowed"),
    ({"g1": [0.45, 0.4709990000000001]}, r"--vary g1: value 0.4709990000000001 is not allowed"),  # not 0.470999 -
])
def test_bad_values_are_refused_before_any_run(scene, tmp_path, monkeypatch, vary, message):
    ran = []
    monkeypatch.setattr(sweep.simulate, "drop_test", lambda *a, **k: ran.append(a))
    with pytest.raises(InputError, match=message):
        cfm.sweep(scene, vary=vary, out=tmp_path / "out", progress=False)
    assert ran == [] and not (tmp_path / "out").exists()


def test_cli_nan_in_vary_is_exit_2_naming_the_value(scene, tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(scene_to_toml(scene))
    assert main(["sweep", "--serial", "--scene", str(path), "--vary", "k2=1.6,nan", "--out", str(tmp_path / "o")]) == 2
    assert "k2: value nan is not a finite number" in capsys.readouterr().err


def test_cli_prints_count_and_estimate_and_asks_above_the_limit(scene, tmp_path, capsys, monkeypatch):
    path = tmp_path / "s.toml"
    path.write_text(scene_to_toml(scene))
    args = ["sweep", "--serial", "--scene", str(path), "--vary", "k2=1.6,1.8", "--out", str(tmp_path / "o")]
    monkeypatch.setattr(sweep, "CONFIRM_RUNS", 1)
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: "n")
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "sweep of 2 drop tests, about" in err and "add --yes" in err
    assert not (tmp_path / "o").exists()
    assert main(args + ["--yes"]) == 0
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)  # a script: proceeds without asking
    assert main(args) == 0


def test_estimate_scales_with_the_mesh(scene):
    coarse = sweep.estimate_seconds(scene, sweep.parse_vary({"k2": [1.6]}, scene))
    fine = sweep.estimate_seconds(scene, sweep.parse_vary({"element_size": [0.00125]}, scene))
    assert fine / coarse == pytest.approx((sweep.RUN_OVERHEAD + 16 * (coarse - sweep.RUN_OVERHEAD))
                                          / coarse, rel=1e-9)
    paper = cfm.builtin_scene("drop-test")  # the reference: 8 mm, 1 mm elements, 50 mm wide
    assert sweep.estimate_seconds(paper, sweep.parse_vary({"k2": [1.6]}, paper)) == pytest.approx(
        sweep.REFERENCE_RUN["seconds"] + sweep.RUN_OVERHEAD)


# ----------------------------------------------------------------------------- the output folder
def test_interrupted_sweep_leaves_no_earlier_table_and_resumes(scene, tmp_path, monkeypatch):
    """Case output-folder-states step 5: a sweep into a folder holding an earlier sweep, interrupted."""
    out = tmp_path / "out"
    first = cfm.sweep(scene, vary={"k2": [1.6, 1.8]}, out=out, progress=False)
    assert first.executed == 2 and (out / "sweep.csv").is_file()
    foreign = out / "notes.txt"
    foreign.write_text("mine")
    real = sweep.map_cases

    def interrupted(runner, tasks, batch_size=64):
        for n, done in enumerate(real(runner, tasks, batch_size)):
            if n == 1:
                raise KeyboardInterrupt
            yield done

    monkeypatch.setattr(sweep, "map_cases", interrupted)
    with pytest.raises(KeyboardInterrupt):
        cfm.sweep(scene, vary={"k2": [1.65, 1.85, 2.05]}, out=out, progress=False)
    left = {p.name for p in out.iterdir()}
    assert left == {"runs", "notes.txt"}  # no sweep.csv, sweep.parquet, peaks.png, sweep.json of the first
    assert len(list(out.glob("runs/*/summary.json"))) == 3  # the first sweep's two runs and one new one
    monkeypatch.setattr(sweep, "map_cases", real)
    resumed = cfm.sweep(scene, vary={"k2": [1.65, 1.85, 2.05]}, out=out, progress=False)
    assert resumed.skipped == 1 and resumed.executed == 2
    table = outcomes.table_frame(resumed.rows, resumed.axes)
    assert list(table["k2 [-]"]) == [1.65, 1.85, 2.05] and foreign.read_text() == "mine"
    assert json.loads((out / ".cfm-output.json").read_text())["files"] == [
        "peaks.png", "runs", "sweep.csv", "sweep.json", "sweep.parquet"]


def test_unwritable_out_is_refused_before_any_run(scene, tmp_path, monkeypatch):
    ran = []
    monkeypatch.setattr(sweep.simulate, "drop_test", lambda *a, **k: ran.append(a))
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(InputError, match="is not a directory|is a file"):
        cfm.sweep(scene, vary={"k2": [1.6]}, out=blocker, progress=False)
    assert ran == []


def test_cli_backend_option_reaches_the_runs_and_sweep_json(scene, tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(scene_to_toml(scene))
    out = tmp_path / "o"
    args = ["sweep", "--serial", "--quiet", "--scene", str(path), "--vary", "k2=1.6", "--out", str(out)]
    assert main(args + ["--option", "hourglass=0.05"]) == 0
    record = json.loads((out / "sweep.json").read_text())
    assert record["provenance"]["backend"]["options"]["hourglass"] == 0.05
    (rid,) = record["run_ids"]
    peak = json.loads((out / "runs" / rid / "summary.json").read_text())["peak_g"]
    stiff = scene.with_overrides(parameters={"k2": 1.6})
    assert peak == cfm.drop_test(stiff, hourglass=0.05).peak_g != cfm.drop_test(stiff).peak_g  # the option ran
    assert main(args) == 0  # the default hourglass: another run, not the cached one
    assert json.loads((out / "sweep.json").read_text())["run_ids"] != [rid]


def test_each_run_of_a_sweep_is_repeated_from_its_own_scene_toml(scene_file, tmp_path):
    """runs/<id>/ held acceleration.csv and summary.json only: no run of a sweep could be repeated from its
    folder (`cfm run --scene runs/<id>/summary.json`: "not valid TOML"). Each run now has its scene.toml,
    with the case's values and the sweep's options, and repeating it gives the same bytes."""
    out = tmp_path / "sw"
    assert main(["sweep", "--scene", scene_file, "--vary", "k1=1000,2000", "--option", "hourglass=0.05", "--serial",
                 "--quiet", "--out", str(out)]) == 0
    runs = sorted((out / "runs").iterdir())
    assert len(runs) == 2
    for run in runs:
        summary = json.loads((run / "summary.json").read_text())
        again = cfm.load_scene(run / "scene.toml")
        assert again.material.parameter_dict["k1"] == summary["sweep"]["k1"] and again.run.option_dict["hourglass"] == 0.05
        assert main(["run", "--scene", str(run / "scene.toml"), "--quiet", "--no-plot",
                     "--out", str(tmp_path / run.name)]) == 0
        assert (tmp_path / run.name / "acceleration.csv").read_bytes() == (run / "acceleration.csv").read_bytes()
    saved = cfm.sweep(cfm.load_scene(scene_file), vary={"k1": [1000.0]}, progress=False).save(tmp_path / "api")
    (rid,) = [p.name for p in (saved / "runs").iterdir()]
    assert (saved / "runs" / rid / "scene.toml").is_file()   # computed without a cache, saved afterwards
