"""Content fingerprints (cfm_core.fingerprint): contents, not names, decide the hash."""

import math

import numpy as np

from cfm_core import fingerprint as fp


def test_file_digest_follows_contents_not_name(tmp_path):
    a, b = tmp_path / "a.msh", tmp_path / "b.msh"
    a.write_bytes(b"mesh one")
    b.write_bytes(b"mesh one")
    assert fp.file_digest(a) == fp.file_digest(b)
    b.write_bytes(b"mesh two")
    assert fp.file_digest(a) != fp.file_digest(b)
    assert fp.file_digest(a) == fp.digest_bytes(b"mesh one")


def test_digest_is_order_free_and_exact():
    assert fp.digest({"a": 1.0, "b": [1, 2]}) == fp.digest({"b": [1, 2], "a": 1.0})
    assert fp.digest({"k2": 1.66}) != fp.digest({"k2": 1.66 + 2e-16})
    assert fp.digest({"x": np.float64(0.1)}) == fp.digest({"x": 0.1})
    assert fp.digest({"x": math.inf}) != fp.digest({"x": -math.inf})


def test_code_state_names_version_commit_and_source():
    s = fp.code_state()
    assert set(s) == {"version", "commit", "dirty", "source_digest"}
    assert len(s["source_digest"]) == 24
    assert s["source_digest"] == fp.source_digest()
    assert fp.DISTRIBUTION in fp.code_label(s)
    assert "uncommitted" in fp.code_label({**s, "commit": "0" * 40, "dirty": True})
    assert "not a git checkout" in fp.code_label({**s, "commit": None, "dirty": None})


def test_source_digest_changes_with_any_source_edit(tmp_path, monkeypatch):
    for d in fp.PACKAGE_DIRS:
        (tmp_path / d).mkdir()
        (tmp_path / d / "m.py").write_text("x = 1\n")
    monkeypatch.setattr(fp, "_root", lambda: tmp_path)
    fp.source_digest.cache_clear()
    try:
        before = fp.source_digest()
        (tmp_path / "backends" / "m.py").write_text("x = 2\n")
        fp.source_digest.cache_clear()
        assert fp.source_digest() != before
    finally:
        fp.source_digest.cache_clear()
