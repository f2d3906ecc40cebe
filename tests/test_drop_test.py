"""The main job end to end (numba backend): single element vs material point, CLI outputs,
bad input, mesh convergence (slow)."""

import json

import numpy as np
import pytest

pytest.importorskip("numba")

from cfm_core import make_material
from cfm_core.simulation import point as pt
from cfm_core.scene.builder import build_model
from cfm_core.cli import main
from cfm_core.scene.scene import builtin_scene
from cfm_core.runs.pipeline import run_model


@pytest.mark.parametrize("elastic", [True, False])
def test_slow_single_element_compression_matches_point_driver(elastic):
    scene = builtin_scene("single-element").with_overrides(stretch=0.6, rate=2.0, elastic=elastic)
    model = build_model(scene)
    res = run_model(model, "numba")
    size = scene.element.size
    u = np.array([model.prescribed.displacement(t) for t in res.t])
    lam_fe = 1 + u / size
    nominal_fe = res.reaction_force / size**2  # N / m^2 on the reference area
    t_ref, lam_ref, P_ref, _ = pt.uniaxial(model.material, 2.0, 0.6, steps=400)
    P_at = np.interp(res.t, t_ref, P_ref)
    # the explicit element rings at its own frequency (no damping when elastic): average it out
    # over a window of many periods (~0.6 ms) before comparing with the quasi-static reference
    w = 201
    kernel = np.ones(w) / w
    fe = np.convolve(nominal_fe, kernel, mode="valid")
    qs = np.convolve(P_at, kernel, mode="valid")
    peak = np.abs(P_ref).max()
    assert np.abs(fe - qs).max() / peak < 5e-3


def test_cli_drop_test_writes_outputs_and_summary(tmp_path):
    out = tmp_path / "run"
    code = main(["drop-test", "--thickness", "0.004", "--element-size", "0.002", "--quiet",
                 "--out", str(out), "--scene", str(_small_scene(tmp_path))])
    assert code == 0
    header = (out / "acceleration.csv").read_text().splitlines()[0]
    assert header == "t [s],a_raw [m/s^2],a_cfc600 [m/s^2]"
    s = json.loads((out / "summary.json").read_text())
    for key in ("peak_g", "t_peak", "duration", "pulse_width", "steps", "elements", "wall_time", "energy_error",
                "hourglass_ratio", "backend", "thickness"):
        assert key in s, key
    assert s["backend"] == "numba" and s["thickness"] == 0.004
    assert s["energy_error"] < 0.01 and s["hourglass_ratio"] < 0.1
    assert 0 < s["t_peak"] < s["duration"]
    assert (out / "acceleration.png").stat().st_size > 10_000
    data = np.loadtxt(out / "acceleration.csv", delimiter=",", skiprows=1)
    assert np.allclose(np.diff(data[:, 0]), 2e-5)  # 50 kHz
    assert np.isfinite(data).all()


def _small_scene(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text('[scene]\ntype = "drop-test"\n[specimen]\nwidth = 0.02\n')
    return path


@pytest.mark.parametrize("args,needle", [
    (["--thickness", "-0.005"], "thickness"),
    (["--thickness", "nan"], "thickness"),
    (["--element-size", "0.01", "--thickness", "0.005"], "element_size"),
    (["--velocity", "0"], "velocity"),
    (["--backend", "nope"], "unknown backend 'nope'"),
    (["--param", "k2=-3"], "'k2' = -3.0"),
])
def test_drop_test_bad_input(tmp_path, capsys, args, needle):
    out = tmp_path / "bad"
    assert main(["drop-test", "--quiet", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert not (out / "summary.json").exists()


def test_unknown_key_in_scene_file(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('[scene]\ntype = "drop-test"\n[specimen]\nthicknes = 0.005\n')
    assert main(["drop-test", "--scene", str(path), "--quiet", "--out", str(tmp_path / "o")]) == 2
    assert "thicknes" in capsys.readouterr().err


def test_overflow_stops_with_element_time_and_quantity(tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["drop-test", "--scene", str(_small_scene(tmp_path)), "--element-size", "0.002",
                 "--velocity", "20", "--param", "k2=400", "--quiet", "--out", str(out)])
    assert code == 3
    err = capsys.readouterr().err
    assert "element" in err and " s" in err
    assert not (out / "summary.json").exists()


@pytest.mark.slow
def test_peak_converges_with_mesh_refinement():
    peaks = []
    for h in (2e-3, 1e-3, 0.5e-3):
        scene = builtin_scene("drop-test").with_overrides(element_size=h)
        from cfm_core.runs.pipeline import drop_test

        peaks.append(drop_test(scene, "numba").summary["peak_g"])
    d1, d2 = abs(peaks[1] - peaks[0]), abs(peaks[2] - peaks[1])
    assert d2 < d1  # differences shrink
    assert d2 / peaks[2] < 0.05
