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


# ----------------------------------------------------------------------------- outputs that cannot be replaced
SWEEP = ["sweep", "--serial", "--quiet", "--vary", "element_size=0.002", "--vary", "width=0.02",
         "--vary", "thickness=0.004"]


@pytest.fixture
def immutable():
    """``lock(path)``: ``chattr +i path`` (skips the test where chattr is missing or not permitted);
    every flag set is cleared again at the end, so that the tmp folder can be removed."""
    import shutil
    import subprocess

    locked = []

    def lock(path):
        if shutil.which("chattr") is None:
            pytest.skip("chattr is not installed")
        done = subprocess.run(["chattr", "+i", str(path)], capture_output=True, text=True)
        if done.returncode != 0:
            pytest.skip(f"chattr +i is not permitted here: {done.stderr.strip()}")
        locked.append(path)

    try:
        yield lock
    finally:
        for path in reversed(locked):
            subprocess.run(["chattr", "-i", str(path)], capture_output=True)


def _tree(folder):
    """Every entry under ``folder``: relative path -> its bytes (None for a folder)."""
    return {str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes() for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("locked", ["sweep.csv", "runs", "runs/<id>"])
def test_a_sweep_over_an_earlier_one_it_cannot_change_exits_2_and_changes_nothing(tmp_path, capsys, immutable,
                                                                                  locked):
    """An immutable sweep.csv, runs/ or run folder gave a PermissionError traceback (from the removal of
    the earlier output, or from the mkdir of runs/<id>) with the earlier sweep half deleted."""
    out = tmp_path / "sw"
    assert main([*SWEEP, "--out", str(out)]) == 0
    target = out / locked.replace("<id>", next((out / "runs").iterdir()).name)
    before = _tree(out)
    immutable(target)
    assert main([*SWEEP, "--vary", "k2=1.7", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(target) in err and "nothing was changed" in err and "Traceback" not in err
    assert err.count("\n") == 1
    assert _tree(out) == before


@pytest.mark.parametrize("command, locked", [
    (["drop-test", *SMALL[:-2], "--vtu", "--fields", "J"], "impactor_0003.vtu"),
    (["export", "cfm", "--to", "lsdyna-umat"], "material.k"),
])
def test_an_earlier_output_with_a_file_that_cannot_be_removed_is_left_whole(tmp_path, capsys, immutable, command,
                                                                             locked):
    """`chattr +i DT/impactor_0003.vtu`: the next run into DT exited 2 having removed the earlier
    summary.json and acceleration.csv; refused now before the run, with every earlier file in place."""
    out = tmp_path / "out"
    assert main([*command, "--out", str(out)]) == 0
    before = _tree(out)
    immutable(out / locked)
    capsys.readouterr()
    assert main([*command, "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert f"{out / locked} cannot be removed" in captured.err and "Traceback" not in captured.err
    assert "peak" not in captured.out  # refused before the run
    assert _tree(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no stage left


def test_a_publication_checks_every_file_before_it_removes_one(tmp_path, immutable):
    """A file that became unremovable during the work (after the check before it) stops the publication
    with the folder as it was, not after the earlier completion marker went."""
    out = tmp_path / "run"
    with staging.staged_folder(out) as stage:
        for name in ("summary.json", "acceleration.csv", "fields.json"):
            (stage / name).write_text("old")
    before = _tree(out)
    with pytest.raises(InputError, match="fields.json cannot be removed or rewritten"):
        with staging.staged_folder(out) as stage:
            (stage / "summary.json").write_text("new")
            immutable(out / "fields.json")
    assert _tree(out) == before


# ----------------------------------------------------------------------------- cfm point's two files
UNIAXIAL = ["point", "--uniaxial", "--rate", "100", "--stretch", "0.7"]


def test_point_writes_no_file_when_its_plot_cannot_be_replaced(tmp_path, capsys, immutable):
    """With an immutable u2.png, `cfm point --uniaxial --out u2.csv` exited 2 having replaced u2.csv."""
    csv = tmp_path / "u2.csv"
    assert main([*UNIAXIAL, "--out", str(csv)]) == 0
    before = _tree(tmp_path)
    immutable(tmp_path / "u2.png")
    capsys.readouterr()
    assert main(["point", "--uniaxial", "--rate", "1", "--stretch", "0.5", "--out", str(csv)]) == 2
    err = capsys.readouterr().err
    assert "u2.png exists and cannot be replaced" in err and "Traceback" not in err
    assert _tree(tmp_path) == before


def test_point_never_replaces_a_png_it_did_not_write_and_warns_of_a_stale_one(tmp_path, capsys):
    """`--out mine.csv` replaced the user's own mine.png silently; a --history run into the CSV of an
    earlier --uniaxial run left its plot without a word (--no-plot warned)."""
    mine = tmp_path / "mine.png"
    mine.write_bytes(b"my own picture")
    assert main([*UNIAXIAL, "--out", str(tmp_path / "mine.csv")]) == 2
    err = capsys.readouterr().err
    assert f"{mine}, which exists and is not the plot of an earlier cfm point output" in err and "Traceback" not in err
    assert mine.read_bytes() == b"my own picture" and not (tmp_path / "mine.csv").exists()
    assert main([*UNIAXIAL, "--no-plot", "--out", str(tmp_path / "mine.csv")]) == 0  # no plot: nothing to refuse
    csv = tmp_path / "u.csv"
    assert main([*UNIAXIAL, "--out", str(csv)]) == 0
    assert main([*UNIAXIAL, "--rate", "10", "--out", str(csv)]) == 0  # its own earlier plot: replaced
    capsys.readouterr()
    history = tmp_path / "F.csv"
    history.write_text("t,F11,F12,F13,F21,F22,F23,F31,F32,F33\n0,1,0,0,0,1,0,0,0,1\n0.001,0.9,0,0,0,1.05,0,0,0,1.05\n")
    assert main(["point", "--history", str(history), "--out", str(csv)]) == 0
    assert f"{tmp_path / 'u.png'} is from an earlier run" in capsys.readouterr().err
    assert main([*UNIAXIAL, "--out", str(csv)]) == 0  # the CSV is still cfm point's: its plot is replaced


def test_an_image_drawn_into_a_run_folder_goes_with_that_run(tmp_path, capsys):
    """`cfm fields RUN --png RUN/x.png` stayed in RUN after the next run replaced RUN's files, though it
    showed the earlier run; now it is recorded in RUN's manifest, drawn again freely, and goes with it."""
    run = tmp_path / "run"
    assert main(["drop-test", *SMALL, "--vtu", "--fields", "von_mises", "--out", str(run)]) == 0
    for at in ("0.001", "0.002"):  # the second replaces the first: not refused as a file of the run
        assert main(["fields", str(run), "--at", at, "--png", str(run / "x.png")]) == 0
    assert main(["compare", str(run), str(run), "--json", str(run / "c.json")]) == 0
    assert json.loads((run / ".cfm-output.json").read_text())["derived"] == ["c.json", "x.png"]
    (run / "mine.png").write_bytes(b"mine")  # not made by cfm from this run: kept
    capsys.readouterr()
    assert main(["drop-test", *SMALL, "--out", str(run)]) == 0
    assert "keeps mine.png" in capsys.readouterr().err
    assert sorted(p.name for p in run.iterdir()) == [".cfm-output.json", "acceleration.csv", "mine.png", "scene.toml",
                                                     "summary.json"]


# ----------------------------------------------------------------------------- empty output options
@pytest.mark.parametrize("command, flag", [
    (["drop-test", *SMALL], "--out"),
    (["run", "--scene", "single-element", "--quiet"], "--out"),
    ([*SWEEP], "--out"),
    (["fit", "--test", "lab.csv:uniaxial:100", "--fit", "k1"], "--out"),
    (["export", "cfm", "--to", "lsdyna-umat"], "--out"),
    ([*UNIAXIAL], "--out"),
    (["compare", "run", "run"], "--plot"),
    (["compare", "run", "run"], "--json"),
    (["fields", "run", "--at", "0.001"], "--png"),
])
def test_an_empty_output_option_is_refused(tmp_path, capsys, monkeypatch, command, flag):
    """`--out ''` (an unset shell variable) wrote into the current folder, replacing an earlier cfm output
    there; `--plot ''` and `--json ''` of compare exited 0 writing nothing."""
    monkeypatch.chdir(tmp_path)
    with staging.staged_folder(tmp_path / "here") as stage:
        (stage / "summary.json").write_text('{"backend": "numba"}')
    monkeypatch.chdir(tmp_path / "here")
    before = _tree(tmp_path)
    assert main([*command, flag, ""]) == 2
    err = capsys.readouterr().err
    assert f"{flag} is empty; give a" in err and "Traceback" not in err
    assert _tree(tmp_path) == before
    with pytest.raises(InputError, match="--out is empty; give a folder"):
        staging.check_folder_target("")
