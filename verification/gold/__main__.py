"""``python -m cfm_verification.gold [--update] [--only TEXT]``: compare the gold cases with their
stored references (exit 1 on a difference) or rewrite the references after an intended change,
printing every difference first. See :mod:`cfm_verification.gold`."""

from __future__ import annotations

import argparse
import sys
import time

from . import RTOL
from .store import case_names, compute, load, save
from .record import compare


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cfm_verification.gold", description=__doc__.splitlines()[0])
    parser.add_argument("--update", action="store_true",
                        help="rewrite the references of the selected cases (after their independent checks pass)")
    parser.add_argument("--force", action="store_true",
                        help="with --update: rewrite every selected reference, also the unchanged ones (new commit stamp)")
    parser.add_argument("--only", default="", metavar="TEXT", help="only cases whose name contains TEXT")
    parser.add_argument("--rtol", type=float, default=RTOL, help=f"relative tolerance (-), default {RTOL:g}")
    args = parser.parse_args(argv)
    names = [n for n in case_names() if args.only in n]
    if not names:
        print(f"no gold case name contains {args.only!r}", file=sys.stderr)
        return 2
    from ..machine import git_commit

    commit = git_commit()  # before anything is written
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
        wall = time.perf_counter() - t0
        print(f"{name}: {'same' if not diffs else 'DIFFERENT'} ({wall:.1f} s)")
        for d in diffs:
            print(f"    {d}")
        changed += bool(diffs)
        if args.update and (diffs or args.force or old is None or old.get("checked") is None):
            try:
                path = save(name, rec, raw, commit)
            except AssertionError as exc:
                print(f"    NOT WRITTEN: the independent check failed: {exc}")
                failed += 1
                continue
            print(f"    written {path}")
    print(f"{len(names)} cases, {changed} different, {failed} errors" + (" (references updated)" if args.update else ""))
    return 1 if failed or (changed and not args.update) else 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
