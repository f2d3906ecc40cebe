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
    ("latin1", "# r\xe9sum\xe9\n" + H + "\n" + "\n".join(ROWS) + "\n", "latin-1", "not valid UTF-8"),
    ("fortran", H + "\n0.0D+00,1.0D+00,0,0,0,1D0,0,0,0,1.0D0\n" + ROWS[1] + "\n", "utf-8", "Fortran 'D' exponent"),
    ("thousands", H.replace(",", ";") + "\n0;1.000,5;0;0;0;1;0;0;0;1\n", "utf-8", "both a comma and a point"),
    ("units_row_ms", H + "\nms" + ",-" * 9 + "\n" + "\n".join(ROWS) + "\n", "utf-8", "divide the times by 1000"),
    ("mixed", H.replace(",", ";") + "\n0,0,1,0,0,0,1,0,0,0,1\n", "utf-8", "separated by semicolons for the 10"),
    ("ms", H.replace("t,", "t [ms],") + "\n" + "\n".join(ROWS) + "\n", "utf-8", "divide the times by 1000"),
])
def test_other_encodings_and_dialects_exit_2_with_one_paragraph(tmp_path, capsys, name, text, encoding, needle):
    path = _write(tmp_path / f"F_{name}.csv", text, encoding)
    out = tmp_path / "s.csv"
    assert main(["point", "--material", "cfm", "--history", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


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


@pytest.mark.parametrize("kw", [{}, {"bom": True}, {"header": "t [s],a [m/s^2]"}, {"header": "t (s), a (m/s2)"}])
def test_measured_curves_in_every_accepted_form(tmp_path, kw):
    path = _pulse(tmp_path, **kw)
    t, a = measured.read_measured(path)
    assert t.size == 510 and t[1] == pytest.approx(2e-5) and a.max() == pytest.approx(300.0, rel=1e-3)


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
