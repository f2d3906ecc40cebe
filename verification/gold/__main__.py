"""``python -m cfm_verification.gold [--update] [--only TEXT]``: compare the gold cases with their
stored references (exit 1 on a difference) or rewrite the references after an intended change,
printing every difference first. See :mod:`cfm_verification.gold`.

``--update`` writes only from committed code (a reference names the commit that produced it, and
"with uncommitted changes" names none that can be checked out again): with uncommitted changes
outside the references' folder, or outside a git checkout, it refuses with exit 2 before
computing anything, unless ``--allow-dirty`` is given; a reference whose independent check fails
is never written (exit 1)."""

from __future__ import annotations

import argparse
import sys
import time

from . import RTOL
from .store import case_names, code_state, compute, load, save, why_rewrite
from .record import compare


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cfm_verification.gold", description=__doc__.splitlines()[0])
    parser.add_argument("--update", action="store_true",
                        help="rewrite the references of the selected cases (after their independent checks pass)")
    parser.add_argument("--force", action="store_true",
                        help="with --update: rewrite every selected reference, also the unchanged ones (new commit stamp)")
    parser.add_argument("--allow-dirty", action="store_true",
                        help="with --update: write references from code with uncommitted changes (stamped so)")
    parser.add_argument("--only", default="", metavar="TEXT", help="only cases whose name contains TEXT")
    parser.add_argument("--rtol", type=float, default=RTOL, help=f"relative tolerance (-), default {RTOL:g}")
    args = parser.parse_args(argv)
    names = [n for n in case_names() if args.only in n]
    if not names:
        print(f"no gold case name contains {args.only!r}", file=sys.stderr)
        return 2
    state = code_state()  # before anything is written
    if args.update and (state.get("dirty") or not state.get("commit")) and not args.allow_dirty:
        why = ("has uncommitted changes (git status)" if state.get("commit") else
               "is not a git checkout, so no commit names it")
        print(f"refusing --update: the code {why}; a reference records the commit that produced it and must be "
              f"reproducible from it. Commit the change first, or pass --allow-dirty to write references stamped "
              f"\"(with uncommitted changes)\" (the regression test then refuses them until they are rewritten "
              f"from a commit).", file=sys.stderr)
        return 2
    changed, failed = 0, 0
    for name in names:
        t0 = time.perf_counter()
        try:
            rec, raw = compute(name)
        except Exception as exc:  # reported per case, the others go on
            print(f"{name}: ERROR {type(exc).__name__}: {exc}")
            failed += 1
            continue
        old = load(name)
        diffs = compare(rec, old["record"], args.rtol) if old else ["no stored reference"]
        stale = why_rewrite(name, old)
        wall = time.perf_counter() - t0
        print(f"{name}: {'same' if not diffs else 'DIFFERENT'} ({wall:.1f} s)"
              + (f"; the reference must be rewritten: {stale}" if stale and old else ""))
        for d in diffs:
            print(f"    {d}")
        changed += bool(diffs or stale)
        if args.update and (diffs or args.force or stale):
            try:
                path = save(name, rec, raw, state)
            except AssertionError as exc:
                print(f"    NOT WRITTEN: the independent check failed: {exc}")
                failed += 1
                continue
            print(f"    written {path}")
    print(f"{len(names)} cases, {changed} different, {failed} errors" + (" (references updated)" if args.update else ""))
    return 1 if failed or (changed and not args.update) else 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
