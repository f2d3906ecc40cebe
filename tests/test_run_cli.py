"""``cfm run``: any scene on any backend; reaction-force outputs; explicit backends refuse
quasi-static scenes with a clear message."""

import json

import numpy as np
import pytest

from cfm_core.scene.builder import build_model
from cfm_core.cli import main
from cfm_core.errors import InputError
from cfm_core.simulation.point import uniaxial
from cfm_core.simulation.registry import get_backend
from cfm_core.scene.scene import builtin_scene, scene_to_toml


def _read(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_explicit_backends_refuse_quasi_static_scene(backend, tmp_path, capsys):
    pytest.importorskip(backend)
    m = build_model(builtin_scene("relaxation"))
    with pytest.raises(InputError, match=rf"backend '{backend}' \(explicit\) cannot run the relaxation scene.*skfem"):
        get_backend(backend).run(m)
    out = tmp_path / "rx"
    assert main(["run", "--scene", "relaxation", "--backend", backend, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "quasi-static" in err and "Traceback" not in err
    assert not out.exists()


def test_run_relaxation_writes_reaction_history(tmp_path):
    """Default backend for the relaxation scene is skfem; reaction.csv against the uniaxial driver."""
    pytest.importorskip("skfem")
    sc = builtin_scene("relaxation").with_overrides(hold=2.0, output_rate=20.0)
    path = tmp_path / "rx.toml"
    path.write_text(scene_to_toml(sc))
    out = tmp_path / "out"
    assert main(["run", "--scene", str(path), "--out", str(out), "--quiet"]) == 0
    header, data = _read(out / "reaction.csv")
    assert header == ["t [s]", "stretch [-]", "reaction_force [N]", "nominal_stress [Pa]"]
    t, lam, force, nominal = data.T
    s = json.loads((out / "summary.json").read_text())
    assert s["backend"] == "skfem" and s["units"]["reaction_force"] == "N" and s["units"]["t"] == "s"
    assert (out / "reaction.png").stat().st_size > 1000
    rx = sc.relaxation
    np.testing.assert_allclose(nominal, force / rx.size**2, rtol=1e-12)
    np.testing.assert_allclose(lam[t >= rx.load_time], rx.stretch, rtol=1e-12)
    # independent truth: the uniaxial material-point driver with the same ramp, then the hold
    tu, _, P, _ = uniaxial(build_model(sc).material, abs(rx.stretch - 1) / rx.load_time, rx.stretch,
                           steps=50, hold=rx.hold)
    for tc in (rx.load_time, rx.load_time + rx.hold):
        ref = float(np.interp(tc, tu, P)) * rx.size**2
        assert abs(np.interp(tc, t, force) - ref) < 1e-3 * abs(P).max() * rx.size**2
    assert s["peak_force"] == pytest.approx(force[np.argmax(np.abs(force))])
    assert 0.0 < s["final_over_peak"] < 1.0  # the held force relaxes


def test_single_element_numba_against_skfem(tmp_path, capsys):
    """Same single-element scene on the explicit and the implicit backend: reaction force within
    1 % of its largest value (the explicit element rings about the quasi-static path)."""
    pytest.importorskip("skfem")
    pytest.importorskip("numba")
    hist = {}
    for backend in ("numba", "skfem"):
        out = tmp_path / backend
        assert main(["run", "--scene", "single-element", "--backend", backend, "--out", str(out),
                     "--quiet", "--no-plot"]) == 0
        hist[backend] = _read(out / "reaction.csv")[1]
        assert not (out / "reaction.png").exists()
    n, s = hist["numba"], hist["skfem"]
    fs = np.interp(n[:, 0], s[:, 0], s[:, 2])
    err = np.abs(n[:, 2] - fs).max() / np.abs(fs).max()
    print(f"single element, numba vs skfem reaction force: max difference {err:.2e} of the peak")
    assert err < 1e-2
    # cfm compare reads both directories back and reports the same comparison
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "skfem"), str(tmp_path / "numba"), "--json", str(tmp_path / "c.json"),
                 "--plot", str(tmp_path / "c.png")]) == 0
    row = json.loads((tmp_path / "c.json").read_text())["rows"][0]
    grid = np.linspace(max(n[0, 0], s[0, 0]), min(n[-1, 0], s[-1, 0]), 2001)
    l2 = np.linalg.norm(np.interp(grid, *n[:, [0, 2]].T) - np.interp(grid, *s[:, [0, 2]].T)) / np.linalg.norm(
        np.interp(grid, *s[:, [0, 2]].T))
    assert row["rel_l2"] == pytest.approx(l2, rel=0.05) and row["run"] == "numba (numba)"
    assert "rel L2" in capsys.readouterr().out and (tmp_path / "c.png").stat().st_size > 1000


def test_compare_bad_input(tmp_path, capsys):
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "acceleration.csv").write_text("t,a_raw,a_cfc600\n0,0,0\n")
    assert main(["compare", str(tmp_path / "half"), str(tmp_path / "half")]) == 2
    assert "no summary.json" in capsys.readouterr().err


def test_run_bad_scene_name(tmp_path, capsys):
    assert main(["run", "--scene", "no-such-scene", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "no-such-scene" in err and "relaxation" in err and "Traceback" not in err


def test_run_drop_test_scene_matches_drop_test_command(tmp_path):
    pytest.importorskip("numba")
    over = dict(thickness=0.005, element_size=0.0025, width=0.02)
    path = tmp_path / "d.toml"
    path.write_text(scene_to_toml(builtin_scene("drop-test").with_overrides(**over)))
    a, b = tmp_path / "run", tmp_path / "drop"
    assert main(["run", "--scene", str(path), "--out", str(a), "--quiet", "--no-plot"]) == 0
    assert main(["drop-test", "--scene", str(path), "--out", str(b), "--quiet", "--no-plot"]) == 0
    np.testing.assert_array_equal(_read(a / "acceleration.csv")[1], _read(b / "acceleration.csv")[1])


def test_cli_drop_test_on_skfem_writes_the_same_outputs(tmp_path, capsys):
    """`cfm drop-test --backend skfem` writes the files every backend writes (8-element specimen);
    its hourglass ratio is n/a (fully integrated elements have no hourglass energy): null in
    summary.json with the reason, "n/a" in the printed line."""
    pytest.importorskip("skfem")
    path = tmp_path / "tiny.toml"
    path.write_text(scene_to_toml(builtin_scene("drop-test").with_overrides(width=0.01, thickness=0.005,
                                                                           element_size=0.0025)))
    out = tmp_path / "skfem"
    assert main(["drop-test", "--scene", str(path), "--backend", "skfem", "--out", str(out), "--quiet"]) == 0
    header, data = _read(out / "acceleration.csv")
    s = json.loads((out / "summary.json").read_text())
    assert header == ["t [s]", "a_raw [m/s^2]", "a_cfc600 [m/s^2]"] and np.isfinite(data).all()
    assert s["backend"] == "skfem" and s["newton_iterations"] >= s["steps"] and s["peak_g"] > 0
    assert s["units"]["newton_iterations"] == "-" and (out / "acceleration.png").exists()
    assert s["hourglass_ratio"] is None and s["hourglass_ratio_note"].startswith("n/a: backend 'skfem' has no hourglass")
    assert "hourglass/internal n/a" in capsys.readouterr().out


COARSE = ["--element-size", "0.002", "--quiet", "--no-plot"]


def test_backend_options_from_the_command_line_change_the_run(tmp_path):
    """--option NAME=VALUE reaches the backend (half the safety factor: about twice the steps, the
    same peak); unknown names and bad values exit 2 naming the option."""
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["drop-test", *COARSE, "--out", str(a)]) == 0
    assert main(["drop-test", *COARSE, "--option", "safety=0.45", "--out", str(b)]) == 0
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert 1.8 < sb["steps"] / sa["steps"] < 2.2 and abs(sb["peak_g"] / sa["peak_g"] - 1) < 5e-3
    assert main(["drop-test", *COARSE, "--option", "hourglas=0.1", "--out", str(tmp_path / "c")]) == 2
    assert main(["drop-test", *COARSE, "--option", "safety=2", "--out", str(tmp_path / "c")]) == 2
    assert main(["drop-test", *COARSE, "--dtype", "float32", "--out", str(tmp_path / "c")]) == 2
    assert not (tmp_path / "c").exists()


def test_point_backend_refuses_scenes_with_exit_2(tmp_path, capsys):
    assert main(["drop-test", "--backend", "numpy", *COARSE, "--out", str(tmp_path / "np")]) == 2
    assert "material points only" in capsys.readouterr().err


def test_a_failed_run_leaves_the_earlier_output_whole(tmp_path):
    """A failed run into a used folder publishes nothing: the earlier run's files stay as they
    were (all of one run, none of the failed one), and no stage is left beside the folder."""
    out = tmp_path / "run"
    assert main(["drop-test", *COARSE, "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    # 60 kg (a 60 g impactor typed in grams?) is only warned about before running; the run then
    # stops with the penetration check
    assert main(["drop-test", *COARSE, "--mass", "60", "--out", str(out)]) == 3
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_written_scene_holds_every_parameter_and_repeats_the_run(tmp_path):
    first, again = tmp_path / "first", tmp_path / "again"
    assert main(["drop-test", *COARSE, "--param", "k2=3", "--out", str(first)]) == 0
    text = (first / "scene.toml").read_text()
    for name in ("c", "k1", "k2", "kappa", "g1", "tau1", "g2", "tau2", "g3", "tau3"):
        assert f"\n{name} = " in text
    assert main(["run", "--scene", str(first / "scene.toml"), "--quiet", "--no-plot", "--out", str(again)]) == 0
    a, b = (np.loadtxt(d / "acceleration.csv", delimiter=",", skiprows=1) for d in (first, again))
    assert np.array_equal(a, b)


def test_every_scene_backend_lists_its_options(capsys):
    """cfm backends --options prints each scene backend's declared options (skfem's too)."""
    import re

    assert main(["backends", "--options"]) == 0
    out = capsys.readouterr().out
    blocks = dict(re.findall(r"^(\w+) +\w+ +available.*\n((?:(?!^\w).*\n?)*)", out, re.M))
    for backend, option in (("numba", "hourglass"), ("torch", "device"), ("skfem", "linear_solver")):
        assert re.search(rf"^\s+{option}\s", blocks[backend], re.M), (backend, blocks.get(backend))
