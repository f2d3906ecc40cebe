"""``cfm fields`` on damaged run folders and bad numeric options: exit status 2, one paragraph
naming the file or option, no traceback, no meshio noise on the terminal."""

from __future__ import annotations

import re
import shutil

import meshio
import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.post.cutview import render_cut

REWRITE = "rerun the drop test with --vtu"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A tiny quarter drop test written with --vtu (2.5 mm elements, 30 mm wide), once per module."""
    out = tmp_path_factory.mktemp("fields_run") / "v1"
    assert main(["drop-test", "--element-size", "0.0025", "--width", "0.03", "--vtu", "--out", str(out),
                 "--quiet"]) == 0
    return out


@pytest.fixture()
def copy(run, tmp_path):
    """A fresh copy of the run folder to damage."""
    return shutil.copytree(run, tmp_path / "run")


def _frame(folder, k=None):
    """(time s, specimen file name, impactor file name) of a middle frame listed in specimen.pvd."""
    pvd = (folder / "specimen.pvd").read_text()
    spec = re.findall(r'timestep="([^"]+)" group="" part="0" file="([^"]+)"', pvd)
    imp = re.findall(r'part="1" file="([^"]+)"', pvd)
    k = len(spec) // 2 if k is None else k
    return float(spec[k][0]), spec[k][1], imp[k]


def _fails(capsys, args, *words):
    """Run ``cfm fields ARGS``: exit 2, one line ``cfm fields: error: ...`` holding every word."""
    rc = main(["fields", *map(str, args)])
    out, err = capsys.readouterr()
    assert rc == 2, (out, err)
    assert "Traceback" not in out + err and "Couldn't read" not in out + err and "Error:" not in out + err
    assert err.startswith("cfm fields: error: ") and err.strip().count("\n") == 0, err
    for w in words:
        assert w in err, (w, err)
    return err


def test_malformed_missing_or_foreign_fields_json(copy, tmp_path, capsys):
    t, _, _ = _frame(copy)
    png = tmp_path / "f.png"
    (copy / "fields.json").write_text("{oops\n")
    _fails(capsys, [copy, "--at", t, "--png", png], "fields.json", "cannot be read as JSON", REWRITE)
    (copy / "fields.json").write_text("[1, 2]\n")
    _fails(capsys, [copy, "--at", t, "--png", png], "fields.json", "list", REWRITE)
    (copy / "fields.json").write_text('{"symmetry": "eighth"}\n')
    _fails(capsys, [copy, "--at", t, "--png", png], "fields.json", "'eighth'", "'quarter'")
    (copy / "fields.json").write_text("")
    _fails(capsys, [copy, "--at", t, "--png", png], "fields.json", "is empty", REWRITE)
    (copy / "fields.json").unlink()
    _fails(capsys, [copy, "--at", t, "--png", png], "fields.json", "is missing", REWRITE)
    assert not png.exists()


def test_fields_json_with_a_byte_order_mark_is_read_and_utf16_is_refused(copy, tmp_path, capsys):
    """Saved again by Windows Notepad: "Unexpected UTF-8 BOM" refused the folder; UTF-16 gave the codec's text."""
    t, _, _ = _frame(copy)
    text = (copy / "fields.json").read_text(encoding="utf-8")
    (copy / "fields.json").write_text(text, encoding="utf-8-sig")
    assert main(["fields", str(copy), "--at", str(t), "--png", str(tmp_path / "bom.png")]) == 0
    assert (tmp_path / "bom.png").is_file()
    (copy / "fields.json").write_text(text, encoding="utf-16")
    _fails(capsys, [copy, "--at", t, "--png", tmp_path / "u.png"], "fields.json", "is encoded as UTF-16",
           "JSON files must be UTF-8")


@pytest.mark.parametrize("text, words", [
    ("garbage\n", ("specimen.pvd", "cannot be read as a ParaView collection")),
    ("", ("specimen.pvd", "is empty")),
    ('<VTKFile type="Collection"><Collection/></VTKFile>\n', ("specimen.pvd", "lists no specimen frame")),
    ('<VTKFile><Collection><DataSet timestep="nan" part="0" file="specimen_0000.vtu"/></Collection></VTKFile>',
     ("specimen.pvd", "timestep 'nan'", "finite time")),
    ('<VTKFile><Collection><DataSet timestep="0.0" part="0"/></Collection></VTKFile>',
     ("specimen.pvd", "file None")),
])
def test_damaged_pvd(copy, tmp_path, capsys, text, words):
    (copy / "specimen.pvd").write_text(text)
    _fails(capsys, [copy, "--at", "0.0", "--png", tmp_path / "f.png"], *words, REWRITE)


def test_no_pvd_names_the_folder(tmp_path, capsys):
    _fails(capsys, [tmp_path, "--at", "1e-3", "--png", tmp_path / "f.png"], "no specimen.pvd", "--vtu")


def test_missing_empty_truncated_or_foreign_specimen_frame(copy, run, tmp_path, capsys):
    t, name, _ = _frame(copy)
    png = tmp_path / "f.png"
    (copy / name).unlink()
    _fails(capsys, [copy, "--at", t, "--png", png], name, "is missing", "specimen.pvd lists it", REWRITE)
    (copy / name).write_bytes(b"")
    _fails(capsys, [copy, "--at", t, "--png", png], name, "is empty", REWRITE)
    (copy / name).write_bytes((run / name).read_bytes()[:3000])
    _fails(capsys, [copy, "--at", t, "--png", png], name, "cannot be read as a VTU mesh", REWRITE)
    (copy / name).write_text("garbage\n")
    _fails(capsys, [copy, "--at", t, "--png", png], name, "cannot be read as a VTU mesh", REWRITE)
    # a frame of another mesh: one hexahedron
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1.0]]) * 1e-3
    meshio.write(copy / name, meshio.Mesh(cube, [("hexahedron", np.arange(8)[None])]), file_format="vtu")
    _fails(capsys, [copy, "--at", t, "--png", png], name, "8 nodes and 1 elements", "first frame", REWRITE)
    assert not png.exists()


def test_frame_with_arrays_of_the_wrong_length(copy, run, tmp_path, capsys):
    t, name, _ = _frame(copy)
    mesh = meshio.read(run / name)
    mesh.cell_data["von_mises [Pa]"] = [mesh.cell_data["von_mises [Pa]"][0][:-1]]
    meshio.write(copy / name, mesh, file_format="vtu")
    n = len(mesh.cell_data["von_mises [Pa]"][0])
    _fails(capsys, [copy, "--at", t, "--png", tmp_path / "f.png"], name, "cannot be read as a VTU mesh", str(n),
           REWRITE)


def test_missing_impactor_frame(copy, tmp_path, capsys):
    t, _, imp = _frame(copy)
    (copy / imp).unlink()
    _fails(capsys, [copy, "--at", t, "--png", tmp_path / "f.png"], imp, "is missing", REWRITE)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "-0.001"])
def test_at_must_be_a_finite_time_of_zero_or_more(run, tmp_path, capsys, value):
    _fails(capsys, [run, f"--at={value}", "--png", tmp_path / "f.png"], f"--at {float(value)!r}", "finite", "0 or more")
    assert not (tmp_path / "f.png").exists()


def test_at_beyond_the_frames(run, tmp_path, capsys):
    _fails(capsys, [run, "--at", "1.0", "--png", tmp_path / "f.png"], "--at 1 s", "outside the stored frames")


def test_at_in_ms_is_asked_about(run, tmp_path, capsys):
    """--at 3 (ms meant) was only "outside the stored frames"."""
    _fails(capsys, [run, "--at", "3", "--png", tmp_path / "f.png"], "Is it in ms? --at 0.003 is 3 ms.")


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_y_must_be_finite(run, tmp_path, capsys, value):
    _fails(capsys, [run, "--at", "0.005", f"--y={value}", "--png", tmp_path / "f.png"], f"--y {float(value)!r}",
           "finite")


@pytest.mark.parametrize("value", ["0.0151", "-0.0151", "1"])
def test_y_outside_the_mirrored_specimen(run, tmp_path, capsys, value):
    err = _fails(capsys, [run, "--at", "0.005", f"--y={value}", "--png", tmp_path / "f.png"], f"--y {float(value):g} m",
                 "outside the specimen", "-0.015 .. 0.015 m", "quarter", "mirrored about y = 0")
    assert "crosses no element" not in err


def test_negative_y_of_a_quarter_run_is_its_mirror_image(run, tmp_path, capsys):
    """As documented (a quarter run is shown mirrored): y -> -y gives the same scalars, and the shear
    component 23 changes sign across y = 0."""
    assert main(["fields", str(run), "--at", "0.005", "--y=-0.005", "--png", str(tmp_path / "n.png")]) == 0
    assert "wrote" in capsys.readouterr().out and (tmp_path / "n.png").stat().st_size > 5_000
    for field, sign in (("von_mises", 1.0), ("cauchy_stress_23", -1.0), ("cauchy_stress_33", 1.0)):
        pos = render_cut(run, 0.005, field, tmp_path / "p.png", y_cut=0.006)
        neg = render_cut(run, 0.005, field, tmp_path / "n.png", y_cut=-0.006)
        got = sorted((sign * neg["min"], sign * neg["max"]))
        assert got == pytest.approx([pos["min"], pos["max"]], rel=1e-12), field
