"""A scene of the wrong type, a file of the wrong kind or encoding, a reader that stops: one paragraph
and exit 2 (or 141 for a closed pipe), never a traceback; found by trying the commands as a new user."""

import gzip
import subprocess
import sys

import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.scene.scene import builtin_scene, load_scene, scene_to_dict, scene_to_toml
from cfm_core.studies import measured


@pytest.fixture
def relaxation_scene(tmp_path):
    path = tmp_path / "rel.toml"
    path.write_text(scene_to_toml(builtin_scene("relaxation")))
    return path


def test_drop_test_refuses_another_scene_type_before_running(relaxation_scene, tmp_path, capsys):
    """It ran the relaxation on skfem, wrote reaction.csv, then failed with KeyError: 'peak_g'."""
    assert main(["drop-test", "--scene", str(relaxation_scene), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "a 'relaxation' scene; cfm drop-test runs drop-test scenes" in err and "cfm run --scene" in err
    assert not (tmp_path / "o").exists()


def test_calibrate_refuses_a_scene_that_is_not_a_drop_test(relaxation_scene, tmp_path, capsys):
    """AttributeError traceback before."""
    data = tmp_path / "m.csv"
    data.write_text("t,a\n" + "".join(f"{float(t)!r},1.0\n" for t in np.arange(0.0, 0.01, 2e-5)))
    rc = main(["calibrate", "--scene", str(relaxation_scene), "--data", f"{data}:0.005", "--fit", "k2",
               "--out", str(tmp_path / "c")])
    assert rc == 2 and "measured acceleration curves are fitted with drop tests" in capsys.readouterr().err


def test_a_measured_curve_is_checked_against_the_speed_of_a_velocity_vector(tmp_path):
    """velocity = [0, 0, -1] gave TypeError: float() argument must be ... not 'tuple'."""
    t = np.arange(0.0, 0.012, 2e-5)
    a = 235.6 * np.sin(np.pi * np.clip(t / 0.01, 0.0, 1.0))   # int a dt = 1.5 m/s
    data = tmp_path / "m.csv"
    data.write_text("t,a\n" + "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in zip(t, a)))
    scene = builtin_scene("drop-test").with_overrides(velocity=(0.0, 0.0, -1.0))
    curve = measured.read_curve(f"{data}:0.008", None, scene=scene)
    assert curve.notes == () and curve.thickness == 0.008


def test_a_scene_file_that_is_not_utf8_names_the_line(tmp_path, capsys):
    path = tmp_path / "latin1.toml"
    path.write_bytes(scene_to_toml(builtin_scene("drop-test")).encode() + "# 5 \u00b5m\n".encode("latin-1"))
    with pytest.raises(Exception, match=r"byte 0xb5 is not UTF-8 text"):
        load_scene(path)
    assert main(["drop-test", "--scene", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_a_scene_file_with_a_byte_order_mark_reads_as_the_clean_one(tmp_path):
    """Windows Notepad's UTF-8 writes a BOM: "not valid TOML: Invalid statement (at line 1, column 1)"."""
    text = scene_to_toml(builtin_scene("drop-test").with_overrides(parameters={"k1": 1500.0}))
    clean, bom = tmp_path / "clean.toml", tmp_path / "bom.toml"
    clean.write_text(text, encoding="utf-8")
    bom.write_text(text, encoding="utf-8-sig")
    assert bom.read_bytes().startswith(b"\xef\xbb\xbf")
    assert scene_to_dict(load_scene(bom)) == scene_to_dict(load_scene(clean))


@pytest.mark.parametrize("name, encode, expected", [
    ("utf16.toml", lambda t: t.encode("utf-16"), "is encoded as UTF-16, which this reader does not accept; TOML files "
                                                  "must be UTF-8"),
    ("gz.toml", lambda t: gzip.compress(t.encode()), "is gzip-compressed; TOML files are read as plain UTF-8 text"),
    ("digits.toml", lambda t: (t + "\n[material.parameters]\nk1 = 1" + "0" * 5000 + "\n").encode(),
     "holds an integer too long to read"),   # ValueError of Python's 4300-digit limit, a traceback before
])
def test_a_scene_file_of_another_encoding_exits_2_with_one_paragraph(tmp_path, capsys, name, encode, expected):
    path = tmp_path / name
    path.write_bytes(encode(scene_to_toml(builtin_scene("drop-test"))))
    assert main(["run", "--scene", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"scene file '{path}'" in err and expected in err and err.count("\n") == 1 and "Traceback" not in err


def test_point_refuses_a_png_as_its_csv_and_warns_about_a_plot_left_by_an_earlier_run(tmp_path, capsys):
    """--out x.png wrote the CSV, then the plot over it ("wrote x.png, x.png")."""
    out = tmp_path / "x.png"
    assert main(["point", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--out", str(out)]) == 2
    assert "name a .csv file" in capsys.readouterr().err and not out.exists()
    csv = tmp_path / "x.csv"
    assert main(["point", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--out", str(csv)]) == 0
    capsys.readouterr()
    assert main(["point", "--uniaxial", "--rate", "1", "--stretch", "0.5", "--no-plot", "--out", str(csv)]) == 0
    assert f"{tmp_path / 'x.png'} is from an earlier run" in capsys.readouterr().err


def test_a_reader_that_stops_ends_the_command_without_a_traceback():
    """`cfm materials | head -40` ended in a BrokenPipeError traceback."""
    proc = subprocess.Popen([sys.executable, "-m", "cfm_core.cli", "materials"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before the first line
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in err and "BrokenPipeError" not in err


def test_a_folder_given_as_a_data_file_is_called_a_folder(tmp_path, capsys):
    """--test, --data and --history given a folder said "it does not exist"."""
    assert main(["fit", "--test", f"{tmp_path}:uniaxial:1", "--fit", "k1", "--out", str(tmp_path / "f")]) == 2
    assert "it is a folder, not a file" in capsys.readouterr().err


def test_an_output_of_another_kind_replaced_in_its_folder_is_named(tmp_path, capsys):
    """cfm export --out into a drop test's folder removed its acceleration.csv, summary.json and scene.toml with
    exit 0 and no word (the documented rule replaces an earlier cfm output, but a mistyped --out lost a run)."""
    out = tmp_path / "o"
    assert main(["drop-test", "--thickness", "0.005", "--element-size", "0.0025", "--no-plot", "--quiet",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["export", "cfm", "--to", "abaqus-umat", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"note: {out} held the output of a run (3 files); it is replaced by this material export's." in err
    assert not (out / "summary.json").exists()
    assert main(["export", "cfm", "--to", "lsdyna-umat", "--out", str(out)]) == 0
    assert "held the output" not in capsys.readouterr().err          # the same kind: replaced as before


def test_result_files_left_beside_a_new_output_are_named(tmp_path, capsys):
    """A cut view and a comparison written into a run's folder stayed beside the next run's files, describing
    the run that was gone, with no note."""
    out = tmp_path / "o"
    args = ["drop-test", "--thickness", "0.005", "--element-size", "0.0025", "--no-plot", "--quiet", "--out", str(out)]
    assert main(args) == 0
    (out / "cut.png").write_bytes(b"png")
    (out / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert main(args) == 0
    err = capsys.readouterr().err
    assert f"note: {out} keeps cut.png, not written by this command" in err and "notes.txt" not in err
    assert (out / "cut.png").exists() and (out / "notes.txt").exists()      # never removed
