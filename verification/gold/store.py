"""Stored gold references: ``verification/gold/data/<case>.json`` (JSON, SI units).

Each file: ``case`` (name), ``definition`` (scene, backend, overrides, options), ``record`` (see
:mod:`.record`), ``rtol``, ``commit`` (git commit that produced it), ``code`` (the code state:
version, commit, whether the checkout had uncommitted changes, source digest), ``inputs``
(digests of the case definition and of the material's definition), ``date``, ``checked`` (one
line: where the value was checked independently, :mod:`.checks`).

A reference is keyed by its content: it holds for the definition whose digest it records (the
regression test refuses one made for another definition), and it is written only from committed
code (:func:`code_state`; ``--allow-dirty`` says otherwise explicitly) after its independent
check passed.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import time
from pathlib import Path

from cfm_core import fingerprint

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


def inputs(name: str) -> dict:
    """Digests of what a case's reference depends on besides the code.

    Parameters
    ----------
    name : str
        A gold case name.

    Returns
    -------
    dict
        ``definition`` (digest of the case: scene, overrides, backend, options, check) and
        ``material`` (name and definition digest of its material,
        :func:`cfm_core.material.cache.spec_fingerprint`).
    """
    from cfm_core.material.cache import spec_fingerprint
    from cfm_core.material.registry import get_material

    c = _BY_NAME[name]
    material = c.overrides.get("material", "cfm")
    return {"definition": fingerprint.digest(dataclasses.asdict(c)),
            "material": {"name": material, "definition_digest": spec_fingerprint(get_material(material))}}


def code_state() -> dict:
    """The running code, as a reference records it: :func:`cfm_core.fingerprint.code_state`, with
    ``dirty`` counting uncommitted changes outside the references' own folder (an update writes
    them one by one).

    Returns
    -------
    dict
        ``version``, ``commit`` (None outside a checkout), ``dirty`` (bool, or None outside a
        checkout), ``source_digest``.
    """
    state = dict(fingerprint.code_state())
    if state.get("commit"):
        root = DATA.parent.parent.parent
        try:
            out = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--",
                                  ".", f":(exclude){DATA.relative_to(root).as_posix()}"],
                                 capture_output=True, text=True, timeout=10)
            state["dirty"] = bool(out.stdout.strip()) if out.returncode == 0 else state["dirty"]
        except (OSError, subprocess.SubprocessError, ValueError):
            pass
    return state


def stamp(state: dict) -> str:
    """The ``commit`` field of a reference: the commit, and "(with uncommitted changes)" if dirty."""
    return (state.get("commit") or "unknown") + (" (with uncommitted changes)" if state.get("dirty") else "")


def why_rewrite(name: str, old: dict | None) -> str | None:
    """Why ``--update`` must rewrite a reference even when its values are unchanged, or None.

    Parameters
    ----------
    name : str
        A gold case name.
    old : dict or None
        The stored reference (:func:`load`).

    Returns
    -------
    str or None
        "no stored reference", "not checked", "stamped with uncommitted changes", "made for
        another definition of the case", or None when it stands.
    """
    if old is None:
        return "no stored reference"
    if old.get("checked") is None:
        return "not checked"
    if "uncommitted" in str(old.get("commit")) or (old.get("code") or {}).get("dirty"):
        return "stamped with uncommitted changes"
    if old.get("definition") != dataclasses.asdict(_BY_NAME[name]):
        return "made for another definition of the case"
    return None


def save(name: str, record: dict, raw: dict, state: dict | None = None) -> Path:
    """Run the case's independent check (CheckFailed propagates: nothing written), then write.

    state: the code state recorded (default :func:`code_state` now; an update computes it once
    before it writes, since every written file changes the tree)."""
    from cfm_core.post.writers import write_json

    c = _BY_NAME[name]
    checked = CHECKS[c.check](c, raw)
    state = state or code_state()
    DATA.mkdir(parents=True, exist_ok=True)
    doc = {"case": name, "definition": dataclasses.asdict(c), "record": record, "rtol": RTOL,
           "commit": stamp(state), "code": state, "inputs": inputs(name),
           "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "checked": checked}
    write_json(path(name), doc)
    return path(name)
