"""``python -m cfm_verification.gold --update`` writes a reference only from committed code and
only after its independent check passed; what it writes records the code and the inputs.

Old code: the update stamped "(with uncommitted changes)" and wrote (4 of 43 references carried
it), and nothing refused such a reference afterwards."""

import copy
import json
import shutil

import numpy as np
import pytest

from cfm_verification.gold import __main__ as gold_cli
from cfm_verification.gold import store

NAME = "point-cfm-visco-uniaxial-numpy"
CLEAN = {"version": "0.2.0", "commit": "a" * 40, "dirty": False, "source_digest": "b" * 24}


@pytest.fixture
def data(tmp_path, monkeypatch):
    """The references folder replaced by a copy of one reference."""
    shutil.copy(store.path(NAME), tmp_path / f"{NAME}.json")
    monkeypatch.setattr(store, "DATA", tmp_path)
    return tmp_path / f"{NAME}.json"


def test_update_refuses_code_with_uncommitted_changes_before_computing(data, monkeypatch, capsys):
    before = data.read_bytes()
    monkeypatch.setattr(gold_cli, "code_state", lambda: {**CLEAN, "dirty": True})
    monkeypatch.setattr(gold_cli, "compute", lambda name: pytest.fail("computed although refused"))
    assert gold_cli.main(["--update", "--force", "--only", NAME]) == 2
    err = capsys.readouterr().err
    assert "refusing --update: the code has uncommitted changes" in err and "--allow-dirty" in err
    assert data.read_bytes() == before
    monkeypatch.setattr(gold_cli, "code_state", lambda: {**CLEAN, "commit": None, "dirty": None})
    assert gold_cli.main(["--update", "--only", NAME]) == 2
    assert "not a git checkout" in capsys.readouterr().err and data.read_bytes() == before


def test_allow_dirty_writes_a_stamped_reference_that_the_regression_test_refuses(data, monkeypatch):
    monkeypatch.setattr(gold_cli, "code_state", lambda: {**CLEAN, "dirty": True})
    assert gold_cli.main(["--update", "--force", "--allow-dirty", "--only", NAME]) == 0
    doc = json.loads(data.read_text())
    assert doc["commit"] == "a" * 40 + " (with uncommitted changes)" and doc["code"]["dirty"] is True
    assert store.why_rewrite(NAME, doc) == "stamped with uncommitted changes"
    # from clean code, the next update rewrites it although its values are the same
    monkeypatch.setattr(gold_cli, "code_state", lambda: dict(CLEAN))
    assert gold_cli.main(["--update", "--only", NAME]) == 0
    doc = json.loads(data.read_text())
    assert doc["commit"] == "a" * 40 and store.why_rewrite(NAME, doc) is None
    assert doc["code"] == CLEAN and doc["inputs"] == store.inputs(NAME)


def test_update_refuses_a_reference_whose_independent_check_fails(data, monkeypatch, capsys):
    """A faulty build (1 % more stress) changes the record; the truth check refuses to write it."""
    before = data.read_bytes()
    real = store.compute

    def faulty(name):
        rec, raw = real(name)
        raw = {**raw, "stress": raw["stress"] * 1.01}
        rec = copy.deepcopy(rec)
        rec["peak"] *= 1.01
        rec["samples"] = (np.asarray(rec["samples"]) * 1.01).tolist()
        return rec, raw

    monkeypatch.setattr(gold_cli, "code_state", lambda: dict(CLEAN))
    monkeypatch.setattr(gold_cli, "compute", faulty)
    assert gold_cli.main(["--update", "--only", NAME]) == 1
    out = capsys.readouterr().out
    assert "DIFFERENT" in out and "NOT WRITTEN: the independent check failed" in out and "1 errors" in out
    assert data.read_bytes() == before


def test_a_reference_made_for_another_definition_must_be_rewritten(data):
    doc = json.loads(data.read_text())
    assert store.why_rewrite(NAME, doc) is None
    doc["definition"]["overrides"]["history"] = "simple shear"
    assert store.why_rewrite(NAME, doc) == "made for another definition of the case"


def test_inputs_digest_the_case_and_its_material():
    a, b = store.inputs(NAME), store.inputs("point-cfm-septa-visco-uniaxial-numpy")
    assert a["material"]["name"] == "cfm" and b["material"]["name"] == "cfm-septa"
    assert a["definition"] != b["definition"] and a["material"]["definition_digest"] != b["material"]["definition_digest"]
