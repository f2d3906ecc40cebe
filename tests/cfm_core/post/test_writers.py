"""Atomic writers: exact round trips, no partial or stale files, non-finite data refused; plots."""

import json
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from cfm_core.post import writers
from cfm_core.errors import InputError, NumericalError
from cfm_core.post.writers import write_csv, write_drop_test, write_json, write_vtu_series


def test_csv_header_first_and_exact_round_trip(tmp_path):
    x = np.array([0.0, 1e-5, 0.1, 1 / 3])
    y = np.array([-2.5e-300, 7.0, np.pi, 1e20])
    p = write_csv(tmp_path / "a.csv", ["t", "a"], [x, y])
    lines = p.read_text().splitlines()
    assert lines[0] == "t,a" and len(lines) == 5
    back = np.loadtxt(p, delimiter=",", skiprows=1)
    assert np.array_equal(back[:, 0], x) and np.array_equal(back[:, 1], y)  # bit-exact


def test_csv_comments_only_when_given(tmp_path):
    p = write_csv(tmp_path / "c.csv", ["t"], [np.zeros(2)], comments=["units: s", "run 3"])
    assert p.read_text().splitlines()[:3] == ["# units: s", "# run 3", "t"]


def test_nan_refused_and_nothing_written(tmp_path):
    with pytest.raises(NumericalError, match="'a'"):
        write_csv(tmp_path / "n.csv", ["t", "a"], [np.zeros(3), np.array([0, np.nan, 1])])
    with pytest.raises(NumericalError):
        write_json(tmp_path / "n.json", {"peak_g": float("inf")})
    with pytest.raises(NumericalError):
        write_drop_test(tmp_path / "out", np.zeros(3), np.zeros(3), np.array([0, 1, np.nan]), {})
    with pytest.raises(NumericalError):
        write_drop_test(tmp_path / "out", np.zeros(3), np.zeros(3), np.zeros(3), {"x": float("nan")})
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_no_file_and_keeps_old(tmp_path, monkeypatch):
    old = tmp_path / "keep.json"
    old.write_text('{"old": 1}')

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(writers.os, "replace", broken_replace)
    with pytest.raises(InputError, match="disk full"):
        write_json(tmp_path / "new.json", {"a": 1})
    with pytest.raises(InputError, match="disk full"):
        write_json(old, {"new": 2})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.json"]  # no temp files left
    assert json.loads(old.read_text()) == {"old": 1}


def test_failure_inside_writer_cleans_up(tmp_path):
    def write(tmp):
        with open(tmp, "w") as f:
            f.write("half")
        raise RuntimeError("crash mid-write")

    with pytest.raises(RuntimeError):
        writers.atomic_write(tmp_path / "x.txt", write)
    assert list(tmp_path.iterdir()) == []


def test_drop_test_output(tmp_path, monkeypatch):
    order = []
    real_replace = os.replace
    monkeypatch.setattr(writers.os, "replace", lambda s, d: (order.append(os.path.basename(d)), real_replace(s, d)))
    t = np.arange(5) * 2e-5
    out = write_drop_test(tmp_path / "run", t, np.ones(5), 2 * np.ones(5), {"peak_g": 0.2, "units": {"peak_g": "g"}})
    assert order == ["acceleration.csv", "summary.json"]  # summary last: its presence means success
    assert (out / "acceleration.csv").read_text().splitlines()[0] == "t [s],a_raw [m/s^2],a_cfc600 [m/s^2]"
    data = np.loadtxt(out / "acceleration.csv", delimiter=",", skiprows=1)
    assert np.array_equal(data[:, 0], t) and np.all(data[:, 2] == 2.0)
    s = json.loads((out / "summary.json").read_text())
    assert s["units"] == {"t": "s", "a_raw": "m/s^2", "a_cfc600": "m/s^2", "peak_g": "g"}


def test_drop_test_removes_stale_summary_before_writing(tmp_path, monkeypatch):
    out = tmp_path / "run"
    write_drop_test(out, np.zeros(2), np.zeros(2), np.zeros(2), {"run": 1})
    monkeypatch.setattr(writers.os, "replace", lambda s, d: (_ for _ in ()).throw(OSError("no space")))
    with pytest.raises(InputError, match="no space"):
        write_drop_test(out, np.zeros(2), np.zeros(2), np.zeros(2), {"run": 2})
    assert not (out / "summary.json").exists()  # the old summary no longer vouches for the folder
    assert sorted(p.name for p in out.iterdir()) == ["acceleration.csv"]


def test_vtu_series(tmp_path):
    meshio = pytest.importorskip("meshio")
    nodes = np.array([[x, y, z] for z in (0, 1e-3) for y in (0, 1e-3) for x in (0, 1e-3, 2e-3)], float)
    hexes = np.array([[0, 1, 4, 3, 6, 7, 10, 9], [1, 2, 5, 4, 7, 8, 11, 10]])
    frames = [(0.0, np.zeros_like(nodes)), (1.5e-4, np.tile([0, 0, -1e-4], (12, 1)))]
    pvd = write_vtu_series(tmp_path, nodes, hexes, frames)
    m = meshio.read(tmp_path / "specimen_0001.vtu")
    np.testing.assert_array_equal(m.points, nodes)
    np.testing.assert_array_equal(m.cells_dict["hexahedron"], hexes)
    np.testing.assert_array_equal(m.point_data["displacement"], frames[1][1])
    ds = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    assert [(float(d.get("timestep")), d.get("file")) for d in ds] == [
        (0.0, "specimen_0000.vtu"), (1.5e-4, "specimen_0001.vtu")]
    bad = [(0.0, np.full_like(nodes, np.nan))]
    with pytest.raises(NumericalError):
        write_vtu_series(tmp_path / "bad", nodes, hexes, bad)
    assert not (tmp_path / "bad").exists()


def test_plots_written_atomically(tmp_path):
    pytest.importorskip("matplotlib")
    from cfm_core.post.plots import plot_acceleration, plot_overlay

    t = np.linspace(0, 6e-3, 301)
    a = 500 * np.sin(np.pi * np.clip(t, 0, 4e-3) / 4e-3)
    plot_acceleration(tmp_path / "a.png", t, a + 20 * np.sin(3e4 * t), a, "8 mm")
    plot_overlay(tmp_path / "o.png", [("8 mm", t, a), ("5 mm", t, 1.5 * a)], "overlay",
                 reference_peaks={"8 mm": 52.5 * 9.80665})
    for name in ("a.png", "o.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "o.png"]


def test_output_folder_refuses_a_file_creates_the_folder_and_removes_a_stale_marker(tmp_path):
    from cfm_core.errors import InputError

    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match=f"--out {tmp_path / 'file'} exists and is not a directory"):
        writers.output_folder(tmp_path / "file")
    with pytest.raises(InputError, match="output directory .* is not a directory"):
        writers.output_folder(tmp_path / "file", what="output directory")
    assert not (tmp_path / "new").exists() and writers.output_folder(tmp_path / "new", create=False) == tmp_path / "new"
    assert not (tmp_path / "new").exists()
    out = writers.output_folder(tmp_path / "a" / "b", marker="summary.json")
    assert out.is_dir()
    (out / "summary.json").write_text("{}")
    (out / "keep.csv").write_text("t\n")
    writers.output_folder(out, marker="summary.json")
    assert not (out / "summary.json").exists() and (out / "keep.csv").exists()


def test_a_file_that_cannot_be_replaced_is_an_input_error_and_stays(tmp_path, monkeypatch):
    target = tmp_path / "cut.png"
    target.write_text("earlier")

    def immutable(src, dst):  # chattr +i, or another user's file in a sticky shared folder
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(writers.os, "replace", immutable)
    with pytest.raises(InputError, match=r"cut.png cannot be replaced: Operation not permitted; it is left as it was"):
        writers.write_text(target, "new")
    assert target.read_text() == "earlier"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.png"]  # no temporary file left


def test_point_refuses_to_write_over_its_own_history(tmp_path, monkeypatch):
    from cfm_core.cli.app import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "F.csv").write_text("t,F11,F12,F13,F21,F22,F23,F31,F32,F33\\n0,1,0,0,0,1,0,0,0,1\\n0.001,0.9,0,0,0,1,0,0,0,1\\n")
    before = (tmp_path / "F.csv").read_bytes()
    assert main(["point", "--history", "F.csv", "--out", "./F.csv"]) == 2
    assert (tmp_path / "F.csv").read_bytes() == before
