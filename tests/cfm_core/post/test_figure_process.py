"""cfm_core.post.figure_process: the figure drawn by a second process is the figure drawn inline;
every failure of that process falls back to drawing inline; the parent never imports matplotlib
when the process draws; its CPU time does not count as load for a run's thread count."""

import json
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

from cfm_backends import threads as T
from cfm_core.post import figure_process, plots

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the figure process forks (Linux only)")

#: A fresh interpreter: start the process, draw through plots (or break the process first), report.
PROBE = r"""
import json, os, sys
import numpy as np
from cfm_core.post import figure_process, plots
out, mode = sys.argv[1], sys.argv[2]
started = figure_process.start()
pid = figure_process.pid()
t = np.linspace(0.0, 0.012, 800)
a = 300.0 * np.sin(260.0 * t).clip(0.0)
if mode == "killed":
    figure_process._worker[0].kill()
    figure_process._worker[0].join()
if mode == "unknown":
    drawn = figure_process.draw("no_such_figure", out)
else:
    drawn = figure_process.draw("plot_acceleration", out, t, a, 0.9 * a, "probe")
if not drawn:
    plots.plot_acceleration(out, t, a, 0.9 * a, "probe")
print(json.dumps({"started": started, "pid": pid, "drawn": drawn, "alive": figure_process.pid() is not None,
                  "parent_imported_matplotlib": "matplotlib" in sys.modules}))
figure_process.stop()
"""


def _probe(tmp_path, mode: str, **env) -> tuple[dict, bytes]:
    out = tmp_path / f"{mode}.png"
    proc = subprocess.run([sys.executable, "-c", PROBE, str(out), mode], capture_output=True, text=True,
                          env={**os.environ, **env}, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1]), out.read_bytes()


def _inline_png(tmp_path) -> bytes:
    t = np.linspace(0.0, 0.012, 800)
    a = 300.0 * np.sin(260.0 * t).clip(0.0)
    path = tmp_path / "inline.png"
    plots.plot_acceleration(path, t, a, 0.9 * a, "probe")
    return path.read_bytes()


@linux
def test_the_second_process_draws_the_inline_figure(tmp_path):
    record, png = _probe(tmp_path, "draw", CFM_FIGURE_PROCESS="")
    if record["started"] is False:
        pytest.skip("no figure process on this machine: " + str(figure_process.usable()))
    assert record["drawn"] and record["alive"] and record["pid"] > 0
    assert not record["parent_imported_matplotlib"]
    assert png == _inline_png(tmp_path)


@linux
@pytest.mark.parametrize("mode", ["killed", "unknown"])
def test_a_broken_process_falls_back_to_drawing_inline(tmp_path, mode):
    record, png = _probe(tmp_path, mode, CFM_FIGURE_PROCESS="")
    if record["started"] is False:
        pytest.skip("no figure process on this machine")
    assert not record["drawn"] and not record["alive"]  # ended, the figure drawn by the caller
    assert record["parent_imported_matplotlib"]
    assert png == _inline_png(tmp_path)


@linux
def test_a_child_ended_mid_figure_leaves_no_temporary_file(tmp_path):
    """A child that does not answer in time is ended; the temporary file it was writing goes too."""
    script = r"""
import json, sys, time
from pathlib import Path
from cfm_core.post import figure_process, plots
out = Path(sys.argv[1])
def stuck(path):  # writes its temporary file, then never answers
    Path(path).parent.joinpath(f".{Path(path).name}.{__import__('os').getpid()}.abc123.tmp").write_bytes(b"x")
    time.sleep(60)
plots.stuck = stuck
figure_process.ANSWER_S = 2.0
started = figure_process.start()
drawn = figure_process.draw("stuck", out / "figure.png")
print(json.dumps({"started": started, "drawn": drawn, "left": sorted(p.name for p in out.iterdir())}))
"""
    proc = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, timeout=120,
                          env={**os.environ, figure_process.ENV: ""})
    assert proc.returncode == 0, proc.stderr
    record = json.loads(proc.stdout.strip().splitlines()[-1])
    if not record["started"]:
        pytest.skip("no figure process on this machine")
    assert record == {"started": True, "drawn": False, "left": []}


def test_switched_off_by_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv(figure_process.ENV, "0")
    assert figure_process.usable() == "CFM_FIGURE_PROCESS=0"
    assert figure_process.start() is False and figure_process.pid() is None
    assert figure_process.draw("plot_acceleration", tmp_path / "x.png") is False


def test_not_in_a_process_with_other_threads(monkeypatch):
    monkeypatch.delenv(figure_process.ENV, raising=False)
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert "threads run in this process" in figure_process.usable()
    finally:
        stop.set()
        other.join()


def test_not_once_numba_threads_run(monkeypatch):
    import types

    monkeypatch.delenv(figure_process.ENV, raising=False)
    monkeypatch.setattr(figure_process.threading, "active_count", lambda: 1)
    monkeypatch.setitem(sys.modules, "numba.np.ufunc.parallel", types.SimpleNamespace(_is_initialized=True))
    assert figure_process.usable() == "numba's threads run in this process"


def test_its_cpu_time_is_not_load(monkeypatch):
    """idle_cores adds the figure process's ticks over the sample to the idle ticks (2 cores)."""
    monkeypatch.setattr(T.time, "sleep", lambda s: None)
    stat = iter([(100.0, 200.0), (150.0, 400.0)])     # (idle, total) ticks: 50 idle of 200
    monkeypatch.setattr(T, "_cpu_times", lambda cpus: next(stat))
    helper = iter([10.0, 110.0])                        # the figure process ran 100 of them
    monkeypatch.setattr(T, "_helper_ticks", lambda: next(helper))
    assert T.idle_cores([0, 1]) == pytest.approx(1.5)   # without it: 2 * 50 / 200 = 0.5


@linux
def test_helper_ticks_read_the_figure_process(monkeypatch):
    """_helper_ticks reads /proc/<pid>/stat of the process figure_process names (here a busy child)."""
    busy = subprocess.Popen([sys.executable, "-c", "import time\nt = time.process_time()\n"
                             "while time.process_time() - t < 0.3: pass\nimport sys; sys.stdin.read()"],
                            stdin=subprocess.PIPE)
    try:
        monkeypatch.setattr(figure_process, "pid", lambda: busy.pid)
        ticks = 0.0
        for _ in range(200):
            ticks = T._helper_ticks()
            if ticks >= 0.2 * os.sysconf("SC_CLK_TCK"):  # 0.2 s of CPU time
                break
            threading.Event().wait(0.02)
        assert ticks >= 0.2 * os.sysconf("SC_CLK_TCK")
        monkeypatch.setattr(figure_process, "pid", lambda: None)
        assert T._helper_ticks() == 0.0
    finally:
        busy.communicate(b"")


CLI = r"""
import json, sys
from cfm_core.cli.__main__ import console
sys.argv = ["cfm", *sys.argv[1:]]
code = console()
print(json.dumps({"code": code, "matplotlib": "matplotlib" in sys.modules}))
"""


@linux
def test_cfm_drop_test_draws_its_figure_in_the_second_process(tmp_path):
    """The command's PNG is the same bytes with and without the figure process; with it, the
    command's own process never imports matplotlib."""
    pytest.importorskip("numba")
    pngs, imported = {}, {}
    for switch in ("", "0"):
        out = tmp_path / f"out{switch or 'on'}"
        proc = subprocess.run([sys.executable, "-c", CLI, "drop-test", "--quiet", "--thickness", "0.004",
                               "--element-size", "0.002", "--width", "0.01", "--out", str(out)],
                              capture_output=True, text=True, timeout=600,
                              env={**os.environ, figure_process.ENV: switch})
        assert proc.returncode == 0, proc.stderr
        record = json.loads(proc.stdout.strip().splitlines()[-1])
        pngs[switch], imported[switch] = (out / "acceleration.png").read_bytes(), record["matplotlib"]
    assert pngs[""] == pngs["0"]
    assert imported["0"]
    if len(os.sched_getaffinity(0)) >= 2:  # a fresh command on this machine forks one
        assert not imported[""]


@linux
def test_not_in_a_daemonic_pool_worker():
    """A multiprocessing pool's worker may not have children: cfm run there draws inline."""
    script = ("import multiprocessing as mp\nfrom cfm_core.post import figure_process\n"
              "if __name__ == '__main__':\n"
              "    with mp.get_context('fork').Pool(1) as pool:\n"
              "        print(pool.apply(figure_process.usable))\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env={**os.environ, figure_process.ENV: ""})
    assert proc.returncode == 0, proc.stderr
    assert "daemonic process" in proc.stdout


@linux
def test_sigterm_to_the_group_prints_one_line_and_leaves_no_process(tmp_path):
    """timeout(1) and batch systems signal the whole process group: the command says it was
    terminated in one line, the figure process prints nothing and does not outlive it."""
    import signal
    import time

    pytest.importorskip("numba")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "cfm_core.cli", "drop-test", "--element-size", "0.0007",
                             "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env={**os.environ, figure_process.ENV: ""})
    time.sleep(4.0)  # past the fork (the run of about 15 000 elements takes longer)
    os.killpg(proc.pid, signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    if proc.returncode == 0:
        pytest.skip("the run ended before the signal")
    assert proc.returncode == 143 and "Traceback" not in err and "terminated (SIGTERM)" in err, err
    assert not out.exists()
    time.sleep(0.5)
    alive = subprocess.run(["pgrep", "-s", str(proc.pid)], capture_output=True, text=True)
    assert alive.stdout.strip() == ""


@linux
def test_a_parent_gone_mid_figure_leaves_the_child_silent(tmp_path):
    """Ctrl-C while the child draws: the parent kills it at once, no figure is written and the
    child prints nothing (its answer to a closed pipe used to raise BrokenPipeError twice)."""
    script = r"""
import os, signal, sys, time
import numpy as np
from cfm_core.post import figure_process as fp, plots
out = sys.argv[1]
draw = plots._save
plots._save = lambda fig, path: (time.sleep(1.0), draw(fig, path))
t = np.linspace(0.0, 1e-3, 50)
signal.signal(signal.SIGALRM, lambda *a: (_ for _ in ()).throw(KeyboardInterrupt()))
started = False
try:
    with fp.started():
        started = fp.pid() is not None
        time.sleep(1.0)
        signal.setitimer(signal.ITIMER_REAL, 0.3)
        plots.plot_acceleration(os.path.join(out, "x.png"), t, t, t, "title")
except KeyboardInterrupt:
    print("interrupted", started, sorted(os.listdir(out)))
"""
    proc = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True,
                          timeout=120, env={**os.environ, figure_process.ENV: ""})
    assert proc.returncode == 0, proc.stderr
    if proc.stdout.strip() == "interrupted False []":
        pytest.skip("no figure process on this machine")
    assert proc.stdout.strip() == "interrupted True []"
    assert "Traceback" not in proc.stderr and "Error" not in proc.stderr, proc.stderr
