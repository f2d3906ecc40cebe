"""The one numeric CSV reader (cfm_core.tables) and its three users: spreadsheet dialects (shared
case csv-dialects), encodings, units in headers, and the plausibility of measured curves."""

import codecs
import json

import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.errors import InputError
from cfm_core.post.compare import read_run
from cfm_core.scene import builtin_scene
from cfm_core.simulation import point
from cfm_core.studies import measured
from cfm_core.tables import read_table

H = "t,F11,F12,F13,F21,F22,F23,F31,F32,F33"
ROWS = ["0.0,1.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,1.0", "0.001,0.9,0.0,0.0,0.0,1.05,0.0,0.0,0.0,1.05"]
DIALECTS = {
    "plain": H + "\n" + "\n".join(ROWS) + "\n",
    "bom": "\ufeff" + H + "\n" + "\n".join(ROWS) + "\n",
    "crlf": H + "\r\n" + "\r\n".join(ROWS) + "\r\n",
    "sci": H + "\n0.0E+00,1.0E+00,0,0,0,1E0,0,0,0,1.000e+00\n1.0e-3,9.0E-01,0,0,0,1.05E+00,0,0,0,105e-2\n",
    "spaces": H.replace(",", ", ") + "\n" + "\n".join(r.replace(",", ", ") for r in ROWS) + "\n",
    "comment": "# exported by some tool\n" + H + "\n" + "\n".join(ROWS) + "\n",
    "trailing": H + ",\n" + "\n".join(r + "," for r in ROWS) + "\n",
    "units": H.replace("t,", "t [s],") + "\n" + "\n".join(ROWS) + "\n",
    # spreadsheets in decimal-comma locales, tab-delimited text, empty columns, a line of units
    "semicolon": H.replace(",", ";") + "\n" + "\n".join(r.replace(",", ";").replace(".", ",") for r in ROWS) + "\n",
    "semicolon_point": H.replace(",", ";") + "\n" + "\n".join(r.replace(",", ";") for r in ROWS) + "\n",
    "tab": H.replace(",", "\t") + "\n" + "\n".join(r.replace(",", "\t").replace(".", ",") for r in ROWS) + "\n",
    "empty_columns": H + ",,\n" + "\n".join(r + ",," for r in ROWS) + "\n",
    "units_row": H + "\ns" + ",-" * 9 + "\n" + "\n".join(ROWS) + "\n",
    # quoting by csv rules (RFC 4180): Excel, pandas.to_csv(quoting=csv.QUOTE_ALL)
    "quoted_header": ",".join(f'"{c}"' for c in H.split(",")) + "\n" + "\n".join(ROWS) + "\n",
    "quoted_all": "\n".join(",".join(f'"{c}"' for c in line.split(",")) for line in [H, *ROWS]) + "\n",
    "quoted_units": ",".join(f'"{c} [{u}]"' for c, u in zip(H.split(","), ["s"] + ["-"] * 9)) + "\n"
                    + "\n".join(ROWS) + "\n",
    "quoted_semicolon": "\n".join(";".join(f'"{c.replace(".", ",")}"' for c in line.split(",")) for line in [H, *ROWS])
                        + "\n",  # decimal commas inside quotes
    "quoted_spaces": '"t" , "F11", "F12","F13","F21","F22","F23","F31","F32","F33"\n' + "\n".join(ROWS) + "\n",
    "quoted_bom_crlf": "\ufeff" + "\r\n".join(",".join(f'"{c}"' for c in line.split(",")) for line in [H, *ROWS])
                       + "\r\n",
}
F_EXPECTED = np.array([np.eye(3), np.diag([0.9, 1.05, 1.05])])


def _write(path, text, encoding="utf-8"):
    with open(path, "w", encoding=encoding, newline="") as f:
        f.write(text)
    return path


@pytest.mark.parametrize("dialect", sorted(DIALECTS))
def test_history_dialects_read_the_same_numbers(tmp_path, dialect):
    t, F = point.read_history(_write(tmp_path / f"F_{dialect}.csv", DIALECTS[dialect]))
    np.testing.assert_array_equal(t, [0.0, 0.001])
    np.testing.assert_array_equal(F, F_EXPECTED)


@pytest.mark.parametrize("name, text, encoding, needle", [
    ("utf16", H + "\n" + "\n".join(ROWS) + "\n", "utf-16", "encoded as UTF-16"),
    ("utf16le", H + "\n" + "\n".join(ROWS) + "\n", "utf-16-le", "UTF-16 or UTF-32"),
    ("latin1", "# r\xe9sum\xe9\n" + H + "\n" + "\n".join(ROWS) + "\n", "latin-1", "byte 0xe9 is not UTF-8 text"),
    ("fortran", H + "\n0.0D+00,1.0D+00,0,0,0,1D0,0,0,0,1.0D0\n" + ROWS[1] + "\n", "utf-8", "Fortran 'D' exponent"),
    ("thousands", H.replace(",", ";") + "\n0;1.000,5;0;0;0;1;0;0;0;1\n", "utf-8", "both a comma and a point"),
    ("units_row_ms", H + "\nms" + ",-" * 9 + "\n" + "\n".join(ROWS) + "\n", "utf-8", "divide the times by 1000"),
    ("mixed", H.replace(",", ";") + "\n0,0,1,0,0,0,1,0,0,0,1\n", "utf-8", "separated by semicolons for the 10"),
    ("ms", H.replace("t,", "t [ms],") + "\n" + "\n".join(ROWS) + "\n", "utf-8", "divide the times by 1000"),
    # an empty value before the line's end was dropped as an empty column: "9 values ... for the 10 columns"
    ("empty_last", H + "\n" + ROWS[0] + "\n" + ROWS[1].rsplit(",", 1)[0] + ",\n", "utf-8",
     "line 3: the value of F33 is empty"),
    ("empty_inner", H + "\n" + ROWS[0].replace(",1.0,", ",,", 1) + "\n", "utf-8", "line 2: the value of F11 is empty"),
    ("open_quote", H + "\n" + ROWS[0] + '\n"0.001,0.9' + ROWS[1][9:] + "\n", "utf-8", "line 3: a quote (\") is opened"),
])
def test_other_encodings_and_dialects_exit_2_with_one_paragraph(tmp_path, capsys, name, text, encoding, needle):
    path = _write(tmp_path / f"F_{name}.csv", text, encoding)
    out = tmp_path / "s.csv"
    assert main(["point", "--material", "cfm", "--history", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


def test_a_quoted_header_names_the_columns_the_unquoted_one_does(tmp_path):
    """A separator inside a quoted name does not set the dialect; a doubled quote is one quote."""
    path = _write(tmp_path / "q.csv", '"t [s]";"y, the ""signal"" [N]"\n"0";"1,5"\n"1e-3";"2"\n')
    table = read_table(path, ("t", 'y, the "signal"'), {"t": "s"})
    assert table.units == ("s", "N")
    np.testing.assert_array_equal(table.data, [[0.0, 1.5], [1e-3, 2.0]])


def test_the_bom_is_not_shown_as_an_invisible_difference(tmp_path):
    path = _write(tmp_path / "bad.csv", "\ufeffx,F11\n0,1\n")
    with pytest.raises(InputError) as err:
        point.read_history(path)
    assert "\ufeff" not in str(err.value)


def _pulse(tmp_path, name="a.csv", t_scale=1.0, a_scale=1.0, header="t,a", encoding="utf-8", bom=False):
    t = np.arange(0.0, 0.0102, 2e-5)
    a = np.where(t < 0.01, 300.0 * np.sin(np.pi * t / 0.01) ** 2, 0.0)  # int a dt = 1.5 m/s
    text = ("\ufeff" if bom else "") + header + "\n" + "".join(f"{float(x * t_scale)!r},{float(y * a_scale)!r}\n" for x, y in zip(t, a))
    return str(_write(tmp_path / name, text, encoding))


@pytest.mark.parametrize("kw", [{}, {"bom": True}, {"header": "t [s],a [m/s^2]"}, {"header": "t (s), a (m/s2)"},
                                {"header": '"t","a"'}, {"header": '"t [s]","a [m/s^2]"', "bom": True}])
def test_measured_curves_in_every_accepted_form(tmp_path, kw):
    path = _pulse(tmp_path, **kw)
    t, a = measured.read_measured(path)
    assert t.size == 510 and t[1] == pytest.approx(2e-5) and a.max() == pytest.approx(300.0, rel=1e-3)


def test_a_measured_curve_with_every_cell_quoted_reads_as_the_plain_one(tmp_path):
    """pandas.to_csv(quoting=csv.QUOTE_ALL) / Excel output: refused as a header 't' 'a' mismatch before."""
    plain = _pulse(tmp_path)
    lines = (tmp_path / "a.csv").read_text().splitlines()
    quoted = _write(tmp_path / "q.csv", "".join(",".join(f'"{c}"' for c in line.split(",")) + "\r\n" for line in lines))
    for got, expected in zip(measured.read_measured(quoted), measured.read_measured(plain)):
        np.testing.assert_array_equal(got, expected)


def test_an_empty_acceleration_names_its_line_and_column(tmp_path):
    """A row '0.00096,' was told as '1 values separated by commas for the 2 columns'."""
    path = _write(tmp_path / "e.csv", "t,a\n0,0\n0.00048,1.5\n0.00096,\n0.00144,2\n")
    with pytest.raises(InputError, match=r"'.*e\.csv', line 4: the value of a is empty") as err:
        measured.read_measured(path)
    assert "values separated by" not in str(err.value)
    path = _write(tmp_path / "short.csv", "t,a\n0,0\n0.00096\n")  # no separator: a missing column, said so
    with pytest.raises(InputError, match="line 3: 1 values separated by commas for the 2 columns"):
        measured.read_measured(path)


def test_measured_utf16_is_refused(tmp_path):
    with pytest.raises(InputError, match="encoded as UTF-16"):
        measured.read_measured(_pulse(tmp_path, encoding="utf-16"))


@pytest.mark.parametrize("kw, needle", [
    ({"t_scale": 1e3}, "Is t in ms"),                 # the time column in ms
    ({"a_scale": 1 / 9.80665}, "Is a in g"),          # the acceleration in g
    ({"a_scale": 1e3}, "Is t in ms or a in mm/s"),    # mm/s^2
    ({"header": "t [ms],a"}, "divide the times by 1000"),
])
def test_implausible_measured_curves_are_refused_against_the_scene(tmp_path, kw, needle):
    scene = builtin_scene("drop-test")
    path = _pulse(tmp_path, **kw)
    with pytest.raises(InputError, match=needle):
        measured.read_curves([f"{path}:0.008"], scene, scene_given=True)


def test_a_plausible_curve_passes_the_checks(tmp_path):
    curves = measured.read_curves([f"{_pulse(tmp_path)}:0.008"], builtin_scene("drop-test"), scene_given=True)
    assert curves[0].peak == pytest.approx(300.0, rel=0.05)


def test_read_table_reports_units_and_line_numbers(tmp_path):
    path = _write(tmp_path / "x.csv", "# c\n\nt [s],y (N)\n0,1\n\n1e-3,2\n")
    table = read_table(path, ("t", "y"), {"t": "s"})
    assert table.columns == ("t", "y") and table.units == ("s", "N")
    np.testing.assert_array_equal(table.lines, [4, 6])
    with pytest.raises(InputError, match="line 5: t = 0.0 s does not follow"):
        read_table(_write(tmp_path / "y.csv", "t,y\n0,1\n1,2\n1,3\n0,4\n"), ("t", "y"), strict=False)


def test_compare_reads_runs_through_the_same_reader(tmp_path):
    d = tmp_path / "run"
    d.mkdir()
    (d / "summary.json").write_text(json.dumps({"backend": "numba"}))
    _write(d / "acceleration.csv", codecs.BOM_UTF8.decode() + "t,a_raw,a_cfc600\n0,0,0\n1e-5,1,2\n2e-5,2,3\n")
    run = read_run(d)
    np.testing.assert_array_equal(run.y, [0.0, 2.0, 3.0])
    _write(d / "acceleration.csv", "t,a_raw,a_cfc600\n0,0,0\n1e-5,1,nan\n")
    with pytest.raises(InputError, match="line 3: a_cfc600 = 'nan'"):
        read_run(d)


def test_compare_reads_quoted_histories_and_a_summary_with_a_bom(tmp_path):
    """A foreign run's files: every cell of acceleration.csv quoted (QUOTE_ALL) and a summary.json
    with a UTF-8 byte-order mark ("Unexpected UTF-8 BOM" before) read as the clean files; a UTF-16
    summary.json is refused with one paragraph saying it must be UTF-8."""
    from cfm_core.post.writers import write_drop_test

    t = np.arange(4) * 2e-5
    clean = write_drop_test(tmp_path / "clean", t, t * 1e4, t * 2e4 + 0.1, {"backend": "numba", "wall_time": 1.5})
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    lines = (clean / "acceleration.csv").read_text().splitlines()
    _write(foreign / "acceleration.csv", "".join(",".join(f'"{c}"' for c in line.split(",")) + "\n" for line in lines))
    (foreign / "summary.json").write_bytes(codecs.BOM_UTF8 + (clean / "summary.json").read_bytes())
    a, b = read_run(clean), read_run(foreign)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.y, b.y)
    assert a.summary == b.summary and b.summary["wall_time"] == 1.5
    (foreign / "summary.json").write_bytes((clean / "summary.json").read_text().encode("utf-16"))
    with pytest.raises(InputError, match=r"summary\.json' is encoded as UTF-16.*JSON files must be UTF-8") as err:
        read_run(foreign)
    assert "\n" not in str(err.value) and "codec" not in str(err.value)


def test_a_summary_wall_time_beyond_the_float_range_is_not_compared(tmp_path):
    """A JSON integer of 400 digits gave OverflowError: int too large to convert to float."""
    d = tmp_path / "run"
    d.mkdir()
    (d / "summary.json").write_text('{"backend": "numba", "wall_time": 1' + "0" * 400 + "}")
    _write(d / "acceleration.csv", "t,a_raw,a_cfc600\n0,0,0\n1e-5,1,2\n")
    assert "wall_time" not in read_run(d).summary


def test_run_files_carry_units_and_both_header_styles_read_back_equal(tmp_path):
    """acceleration.csv and reaction.csv are written with ``name [unit]`` headers (as sweep.csv);
    cfm compare reads them and the older files without units to the same numbers, and refuses a
    header whose unit is not the one the column is read in."""
    from cfm_core.post.writers import write_drop_test, write_reaction

    t = np.arange(4) * 2e-5
    new = write_drop_test(tmp_path / "new", t, t * 1e4, t * 2e4 + 0.1, {"backend": "numba"})
    assert (new / "acceleration.csv").read_text().splitlines()[0] == "t [s],a_raw [m/s^2],a_cfc600 [m/s^2]"
    old = tmp_path / "old"
    old.mkdir()
    (old / "summary.json").write_text(json.dumps({"backend": "numba"}))
    lines = (new / "acceleration.csv").read_text().splitlines()
    _write(old / "acceleration.csv", "\n".join(["t,a_raw,a_cfc600", *lines[1:]]) + "\n")
    a, b = read_run(new), read_run(old)
    np.testing.assert_array_equal(a.t, t)
    np.testing.assert_array_equal(a.y, t * 2e4 + 0.1)  # the numbers are unchanged by the header
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.y, b.y)
    rx = write_reaction(tmp_path / "rx", t, 1 - t, 3 * t, 4 * t, {"backend": "skfem"})
    assert (rx / "reaction.csv").read_text().splitlines()[0] == "t [s],stretch [-],reaction_force [N],nominal_stress [Pa]"
    np.testing.assert_array_equal(read_run(rx).y, 3 * t)
    _write(old / "acceleration.csv", "t [s],a_raw [g],a_cfc600 [g]\n0,0,0\n1e-5,1,2\n")
    with pytest.raises(InputError, match=r"a_cfc600"):
        read_run(old)


@pytest.mark.parametrize("every, warned", [(1, False), (4, False), (10, True)])
def test_a_curve_sampled_below_10_cfc_is_warned_about(tmp_path, every, warned):
    """Curves sampled at 2-10 x CFC were fitted silently, k1 up to 30 % off the truth with tight intervals:
    the linear interpolation before the filter flattens the peak. 50 kHz / 4 = 12.5 kHz is fine (>= 6 kHz)."""
    t = np.arange(0.0, 0.0102, 2e-5)[::every]
    a = np.where(t < 0.01, 300.0 * np.sin(np.pi * t / 0.01) ** 2, 0.0)
    path = _write(tmp_path / "a.csv", "t,a\n" + "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in zip(t, a)))
    (curve,) = measured.read_curves([f"{path}:0.008"], builtin_scene("drop-test"), scene_given=True)
    assert bool(curve.notes) == warned
    if warned:
        assert "below SAE J211/1's 10 x CFC = 6000 per s" in curve.notes[0]


@pytest.mark.parametrize("row, needle", [("1e110,0,0,0,1e110,0,0,0,1e110", "line 3: det F = inf: beyond the float64"),
                                         ("1e200,0,0,0,1e200,0,0,0,1e-300", r"line 3: C = F\^T F overflows")])
def test_a_deformation_beyond_the_float_range_is_refused_by_its_line(tmp_path, row, needle):
    """det F = inf: numba and torch called it "det F = inf <= 0 (inverted)", numpy and skfem wrote a
    zero stress with exit 0."""
    path = _write(tmp_path / "F.csv", f"t,F11,F12,F13,F21,F22,F23,F31,F32,F33\n0.001,1.1,0,0,0,1,0,0,0,1\n0.002,{row}\n")
    with pytest.raises(InputError, match=needle):
        point.read_history(path)


@pytest.mark.parametrize("row, needle", [("1e-170,0,0,0,1,0,0,0,1", r"line 3: .*but C11 = 0: a squared stretch that underflowed"),
                                         ("1,0,0,0,1e-160,0,0,0,1", r"line 3: .*but C22 = 9.99989e-321: a squared stretch"),
                                         ("1,1e9,0,0,1,0,0,0,1", r"line 3: .*but its smallest eigenvalue is 0: lost to round-off")])
def test_a_c_that_underflows_or_is_not_positive_definite_is_refused_by_its_line(tmp_path, row, needle):
    """det F = 1e-170 > 0 passed, but C11 = (1e-170)^2 underflows to 0: J = sqrt(det C) = 0 and the
    diagnosis of the non-finite stress crashed with "ZeroDivisionError: 0.0 cannot be raised to a
    negative power" (a traceback, exit 1). A shear of 1e9 leaves C's smallest eigenvalue, 1e-18 in
    exact arithmetic, as 0 in float64: the same crash."""
    path = _write(tmp_path / "F.csv", f"t,F11,F12,F13,F21,F22,F23,F31,F32,F33\n0.001,1.1,0,0,0,1,0,0,0,1\n0.002,{row}\n")
    with pytest.raises(InputError, match=needle) as err:
        point.read_history(path)
    assert "positive definite with every diagonal entry at least 2.22507e-308" in str(err.value)


def test_a_tiny_but_normal_squared_stretch_is_read(tmp_path):
    """The bound is the underflow, not a physical judgement: C11 = 1e-200 (F11 = 1e-100) is read (the
    run then names the term that overflows)."""
    path = _write(tmp_path / "F.csv", "t,F11,F12,F13,F21,F22,F23,F31,F32,F33\n0,1e-100,0,0,0,1,0,0,0,1\n")
    t, F = point.read_history(path)
    assert F[0, 0, 0] == 1e-100
