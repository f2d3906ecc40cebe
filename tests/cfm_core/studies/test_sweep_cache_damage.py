"""cfm sweep: a damaged run cache entry is run again (a note, never a traceback or an "ok" row without
numbers), and --vary values that look like a decimal comma are refused with a clear message."""

import json
import shutil

import pytest

from cfm_core.cli import main
from cfm_core.errors import InputError
from cfm_core.studies import sweep

pytest.importorskip("numba")

VARY = "thickness=0.005,0.006"
TIMES = ("run_time", "wall_time")  # differ from run to run; everything else must be equal




@pytest.fixture(scope="module")
def reference(scene_file, tmp_path_factory):
    """An undamaged sweep of two runs: its folder and its run ids (product order)."""
    out = tmp_path_factory.mktemp("reference") / "sweep"
    assert main(["sweep", "--scene", scene_file, "--serial", "--quiet", "--out", str(out), "--vary", VARY]) == 0
    return out, json.loads((out / "sweep.json").read_text())["run_ids"]


def _numbers(path):
    """The table without the run times (s), which differ from run to run."""
    return [{k: v for k, v in row.items() if k.split(" ")[0] not in TIMES} for row in sweep.read_table(path)]


def _truncate_mid_line(entry):
    text = (entry / "acceleration.csv").read_text()
    (entry / "acceleration.csv").write_text(text[: len(text) // 2 + 7])


def _cut_after_rows(entry, rows=40):
    lines = (entry / "acceleration.csv").read_text().splitlines(keepends=True)
    (entry / "acceleration.csv").write_text("".join(lines[: rows + 1]))


def _summary_edit(**changes):
    def damage(entry):
        summary = json.loads((entry / "summary.json").read_text())
        summary.update(changes)
        (entry / "summary.json").write_text(json.dumps(summary))
    return damage


def _replace_with_folder(entry):
    (entry / "summary.json").unlink()
    (entry / "summary.json").mkdir()


def _entry_is_a_file(entry):
    shutil.rmtree(entry)
    entry.write_text("")


DAMAGE = {
    "empty summary.json": lambda e: (e / "summary.json").write_text(""),
    "broken JSON": lambda e: (e / "summary.json").write_text("{broken\n"),
    "empty JSON object": lambda e: (e / "summary.json").write_text("{}\n"),
    "JSON list": lambda e: (e / "summary.json").write_text("[1, 2]\n"),
    "not UTF-8": lambda e: (e / "summary.json").write_bytes(b"\xff\xfe{"),
    "peak_g null": _summary_edit(peak_g=None),
    "run_time missing": _summary_edit(run_time="fast"),
    "another run's summary": _summary_edit(run_id="000000000000"),
    "other values": _summary_edit(sweep={"thickness": 0.007}),
    "energy_error text": _summary_edit(energy_error="n/a"),
    "acceleration.csv missing": lambda e: (e / "acceleration.csv").unlink(),
    "acceleration.csv empty": lambda e: (e / "acceleration.csv").write_text(""),
    "acceleration.csv cut mid-line": _truncate_mid_line,
    "acceleration.csv cut before the pulse ends": _cut_after_rows,
    "summary.json is a folder": _replace_with_folder,
    "the entry is a file": _entry_is_a_file,
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_entry_is_run_again_and_the_table_is_the_undamaged_one(reference, scene_file, tmp_path, capsys,
                                                                          damage):
    ref, ids = reference
    out = tmp_path / "sweep"
    shutil.copytree(ref, out)
    entry = out / "runs" / ids[0]
    DAMAGE[damage](entry)
    capsys.readouterr()
    assert main(["sweep", "--scene", scene_file, "--serial", "--quiet", "--out", str(out), "--vary", VARY]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("note: run cache entry")]
    assert len(notes) == 1 and ids[0] in notes[0] and "thickness=0.005" in notes[0]
    assert "running it again" in notes[0] and "Traceback" not in err and ids[1] not in err
    record = json.loads((out / "sweep.json").read_text())
    assert record["run_ids"] == ids and record["executed"] == 1 and record["skipped"] == 1
    assert record["ok"] == 2 and record["failed"] == 0
    assert _numbers(out / "sweep.csv") == _numbers(ref / "sweep.csv")  # the same numbers as the undamaged sweep
    # the damaged files were replaced by the run's: the entry is complete again
    summary, why = sweep.cached_summary(entry, ids[0], {"thickness": 0.005})
    assert why is None and summary["run_id"] == ids[0]
    assert (entry / "acceleration.csv").read_text() == (ref / "runs" / ids[0] / "acceleration.csv").read_text()
    # and a further rerun computes nothing and notes nothing
    assert main(["sweep", "--scene", scene_file, "--serial", "--quiet", "--out", str(out), "--vary", VARY]) == 0
    assert "note: run cache entry" not in capsys.readouterr().err
    assert json.loads((out / "sweep.json").read_text())["executed"] == 0


def test_complete_entries_are_reused_without_a_note(reference, scene_file, tmp_path, capsys):
    ref, ids = reference
    out = tmp_path / "sweep"
    shutil.copytree(ref, out)
    for rid, t in zip(ids, (0.005, 0.006)):
        summary, why = sweep.cached_summary(out / "runs" / rid, rid, {"thickness": t})
        assert why is None and summary["thickness"] == t
    capsys.readouterr()
    assert main(["sweep", "--scene", scene_file, "--serial", "--quiet", "--out", str(out), "--vary", VARY]) == 0
    assert "note:" not in capsys.readouterr().err
    assert json.loads((out / "sweep.json").read_text())["executed"] == 0
    assert _numbers(out / "sweep.csv") == _numbers(ref / "sweep.csv")


def test_an_entry_whose_summary_has_a_byte_order_mark_is_complete(reference, tmp_path):
    """summary.json saved again with a UTF-8 BOM ("Unexpected UTF-8 BOM") was damage and run again; a
    number beyond the float range in it gave an OverflowError traceback."""
    ref, ids = reference
    entry = shutil.copytree(ref / "runs" / ids[0], tmp_path / "entry")
    text = (entry / "summary.json").read_text(encoding="utf-8")
    (entry / "summary.json").write_text(text, encoding="utf-8-sig")
    summary, why = sweep.cached_summary(entry, ids[0], {"thickness": 0.005})
    assert why is None and summary == json.loads(text)
    (entry / "summary.json").write_text(json.dumps({**json.loads(text), "peak_g": 10 ** 400}))
    summary, why = sweep.cached_summary(entry, ids[0], {"thickness": 0.005})
    assert summary is None and "lacks finite numbers for peak_g" in why


def test_missing_entries_are_not_damage(tmp_path):
    assert sweep.cached_summary(tmp_path / "none", "abc", {"k2": 1.0}) == (None, None)
    (tmp_path / "failed").mkdir()
    (tmp_path / "failed" / "failed.json").write_text("{}")
    assert sweep.cached_summary(tmp_path / "failed", "abc", {"k2": 1.0}) == (None, None)


@pytest.mark.parametrize("vary, meant", [
    ("thickness=0,005", "0.005"),
    ("velocity=0,5", "0.5"),
    ("k2=1,05", "1.05"),
    ("k2=5,0", "5.0"),
    ("thickness=0,005,0,006", "0.005"),
])
def test_a_decimal_comma_is_refused_with_exit_2(scene_file, tmp_path, capsys, vary, meant):
    out = tmp_path / "sweep"
    assert main(["sweep", "--scene", scene_file, "--serial", "--quiet", "--out", str(out), "--vary", vary]) == 2
    err = capsys.readouterr().err
    assert f"--vary {vary}:" in err and "decimal comma" in err
    assert f"if you meant {meant} write a decimal point" in err and "values are separated by commas" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_the_two_value_reading_can_still_be_written(scene):
    with pytest.raises(InputError, match=r"To sweep the two values 0 and 5 m, write one with a decimal point "
                                         r"\(thickness=0\.0,005\)"):
        sweep.parse_vary(["thickness=0,005"], scene)
    (axis,) = sweep.parse_vary(["friction=0.0,5"], scene)
    assert axis.values == (0.0, 5.0)  # taken as written (then refused by the friction range, below)


@pytest.mark.parametrize("vary, values", [
    ("k2=1,2", (1.0, 2.0)),
    ("k1=1000,1320", (1000.0, 1320.0)),
    ("c=10,100", (10.0, 100.0)),
    ("velocity=1,5", (1.0, 5.0)),
    ("friction=0,0.1", (0.0, 0.1)),
    ("thickness=0.005,0.006", (0.005, 0.006)),
    ("k2=1.0,05", (1.0, 5.0)),
    ("k2=1,2,3", (1.0, 2.0, 3.0)),
])
def test_legitimate_lists_are_taken_as_written(scene, vary, values):
    (axis,) = sweep.parse_vary([vary], scene)
    assert axis.values == values
    sweep.check_cases(scene, [axis])


@pytest.mark.parametrize("vary, message", [
    ("k1=1,x", "value 'x' is not a number"),
    ("k2=1,1", "a value is repeated"),
    ("thickness=0.005,-1", "value -1.0 m is not allowed"),
    ("friction=0.0,5", "value 5.0 is not allowed"),
    ("velocity=1,inf", "is not a finite number"),
])
def test_every_error_about_a_comma_list_mentions_the_decimal_comma(scene, vary, message):
    with pytest.raises(InputError, match=message) as info:
        axes = sweep.parse_vary([vary], scene)
        sweep.check_cases(scene, axes)
    assert "decimal comma" in str(info.value) and "separated by commas" in str(info.value)


def test_single_values_and_python_lists_get_no_comma_reminder(scene):
    with pytest.raises(InputError) as info:
        sweep.check_cases(scene, sweep.parse_vary(["thickness=-1"], scene))
    assert "comma" not in str(info.value)
    with pytest.raises(InputError) as info:
        sweep.check_cases(scene, sweep.parse_vary({"thickness": [0.005, -1.0]}, scene))
    assert "comma" not in str(info.value)
