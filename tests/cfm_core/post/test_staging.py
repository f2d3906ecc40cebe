"""Staged output folders (cfm_core.post.staging): one run's files, published whole, checked first."""

import json
import os
import subprocess

import pytest

from cfm_core.errors import InputError
from cfm_core.post.staging import MANIFEST, check_file_target, check_folder_target, staged_folder


def _write(folder, **files):
    for name, text in files.items():
        (folder / name).write_text(text)


def test_new_folder_gets_exactly_the_new_files_and_a_manifest(tmp_path):
    out = tmp_path / "run"
    with staged_folder(out) as stage:
        assert stage.parent == tmp_path and stage.name.startswith(".run.cfm-stage-")
        assert not out.exists()  # nothing visible before success
        _write(stage, **{"summary.json": "{}", "acceleration.csv": "t\n"})
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "summary.json", "acceleration.csv"])
    assert json.loads((out / MANIFEST).read_text())["files"] == ["acceleration.csv", "summary.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no stage left


def test_rerun_removes_every_file_of_the_earlier_run_but_not_foreign_files(tmp_path):
    out = tmp_path / "run"
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "8mm", "specimen.pvd": "8mm", "specimen_0001.vtu": "8mm", "custom.dat": "8"})
    (out / "notes.txt").write_text("mine")
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "5mm", "acceleration.csv": "5mm"})
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted([MANIFEST, "summary.json", "acceleration.csv", "notes.txt"])
    assert (out / "summary.json").read_text() == "5mm"


def test_legacy_output_without_manifest_is_recognised(tmp_path):
    out = tmp_path / "old"
    out.mkdir()
    _write(out, **{"summary.json": '{"backend": "numba"}', "acceleration.png": "old", "specimen_0003.vtu": "old",
                   "keep.me": "x"})
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "new"})
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "summary.json", "keep.me"])


@pytest.mark.parametrize("summary", [None, "my own notes", '{"peak": 3.1}', "[1, 2]"])
def test_files_named_like_cfm_outputs_in_a_folder_cfm_never_wrote_are_kept(tmp_path, summary):
    """Without a manifest, names alone make no cfm output: a user's acceleration.csv (measured data)
    and fit.json in a folder with no summary.json of cfm's (none, not JSON, JSON without cfm's keys)
    were removed by a calibration written there."""
    out = tmp_path / "mine"
    out.mkdir()
    _write(out, **{"acceleration.csv": "measured", "fit.json": "{}"})
    if summary is not None:
        _write(out, **{"summary.json": summary})
    with staged_folder(out) as stage:
        _write(stage, **{"sweep.json": "new"})
    kept = {"acceleration.csv", "fit.json"} | ({"summary.json"} if summary is not None else set())
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "sweep.json", *kept])
    assert (out / "acceleration.csv").read_text() == "measured"


def test_failure_leaves_the_earlier_output_untouched(tmp_path):
    out = tmp_path / "run"
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "first"})
    with pytest.raises(RuntimeError):
        with staged_folder(out) as stage:
            _write(stage, **{"summary.json": "second"})
            raise RuntimeError("solver blew up")
    assert (out / "summary.json").read_text() == "first"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_no_overwrite_refuses_before_any_work(tmp_path):
    out = tmp_path / "run"
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "first"})
    with pytest.raises(InputError, match="earlier run"):
        with staged_folder(out, overwrite=False):
            raise AssertionError("the block must not run")


def test_wrong_kinds_of_target_are_input_errors(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="exists and is not a directory"):
        check_folder_target(tmp_path / "f")
    with pytest.raises(InputError, match="is a file"):
        check_folder_target(tmp_path / "f" / "sub")
    with pytest.raises(InputError, match="existing directory"):
        check_file_target(tmp_path)
    with pytest.raises(InputError, match="MiB are free"):
        check_folder_target(tmp_path / "new", need_bytes=2**62)


@pytest.mark.skipif(os.geteuid() != 0, reason="chattr +i needs root")
def test_immutable_folder_is_refused_before_the_work(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    if subprocess.run(["chattr", "+i", str(locked)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i not supported on this file system")
    try:
        with pytest.raises(InputError, match="cannot be written"):
            check_folder_target(locked / "sub")
        with pytest.raises(InputError, match="cannot be written"):
            check_file_target(locked / "p.csv")
    finally:
        subprocess.run(["chattr", "-i", str(locked)])


def _earlier_run(out):
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "old", "acceleration.csv": "old", "specimen_0001.vtu": "old"})


def test_an_earlier_marker_that_cannot_be_removed_leaves_the_folder_as_it_was(tmp_path, monkeypatch):
    from cfm_core.post import staging

    out = tmp_path / "run"
    _earlier_run(out)
    before = {p.name: p.read_text() for p in out.iterdir()}
    real = staging.remove_entry

    def locked(path):  # a summary.json owned by another user, or chattr +i
        if path.name == "summary.json":
            raise PermissionError(1, "Operation not permitted")
        real(path)

    monkeypatch.setattr(staging, "remove_entry", locked)
    with pytest.raises(InputError, match="nothing was published and the folder is as it was"):
        with staged_folder(out) as stage:
            _write(stage, **{"summary.json": "new", "acceleration.csv": "new"})
    assert {p.name: p.read_text() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_publication_failing_midway_never_leaves_a_folder_that_looks_complete(tmp_path, monkeypatch):
    from cfm_core.post import staging

    out = tmp_path / "run"
    _earlier_run(out)
    real = os.replace

    def full_disk(src, dst):
        if str(dst).endswith("acceleration.csv"):
            raise OSError(28, "No space left on device")
        real(src, dst)

    monkeypatch.setattr(staging.os, "replace", full_disk)
    with pytest.raises(InputError, match="partly removed.*no complete output"):
        with staged_folder(out) as stage:
            _write(stage, **{"summary.json": "new", "acceleration.csv": "new", "specimen_0001.vtu": "new"})
    assert not (out / "summary.json").exists()  # neither the earlier run's nor the new one's
    listed = set(json.loads((out / MANIFEST).read_text())["files"])
    assert {p.name for p in out.iterdir()} - {MANIFEST} <= listed  # a later run still removes what is left


def test_a_signal_during_publication_is_delivered_after_it_with_the_folder_complete(tmp_path, monkeypatch):
    import signal

    from cfm_core.post import staging

    out = tmp_path / "run"
    _earlier_run(out)
    real = staging.remove_entry

    def interrupted(path):  # Ctrl-C the moment the earlier files start to go
        signal.raise_signal(signal.SIGINT)
        real(path)

    monkeypatch.setattr(staging, "remove_entry", interrupted)
    # Python's own Ctrl-C handler, as in an interactive run: a test run started as a background job of a
    # shell inherits SIGINT ignored, and an ignored signal is rightly not delivered.
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt) as caught:
            with staged_folder(out) as stage:
                _write(stage, **{"summary.json": "new", "acceleration.csv": "new"})
        assert caught.value.published == out
        assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "summary.json", "acceleration.csv"])
        assert (out / "summary.json").read_text() == "new"
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, old)


def test_the_command_line_says_an_interrupted_output_was_finished(tmp_path, monkeypatch, capsys):
    from cfm_core.cli import app, material

    def command(args):
        exc = KeyboardInterrupt()
        exc.published = tmp_path / "run"
        raise exc

    monkeypatch.setitem(material.COMMANDS, "materials", command)
    assert app.main(["materials"]) == 130
    assert f"{tmp_path / 'run'} is complete" in capsys.readouterr().err


def test_frames_and_fields_of_a_folder_without_manifest_are_cfm_files(tmp_path):
    out = tmp_path / "copied"  # `cp run/* copied/` leaves the manifest (a dot file) behind
    out.mkdir()
    _write(out, **{"summary.json": '{"units": {}}', "fields.json": "old", "specimen_0020.vtu": "old",
                   "impactor_0020.vtu": "old", "fitted-scene.toml": "old", "mine.vtk": "x"})
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "new", "specimen_0000.vtu": "new", "impactor_0000.vtu": "new"})
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [MANIFEST, "summary.json", "specimen_0000.vtu", "impactor_0000.vtu", "mine.vtk"])


def test_a_sweep_clearing_a_runs_folder_says_what_it_replaces(tmp_path, capsys):
    from cfm_core.studies.outcomes import clear_earlier_output

    out = tmp_path / "dt"
    _earlier_run(out)
    clear_earlier_output(out, keep=("runs",))
    assert "held the output of a run (3 files); it is replaced by this sweep's" in capsys.readouterr().err
    assert list(out.iterdir()) == []


def test_the_keeps_note_never_names_files_the_publication_removes(tmp_path, capsys):
    """A fit written into a run's folder said "keeps reaction.csv, reaction.png, summary.json" and removed them."""
    out = tmp_path / "se"
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "run", "reaction.csv": "run", "reaction.png": "run"})
    (out / "cut.png").write_text("mine")
    capsys.readouterr()
    with staged_folder(out) as stage:
        _write(stage, **{"fit.json": "fit", "fitted-scene.toml": "fit"})
    err = capsys.readouterr().err
    assert "held the output of a run (3 files); it is replaced by this fit's" in err
    assert "keeps cut.png, not written" in err and "reaction.csv" not in err.split("keeps", 1)[1]
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "cut.png", "fit.json", "fitted-scene.toml"])


def test_an_output_never_removes_or_replaces_a_file_the_command_reads(tmp_path, capsys):
    """A fit into the folder of an earlier run removed that run's files, the scene.toml the fit read among them.
    An input that publishing would remove or replace is refused, naming it; ``out`` stays as it was."""
    out = tmp_path / "run"
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "run", "scene.toml": "run", "acceleration.csv": "run"})
    (out / "runs").mkdir()  # a folder its manifest lists (a sweep's cache), with a file a command reads
    (out / "runs" / "a.csv").write_text("run")
    manifest = json.loads((out / MANIFEST).read_text())
    (out / MANIFEST).write_text(json.dumps({**manifest, "files": [*manifest["files"], "runs"]}))
    (out / "data.csv").write_text("mine")
    before = sorted(p.name for p in out.iterdir())
    entered = []
    for read in (out / "scene.toml", tmp_path / "run" / ".." / "run" / "acceleration.csv", out / "runs" / "a.csv"):
        with pytest.raises(InputError) as err:
            with staged_folder(out, inputs=[None, read]):
                entered.append(read)  # never: refused before the work
        assert str(read) in str(err.value) and "a file this command reads" in str(err.value)
    assert "lies in runs/" in str(err.value)
    assert entered == [] and sorted(p.name for p in out.iterdir()) == before
    with pytest.raises(InputError, match="data.csv is a file of the same name as a file this command writes"):
        with staged_folder(out, inputs=[out / "data.csv"]) as stage:  # known only once the output is written
            _write(stage, **{"fit.json": "fit", "data.csv": "fit"})
    assert sorted(p.name for p in out.iterdir()) == before and (out / "data.csv").read_text() == "mine"
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no stage left
    capsys.readouterr()
    with staged_folder(out, inputs=[out / "data.csv"]) as stage:  # a foreign input: kept, and not called stale
        _write(stage, **{"fit.json": "fit"})
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "data.csv", "fit.json"])
    assert "keeps" not in capsys.readouterr().err
