"""The suite's verdict: PASSED, FAILED or INCOMPLETE, with the message of every check behind it.

- FAILED (exit 1): a check missed its tolerance or its expected outcome, or a backend named in
  ``--require`` (or the environment variable ``CFM_VERIFY_REQUIRE``) is not available.
- INCOMPLETE (exit 4): no check failed, but something that should have run did not: a backend in
  scope that is not installed, unavailable, broken or not registered; a run skipped by the
  budget; a section left out. A suite that did not look cannot pass.
- PASSED (exit 0): every check ran, on every backend in scope, and met its tolerance.

Rows are the dicts of the sections (agreement, stability, drucker, paper-stored): ``passed`` True,
False or None (not run, with the reason in ``error`` or ``verdict``); rows with ``informational``
set (a pair that shares the code, stated as such) do not count.
"""

from __future__ import annotations

import os

EXIT = {"PASSED": 0, "FAILED": 1, "INCOMPLETE": 4}
#: Environment variable with the comma-separated backends a CI run requires (cfm verify --require).
REQUIRE_ENV = "CFM_VERIFY_REQUIRE"


def required_from_env() -> list[str]:
    """Backends named in $CFM_VERIFY_REQUIRE (comma-separated), [] when unset or empty."""
    return [s.strip() for s in os.environ.get(REQUIRE_ENV, "").split(",") if s.strip()]


def _name(section: str, r: dict) -> str:
    if section == "agreement":
        who = r["b"] if r["a"] == r["b"] else f"{r['b']} vs {r['a']}"
        return f"agreement / {r['check']} / {r['case']} / {who}"
    if section == "stability":
        return f"stability / {r['case']} / {r['backend']}"
    case = f" / {r['case']}" if r.get("case") and r.get("case") != r.get("check") else ""
    return f"{section} / {r.get('check', '?')}{case}"


def _why(r: dict) -> str:
    return r.get("reason") or r.get("error") or r.get("verdict") or ""


def decide(sections: dict, inventory: list[dict], required=(), not_run_sections=()) -> dict:
    """Verdict of one suite run.

    sections: {"agreement": rows, "stability": rows, ...}; inventory: rows of
    :func:`.inventory.discover`; required: backend names that must be available;
    not_run_sections: names of sections left out (each makes the run INCOMPLETE).
    Returns {"verdict", "exit_code", "failed": [str], "incomplete": [str], "checks": int}.
    """
    failed, incomplete, n = [], [], 0
    for section, rows in sections.items():
        for r in rows:
            if r.get("informational"):
                continue
            n += 1
            if r.get("passed") is None:
                incomplete.append(f"{_name(section, r)}: not run: {_why(r)}")
            elif not r["passed"]:
                failed.append(f"{_name(section, r)}: {_why(r)}")
    by_name = {b["name"]: b for b in inventory}
    for b in inventory:
        if b["status"] not in ("available", "not selected"):
            incomplete.append(f"inventory / backend '{b['name']}' is {b['status']}: {b['reason']}")
    for name in required:
        b = by_name.get(name)
        if b is None or b["status"] != "available":
            status = "not registered" if b is None else b["status"]
            failed.append(f"inventory / required backend '{name}' is {status}"
                          f"{': ' + b['reason'] if b is not None and b['reason'] else ''} (--require / ${REQUIRE_ENV})")
    for s in not_run_sections:
        incomplete.append(f"{s}: section not run")
    verdict = "FAILED" if failed else ("INCOMPLETE" if incomplete else "PASSED")
    return {"verdict": verdict, "exit_code": EXIT[verdict], "failed": failed, "incomplete": incomplete, "checks": n}
