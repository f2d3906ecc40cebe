"""Calibration: twin experiment (recover known parameters), CLI outputs, Dask, bad input."""

import json

import numpy as np
import pytest

from cfm_core.studies import calibrate
from cfm_core.studies import measured as measured_data

from cfm_core.runs import pipeline as simulate
from cfm_core.cli import main
from cfm_core.studies.dask_runner import open_runner
from cfm_core.errors import InputError
from cfm_core.scene.scene import load_scene, scene_to_toml
from cfm_core.post.writers import write_csv

pytest.importorskip("numba")

TRUE = {"k1": 1320.0, "k2": 1.66, "g1": 0.45}  # Table 1
THICKNESSES = (0.005, 0.008)  # two thicknesses: the fibre stiffening shows differently



@pytest.fixture(scope="module")
def measured(scene, tmp_path_factory):
    """Synthetic measurements: the raw 50 kHz histories of the true parameters, as CSV t,a."""
    folder = tmp_path_factory.mktemp("data")
    specs = []
    for h in THICKNESSES:
        o = simulate.drop_test(scene.with_overrides(thickness=h, parameters=TRUE), "numba")
        write_csv(folder / f"drop{1e3 * h:g}mm.csv", ["t", "a"], [o.t, o.a_raw])
        specs.append(f"{folder / f'drop{1e3 * h:g}mm.csv'}:{h}")
    return specs


def _perturbed(names):
    """Start values 30 % off: k1 and g1 down, k2 up."""
    return {n: TRUE[n] * (1.3 if n == "k2" else 0.7) for n in names}


def test_twin_experiment_recovers_k1_k2_g1_within_2_percent(scene, measured):
    curves = measured_data.read_curves(measured, scene, scene_given=False)
    names = ["k1", "k2", "g1"]
    result = calibrate.fit(scene, curves, names, _perturbed(names))
    for n in names:
        assert result.final.params[n] == pytest.approx(TRUE[n], rel=0.02), n
        assert result.start.params[n] == pytest.approx(_perturbed(names)[n])
    assert result.final.cost < 1e-4 * result.start.cost
    assert max(result.final.rel_l2) < 1e-3 < min(result.start.rel_l2)
    conf = result.confidence
    assert all(conf["parameters"][n]["ci"][0] < result.final.params[n] < conf["parameters"][n]["ci"][1]
               for n in names)
    assert conf["correlation"][0][2] < -0.99  # k1 and g1 trade off (both set k1/g_inf); documented
    assert result.problem.runs < 400


def test_cli_fit_writes_parameters_plots_and_a_runnable_scene(scene, measured, tmp_path, capsys):
    scene_file = tmp_path / "coarse.toml"
    scene_file.write_text(scene_to_toml(scene))
    out = tmp_path / "fit"
    start = _perturbed(["k1", "k2"])
    args = ["calibrate", "--scene", str(scene_file), "--data", *measured, "--fit", "k1,k2", "--serial",
            "--param", f"k1={start['k1']}", "--param", f"k2={start['k2']}", "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr()
    assert "evaluation 1: cost" in printed.err and "95 % CI" in printed.out
    fit = json.loads((out / "fit.json").read_text())
    for n in ("k1", "k2"):
        p = fit["parameters"][n]
        assert p["fitted"] == pytest.approx(TRUE[n], rel=0.02) and p["start"] == pytest.approx(start[n])
        assert p["ci95"][0] < p["fitted"] < p["ci95"][1] and p["unit"] == ("Pa" if n == "k1" else "-")
    assert [c["thickness"] for c in fit["curves"]] == list(THICKNESSES)
    assert fit["history"][0]["cost"] == fit["cost_start"] > fit["cost"]
    assert fit["drop_tests"] >= 2 * len(fit["history"])
    for name in ("fit_drop5mm.png", "fit_drop8mm.png", "objective.png"):
        assert (out / name).stat().st_size > 0
    fitted = load_scene(out / "fitted-scene.toml")
    assert fitted.material.parameter_dict["k1"] == fit["parameters"]["k1"]["fitted"]
    assert fitted.specimen.element_size == 0.0025  # the coarse scene of conftest.py
    assert main(["drop-test", "--scene", str(out / "fitted-scene.toml"), "--quiet", "--no-plot",
                 "--out", str(tmp_path / "drop")]) == 0


def test_dask_fit_equals_serial_fit(scene, measured):
    pytest.importorskip("distributed")
    curves = measured_data.read_curves(measured, scene, scene_given=False)
    start = _perturbed(["k1", "k2"])
    serial = calibrate.fit(scene, curves, ["k1", "k2"], start, max_evaluations=3)
    with open_runner(None, workers=2) as runner:
        dask = calibrate.fit(scene, curves, ["k1", "k2"], start, runner=runner, max_evaluations=3)
    assert dask.final.params == serial.final.params
    assert [h["cost"] for h in dask.problem.history] == [h["cost"] for h in serial.problem.history]


def _write(path, text):
    path.write_text(text)
    return str(path)


def test_bad_data_files_name_the_file_and_line(scene, tmp_path):
    rows = "".join(f"{1e-4 * k!r},{float(k)}\n" for k in range(20))
    cases = {
        "empty.csv": ("", "is empty"),
        "header.csv": ("time,acc\n" + rows, "line 1: the header must name the columns 't,a'.*got 'time,acc'"),
        "nan.csv": ("t,a\n" + rows.replace("0.0005,5.0", "0.0005,nan"), "line 7: a = 'nan' is not a finite"),
        "text.csv": ("t,a\n" + rows.replace("0.0005,5.0", "0.0005,five"), "line 7: a = 'five'"),
        "order.csv": ("t,a\n" + rows.replace("0.0005,5.0", "0.0001,5.0"), "line 7: t = 0.0001 s does not follow"),
        "short.csv": ("t,a\n" + "".join(rows.splitlines(True)[:5]), "has 5 rows at t >= 0 s; at least 10"),
        "ragged.csv": ("t,a\n" + rows.replace("0.0005,5.0", "0.0005,5.0,1"), "line 7: 3 values separated by commas for the 2 columns"),
        "negative.csv": ("t,a\n" + rows.replace(",", ",-"), "flip its sign"),
    }
    for name, (text, message) in cases.items():
        with pytest.raises(InputError, match=message) as err:
            measured_data.read_curve(f"{_write(tmp_path / name, text)}:0.005", None)
        assert name in str(err.value)
    with pytest.raises(InputError, match="cannot be read"):
        measured_data.read_curve(f"{tmp_path / 'missing.csv'}:0.005", None)
    curve = measured_data.read_curve(_write(tmp_path / "ok.csv", "# drop 1\nt,a\n" + rows), 0.006)
    assert curve.thickness == 0.006 and curve.t[1] == pytest.approx(2e-5) and curve.peak > 0


@pytest.mark.parametrize("suffix, message", [
    ("", "no specimen thickness; give it as"),
    (":5", "thickness 5.0 m is not allowed.*5 mm is 0.005 m"),
    (":-0.005", "thickness -0.005 m is not allowed"),
    (":0", "thickness 0.0 m is not allowed"),
])
def test_missing_or_inconsistent_thickness_is_a_clear_error(measured, suffix, message):
    path = measured[0].rpartition(":")[0]
    with pytest.raises(InputError, match=message):
        measured_data.read_curve(path + suffix, None)


def test_thickness_inconsistent_with_the_scene_is_a_clear_error(scene, measured):
    path = measured[0].rpartition(":")[0]
    curves = measured_data.read_curves([f"{path}:0.002"], scene, scene_given=False)  # 2 mm < 2.5 mm elements
    with pytest.raises(InputError, match=r":0.002: this thickness does not fit the scene: \[specimen\] element_size"):
        calibrate.fit(scene, curves, ["k1"])


def test_fit_names_and_inputs_are_checked(scene, measured, tmp_path, capsys):
    assert calibrate.fit_names("k1, k2,prony", scene) == ["k1", "k2", "g1", "tau1"]
    with pytest.raises(InputError, match="no parameter of that name; its parameters are c, k1"):
        calibrate.fit_names("k1,kk2", scene)
    with pytest.raises(InputError, match="names k1 twice"):
        calibrate.fit_names("k1,k1", scene)
    with pytest.raises(InputError, match="given twice"):
        measured_data.read_curves([measured[0], measured[0]], scene, scene_given=False)
    base = ["calibrate", "--data", *measured, "--serial", "--out", str(tmp_path / "x")]
    assert main(base + ["--fit", "k3"]) == 2
    assert "no parameter of that name" in capsys.readouterr().err
    assert main(base + ["--fit", "k1", "--param", "k2=2"]) == 2
    assert "only fitted parameters take a starting value" in capsys.readouterr().err
    assert main(base + ["--fit", "k1", "--param", "k1=-3"]) == 2
    assert "'k1' = -3.0 Pa is outside the allowed range" in capsys.readouterr().err
    assert main(["calibrate", "--data", measured[0].rpartition(":")[0], "--fit", "k1", "--serial",
                 "--out", str(tmp_path / "x")]) == 2
    assert "no specimen thickness" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_bounds_keep_prony_sum_below_one(scene):
    values = {**calibrate.material_values(scene), "g1": 0.45}
    coords = calibrate.coordinates(["g1", "g2", "k1"], scene, values)
    g_inf = 1 - 0.45 - 0.435 - 0.094
    high = np.exp(coords.upper[:2])
    assert high.sum() < 1 - 0.094 and high.sum() - 0.45 - 0.435 == pytest.approx(0.99 * (g_inf - 1e-6), rel=1e-6)
    assert 1 - high.sum() - 0.094 >= 1e-6       # every fitted g_i at its bound leaves gamma_inf at cfm's floor
    assert coords.upper[2] == np.inf and coords.log == (True, True, True)


def _earlier_output_with(out, scene_text, curve_text):
    """An earlier cfm output in ``out`` (its manifest lists them) holding a scene and a curve t,a."""
    from cfm_core.post.staging import staged_folder

    with staged_folder(out) as stage:
        (stage / "scene.toml").write_text(scene_text)
        (stage / "acceleration.csv").write_text(curve_text)
        (stage / "summary.json").write_text("{}")
    return {p.name: p.read_bytes() for p in out.iterdir()}


def test_a_calibration_into_the_folder_of_its_inputs_is_refused_before_any_drop_test(scene, measured, tmp_path,
                                                                                       capsys):
    """--data run/acceleration.csv (a drop test as the measurement) or --scene run/scene.toml with --out run: the
    fit removed the run's files, its own inputs among them; now exit 2 naming the file, the folder as it was."""
    from pathlib import Path

    out = tmp_path / "run"
    before = _earlier_output_with(out, scene_to_toml(scene), Path(measured[0].rpartition(":")[0]).read_text())
    for data, extra, name in ((f"{out / 'acceleration.csv'}:{THICKNESSES[0]}", [], "acceleration.csv"),
                              (measured[0], ["--scene", str(out / "scene.toml")], "scene.toml")):
        rc = main(["calibrate", "--data", data, "--fit", "k1", "--serial", "--max-evaluations", "1", *extra,
                   "--out", str(out)])
        err = capsys.readouterr().err
        assert rc == 2 and f"{name} is a file of the earlier cfm output there" in err and "Traceback" not in err
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_fitted_parameter_no_layer_takes_is_refused_before_any_drop_test(tmp_path, capsys):
    """A layered scene whose only layer taking [material] gives its own k1: the calibration ran its drop tests and
    warned of a zero Jacobian column afterwards (a minute later); now refused with the reason."""
    path = tmp_path / "layered.toml"
    path.write_text('[scene]\ntype = "drop-test"\n[specimen]\nwidth = 0.03\nelement_size = 0.002\n'
                    '[[specimen.layers]]\nname = "muscle"\nthickness = 0.004\nmaterial = "neo-hookean"\n'
                    '[[specimen.layers]]\nname = "fat"\nthickness = 0.004\n[specimen.layers.parameters]\nk1 = 1000.0\n')
    layered = load_scene(path)
    assert calibrate.fit_names("k2", layered) == ["k2"]
    with pytest.raises(InputError, match=r"--fit k1: no layer of the specimen uses \[material\] k1"):
        calibrate.fit_names("k2,k1", layered)
    data = tmp_path / "d.csv"
    data.write_text("t,a\n0,0\n0.001,100\n0.002,200\n0.003,100\n0.004,0\n")
    assert main(["calibrate", "--scene", str(path), "--data", f"{data}:0.008", "--fit", "k1", "--serial",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--fit k1: no layer of the specimen uses [material] k1" in err and "drop k1 from --fit" in err
    assert not (tmp_path / "o").exists()
