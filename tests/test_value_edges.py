"""Legal-looking values at the edges of options and parameters: each gave a silently wrong result or a
traceback (found by trying extreme inputs as a new user); now one paragraph and exit 2, or the right value."""

import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.errors import InputError
from cfm_core.export.lsdyna import _field
from cfm_core.material import make_material
from cfm_core.material.plausible import check_material
from cfm_core.scene.scene import builtin_scene, scene_to_toml
from cfm_core.simulation import point

SMALL = ["--thickness", "0.005", "--element-size", "0.0025", "--no-plot", "--quiet"]


@pytest.mark.parametrize("args, expected", [
    (["drop-test", *SMALL, "--option", "threads=64"], "is more than the"),           # ValueError traceback
    (["drop-test", *SMALL, "--vtu", "--option", "frame_interval=nan"], "frame_interval = nan"),  # int(nan)
    (["drop-test", *SMALL, "--option", "hourglass=inf"], "option hourglass = inf"),  # "non-finite state", exit 3
    (["run", "--scene", "single-element", "--backend", "skfem", "--option", "dt=1e-300"], "option dt = 1e-300"),
    (["run", "--scene", "single-element", "--backend", "skfem", "--option", "rtol=10"], "option rtol = 10"),
])
def test_option_values_that_broke_runs_are_refused(tmp_path, capsys, args, expected):
    """rtol = 10 accepted the unsolved predictor: -75.75 N for -0.78 N, exit 0; dt = 1e-300 divided by 0."""
    if "skfem" in args:
        pytest.importorskip("skfem")
    assert main([*args, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_a_scene_stop_limit_applies_below_the_warning_threshold(tmp_path, capsys):
    """hourglass_limit = 0.001 was ignored at 1.3 % (only tested above the 10 % warning), exit 0."""
    scene = builtin_scene("drop-test").with_overrides(thickness=0.005, element_size=0.0025)
    text = scene_to_toml(scene).replace("[scene]\n", "[scene]\nhourglass_limit = 0.001\n", 1)
    path = tmp_path / "limit.toml"
    path.write_text(text)
    assert main(["run", "--scene", str(path), "--no-plot", "--quiet", "--out", str(tmp_path / "o")]) == 3
    assert "above the scene's stop limit hourglass_limit = 0.001" in capsys.readouterr().err


def test_an_ogden_exponent_too_small_for_float64_is_refused_and_small_ones_are_right():
    """|alpha| = 1e-16 made l^alpha - 1 = 0 and dropped the term: 32 % low stresses on every backend."""
    with pytest.raises(InputError, match=r"with \|alpha1\| >= 0.001"):
        make_material("ogden", {"alpha1": 1e-16})
    P = {a: point.uniaxial(make_material("ogden", {"alpha1": a}), 100.0, 0.7, steps=50)[2][-1]
         for a in (1e-3, 2e-3, 4e-3)}
    limit = 2.0 * P[2e-3] - P[4e-3]  # Richardson: the alpha -> 0 limit (log-strain energy) to O(alpha^2)
    assert P[1e-3] == pytest.approx(limit, rel=1e-3)
    assert abs(P[1e-3] - limit) < 0.6 * abs(P[2e-3] - limit)  # converging linearly: no cancellation noise


def test_a_scene_file_parameter_that_is_not_a_number_is_named(tmp_path, capsys):
    """c = nan gave "(SI unit of the parameter) ... -inf < c < inf"."""
    text = scene_to_toml(builtin_scene("drop-test")) + "\n[material.parameters]\nc = nan\n"
    path = tmp_path / "nan.toml"
    path.write_text(text)
    assert main(["run", "--scene", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "[material.parameters] c = nan is not allowed" in err and "SI unit of the parameter" not in err


HUGE = "1" + "0" * 400   # a TOML integer beyond the float range (about 1.8e308)


@pytest.mark.parametrize("text, expected", [
    (f"[material.parameters]\nk1 = {HUGE}\n", "[material.parameters] k1 = 1000...0 (an integer of 401 digits) is "
                                                "not allowed: a material parameter is a finite number in SI units"),
    (f"[specimen]\nelement_size = {HUGE}\n", "[specimen] element_size = 1000...0 (an integer of 401 digits) m is out "
                                              "of range; it must be a finite number"),
    (f"[impactor]\nvelocity = [0.0, 0.0, -{HUGE}]\n", "[impactor] velocity = [0.0, 0.0, -1000...0 (an integer of "
                                                       "401 digits)] must be a list of 3 finite numbers"),
    (f"[run]\nbackend = \"numba\"\n[run.options]\nmax_steps = {HUGE}\n", "option max_steps = 1000...0 (an integer "
                                                                         "of 401 digits) is not allowed"),
], ids=["k1", "element_size", "velocity", "max_steps"])
def test_a_scene_integer_beyond_the_float_range_is_refused_as_1e400_is(tmp_path, capsys, text, expected):
    """k1 = 1 followed by 400 zeros gave "OverflowError: int too large to convert to float" from the
    value checks; now the paragraph a non-finite value gets, exit 2."""
    path = tmp_path / "huge.toml"
    path.write_text('[scene]\ntype = "drop-test"\n\n' + text)
    assert main(["run", "--scene", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_a_material_parameter_beyond_the_float_range_is_refused_naming_it():
    with pytest.raises(InputError, match=r"k1' = 1000\.\.\.0 \(an integer of 401 digits\) Pa is outside"):
        make_material("cfm", {"k1": 10 ** 400})


def test_a_stress_column_out_of_any_scale_is_refused(tmp_path, capsys):
    """x 1e-300: scipy's "array must not contain infs or NaNs" traceback; x 1e300: "NaN or inf in the data"."""
    t, lam, P, _ = point.uniaxial(make_material("cfm"), 100.0, 0.6, steps=40)
    for scale in (1e-300, 1e300):
        path = tmp_path / "s.csv"
        path.write_text("t,stretch,stress\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c * scale)!r}\n"
                                                        for a, b, c in zip(t, lam, P)))
        assert main(["fit", "--test", f"{path}:uniaxial:100", "--fit", "k1", "--quiet", "--out", str(tmp_path / "f")]) == 2
        assert "no material test records" in capsys.readouterr().err


def test_lsdyna_fields_keep_every_digit_ten_characters_hold():
    """A 9-character limit kept 1.235e-07 of 1.23456789e-7 and 0.4709997 of 0.47099966."""
    for value, text in ((0.47099966, "0.47099966"), (1.23456789e-7, "1.23457e-7"), (666100.0, "666100.0"),
                        (-1.23456789e-7, "-1.2346e-7")):
        field = _field(value)
        assert len(field) == 10 and field.strip() == text
    assert float(_field(1.23456789e-7)) == pytest.approx(1.23456789e-7, rel=5e-6)


def test_the_lsdyna_card_says_how_its_rounding_moves_gamma_inf(tmp_path, capsys):
    """g_i written to 10 characters moved each by 1e-8 relative but gamma_inf = 1 - sum g_i by 1.1 % (to below
    the floor the routine accepts), and the card named only the 1e-8: the card and the command now say so."""
    from fractions import Fraction

    from cfm_core.export.lsdyna import gamma_inf_on_card
    from cfm_core.export.layout import constants

    gs = ("0.333333335", "0.333333335", "0.333332329")
    args = ["export", "cfm", "--to", "lsdyna-umat", *[f"--param=g{i}={g}" for i, g in enumerate(gs, 1)]]
    assert main([*args, "--out", str(tmp_path / "d")]) == 0
    card = (tmp_path / "d" / "material.k").read_text()
    assert "gamma_inf = 1 - sum g_i = 1.001e-06 is 9.9e-07 from the written g_i (relative change 0.01" in card
    err = capsys.readouterr().err
    assert "relative change 0.01" in err and "error code 3" in err
    m = make_material("cfm", {f"g{i}": float(g) for i, g in enumerate(gs, 1)})
    exact, held = gamma_inf_on_card(constants(m.spec, lsdyna=True, material=m))
    written = [Fraction(v) for v in ("0.33333334", "0.33333334", "0.33333233")]
    assert exact == pytest.approx(float(1 - sum(Fraction(float(g)) for g in gs)), rel=1e-12)
    assert held == pytest.approx(float(1 - sum(written)), rel=1e-9)
    assert main(["export", "cfm", "--to", "lsdyna-umat", "--out", str(tmp_path / "t1")]) == 0  # Table 1: exact
    assert "fields: gamma_inf" not in (tmp_path / "t1" / "material.k").read_text()
    assert "gamma_inf" not in capsys.readouterr().err


def test_the_poisson_warning_names_the_prony_series_when_it_is_the_cause():
    """g summing to 1 - 1e-5 gave nu = -0.96 with "check kappa" only."""
    m = make_material("cfm", {"g1": 0.471, "g2": 0.435, "g3": 0.09399})
    text = next(w for w in check_material(m) if "Poisson" in w)
    assert "The Prony coefficients leave gamma_inf = 1e-05" in text
    assert not any("Prony coefficients leave" in w and "Poisson" in w for w in check_material(make_material("cfm")))
    assert np.isfinite(m.iso_scale)


def test_a_ringing_single_element_is_warned(tmp_path, capsys):
    """kappa = 1e10 Pa on the explicit single element: the reaction force rang about its trend, the peak 25 %
    high, exit 0 without a warning (the inertia check compares energies, which a stiff mode hardly has)."""
    assert main(["run", "--scene", "single-element", "--param", "kappa=1e10", "--no-plot", "--quiet",
                 "--out", str(tmp_path / "k10")]) == 0
    assert "the reaction force rings" in capsys.readouterr().err
    assert main(["run", "--scene", "single-element", "--no-plot", "--quiet", "--out", str(tmp_path / "t1")]) == 0
    assert "rings" not in capsys.readouterr().err


def test_export_writes_the_density_given_and_refuses_an_impossible_one(tmp_path, capsys):
    """The VUMAT and LS-DYNA cards always said 950 kg/m^3, with no way to change it."""
    assert main(["export", "cfm", "--to", "abaqus-vumat", "--density", "1100", "--out", str(tmp_path / "v")]) == 0
    assert "*DENSITY\n1100.0" in (tmp_path / "v" / "material.inp").read_text()
    assert main(["export", "cfm", "--to", "lsdyna-umat", "--density", "1.06", "--out", str(tmp_path / "d")]) == 0
    assert "almost surely a unit slip. 1.06 kg/m^3: did you mean 1060 kg/m^3 (1.06 g/cm^3)?" in capsys.readouterr().err
    assert main(["export", "cfm", "--to", "lsdyna-umat", "--density", "0", "--out", str(tmp_path / "z")]) == 2
    assert not (tmp_path / "z").exists()


def test_bottoming_out_beside_the_specimen_is_told_from_crushing_it():
    """angle = 89 deg: the impactor slid 0.55 m past a 25 mm half-width specimen and reached the plate beside
    it; the error said "crushed through: too heavy or too fast"."""
    import types

    from cfm_core.simulation.checks import _uncrushed

    nodes = np.array([[x, y, z] for z in (0.0, 0.004, 0.008) for y in (0.0, 0.01) for x in (0.0, 0.01)])
    model = types.SimpleNamespace(nodes=nodes)
    position = lambda x, i: x[i]  # noqa: E731 (the scan's mapping: here the user's own order)
    assert _uncrushed(model, nodes, position)            # untouched: the impactor is elsewhere
    crushed = nodes.copy()
    crushed[-1, 2] = 0.001                               # one top node pressed to 1 mm
    assert not _uncrushed(model, crushed, position)


def test_numbers_in_messages_near_their_limits_are_told_apart():
    """gamma_inf = 9.99999999e-07 was shown as "1e-06 ... must be at least 1e-06"; c = 5e-324 as "infx below"."""
    from cfm_core.material.plausible import _times
    from cfm_core.material.prony import _shown

    assert _shown(9.99999999e-07, 1e-06) == "9.99999999e-07" and _shown(5e-07, 1e-06) == "5e-07"
    assert _times(float("inf")) == "more than 1e308" and _times(1000.0000000000001) == "1,000"


def test_a_run_that_cannot_reach_its_end_time_says_so_at_once(tmp_path, capsys):
    """safety = 1e-300: a step of 1e-305 s, and the run went on towards max_steps = 5e7 for hours."""
    assert main(["drop-test", *SMALL, "--option", "safety=1e-300", "--out", str(tmp_path / "o")]) == 3
    err = capsys.readouterr().err
    assert "4096 steps reached only" in err and "more than option max_steps = 50000000" in err


def test_skfem_refuses_a_smallest_step_above_the_largest(tmp_path, capsys):
    pytest.importorskip("skfem")
    assert main(["run", "--scene", "single-element", "--backend", "skfem", "--option", "dt_min=1", "--option",
                 "dt_max=1e-6", "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert "dt_min = 1 s is above dt_max = 1e-06 s" in capsys.readouterr().err


def test_a_frame_interval_longer_than_the_run_is_warned(tmp_path, capsys):
    """frame_interval = 0.5 (meant in ms) stored the t = 0 frame only, exit 0, no word."""
    assert main(["drop-test", *SMALL, "--vtu", "--option", "frame_interval=0.5", "--out", str(tmp_path / "f")]) == 0
    err = capsys.readouterr().err
    assert "frame_interval = 0.5 s is longer than the run" in err and "meant in ms" in err
    assert main(["drop-test", *SMALL, "--vtu", "--option", "frame_interval=0.001", "--out", str(tmp_path / "g")]) == 0
    assert "frame_interval" not in capsys.readouterr().err


def test_a_penetration_tolerance_in_mm_is_refused(tmp_path, capsys):
    """[scene] penetration_tolerance = 0.05 (meant as 0.05 mm) stopped the paper's drop test at first contact,
    exit 3, explaining that an oblique impact had slid off."""
    scene = builtin_scene("drop-test").with_overrides(thickness=0.005, element_size=0.0025)
    text = scene_to_toml(scene).replace("[scene]\n", "[scene]\npenetration_tolerance = 0.05\n", 1)
    (tmp_path / "s.toml").write_text(text)
    assert main(["drop-test", "--scene", str(tmp_path / "s.toml"), "--no-plot", "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "penetration_tolerance = 0.05 m is not allowed" in err and "write 5e-05" in err
    (tmp_path / "t.toml").write_text(text.replace("penetration_tolerance = 0.05", "penetration_tolerance = 5e-05"))
    assert main(["drop-test", "--scene", str(tmp_path / "t.toml"), "--no-plot", "--quiet", "--out", str(tmp_path / "p")]) == 0


def test_hints_for_a_layer_name_the_layer_not_a_flag_that_sets_another_section(tmp_path, capsys):
    """A layer's k1 = 1.32 was told '(--param k1=1320)' and its element_size = 2.0 '(--element-size 0.002)': both
    flags set [material] and [specimen], not the layer."""
    base = scene_to_toml(builtin_scene("drop-test").with_overrides(width=0.03, element_size=0.0025))
    layers = ('[[specimen.layers]]\nthickness = 0.004\n[specimen.layers.parameters]\nk1 = 1.32\n'
              '[[specimen.layers]]\nthickness = 0.004\n')
    (tmp_path / "a.toml").write_text(base.replace("[impactor]", layers + "[impactor]", 1))
    assert main(["drop-test", "--scene", str(tmp_path / "a.toml"), "--no-plot", "--quiet", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "Write k1 = 1320 in the parameters of [[specimen.layers]] 1" in err and "--param" not in err
    (tmp_path / "b.toml").write_text(base.replace("[impactor]", layers.replace("k1 = 1.32\n", "k1 = 1320.0\n")
                                                  .replace("thickness = 0.004\n[specimen.layers.p",
                                                           "thickness = 0.004\nelement_size = 2.0\n[specimen.layers.p", 1)
                                                  + "[impactor]", 1))
    assert main(["drop-test", "--scene", str(tmp_path / "b.toml"), "--no-plot", "--quiet", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "Write element_size = 0.002;" in err and "--element-size" not in err


def test_a_thickness_sweep_of_a_layered_specimen_is_refused_saying_why(tmp_path, capsys):
    """It failed with "[specimen] thickness disagrees with the sum of the layers" and a decimal-comma hint."""
    (tmp_path / "l.toml").write_text(scene_to_toml(builtin_scene("layered-tissue")))
    assert main(["sweep", "--scene", str(tmp_path / "l.toml"), "--vary", "thickness=0.008,0.01", "--serial",
                 "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "the specimen is layered (3 [[specimen.layers]])" in err and "decimal" not in err


def test_a_run_failing_with_a_high_hourglass_coefficient_names_it(tmp_path, capsys):
    """hourglass = 1 (allowed: at most 1) inverted an element of the default drop test and the message advised to
    raise the hourglass coefficient; the viscous hourglass forces are not in the stable step."""
    args = ["drop-test", "--width", "0.03", "--element-size", "0.0025", "--no-plot", "--quiet"]
    assert main([*args, "--option", "hourglass=1.0", "--out", str(tmp_path / "a")]) == 3
    assert "The option hourglass = 1 is above 0.15" in capsys.readouterr().err
    assert main([*args, "--option", "hourglass=1.0", "--option", "safety=0.2", "--out", str(tmp_path / "b")]) == 0


def test_a_speed_given_over_a_velocity_vector_says_the_direction_is_dropped(tmp_path, capsys):
    """--velocity 2 on a scene with velocity = [0.5, 0, -0.866] ran a vertical impact; the note only said the
    value was overridden."""
    scene = builtin_scene("drop-test").with_overrides(width=0.03, element_size=0.0025, thickness=0.005)
    text = scene_to_toml(scene).replace("velocity = 1.0", "velocity = [0.5, 0.0, -0.866]").replace(
        'symmetry = "auto"', 'symmetry = "none"')
    (tmp_path / "v.toml").write_text(text)
    assert main(["drop-test", "--scene", str(tmp_path / "v.toml"), "--velocity", "2", "--no-plot", "--quiet",
                 "--out", str(tmp_path / "o")]) == 0
    assert "the impact is now vertical" in capsys.readouterr().err


BIG = "1" + "0" * 30   # 10**30: an integer no count option can mean


def _lab_curve(tmp_path):
    t, lam, P, _ = point.uniaxial(make_material("cfm"), 100.0, 0.6, steps=40)
    path = tmp_path / "u.csv"
    path.write_text("t,stretch,stress\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t, lam, P)))
    return path


def _drop_curve(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("t,a\n" + "".join(f"{k * 2e-5!r},{100.0 * np.sin(np.pi * k / 200) if k <= 200 else 0.0!r}\n"
                                      for k in range(300)))
    return path


@pytest.mark.parametrize("args, expected", [
    (["point", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--steps", BIG],
     "--steps 1000...0 (an integer of 31 digits) is not allowed: give a whole number from 2 to 100000"),  # ValueError
    (["point", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--steps", "100001"],   # ran for many minutes
     "--steps 100001 is not allowed: give a whole number from 2 to 100000"),
    (["fit", "--test", "{lab}:uniaxial:100", "--fit", "k1", "--starts", BIG],              # OverflowError traceback
     "--starts 1000...0 (an integer of 31 digits) is not allowed: give a whole number from 1 to 1000"),
    (["fit", "--test", "{lab}:uniaxial:100", "--fit", "k1", "--max-evaluations", BIG],
     "--max-evaluations 1000...0 (an integer of 31 digits) is not allowed: give a whole number from 1 to 100000"),
    (["calibrate", "--data", "{drop}:0.005", "--fit", "k1", "--serial", "--max-evaluations", BIG],
     "--max-evaluations 1000...0 (an integer of 31 digits) is not allowed: give a whole number from 1 to 100000"),
    (["sweep", "--vary", "k1=1000", "--workers", BIG],                                      # started a cluster for ever
     "--workers 1000...0 (an integer of 31 digits) is not allowed: give a whole number from 1 to {most}"),
    (["calibrate", "--data", "{drop}:0.005", "--fit", "k1", "--workers", "{over}"],
     "--workers {over} is not allowed: give a whole number from 1 to {most}"),
], ids=["steps", "steps+1", "starts", "fit-evaluations", "calibrate-evaluations", "workers", "workers+1"])
def test_count_options_beyond_their_range_are_refused_naming_it(tmp_path, capsys, args, expected):
    """Huge counts gave a traceback (--steps: "Maximum allowed size exceeded", --starts: OverflowError), or
    started the impossible (--workers 10**30: a local cluster that never came up); now one paragraph with the
    option, the value (shortened) and the range, exit 2, nothing written."""
    from cfm_core.studies.dask_runner import max_local_workers

    fill = {"lab": _lab_curve(tmp_path), "drop": _drop_curve(tmp_path), "most": max_local_workers(),
            "over": max_local_workers() + 1}
    out = tmp_path / ("o.csv" if args[0] == "point" else "o")
    assert main([a.format(**fill) for a in args] + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert expected.format(**fill) in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("text, shown_as", [("1e400", "max_steps=1e400"), ("-1e400", "max_steps=-1e400")])
def test_an_option_beyond_the_float_range_is_named_as_typed(tmp_path, capsys, text, shown_as):
    """--option max_steps=1 followed by 400 zeros said "option max_steps = inf is not allowed": the value the user
    typed is shown (shortened), with why it reads as inf and the allowed range."""
    assert main(["drop-test", *SMALL, "--option", f"max_steps={text}", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"--option {shown_as} is beyond the float range" in err and "expected an integer in [1, 1e+12]" in err
    assert "= inf" not in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("text", ["99999999999999999999999999", "1" + "0" * 400])
def test_a_huge_integer_option_is_read_exactly_and_refused_by_its_range(tmp_path, capsys, text):
    """--option max_steps=10**26 - 1 was read through a float and recorded as 100000000000000004764729344; an
    integer option is read exactly, and max_steps has a finite range (at most 1e12 steps), so a huge one is
    refused with its value as typed (shortened) and a range that holds no inf."""
    from argparse import Namespace

    from cfm_core.cli.options import backend_options

    assert backend_options(Namespace(option=["max_steps=123456789012"]), "numba")[0]["max_steps"] == 123456789012
    assert main(["drop-test", *SMALL, "--option", f"max_steps={text}", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "option max_steps = " in err and "expected an integer in [1, 1e+12]" in err and "inf" not in err
    assert ("(an integer of 401 digits)" in err) == (len(text) == 401) and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_an_option_whose_range_takes_inf_reads_an_overflowing_number_as_inf():
    """dt_max's range is open to inf: 1e400 reads as inf there, as before."""
    from argparse import Namespace

    from cfm_core.cli.options import backend_options

    options, _ = backend_options(Namespace(option=["dt_max=1e400"]), "numba")
    assert options["dt_max"] == float("inf")


@pytest.mark.parametrize("value, hint", [
    ("9.2e-10", "9.2e-10 kg/m^3: did you mean 920 kg/m^3 (9.2e-10 tonne/mm^3)? Give --density 920; every value is in "
                "SI units."),
    ("0.92", "0.92 kg/m^3: did you mean 920 kg/m^3 (0.92 g/cm^3)? Give --density 920"),
], ids=["tonne/mm^3", "g/cm^3"])
def test_an_export_density_in_other_units_is_refused_with_its_value_in_kg_per_m3(tmp_path, capsys, value, hint):
    """9.2e-10 (tonne/mm^3, what an LS-DYNA model in mm-s-tonne holds) was refused with "give the tissue's density
    in kg/m^3" and no hint; the scenes' hint now names the unit it looks like and the kg/m^3 value."""
    assert main(["export", "cfm", "--to", "lsdyna-umat", "--density", value, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert f"--density {value} kg/m^3 is not allowed" in err and hint in err and err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def test_a_scene_density_in_tonne_per_cubic_millimetre_gets_the_hint_too(tmp_path, capsys):
    assert main(["drop-test", *SMALL, "--density", "9.2e-10", "--out", str(tmp_path / "o")]) == 2
    assert ("9.2e-10 kg/m^3: did you mean 920 kg/m^3 (9.2e-10 tonne/mm^3)? Write density = 920 (--density 920)"
            in capsys.readouterr().err)


def test_a_worker_timeout_beyond_its_range_names_the_range(tmp_path, capsys):
    """--worker-timeout 1e400 (inf) was refused with "give a number of seconds > 0", which inf is."""
    assert main(["sweep", "--vary", "k1=1000", "--worker-timeout", "1e400", "--out", str(tmp_path / "o")]) == 2
    assert "--worker-timeout inf s is not allowed: give a number of seconds > 0 and below 1e+06" in \
        capsys.readouterr().err
