"""The numba element pass of this tree's kernels against another git revision's, in one process.

    python -m cfm_verification.benchmarks.numba --against REV [--size 0.001] [--repeat 15]

On a shared machine whole runs in separate processes move by 30-40 % within the hour, more than
most kernel changes gain. Here both versions of ``backends/numba_explicit/kernels/*.py`` are
compiled into one process (the revision's files read with ``git show``, each version a generated
module of its own; the first run of a revision compiles, 1-2 min), the drop test (8 mm, one
thread) is advanced to t = 0.8 ms once, and the element pass of each version is timed at that
state in turns (``repeat`` rounds, each a stretch of passes on copies of the state; CPU time of
the process). Printed per version: the best round and the mean of the best third (ns per
element, one thread), their ratio to this tree's, and whether one pass gives the same bits (the
stress work, the force buffer and the element state).

The two versions must share the constants of ``kernels/layout.py`` (its comments may differ): the
state arrays are prepared by this tree's solver, and a revision whose layout differs would read
them wrongly, so it is refused.
"""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import numpy as np

from cfm_core.errors import InputError


def revision_files(rev: str) -> dict:
    """The text of each kernel file (``codegen.KERNEL_FILES``) at git revision ``rev``.

    Raises
    ------
    InputError
        ``rev`` is not a revision of the repository this tree is in, a kernel file is missing
        there, or its ``layout.py`` differs from this tree's.
    """
    from cfm_backends.numba_explicit import codegen

    root = Path(codegen.KERNELS_DIR)
    files = {}
    for name in codegen.KERNEL_FILES:
        try:   # "REV:./name": the path relative to the kernel folder, wherever the repository is
            proc = subprocess.run(["git", "show", f"{rev}:./{name}"], cwd=root, capture_output=True, text=True)
        except FileNotFoundError:
            raise InputError("--against: git is not installed; it reads the other revision's kernels.") from None
        if proc.returncode != 0:
            raise InputError(f"--against {rev!r}: git cannot show kernels/{name} at that revision "
                             f"({proc.stderr.strip() or 'no output'}); give a commit, tag or branch of this "
                             f"repository whose numba kernels have that file.")
        files[name] = proc.stdout
    if _constants(files["layout.py"]) != _constants((root / "layout.py").read_text()):
        raise InputError(f"--against {rev!r}: kernels/layout.py differs at that revision; the state arrays "
                         f"this tree prepares do not fit its kernels, so its element pass cannot be timed "
                         f"here (compare whole runs of the two checkouts instead).")
    return files


def _constants(text: str) -> dict:
    """The upper-case names a ``layout.py`` text defines and their values (its comments and
    docstrings aside: two layouts that differ only there fit the same arrays)."""
    names: dict = {}
    exec(compile(text, "layout.py", "exec"), names)
    return {k: v for k, v in names.items() if k.isupper()}


def compare(rev: str, size: float = 1e-3, repeat: int = 15, say=print) -> dict:
    """Time the element pass of this tree's kernels and of revision ``rev``'s (module docstring).

    Parameters
    ----------
    rev : str
        A git revision (commit, tag, branch) of this repository.
    size : float
        Element size (m) of the built-in drop test (8 mm specimen).
    repeat : int
        Rounds; each round times both versions, one after the other.

    Returns
    -------
    dict
        ``{"this": {...}, rev: {...}}``, each with best and third (ns per element: the best
        round, the mean of the best third) and same (bool: one pass gives this tree's bits).
    """
    from cfm_backends.numba_explicit import codegen, solver

    from .scale import drop_model, element_pass_args, one_thread_run

    files = revision_files(rev)
    model = drop_model(size)
    with one_thread_run(model, 8e-4) as (this, prep, _hist):   # this tree's kernels, the state at 0.8 ms
        t0 = time.perf_counter()
        other = codegen.load(model.material, files)
        solver.warm_up(other, model.material)
        say(f"kernels of {rev}: loaded or compiled in {time.perf_counter() - t0:.1f} s", flush=True)
        mods = {"this": this, rev: other}
        x, v, ed, eh, fb = prep.st[0], prep.st[1], prep.st[3], prep.st[4], prep.st[5]
        ne = model.n_elements
        passes = max(2, int(2e6 // ne))
        times = {name: [] for name in mods}
        first = {}
        for r in range(repeat):
            for name, mod in mods.items():
                copies = (ed.copy(), eh.copy(), fb.copy())
                args = element_pass_args(this, prep, x, v, *copies)
                out = mod.element_pass(*args)
                if r == 0:
                    first[name] = (out, *(c.copy() for c in copies))
                c0 = time.process_time()
                for _ in range(passes):
                    mod.element_pass(*args)
                times[name].append((time.process_time() - c0) / passes / ne * 1e9)
    ref = first["this"]
    result = {}
    for name in mods:
        t = np.sort(times[name])
        got = first[name]
        same = got[0] == ref[0] and all(np.array_equal(a, b) for a, b in zip(got[1:], ref[1:]))
        result[name] = {"best": float(t[0]), "third": float(t[:max(1, len(t) // 3)].mean()), "same": bool(same)}
    return result


def report(rev: str, size: float = 1e-3, repeat: int = 15, say=print) -> None:
    """Print :func:`compare`'s table (ns per element, one thread) and the load average."""
    import os

    res = compare(rev, size, max(repeat, 1), say)
    base = res["this"]
    say(f"element pass, one thread, drop test (8 mm, {size * 1e3:g} mm elements) at t = 0.8 ms, {repeat} rounds "
        f"in turns (load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores):")
    for name, r in res.items():
        ratio = "" if name == "this" else (f"  ({r['best'] / base['best']:.3f} / {r['third'] / base['third']:.3f} "
                                           f"x this tree's)")
        bits = "" if name == "this" else ("  same bits" if r["same"] else "  DIFFERENT results")
        say(f"  {name:>12}: best {r['best']:7.1f} ns, best third {r['third']:7.1f} ns per element{ratio}{bits}")
