"""Material-point driver and `cfm point` against independent references and bad input."""

import csv

import numpy as np
import pytest

from cfm_core import make_material
from cfm_core.simulation import point as pt
from cfm_core.cli import main
from cfm_verification.truths import cauchy_mp  # the paper's Eq. 2-7 in mpmath, independent of codegen

HEADER = "t,F11,F12,F13,F21,F22,F23,F31,F32,F33"


def write_history(path, t, F):
    with open(path, "w") as fh:
        fh.write(HEADER + "\n")
        for ti, Fi in zip(t, F):
            fh.write(",".join(repr(float(v)) for v in [ti, *Fi.ravel()]) + "\n")


def read_out(path):
    with open(path) as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t [s]", "s11 [Pa]", "s22 [Pa]", "s33 [Pa]", "s12 [Pa]", "s23 [Pa]", "s13 [Pa]"]
    return np.array(rows[1:], dtype=float)


def test_elastic_cli_matches_independent_mpmath_reference(tmp_path):
    rng = np.random.default_rng(7)
    Fs = [np.eye(3), np.diag([0.6, 1.25, 1.3]), np.diag([0.8, 1.1, 1.1]),  # repeated stretches
          np.eye(3) + 0.2 * rng.standard_normal((3, 3)), np.array([[1, 0.4, 0], [0, 1, 0], [0, 0, 1.0]])]
    t = np.arange(len(Fs)) * 1e-3
    write_history(tmp_path / "F.csv", t, np.array(Fs))
    assert main(["point", "--material", "cfm", "--elastic", "--history", str(tmp_path / "F.csv"),
                 "--out", str(tmp_path / "s.csv")]) == 0
    got = read_out(tmp_path / "s.csv")
    assert np.allclose(got[:, 0], t)
    for row, F in zip(got, Fs):
        truth = cauchy_mp(F)
        tv = np.array([truth[0, 0], truth[1, 1], truth[2, 2], truth[0, 1], truth[1, 2], truth[0, 2]])
        scale = max(np.abs(tv).max(), 1.0)
        assert np.abs(row[1:] - tv).max() / scale < 1e-6


def test_uniaxial_mode_zero_lateral_stress_and_energy_consistency(tmp_path):
    out = tmp_path / "u.csv"
    assert main(["point", "--material", "cfm", "--elastic", "--uniaxial", "--rate", "100", "--stretch", "0.5",
                 "--steps", "50", "--out", str(out)]) == 0
    rows = list(csv.reader(open(out)))
    assert rows[0] == ["t [s]", "stretch [-]", "nominal_stress [Pa]", "lateral_stretch [-]"]
    data = np.array(rows[1:], dtype=float)
    assert data[-1, 1] == pytest.approx(0.5)
    assert data[-1, 0] == pytest.approx(0.005)
    # independent check: P11 = d W(diag(l, lt, lt)) / d l at fixed lt (lateral stress is zero)
    mat = make_material("cfm", elastic=True)
    from cfm_core.material import reference as ref

    for _, lam, P, lt in data[5::10]:
        h = 1e-7
        Wp = ref.energy(mat, np.diag([lam + h, lt, lt]))[0]
        Wm = ref.energy(mat, np.diag([lam - h, lt, lt]))[0]
        assert P == pytest.approx((Wp - Wm) / (2 * h), rel=1e-6)
        sigma = ref.cauchy(mat, np.diag([lam, lt, lt]))[0]
        assert abs(sigma[1, 1]) < 1e-8 * abs(sigma[0, 0])


def test_viscoelastic_uniaxial_is_stiffer_at_higher_rate():
    mat = make_material("cfm")
    _, _, P_slow, _ = pt.uniaxial(mat, 1.0, 0.6, steps=40)
    _, _, P_fast, _ = pt.uniaxial(mat, 1000.0, 0.6, steps=40)
    assert P_fast[-1] < P_slow[-1] < 0  # compression: more negative when faster


@pytest.mark.parametrize("content,needle", [
    ("t,F11\n0,1\n", "header must be exactly"),
    (HEADER + "\n0,1,0,0,0,1,0,0,0,1\n0.1,1,0,0,0,1,0,0,0\n", "line 3"),
    (HEADER + "\n0,1,0,0,0,1,0,0,0,1\n0.1,1,0,0,0,x,0,0,0,1\n", "line 3: F22 = 'x' is not a finite decimal number"),
    (HEADER + "\n0,1,0,0,0,1,0,0,0,1\n0.1,-1,0,0,0,1,0,0,0,1\n", "line 3: det F"),
    (HEADER + "\n0.2,1,0,0,0,1,0,0,0,1\n0.1,1,0,0,0,1,0,0,0,1\n", "line 3: t = 0.1 s does not follow"),
    (HEADER + "\n0,nan,0,0,0,1,0,0,0,1\n", "line 2: F11 = 'nan' is not a finite"),
    (HEADER + "\n", "no data rows"),
])
def test_malformed_history_names_the_line_and_leaves_no_output(tmp_path, capsys, content, needle):
    (tmp_path / "F.csv").write_text(content)
    out = tmp_path / "s.csv"
    assert main(["point", "--history", str(tmp_path / "F.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("args,needle", [
    (["--material", "nope"], "unknown material 'nope'; available: cfm"),
    (["--param", "c=-1"], "'c' = -1.0 Pa is outside the allowed range (0, inf) Pa"),
    (["--param", "c=nan"], "'c' = nan Pa is outside"),
    (["--param", "zz=1"], "has no parameter 'zz'"),
    (["--param", "g1=0.6"], "must be at least 1e-06"),
    (["--param", "tau2=0"], "'tau2' = 0.0 s is outside the allowed range (0, inf) s"),
    (["--param", "c"], "NAME=VALUE"),
    (["--backend", "nope"], "unknown backend 'nope'"),
])
def test_bad_material_input_is_a_clear_error(tmp_path, capsys, args, needle):
    write_history(tmp_path / "F.csv", np.array([0.0]), np.eye(3)[None])
    out = tmp_path / "s.csv"
    assert main(["point", "--history", str(tmp_path / "F.csv"), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert needle in err, err
    assert not out.exists()


def test_listing_commands(capsys):
    assert main(["materials"]) == 0
    text = capsys.readouterr().out
    assert "cfm:" in text and "kappa" in text and "666100" in text and "Pa" in text
    assert main(["backends"]) == 0
    assert "numpy" in capsys.readouterr().out


@pytest.mark.parametrize("backend", ["numba", "torch", "skfem"])
def test_uniaxial_on_a_backend_follows_the_reference_and_draws_a_plot(tmp_path, backend):
    """cfm point --uniaxial --backend B: B's stress along the reference's uniaxial path equals the
    reference's own nominal stress (the backends share no stress code with the reference except
    skfem, whose point driver is the reference itself) and its lateral stress is ~0."""
    ref_out, out = tmp_path / "ref.csv", tmp_path / f"{backend}.csv"
    args = ["point", "--material", "cfm", "--uniaxial", "--rate", "100", "--stretch", "0.6", "--steps", "40"]
    assert main(args + ["--out", str(ref_out)]) == 0
    assert main(args + ["--backend", backend, "--out", str(out)]) == 0
    ref = np.loadtxt(ref_out, delimiter=",", skiprows=1)
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.abs(got[:, 2] - ref[:, 2]).max() < 1e-9 * np.abs(ref[:, 2]).max()
    assert out.with_suffix(".png").stat().st_size > 10_000


def test_point_help_names_the_default_material(capsys):
    """A user running `cfm point` without --material learns from --help which material is used."""
    with pytest.raises(SystemExit):
        main(["point", "--help"])
    assert "default: cfm" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("args, named", [
    (["--steps", "50"], "--steps"),
    (["--steps", "0"], "--steps"),  # refused as a flag of --uniaxial, not checked as a count of its ramp
    (["--hold", "1"], "--hold"),
    (["--hold", "0"], "--hold"),  # typed, even at its default
    (["--rate", "100", "--stretch", "0.7"], "--rate, --stretch"),
    (["--no-plot"], "--no-plot"),
])
def test_history_refuses_the_flags_of_uniaxial(tmp_path, capsys, args, named):
    """--history silently ignored --steps and --hold (they shape the --uniaxial ramp) yet checked --steps 0
    as "steps of the --uniaxial loading ramp"."""
    write_history(tmp_path / "F.csv", np.array([0.0]), np.eye(3)[None])
    out = tmp_path / "s.csv"
    assert main(["point", "--history", str(tmp_path / "F.csv"), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert f"{named}: only with --uniaxial" in err and "--history" in err and "Traceback" not in err, err
    assert not out.exists()


def test_history_without_uniaxial_flags_and_uniaxial_defaults_still_work(tmp_path):
    write_history(tmp_path / "F.csv", np.array([0.0, 1e-3]), np.stack([np.eye(3), np.diag([0.9, 1.05, 1.05])]))
    assert main(["point", "--history", str(tmp_path / "F.csv"), "--out", str(tmp_path / "s.csv")]) == 0
    out = tmp_path / "u.csv"
    assert main(["point", "--uniaxial", "--rate", "100", "--stretch", "0.9", "--no-plot", "--out", str(out)]) == 0
    assert np.loadtxt(out, delimiter=",", skiprows=1).shape == (201, 4)  # --steps 200, --hold 0 by default


def test_uniaxial_reports_its_progress_step_by_step():
    """`cfm point --uniaxial --steps 100000` ran 3.5 minutes without a word: the driver reports each step
    (steps done, steps in all) to a callable (the command's progress bar), ending at all of them."""
    from cfm_core.material.registry import make_material
    from cfm_core.simulation.point import uniaxial

    seen = []
    t = uniaxial(make_material("cfm"), 100.0, 0.9, steps=10, hold=0.01, progress=lambda d, n: seen.append((d, n)))[0]
    assert seen == [(k, t.size) for k in range(1, t.size + 1)] and t.size == 21
