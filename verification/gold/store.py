"""Stored gold references: ``verification/gold/data/<case>.json`` (JSON, SI units).

Each file: ``case`` (name), ``definition`` (scene, backend, overrides, options), ``record`` (see
:mod:`.record`), ``rtol``, ``commit`` (git commit that produced it), ``date``, ``checked`` (one
line: where the value was checked independently, :mod:`.checks`).
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

from . import RTOL
from .cases import CASES
from .checks import CHECKS
from .record import run_case

DATA = Path(__file__).resolve().parent / "data"
_BY_NAME = {c.name: c for c in CASES}


def case_names() -> list[str]:
    return [c.name for c in CASES]


def case(name: str):
    return _BY_NAME[name]


def path(name: str) -> Path:
    return DATA / f"{name}.json"


def load(name: str) -> dict | None:
    p = path(name)
    return json.loads(p.read_text(encoding="utf-8")) if p.is_file() else None


def compute(name: str) -> tuple[dict, dict]:
    """(record, raw) of the named case, computed now."""
    return run_case(_BY_NAME[name])


def save(name: str, record: dict, raw: dict, commit: str | None = None) -> Path:
    """Run the case's independent check (CheckFailed propagates: nothing written), then write.
    commit: the stamp (default: ``git rev-parse HEAD`` now; an update computes it once before it
    writes, since every written file makes the tree dirty)."""
    from cfm_core.post.writers import write_json

    from ..machine import git_commit

    c = _BY_NAME[name]
    checked = CHECKS[c.check](c, raw)
    DATA.mkdir(parents=True, exist_ok=True)
    doc = {"case": name, "definition": dataclasses.asdict(c), "record": record, "rtol": RTOL,
           "commit": commit or git_commit(), "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "checked": checked}
    write_json(path(name), doc)
    return path(name)
