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
    _write(out, **{"summary.json": "old", "acceleration.png": "old", "specimen_0003.vtu": "old", "keep.me": "x"})
    with staged_folder(out) as stage:
        _write(stage, **{"summary.json": "new"})
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "summary.json", "keep.me"])


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
