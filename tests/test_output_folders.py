"""Outputs that never mislead (issue 20 item 4): the run-level commands and outcome.save stage their
files, check the target before the solve, replace an earlier run's files (stale VTU frames
included), keep foreign files, and refuse wrong kinds of target with exit 2, no traceback."""

import json
import os
import time

import pytest

import cfm_core as cfm
from cfm_core.errors import InputError
from cfm_core.cli import main
from cfm_core.post import staging
from cfm_core.runs.outcomes import output_bytes

SMALL = ["--element-size", "0.002", "--width", "0.02", "--thickness", "0.004", "--quiet", "--no-plot"]


def _earlier_vtu_run(folder, frames=55):
    """A folder as an earlier --vtu run of cfm (version 0.2.0, no manifest) left it, plus a user's file."""
    folder.mkdir()
    for k in range(frames):
        (folder / f"specimen_{k:04d}.vtu").write_text("old frame")
    for name in ("specimen.pvd", "acceleration.png", "acceleration.csv", "scene.toml"):
        (folder / name).write_text("old")
    (folder / "summary.json").write_text('{"peak_g": 56.8, "backend": "numba"}')
    (folder / "my notes.txt").write_text("mine")


def test_a_run_into_a_used_folder_leaves_only_its_own_files_and_foreign_ones(tmp_path, capsys):
    out = tmp_path / "out"
    _earlier_vtu_run(out)
    assert main(["drop-test", *SMALL, "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [".cfm-output.json", "acceleration.csv", "my notes.txt", "scene.toml", "summary.json"]
    assert (out / "my notes.txt").read_text() == "mine"
    assert json.loads((out / ".cfm-output.json").read_text())["files"] == ["acceleration.csv", "scene.toml",
                                                                           "summary.json"]
    assert capsys.readouterr().out.splitlines()[-1] == f"wrote {out}/: acceleration.csv, scene.toml, summary.json"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no stage left beside it


def test_no_overwrite_refuses_an_earlier_run_before_solving(tmp_path, capsys):
    out = tmp_path / "out"
    _earlier_vtu_run(out, frames=2)
    before = sorted(p.name for p in out.iterdir())
    assert main(["drop-test", *SMALL, "--no-overwrite", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert "holds the files of an earlier run" in captured.err and "peak" not in captured.out
    assert sorted(p.name for p in out.iterdir()) == before
    assert main(["drop-test", *SMALL, "--no-overwrite", "--out", str(tmp_path / "new")]) == 0


@pytest.mark.parametrize("command", [["drop-test", *SMALL], ["run", "--scene", "single-element", "--quiet"]])
def test_a_target_that_cannot_be_an_output_folder_is_refused_before_the_run(tmp_path, capsys, command):
    (tmp_path / "file").write_text("x")
    for out, words in ((tmp_path / "file", "exists and is not a directory"),
                       (tmp_path / "file" / "sub", "is a file, so no folder can be made there")):
        start = time.perf_counter()
        assert main([*command, "--out", str(out)]) == 2
        captured = capsys.readouterr()
        assert words in captured.err and "Traceback" not in captured.err
        assert "peak" not in captured.out and "largest" not in captured.out  # refused before solving
        assert time.perf_counter() - start < 20


def test_a_full_disk_is_refused_before_the_run_with_the_estimated_size(tmp_path, capsys, monkeypatch):
    class Usage:
        free = 1_000_000

    monkeypatch.setattr(staging.shutil, "disk_usage", lambda path: Usage)
    assert main(["drop-test", *SMALL, "--vtu", "--out", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    assert "the output needs about" in captured.err and "MiB are free" in captured.err and "peak" not in captured.out
    assert not (tmp_path / "out").exists()


def test_output_size_estimate_covers_what_a_vtu_run_writes(tmp_path):
    scene = cfm.builtin_scene("drop-test").with_overrides(element_size=0.002, width=0.02, thickness=0.004)
    out = tmp_path / "out"
    assert main(["drop-test", *SMALL[:-2], "--vtu", "--out", str(out)]) == 0
    written = sum(p.stat().st_size for p in out.iterdir())
    estimate = output_bytes(scene, {"frame_interval": 2e-4}, plot=True, vtu=True)
    assert written <= estimate < 60 * written, (written, estimate)


def test_point_and_compare_refuse_a_directory_where_a_file_is_written(tmp_path, capsys):
    d = tmp_path / "dir"
    d.mkdir()
    assert main(["point", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--out", str(d)]) == 2
    err = capsys.readouterr().err
    assert "is an existing directory, but a file is written there" in err and "Traceback" not in err
    run = tmp_path / "run"
    assert main(["drop-test", *SMALL, "--out", str(run)]) == 0
    for flag in ("--plot", "--json"):
        assert main(["compare", str(run), str(run), flag, str(d)]) == 2
        err = capsys.readouterr().err
        assert f"{flag} {d} is an existing directory" in err and "Traceback" not in err


def test_outcome_save_from_python_is_staged(tmp_path):
    out = tmp_path / "out"
    _earlier_vtu_run(out)
    scene = cfm.builtin_scene("drop-test").with_overrides(element_size=0.002, width=0.02, thickness=0.004)
    outcome = cfm.drop_test(scene)
    assert outcome.save(out, plot=False) == out
    assert sorted(p.name for p in out.iterdir()) == [".cfm-output.json", "acceleration.csv", "my notes.txt",
                                                     "scene.toml", "summary.json"]
    with pytest.raises(cfm.InputError, match="holds the files of an earlier run"):
        outcome.save(out, overwrite=False)


def test_a_plot_or_json_path_cannot_replace_a_file_of_a_run(tmp_path, capsys):
    """cfm compare --plot run/acceleration.csv wrote a PNG over the run's data; --plot and --json on one
    path lost the JSON; cfm fields --png run/specimen.pvd replaced the run's collection."""
    from cfm_core.cli import main
    from cfm_core.post.staging import check_file_target

    run = tmp_path / "run"
    assert main(["drop-test", "--element-size", "0.0025", "--width", "0.03", "--quiet", "--out", str(run)]) == 0
    before = (run / "acceleration.csv").read_bytes()
    capsys.readouterr()
    assert main(["compare", str(run), str(run), "--plot", str(run / "acceleration.csv")]) == 2
    assert "a PNG file is written there, but the name ends in .csv" in capsys.readouterr().err
    assert main(["compare", str(run), str(run), "--plot", str(run / "acceleration.png")]) == 2
    assert "is a file of the cfm output in" in capsys.readouterr().err
    assert main(["compare", str(run), str(run), "--plot", str(tmp_path / "c.png"), "--json", str(tmp_path / "c.png")]) == 2
    assert "a JSON file is written there" in capsys.readouterr().err
    assert (run / "acceleration.csv").read_bytes() == before
    with pytest.raises(InputError, match="is a file of the cfm output"):
        check_file_target(run / "summary.json", "--png")
    assert check_file_target(tmp_path / "new.png", "--plot", suffix=".png") == tmp_path / "new.png"


def test_a_failed_run_removes_the_folders_it_made_and_stale_stages_go(tmp_path):
    """A failed run with a new nested --out left its parent folders behind; a stage of a killed process
    (SIGKILL cannot be caught) stayed beside --out for good."""
    nested = tmp_path / "a" / "b" / "c"
    with pytest.raises(RuntimeError):
        with staging.staged_folder(nested) as stage:
            (stage / "x.txt").write_text("partial")
            raise RuntimeError("the run failed")
    assert list(tmp_path.iterdir()) == []
    stale = tmp_path / f".out{staging.STAGE_TAG}999999999-dead"      # no such process
    live = tmp_path / f".out{staging.STAGE_TAG}{os.getppid()}-live"   # a running process's stage stays
    for s in (stale, live):
        s.mkdir()
    with staging.staged_folder(tmp_path / "out") as stage:
        (stage / "summary.json").write_text("{}")
    assert not stale.exists() and live.exists() and (tmp_path / "out" / "summary.json").is_file()


def test_sigterm_ends_a_run_like_ctrl_c_and_leaves_out_as_it_was(tmp_path):
    """`timeout` and batch systems send SIGTERM: the stage stayed behind and the output half-made."""
    import signal
    import subprocess
    import sys

    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from cfm_core.cli.__main__ import console; "
                             "sys.exit(console())", "drop-test", "--element-size", "0.001", "--out", str(out)],
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(staging.STAGE_TAG in p.name for p in tmp_path.iterdir()):
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "terminated (SIGTERM); no result written" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_run_never_removes_the_mesh_it_reads_from_its_out_folder(tmp_path, capsys):
    """`cfm drop-test --mesh V/specimen_0000.vtu --out V` (a frame of an earlier --vtu run as the
    mesh) removed the mesh with the earlier frames, and its scene.toml named a file that was gone:
    refused before the run, naming the file, with nothing removed."""
    out = tmp_path / "V"
    assert main(["drop-test", *SMALL, "--vtu", "--fields", "J", "--out", str(out)]) == 0
    mesh = out / "specimen_0000.vtu"
    before = sorted(p.name for p in out.iterdir())
    capsys.readouterr()
    assert main(["drop-test", "--mesh", str(mesh), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "specimen_0000.vtu" in err and "remove a file this command reads" in err
    assert sorted(p.name for p in out.iterdir()) == before
