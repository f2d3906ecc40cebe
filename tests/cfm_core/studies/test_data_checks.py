"""Measured data that fits and comparisons used to read wrongly without a word.

Each test names the input that gave a wrong number (or a traceback) before: coarse lab rows, a
relaxation ramp recorded by its end points, a stress column of the wrong sign or all zeros, a fit
that misses its data, a curve with missing samples or recorded from before contact, another
solver's run in ms or g or with a foreign summary.json, a lost Dask cluster during a calibration.
"""

import json

import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.errors import InputError, NumericalError
from cfm_core.material import make_material
from cfm_core.post.compare import compare_runs, read_run
from cfm_core.runs import pipeline
from cfm_core.scene.scene import builtin_scene, scene_to_toml
from cfm_core.simulation import point
from cfm_core.studies import calibrate, fit, identifiability, lab_tests
from cfm_core.studies.dask_runner import Done, lost_reason
from cfm_core.studies.lab_tests import LabTest, simulate
from cfm_core.studies.measured import Curve, check_plausible


def _csv(path, t, x, P):
    rows = "\n".join(f"{a!r},{b!r},{c!r}" for a, b, c in zip(map(float, t), map(float, x), map(float, P)))
    path.write_text(f"t,stretch,stress\n{rows}\n")
    return path


# ----------------------------------------------------------------------------- lab tests (cfm fit)
def test_coarse_rows_simulate_like_fine_ones():
    """Six rows of a compression to 0.6: the Prony recurrence on the rows themselves was 5 % off the
    fine driver; cut into steps of MAX_STEP it is within 3e-4 (the steps' own O(dt^2) error)."""
    m = make_material("cfm")
    t, lam, P, _ = point.uniaxial(m, 1.0, 0.6, steps=800)
    for every in (8, 40, 160):
        test = LabTest("u", "-", "uniaxial", 1.0, 1.0, t[::every], lam[::every], P[::every])
        assert np.abs(simulate(m, test) - test.P).max() <= 3e-4 * np.abs(P).max()


def test_relaxation_ramp_recorded_by_its_end_points_is_the_ramp_at_the_stated_rate():
    m = make_material("cfm")
    t, lam, P, _ = point.uniaxial(m, 100.0, 0.7, steps=600, hold=0.5)
    end = int(np.argmax(lam <= 0.7))
    rows = np.r_[0, np.arange(end + 1, t.size)]  # t = 0, then the hold only: the ramp is not in the file
    test = LabTest("r", "-", "relaxation", 100.0, 1.0, t[rows], lam[rows], P[rows])
    assert np.abs(simulate(m, test) - test.P).max() <= 1e-4 * np.abs(P).max()


def test_fit_of_six_rows_recovers_the_parameters(tmp_path):
    """k1 = 2000 Pa, k2 = 2 from 6 rows: 2056.5 and 2.064 before, intervals excluding the truth."""
    m = make_material("cfm", {"k1": 2000.0, "k2": 2.0})
    t, lam, P, _ = point.uniaxial(m, 1.0, 0.6, steps=800)
    path = _csv(tmp_path / "six.csv", t[::160], lam[::160], P[::160])
    result = fit.fit_lab("cfm", [lab_tests.read_lab_test(path, "uniaxial", 1.0)], ["k1", "k2"])
    assert result.fitted["k1"] == pytest.approx(2000.0, rel=2e-3)
    assert result.fitted["k2"] == pytest.approx(2.0, rel=2e-3)


def _relaxation(tmp_path, g1):
    m = make_material("cfm", {"g1": g1}, "instantaneous")
    t, lam, P, _ = point.uniaxial(m, 100.0, 0.8, steps=100, hold=5.0)
    return lab_tests.read_lab_test(_csv(tmp_path / "relax.csv", t, lam, P), "relaxation", 100.0)


@pytest.mark.parametrize("start", [0.4709, 0.47])
def test_a_prony_coefficient_near_sum_one_is_fitted_to_its_value(tmp_path, start):
    """gamma_inf = 2e-5: the gradient test, scaled by the distance to the bound, could stop the fit early
    (a second run without it, fit._trf, goes on to the minimum)."""
    result = fit.fit_lab("cfm", [_relaxation(tmp_path, 0.47098)], ["g1"], start={"g1": start}, moduli="instantaneous")
    assert result.fitted["g1"] == pytest.approx(0.47098, rel=1e-9)
    lo, hi = result.confidence["parameters"]["g1"]["ci"]
    assert lo <= 0.47098 <= hi


def test_a_prony_coefficient_fitted_toward_the_floor_ends_on_its_bound_not_on_a_false_interval(tmp_path):
    """Data with gamma_inf at cfm's floor (1e-6): the fit stopped after 4 evaluations at gamma_inf = 6.9e-6 with
    a 95 % interval 14 standard deviations from the truth and no warning; then, pushed on, it evaluated
    gamma_inf < 1e-6 and failed. The bound keeps gamma_inf above the floor and the fit says it ended there."""
    result = fit.fit_lab("cfm", [_relaxation(tmp_path, 0.470999)], ["g1"], start={"g1": 0.47095},
                         moduli="instantaneous")
    assert "g1" in result.confidence["at_bound"] and result.confidence["parameters"]["g1"]["ci"] is None
    assert any("ended on the upper end of its search range" in w for w in result.warnings)
    assert 1e-6 <= 1 - result.fitted["g1"] - 0.435 - 0.094 < 2e-6


def test_a_file_with_nominal_and_true_stress_is_read_by_its_nominal_column(tmp_path):
    """Header t,stretch,nominal_stress,stress (true stress P / stretch): the plain 'stress' column was taken, and
    k1 = 2000 Pa was fitted as 3243 Pa, CI [3189, 3298], exit 0."""
    m = make_material("cfm", {"k1": 2000.0})
    t, lam, P, _ = point.uniaxial(m, 100.0, 0.7, steps=60)
    path = tmp_path / "both.csv"
    path.write_text("t [s],stretch [-],nominal_stress [Pa],stress [Pa]\n" + "".join(
        f"{float(a)!r},{float(b)!r},{float(c)!r},{float(c / b)!r}\n" for a, b, c in zip(t, lam, P)))
    test = lab_tests.read_lab_test(path, "uniaxial", 100.0)
    assert np.array_equal(test.P, P)


def test_a_lab_test_with_quoted_cells_reads_as_the_plain_file(tmp_path):
    """Header "t","stretch","stress" (Excel, pandas QUOTE_ALL) was refused: the header must name
    the columns t,stretch; with every cell quoted the rows read as the unquoted ones."""
    m = make_material("cfm")
    t, lam, P, _ = point.uniaxial(m, 100.0, 0.7, steps=60)
    plain = lab_tests.read_lab_test(_csv(tmp_path / "plain.csv", t, lam, P), "uniaxial", 100.0)
    lines = (tmp_path / "plain.csv").read_text().splitlines()
    for name, quote in (("header.csv", lambda k, c: f'"{c}"' if k == 0 else c), ("all.csv", lambda k, c: f'"{c}"')):
        (tmp_path / name).write_text("".join(",".join(quote(k, c) for c in line.split(",")) + "\n"
                                             for k, line in enumerate(lines)))
        test = lab_tests.read_lab_test(tmp_path / name, "uniaxial", 100.0)
        assert np.array_equal(test.t, plain.t) and np.array_equal(test.x, plain.x) and np.array_equal(test.P, plain.P)


def test_a_lab_test_rate_beyond_the_float_range_is_refused_naming_it(tmp_path):
    """rate = 10**400 (an unbounded Python or JSON integer) gave OverflowError from math.isfinite."""
    path = _csv(tmp_path / "u.csv", [0.0, 0.1], [1.0, 0.9], [0.0, -10.0])
    with pytest.raises(InputError, match=r"rate = 1000\.\.\.0 \(an integer of 401 digits\) 1/s is not allowed"):
        lab_tests.read_lab_test(path, "uniaxial", 10 ** 400)


@pytest.mark.parametrize("sign, stress, expected", [
    (-1.0, None, "Flip the sign of the stress column"),   # compression written positive
    (1.0, 0.0, "the stress column is 0 on every line"),   # was a ZeroDivisionError traceback in the fit
])
def test_stress_column_of_the_wrong_sign_or_all_zero_exits_2(tmp_path, capsys, sign, stress, expected):
    m = make_material("cfm")
    t, lam, P, _ = point.uniaxial(m, 1.0, 0.6, steps=40)
    path = _csv(tmp_path / "bad.csv", t, lam, sign * P if stress is None else np.full_like(P, stress))
    assert main(["fit", "--test", f"{path}:uniaxial:1", "--fit", "k1", "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err and "np.float64" not in err
    assert not (tmp_path / "o").exists()


def test_a_fit_that_misses_its_data_withholds_every_interval(tmp_path):
    """A constant stress fitted by the CFM: 62 % relative RMS, and the intervals were reported "ok"."""
    m = make_material("cfm")
    t, lam, _, _ = point.uniaxial(m, 1.0, 0.6, steps=40)
    path = _csv(tmp_path / "const.csv", t, lam, np.full_like(t, -1000.0))
    result = fit.fit_lab("cfm", [lab_tests.read_lab_test(path, "uniaxial", 1.0)], ["k1", "k2"])
    assert max(result.rel_rms()) > identifiability.MISFIT_LIMIT
    assert result.withheld == {"k1", "k2"}
    assert all(result.confidence["parameters"][n]["ci"] is None for n in ("k1", "k2"))
    assert any("misses the data" in w for w in result.warnings)


def test_an_interval_beyond_the_float_range_is_withheld_with_a_warning():
    """A log coordinate whose residuals do not depend on it: its interval overflowed, was withheld without a
    warning and written as "interval": "ok" by cfm fit."""
    coords = calibrate.Coordinates(("tau3",), ("s",), np.array([True]), np.log([1e-3]), np.log([1e3]))
    jac = np.array([[1e-6], [2e-6], [-1e-6]])   # half-width ~1e4 in ln tau3: exp overflows
    conf = calibrate.confidence(np.log([1.0]), jac, np.array([0.01, -0.02, 0.01]), coords)
    assert conf["parameters"]["tau3"]["ci"] is None and "tau3" in conf["flat"]
    assert any("tau3 is not determined by the data" in w for w in conf["warnings"])
    warnings, withheld = fit.identifiability(conf, ["tau3"])
    assert "tau3" in withheld and any("tau3 is not determined" in w for w in warnings)


def test_misfit_warning_names_the_curves_above_the_limit():
    assert identifiability.misfit_warning({"a": 0.05, "b": 0.2}, "relative L2") is None
    text = identifiability.misfit_warning({"a": 0.05, "b": 1.24}, "relative L2")
    assert "'b' 124 %" in text and "'a'" not in text


# ----------------------------------------------------------------------------- measured drop tests (cfm calibrate)
def _pulse(t, start=0.0, T=0.01, peak=235.6):
    """A half-sine deceleration pulse of duration T (s) from ``start``: int a dt = 2 peak T / pi (m/s)."""
    s = np.clip((t - start) / T, 0.0, 1.0)
    return peak * np.sin(np.pi * s)


def test_a_gap_in_a_measured_curve_is_refused_naming_it():
    """60 samples missing at the peak were joined by a straight line: 116 g read as 68 g, exit 0."""
    t = np.arange(0.0, 0.012, 2e-5)
    keep = (t < 0.004) | (t > 0.0052)
    with pytest.raises(InputError, match=r"no samples between t = 0\.00398 s and 0\.0052"):
        check_plausible("gap.csv", t[keep], _pulse(t[keep]), 1.0, 0.02)
    assert check_plausible("full.csv", t, _pulse(t), 1.0, 0.02) == []  # the same curve whole: no note


def test_a_scene_speed_in_km_h_or_a_curve_cut_short_is_refused_naming_both():
    """velocity = 3.6 (km/h for 1 m/s) passed the 0.3 - 3 check with a ratio of 0.44; the fit then ran to k1 =
    1.6e-20 Pa and failed naming a folded element."""
    from cfm_core.post.metrics import velocity_change

    t = np.arange(0.0, 0.012, 2e-5)
    a = _pulse(t)
    speed = velocity_change(t, a) / 1.6                  # the pulse of an impact at this speed, e = 0.6
    assert check_plausible("ok.csv", t, a, speed, 0.02) == []
    with pytest.raises(InputError, match=r"0\.444 times .* \(in km/h\? "):
        check_plausible("kmh.csv", t, a, 3.6 * velocity_change(t, a) / 1.6, 0.02)
    with pytest.raises(InputError, match="cut short"):
        check_plausible("short.csv", t[t < 0.004], a[t < 0.004], speed, 0.02)


def test_a_curve_recorded_from_before_contact_is_warned():
    t = np.arange(0.0, 0.014, 2e-5)
    notes = check_plausible("late.csv", t, _pulse(t, start=0.002), 1.0, 0.02)
    assert len(notes) == 1 and "stays below 1 % of its peak until t = 0.00204 s" in notes[0]


@pytest.mark.parametrize("cut, start, offset, said", [(0.0, 0.0, 0.0, False), (2e-4, 0.0, 0.0, True),
                                                      (4e-4, 0.0, 0.0, True), (0.0, 1e-3, 0.03, False)])
def test_a_record_that_starts_in_contact_is_said_and_a_level_offset_is_not(tmp_path, cut, start, offset, said):
    """A drop test recorded from 0.2 ms after contact (under 2 % of the peak missing): k1 +21 % and k2
    +26 % with intervals excluding the truth, no warning. A constant offset before contact is level."""
    from cfm_core.studies.measured import read_curve, starts_in_contact

    t = np.arange(0.0, 0.014, 2e-5)
    a = _pulse(t + cut, start=start) + offset * 235.6
    assert bool(starts_in_contact("m.csv", t, a)) == said
    path = tmp_path / "m.csv"
    path.write_text("t,a\n" + "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in zip(t, a)))
    curve = read_curve(f"{path}:0.008", None)
    assert bool(curve.late) == said
    assert ("starts in contact" in " ".join(curve.notes)) == said


def test_a_lost_cluster_during_a_calibration_says_it_starts_over():
    """It promised that "runs finished so far are kept ... rerun to resume" and blamed the parameters."""

    class LostRunner:
        label = "dask (lost)"
        workers = 1
        in_process = True

        def map(self, fn, items):
            for i, _ in enumerate(items):
                yield Done(i, error="WorkersLost: the Dask scheduler has had no worker for 5 s (the last one died "
                                    "or was stopped), so this run was not done; runs finished so far are kept: start "
                                    "workers and rerun the same command to resume.")

    t = np.arange(0.0, 0.012, 2e-5)
    curve = Curve("m", "m.csv", 0.008, t, _pulse(t))
    scene = builtin_scene("drop-test")
    with pytest.raises(NumericalError) as info:
        calibrate.fit(scene, [curve], ["k1"], runner=LostRunner())
    text = str(info.value)
    assert "keeps no partial results" in text and "starts over" in text
    assert "resume" not in text and "failed at" not in text
    assert lost_reason("ValueError: bad") is None


# ----------------------------------------------------------------------------- cfm compare
def _run_dir(path, t, a, summary):
    path.mkdir()
    rows = "\n".join(f"{x!r},{y!r},{y!r}" for x, y in zip(map(float, t), map(float, a)))
    (path / "acceleration.csv").write_text(f"t [s],a_raw [m/s^2],a_cfc600 [m/s^2]\n{rows}\n")
    (path / "summary.json").write_text(summary if isinstance(summary, str) else json.dumps(summary))
    return path


@pytest.fixture
def reference(tmp_path):
    t = np.arange(0.0, 0.012, 2e-5)
    return t, _run_dir(tmp_path / "ref", t, _pulse(t), {"backend": "numba", "wall_time": 0.3})


@pytest.mark.parametrize("scale_t, scale_a, expected", [
    (1e3, 1.0, "is t in ms or us"),     # rel L2 99.8 %, t_peak +3676 ms, exit 0 before
    (1.0, 1 / 9.80665, "Is a in g?"),   # |peak| -89.8 %, exit 0 before
])
def test_compare_refuses_another_unit(tmp_path, reference, capsys, scale_t, scale_a, expected):
    t, ref = reference
    other = _run_dir(tmp_path / "other", scale_t * t, scale_a * _pulse(t), {"backend": "lsdyna"})
    assert main(["compare", str(ref), str(other)]) == 2
    assert expected in capsys.readouterr().err


@pytest.mark.parametrize("summary", ['[]', {"wall_time": "12 s"}, {"provenance": "abc", "scene": [1, 2]},
                                     {"provenance": {"backend": "x", "parts": 3}}])
def test_compare_reads_a_foreign_summary_without_a_traceback(tmp_path, reference, capsys, summary):
    t, ref = reference
    other = _run_dir(tmp_path / "other", t, _pulse(t), summary)
    rc = main(["compare", str(ref), str(other)])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert rc == (2 if summary == "[]" else 0)
    if summary != "[]":
        row = compare_runs(read_run(ref), [read_run(other)])[0]
        assert row["rel_l2"] == 0.0 and row["wall_ratio"] is None


def test_compare_names_the_line_of_a_repeated_time(tmp_path, reference, capsys):
    t, ref = reference
    t2 = np.r_[t, t[-1]]
    other = _run_dir(tmp_path / "other", t2, _pulse(t2), {"backend": "x"})
    assert main(["compare", str(ref), str(other)]) == 2
    err = capsys.readouterr().err
    assert f"line {t2.size + 1}" in err and "does not increase" in err


# ----------------------------------------------------------------------------- warnings of a study
def test_warnings_once_says_a_warning_that_differs_in_its_numbers_once(capsys):
    with pipeline.warnings_once():
        for nu in (0.413, 0.42, 0.424):
            pipeline.report_warnings({"warnings": [f"kappa gives nu = {nu}, far from 0.5", "other"]})
    err = capsys.readouterr().err.splitlines()
    assert err == ["warning: kappa gives nu = 0.413, far from 0.5", "warning: other"]
    pipeline.report_warnings({"warnings": ["other"]})  # outside the block: said every time
    assert capsys.readouterr().err == "warning: other\n"


def test_a_calibration_says_the_material_warnings_of_the_users_values_not_of_its_trials(capsys):
    """cfm calibrate printed "k1 = 1.51376e+06 Pa ... Was it converted from kPa to Pa twice? Then write k1 = 1513.76"
    about a value its optimiser tried; the user's start values are checked once before the fit."""
    trial = "[material] k1 = 1.51376e+06 Pa is 1,147x above the typical 1320 Pa. Then write k1 = 1513.76."
    with pipeline.warnings_once(material=False):
        pipeline.report_warnings({"warnings": [trial, "the pulse is cut short"]})
    assert capsys.readouterr().err == "warning: the pulse is cut short\n"
    with pipeline.warnings_once():
        pipeline.report_warnings({"warnings": [trial]})
    assert "k1 = 1.51376e+06" in capsys.readouterr().err


# ----------------------------------------------------------------------------- output folders of fits
def test_a_fit_that_fails_keeps_the_earlier_output_in_its_folder(tmp_path, capsys):
    """A fit refused after its start (--starts 0) emptied --out first: the earlier fit was lost."""
    m = make_material("cfm")
    t, lam, P, _ = point.uniaxial(m, 1.0, 0.6, steps=200)
    path = _csv(tmp_path / "u.csv", t, lam, P)
    out = tmp_path / "fit"
    assert main(["fit", "--test", f"{path}:uniaxial:1", "--fit", "k1", "--quiet", "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert "fit.json" in before
    assert main(["fit", "--test", f"{path}:uniaxial:1", "--fit", "k1", "--starts", "0", "--quiet",
                 "--out", str(out)]) == 2
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


def test_fit_json_records_the_evaluation_limit(tmp_path):
    """A fit stopped by --max-evaluations could not be repeated from fit.json (k2 = 1.65417556 with 3,
    1.65417273 with 4; neither recorded)."""
    m = make_material("cfm")
    t, lam, P, _ = point.uniaxial(m, 1.0, 0.6, steps=200)
    path = _csv(tmp_path / "u.csv", t, lam, P)
    out = tmp_path / "fit"
    assert main(["fit", "--test", f"{path}:uniaxial:1", "--fit", "k1", "--max-evaluations", "7", "--quiet",
                 "--out", str(out)]) == 0
    data = json.loads((out / "fit.json").read_text())
    assert data["max_evaluations"] == 7 and data["units"]["max_evaluations"] == "-"


def test_a_sweep_table_keeps_the_runs_warnings(tmp_path, capsys):
    """end_time = 2 ms cut every pulse short: sweep.csv said "ok", peak 9.0 g (the real one ~114 g), and a
    rerun skipping the cached runs said nothing."""
    scene = builtin_scene("drop-test").with_overrides(thickness=0.005, element_size=0.0025, width=0.03)
    text = scene_to_toml(scene).replace("[scene]\n", "[scene]\nend_time = 0.002\n", 1)
    path = tmp_path / "short.toml"
    path.write_text(text)
    out = tmp_path / "sw"
    args = ["sweep", "--serial", "--scene", str(path), "--vary", "k2=1.6,1.7", "--quiet", "--out", str(out)]
    for _ in range(2):  # the second time from the run cache
        assert main(args) == 0
        assert "2 of 2 runs finished with warnings" in capsys.readouterr().err
    import pandas as pd
    table = pd.read_csv(out / "sweep.csv")
    assert all("end time" in w for w in table["warnings"])


def test_a_speed_sweep_of_an_oblique_impact_is_refused_with_the_speed_and_angle():
    """--vary velocity=0.5 on velocity = [0.2, 0, -1] ran a vertical 0.5 m/s impact, without a note."""
    from cfm_core.studies.sweep import parse_vary

    scene = builtin_scene("drop-test").with_overrides(velocity=(0.2, 0.0, -1.0))
    with pytest.raises(InputError, match=r"velocity = 1.0198, angle = 11.3099"):
        parse_vary(["velocity=0.5"], scene)
    assert [a.values for a in parse_vary(["velocity=0.5,2"], builtin_scene("drop-test"))] == [(0.5, 2.0)]


def test_compare_says_what_a_study_folder_is(tmp_path, reference, capsys):
    """A sweep's folder was "no summary.json, so the run did not complete"."""
    _, ref = reference
    sweep = tmp_path / "sweep"
    sweep.mkdir()
    (sweep / "sweep.json").write_text("{}")
    assert main(["compare", str(ref), str(sweep)]) == 2
    assert "is the output of cfm sweep: compare its runs, the folders in runs/" in capsys.readouterr().err


def test_a_lateral_stretch_that_does_not_converge_names_the_test_and_the_time(tmp_path, capsys):
    """k2 = 300: "the lateral stretch did not converge ... (largest lateral stress 1.66e+19 Pa)", no test,
    no time, no stretch."""
    m = make_material("cfm", {"k2": 300.0})
    t, lam, P, _ = point.uniaxial(m, 100.0, 0.6, steps=200)
    path = _csv(tmp_path / "k2.csv", t, lam, P)
    assert main(["fit", "--test", f"{path}:uniaxial:100", "--fit", "c", "--param", "k2=300", "--quiet",
                 "--out", str(tmp_path / "f")]) == 3
    err = capsys.readouterr().err
    assert "test 'k2'" in err and "at t = " in err and "axial stretch" in err


def test_starts_stopped_by_the_evaluation_limit_are_warned():
    """5 of 6 starts hit --max-evaluations while the status read "gtol termination condition is satisfied"."""
    m = make_material("cfm", {"k1": 2000.0})
    t, lam, P, _ = point.uniaxial(m, 1.0, 0.6, steps=200)
    test = LabTest("u", "-", "uniaxial", 1.0, 1.0, t, lam, P)
    result = fit.fit_lab("cfm", [test], ["k1", "k2"], max_evaluations=3, starts=1)
    assert any(w.startswith("the fit stopped at the limit of 3 evaluations") and "intervals are withheld" in w
               for w in result.warnings)  # one start: not "the best start may not be the best fit"
    assert all(result.confidence["parameters"][n]["ci"] is None for n in ("k1", "k2"))
    other = fit.fit_lab("cfm", [test], ["k1", "k2"], max_evaluations=9, starts=4)  # the second start stops at 9
    assert [t["converged"] for t in other.tried] == [True, False, True, True]
    assert any("1 of 4 starts stopped at the limit of 9 evaluations" in w and "best start may not be the best fit" in w
               for w in other.warnings)
    assert other.confidence["parameters"]["k1"]["ci"] is not None  # the reported start converged
    assert not any("stopped at the limit" in w for w in fit.fit_lab("cfm", [test], ["k1"], starts=1).warnings)


@pytest.mark.parametrize("suffix", [":abc", ":", ":0.008:x"])
def test_a_malformed_thickness_after_an_existing_file_is_named_not_the_file(tmp_path, suffix):
    """`--data d8.csv:abc` said "cannot be read: it does not exist" of a file that exists."""
    from cfm_core.studies.measured import parse_data_spec

    f = tmp_path / "d8.csv"
    f.write_text("t,a\n0,0\n")
    with pytest.raises(InputError, match=f"after the file {f} comes '{suffix}', which is not ':THICKNESS'"):
        parse_data_spec(f"{f}{suffix}", None)
    colon = tmp_path / "run:1.csv"          # a ':' that is part of an existing file's name stays a file
    colon.write_text("t,a\n0,0\n")
    assert parse_data_spec(str(colon), 0.008) == (str(colon), 0.008)
    assert parse_data_spec(f"{f}:0.005", None) == (str(f), 0.005)
