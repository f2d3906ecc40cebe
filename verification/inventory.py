"""Which backends the suite can use: every registered backend, with the reason when it cannot run.

A backend that fails to import or whose ``available()`` is False is *listed* with the reason, never
silently skipped. Backends the design names (docs/conventions.md section 1) but nobody has registered yet are
listed too, as "not registered".
"""

from __future__ import annotations

import warnings

#: Backends the design promises; listed as "not registered" when no plugin provides them.
EXPECTED = ("numpy", "numba", "torch", "skfem")


def discover(selected=None) -> list[dict]:
    """One dict per backend: name, kind, status ("available" | "unavailable" | "broken" |
    "not registered" | "not selected"), reason, can_point, can_run, instance (or None)."""
    from cfm_core import plugins as registry
    from cfm_core.simulation.backend import Backend

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        table = registry.entries("backends")
    names = sorted(set(table) | set(EXPECTED))
    out = []
    for name in names:
        row = {"name": name, "kind": "?", "status": "", "reason": "", "can_point": False, "can_run": False,
               "instance": None}
        if name not in table:
            row.update(status="not registered", reason="no plugin in the 'cfm.backends' entry-point group "
                       "(nor a runtime registration) provides it")
        else:
            cls, err = table[name]
            if err:
                row.update(status="broken", reason=err)
            else:
                row["kind"] = cls.kind
            if not err and getattr(cls, "experimental", False) and (selected is None or name not in selected):
                # optional and not yet complete (calculix): neither run nor required unless named
                row.update(status="not selected", reason=f"experimental backend: verified when named "
                                                         f"(--backends {name})")
            elif not err:
                try:
                    inst = cls()
                    ok, why = inst.available()
                except Exception as exc:  # a backend's own check failing is itself a finding
                    ok, why, inst = False, f"available() raised {type(exc).__name__}: {exc}", None
                if not ok:
                    row.update(status="unavailable", reason=why)
                elif selected is not None and name not in selected:
                    row.update(status="not selected", reason="left out by --backends")
                else:
                    row.update(status="available", instance=inst,
                               can_point=type(inst).point is not Backend.point,
                               can_run=type(inst).run is not Backend.run)
        out.append(row)
    if selected:
        unknown = sorted(set(selected) - set(names))
        if unknown:
            from cfm_core.errors import InputError

            raise InputError(f"--backends names unknown backend(s) {', '.join(unknown)}; known: {', '.join(names)}.")
    return out


def usable(rows, what: str) -> list[dict]:
    """The available rows that can do ``what`` ("point" or "run")."""
    return [r for r in rows if r["status"] == "available" and r[f"can_{what}"]]
