"""Phases of a warm ``cfm drop-test`` end to end (kernels compiled and in the disk cache).

    python -m cfm_verification.benchmarks.startup [--thickness 0.008] [--size 0.001] [--repeat 3]

Runs the command in fresh processes, as a user does, and splits each run's wall time into phases
that add up to it: interpreter start-up, imports of the ``cfm`` command, command line (parser,
``cfm.commands`` entry points, scene), model, backend look-up (``cfm.backends`` entry point,
backend package), numba import, kernels loaded (numba's cache look-up and its first-call set-up),
solve, other run set-up (arrays, checks, result), post-processing (end-of-run checks, CFC 600
filter, summary), writing, matplotlib import, plotting and exit (interpreter shut-down). The
instrumented process runs ``cfm_core.cli.main`` exactly as the ``cfm`` console script does, with
timestamps taken around the functions that bound each phase (wrapped from outside; nothing in the
package is changed) and ``time.time()`` across the process boundary. The uninstrumented console
script is timed in the same benchmark run, alternating with the instrumented one, so that the two
totals can be compared. The children run without ``PYTHONDONTWRITEBYTECODE`` (warm means Python's
bytecode cache too). Where :mod:`cfm_core.post.figure_process` draws the figure in a second
process, the matplotlib import is that process's (overlapping the run; the phase shows 0) and
'plotting' is the wait for the figure; the report says where the figure was drawn. Timings on a
loaded machine are meaningless: check ``uptime`` first.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: Target of issue 15, item 3: a warm ``cfm drop-test`` end to end, s.
TARGET_S = 2.0

#: The instrumented child: argv = [-c, phases.json, console-script entry point "module:function",
#: cfm arguments...]; it imports and calls the entry point as the console script does.
CHILD = r"""
import time
T, C = {"start": time.time()}, {"start": time.process_time()}
import importlib, json, sys
record, (module, _, function) = sys.argv[1], sys.argv[2].partition(":")
sys.argv = ["cfm", *sys.argv[3:]]
entry = getattr(importlib.import_module(module), function)

def now(key):
    T[key], C[key] = time.time(), time.process_time()

now("imported")
from cfm_core.runs import outcomes, pipeline
R = {}

def stamp(name, fn):
    def wrapped(*args, **kwargs):
        now(name + "0")
        try:
            return fn(*args, **kwargs)
        finally:
            now(name + "1")
    return wrapped

class TimedBackend:
    def __init__(self, backend):
        self._backend = backend
    def __getattr__(self, name):
        return getattr(self._backend, name)
    def run(self, model, **kwargs):
        now("run0")
        import numba  # the backend imports it first thing in run(); timed apart here
        now("numba")
        result = self._backend.run(model, **kwargs)
        now("run1")
        R["kernels"], R["solve"] = float(result.info["compile_time"]), float(result.wall_time)
        return result

def timed_plot(*args, **kwargs):
    now("plot0")
    from cfm_core.post import figure_process
    ahead = figure_process.pid() is not None
    R["figures"] = "a second process" if ahead else "this process"
    if not ahead:  # the plot's first lines import them; timed apart
        import matplotlib.figure, matplotlib.backends.backend_agg
    now("mpl")
    try:
        return plot_acceleration(*args, **kwargs)
    finally:
        now("plot1")

backend_for = pipeline.backend_for
plot_acceleration = outcomes.plot_acceleration
pipeline.build_model = stamp("model", pipeline.build_model)
pipeline.backend_for = lambda name: TimedBackend(backend_for(name))
outcomes.plot_acceleration = timed_plot
outcomes.DropTestOutcome.write = stamp("save", outcomes.DropTestOutcome.write)  # the CLI writes into its staged folder
code = entry()
now("main1")
with open(record, "w") as f:
    json.dump({"t": T, "cpu": C, "run": R, "modules": sorted(sys.modules)}, f)
sys.exit(code)
"""

#: (key, label) of each phase, in the order they happen; they add up to the end-to-end time.
PHASES = (
    ("startup", "interpreter start-up"), ("imports", "imports of cfm"), ("command", "command line and plugins"),
    ("model", "model"), ("backend", "backend look-up"), ("numba", "numba import"), ("kernels", "kernels loaded"),
    ("solve", "solve"), ("run_other", "other run set-up"), ("post", "post-processing"), ("write", "writing"),
    ("mpl", "matplotlib import"), ("plot", "plotting"), ("exit", "exit"),
)


def cfm_command() -> list[str]:
    """The ``cfm`` console script beside this interpreter, else ``python -m cfm_core.cli``."""
    script = Path(sys.executable).with_name("cfm")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "cfm_core.cli"]


def entry_point() -> str:
    """``module:function`` of the installed ``cfm`` console script."""
    from importlib.metadata import entry_points

    (ep,) = entry_points(group="console_scripts", name="cfm")
    return ep.value


def _arguments(thickness: float, size: float, out: str) -> list[str]:
    return ["drop-test", "--quiet", "--thickness", repr(thickness), "--element-size", repr(size), "--out", out]


def phases(spawn: float, end: float, child: dict) -> dict:
    """Phases (s) of one instrumented run from the child's timestamps; they add up to ``total``.

    Parameters
    ----------
    spawn, end : float
        ``time.time()`` in the parent just before starting the child and just after it ended (s).
    child : dict
        The child's record: ``t`` (timestamps, s), ``run`` (kernels and solve, s).

    Returns
    -------
    dict
        One entry per key of :data:`PHASES` and ``total`` (``end - spawn``), s.
    """
    t, r = child["t"], child["run"]
    p = {
        "startup": t["start"] - spawn,
        "imports": t["imported"] - t["start"],
        "command": t["model0"] - t["imported"],
        "model": t["model1"] - t["model0"],
        "backend": t["run0"] - t["model1"],
        "numba": t["numba"] - t["run0"],
        "kernels": r["kernels"],
        "solve": r["solve"],
        "run_other": t["run1"] - t["numba"] - r["kernels"] - r["solve"],
        "post": t["save0"] - t["run1"],
        "write": t["save1"] - t["save0"] - (t["plot1"] - t["plot0"]),
        "mpl": t["mpl"] - t["plot0"],
        "plot": t["plot1"] - t["mpl"],
        "exit": end - t["save1"],
    }
    p["total"] = end - spawn
    return p


#: (key, label) of the CPU-time phases: one thread runs in each but ``run`` (numba's threads).
CPU_PHASES = (
    ("startup", "start-up"), ("imports", "imports"), ("command", "command line"), ("model", "model"),
    ("backend", "backend look-up"), ("numba", "numba import"), ("run", "run (kernels, solve, set-up; all threads)"),
    ("post", "post-processing"), ("write", "writing"), ("mpl", "matplotlib import"), ("plot", "plotting"),
    ("exit", "exit"),
)


def cpu_phases(child: dict, cpu_total: float) -> dict:
    """CPU time (s, user + system) of the child per phase; they add up to ``cpu_total``.

    Parameters
    ----------
    child : dict
        The child's record: ``cpu`` (``time.process_time()`` at the same points as ``t``, s).
    cpu_total : float
        The child's CPU time measured by the parent (``resource.getrusage``), s.

    Returns
    -------
    dict
        One entry per key of :data:`CPU_PHASES`, ``total`` (``cpu_total``) and ``outside_run``
        (everything but ``run``: the part that one thread does, about its wall time on an idle
        machine), s.
    """
    c = child["cpu"]
    p = {
        "startup": c["start"], "imports": c["imported"] - c["start"], "command": c["model0"] - c["imported"],
        "model": c["model1"] - c["model0"], "backend": c["run0"] - c["model1"], "numba": c["numba"] - c["run0"],
        "run": c["run1"] - c["numba"], "post": c["save0"] - c["run1"],
        "write": c["save1"] - c["save0"] - (c["plot1"] - c["plot0"]), "mpl": c["mpl"] - c["plot0"],
        "plot": c["plot1"] - c["mpl"], "exit": cpu_total - c["save1"],
    }
    p["total"] = cpu_total
    p["outside_run"] = cpu_total - p["run"]
    return p


def _warm_environment() -> dict:
    """This process's environment without ``PYTHONDONTWRITEBYTECODE``: a warm run has Python's
    bytecode cache too (some sandboxes set it, and every import then compiles its source again:
    about 0.1 s of this command)."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _children_cpu() -> float:
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def instrumented(thickness: float, size: float) -> tuple[dict, list[str]]:
    """One instrumented warm ``cfm drop-test --quiet`` in a fresh process: (phases, modules it
    imported); the phases (s, wall) also hold ``cpu``, the :func:`cpu_phases` of the run."""
    with tempfile.TemporaryDirectory() as folder:
        record = os.path.join(folder, "phases.json")
        cmd = [sys.executable, "-c", CHILD, record, entry_point(),
               *_arguments(thickness, size, os.path.join(folder, "out"))]
        cpu0 = _children_cpu()
        spawn = time.time()
        subprocess.run(cmd, capture_output=True, text=True, check=True, env=_warm_environment())
        end = time.time()
        cpu = _children_cpu() - cpu0
        with open(record) as f:
            child = json.load(f)
    p = phases(spawn, end, child)
    p["cpu"] = cpu_phases(child, cpu)
    p["figures"] = child["run"].get("figures", "this process")
    return p, child["modules"]


def console_script(thickness: float, size: float) -> float:
    """Wall time (s) of one uninstrumented ``cfm drop-test --quiet`` (the console script)."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        subprocess.run([*cfm_command(), *_arguments(thickness, size, folder)], capture_output=True, check=True,
                       env=_warm_environment())
        return time.perf_counter() - start


def measure(thickness: float = 8e-3, size: float = 1e-3, repeat: int = 3) -> dict:
    """Warm end-to-end runs: the kernel cache filled first, then ``repeat`` instrumented runs
    alternating with ``repeat`` runs of the console script.

    Returns
    -------
    dict
        ``phases``: the phases (s) of the instrumented run with the median total; ``totals``:
        every instrumented total (s); ``script``: every console-script time (s); ``modules``: the
        modules that run imported.
    """
    console_script(thickness, size)  # fills the kernel cache (and the OS file cache)
    runs, script = [], []
    for _ in range(repeat):
        runs.append(instrumented(thickness, size))
        script.append(console_script(thickness, size))
    runs.sort(key=lambda pm: pm[0]["total"])
    middle = runs[len(runs) // 2]
    return {"phases": middle[0], "totals": [p["total"] for p, _ in runs], "script": script, "modules": middle[1],
            "figures": middle[0].get("figures", "this process")}


def report(m: dict) -> str:
    """The lines printed by the benchmark for :func:`measure`'s result."""
    p = m["phases"]
    met = "met" if p["total"] < TARGET_S else "not met"
    parts = ", ".join(f"{label} {p[key]:.2f}" for key, label in PHASES)
    spread = f"{min(m['totals']):.2f}-{max(m['totals']):.2f} s over {len(m['totals'])} runs"
    text = (f"warm 'cfm drop-test --quiet' end to end (fresh process, kernels cached): {p['total']:.2f} s, target "
            f"< {TARGET_S:g} s: {met} (median run; {spread}; the console script alone: "
            f"{statistics.median(m['script']):.2f} s median)\n"
            f"  phases (s, adding up to {sum(p[k] for k, _ in PHASES):.2f}): {parts}\n"
            f"  the figure drawn in {m.get('figures', 'this process')} (cfm_core.post.figure_process; in a second "
            f"process, matplotlib's import overlaps the run and 'plotting' is the wait for the figure)")
    c = p.get("cpu")
    if c:
        text += (f"\n  CPU time of the same run (s, adding up to {c['total']:.2f}): "
                 + ", ".join(f"{label} {c[key]:.2f}" for key, label in CPU_PHASES)
                 + f"; outside the run {c['outside_run']:.2f} (one thread: about its wall time on an idle machine)")
    return text


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--thickness", type=float, default=8e-3, help="specimen thickness (m)")
    ap.add_argument("--size", type=float, default=1e-3, help="element size (m)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each kind (the median is shown)")
    args = ap.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) on {os.cpu_count()} cores", flush=True)
    print(report(measure(args.thickness, args.size, args.repeat)))


if __name__ == "__main__":
    main()
