"""Sweeps: Dask (two workers) equals the serial loop, failures are recorded, reruns skip, bad input."""

import json
import logging
import shutil
import time

import numpy as np
import pandas as pd
import pytest

from cfm_core.studies import sweep
from cfm_core.cli import main
from cfm_core.studies.dask_runner import WORKER_ENV, SerialRunner, open_runner
from cfm_core.errors import InputError

pytest.importorskip("numba")
distributed = pytest.importorskip("distributed")

# velocity 30 m/s inverts an element within 0.1 ms: those runs fail numerically, the others complete
VARY = ["thickness=0.005,0.008", "k1=1000,1320", "velocity=1,30"]
TIMES = ("run_time", "wall_time")  # differ from run to run; everything else must be equal




@pytest.fixture(scope="module")
def serial(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    result = sweep.run_sweep(scene, sweep.parse_vary(VARY, scene), out, "numba", SerialRunner())
    return out, result


@pytest.fixture(scope="module")
def scheduler():
    """A scheduler with two one-thread worker processes, reached by address as a remote one."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, env=dict(WORKER_ENV),
                                  dashboard_address=":0", silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


def _values(path):
    return [{k: v for k, v in row.items() if k.split(" ")[0] not in TIMES} for row in sweep.read_table(path)]


def test_serial_sweep_records_failures_and_completes_the_rest(serial):
    out, result = serial
    rows = sweep.read_table(out / "sweep.csv")
    assert [r["thickness [m]"] for r in rows] == [0.005] * 4 + [0.008] * 4  # the last --vary runs fastest
    assert [r["k1 [Pa]"] for r in rows] == [1000.0, 1000.0, 1320.0, 1320.0] * 2
    assert [r["velocity [m/s]"] for r in rows] == [1.0, 30.0] * 4
    assert [r["status"] for r in rows] == ["ok", "failed"] * 4
    assert result.executed == 8 and result.skipped == 0 and result.failed == 4
    for r in rows:
        folder = out / "runs" / r["run_id"]
        if r["status"] == "failed":
            assert "NumericalError" in r["error"] and "inverted" in r["error"] and r["peak_g [g]"] is None
            assert json.loads((folder / "failed.json").read_text())["error"] == r["error"]
            assert not (folder / "summary.json").exists()
        else:
            assert r["error"] == "" and r["peak_g [g]"] > 0
            summary = json.loads((folder / "summary.json").read_text())
            assert summary["sweep"] == {"thickness": r["thickness [m]"], "k1": r["k1 [Pa]"], "velocity": 1.0}
            assert summary["peak_g"] == r["peak_g [g]"]
            assert (folder / "acceleration.csv").read_text().startswith("t [s],a_raw [m/s^2],a_cfc600 [m/s^2]\n")
    ok = {(r["thickness [m]"], r["k1 [Pa]"]): r["peak_g [g]"] for r in rows if r["status"] == "ok"}
    assert ok[(0.005, 1000.0)] > ok[(0.005, 1320.0)] > ok[(0.008, 1000.0)] > ok[(0.008, 1320.0)]
    assert (out / "peaks.png").stat().st_size > 0
    record = json.loads((out / "sweep.json").read_text())
    assert record["runs"] == 8 and record["failed"] == 4 and record["run_ids"] == [r["run_id"] for r in rows]
    assert record["provenance"]["backend"]["options"]["hourglass"] == result.options["hourglass"]
    assert record["provenance"]["material"]["definition_digest"] == result.key["material"]


def test_parquet_table_matches_the_csv(serial):
    """pandas reads both files (a plain install of the 'all' extra has pyarrow) to the same table."""
    out, _ = serial
    parquet = pd.read_parquet(out / "sweep.parquet")
    csv = pd.read_csv(out / "sweep.csv")
    assert list(parquet.columns) == list(csv.columns) and "peak_g [g]" in parquet.columns
    numeric = [c for c in csv.columns if c not in ("run_id", "status", "error", "warnings")]
    assert np.array_equal(parquet[numeric].to_numpy(float), csv[numeric].to_numpy(float), equal_nan=True)
    assert list(parquet["run_id"]) == list(csv["run_id"])


def test_rerun_skips_complete_runs_and_retries_failed_ones(scene, serial, tmp_path):
    out = tmp_path / "sweep"
    shutil.copytree(serial[0], out)
    before = {p: p.stat().st_mtime_ns for p in out.glob("runs/*/summary.json")}
    again = sweep.run_sweep(scene, sweep.parse_vary(VARY, scene), out, "numba", SerialRunner())
    assert again.skipped == 4 and again.executed == 4 and again.failed == 4  # only the failed ones ran
    assert {p: p.stat().st_mtime_ns for p in out.glob("runs/*/summary.json")} == before
    done = sweep.parse_vary(["thickness=0.005,0.008", "k1=1000,1320", "velocity=1"], scene)
    assert sweep.run_sweep(scene, done, out, "numba", SerialRunner()).executed == 0


def test_two_dask_workers_by_address_give_the_serial_table(serial, scene_file, scheduler, tmp_path, capsys):
    out, _ = serial
    args = ["sweep", "--scene", scene_file, "--out", str(tmp_path), "--scheduler", scheduler]
    assert main(args + [a for v in VARY for a in ("--vary", v)]) == 1  # 1: some runs failed
    err = capsys.readouterr().err
    assert f"on Dask scheduler {scheduler} (2 worker thread(s))" in err and "[8/8]" in err
    assert "4 run(s) failed" in err
    assert _values(tmp_path / "sweep.csv") == _values(out / "sweep.csv")  # bitwise: same numbers as text


def test_local_cluster_runs_the_same_command(scene, scene_file, tmp_path, capsys):
    vary = ["velocity=1.0,1.5"]
    assert main(["sweep", "--scene", scene_file, "--vary", vary[0], "--workers", "2", "--out", str(tmp_path)]) == 0
    assert "local Dask cluster, 2 worker process(es)" in capsys.readouterr().err
    ref = tmp_path / "serial"
    sweep.run_sweep(scene, sweep.parse_vary(vary, scene), ref)
    assert _values(tmp_path / "sweep.csv") == _values(ref / "sweep.csv")


@pytest.mark.parametrize("vary, message", [
    (["kk1=1,2"], "unknown name; a drop-test sweep can vary the scene values thickness, velocity"),
    (["k1=1,x"], "value 'x' is not a number"),
    (["k1"], "--vary expects NAME=V1,V2"),
    (["k1=1,2", "k1=3"], "is given twice"),
    (["k1=1,1"], "a value is repeated"),
])
def test_bad_vary_is_a_clear_error(scene, vary, message):
    with pytest.raises(InputError, match=message):
        sweep.parse_vary(vary, scene)


def test_cli_input_errors_exit_2(scene_file, tmp_path, capsys):
    base = ["sweep", "--scene", scene_file, "--out", str(tmp_path)]
    assert main(base + ["--vary", "mass_kg=1"]) == 2
    assert "its parameters" not in capsys.readouterr().err  # names the sweepable names instead
    assert main(base + ["--vary", "k1=1", "--workers", "0"]) == 2
    assert "--workers 0 is not allowed" in capsys.readouterr().err
    assert main(base + ["--vary", "k1=1", "--serial", "--workers", "2"]) == 2
    assert main(["sweep", "--scene", scene_file, "--vary", "k1=1", "--serial", "--out", scene_file]) == 2
    assert "is not a directory" in capsys.readouterr().err
    assert not (tmp_path / "sweep.csv").exists()


def test_runner_records_errors_without_stopping():
    with open_runner("none") as runner:
        done = sorted(runner.map(lambda x: 1.0 / x, [1.0, 0.0, 2.0]), key=lambda d: d.index)
    assert [d.value for d in done] == [1.0, None, 0.5]
    assert done[1].error == "ZeroDivisionError: float division by zero"


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:1", "no-port"])
def test_unreachable_scheduler_is_an_input_error(address):
    from cfm_core.studies.dask_runner import connect

    with pytest.raises(InputError, match=f"--scheduler {address}: cannot connect to a Dask scheduler"):
        connect(address, timeout=1.0)


def test_a_value_the_backend_refuses_stops_the_sweep_before_any_run(tmp_path, capsys):
    """skfem's frictionless contact: a friction sweep on skfem was a table of failed runs (exit 1) while
    cfm drop-test refused the same input (exit 2)."""
    pytest.importorskip("skfem")
    out = tmp_path / "sw"
    assert main(["sweep", "--serial", "--quiet", "--backend", "skfem", "--vary", "friction=0.1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--vary friction: value 0.1" in err and "friction = 0.1 is not supported" in err
    assert not out.exists()


@pytest.mark.parametrize("greeting", [None, b"HTTP/1.0 400 Bad request\r\n\r\n"])
def test_a_server_that_is_not_a_dask_scheduler_is_named_in_bounded_time(greeting):
    """--scheduler at the dashboard's port (or any HTTP server): the sweep waited silently until
    killed; a server sending other bytes made numpy allocate 3 EiB (a raw traceback)."""
    import socket
    import threading

    from cfm_core.studies import dask_runner

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    held = []

    def accept():
        conn, _ = server.accept()
        held.append(conn)  # kept open, as a server waiting for a request does
        if greeting:
            conn.sendall(greeting)

    threading.Thread(target=accept, daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=f"--scheduler {address}: .*not .*as a Dask scheduler.*8786"):
        dask_runner.check_speaks_dask(address, timeout=1.0)
    assert time.perf_counter() - t0 < 5.0
    server.close()
    for conn in held:
        conn.close()


@pytest.mark.parametrize("address, tcp", [("http://localhost:8787", "tcp://localhost:8786"),
                                          ("https://10.0.0.5:8787/status", "tcp://10.0.0.5:8786"),
                                          ("http://[::1]:8787", "tcp://[::1]:8786")])
def test_a_dashboard_address_is_refused_with_the_schedulers_address(tmp_path, capsys, address, tcp):
    """--scheduler http://host:8787 (the dashboard a browser shows): the hint said to start workers with
    'dask worker http://host:8787', which no worker can connect to; workers and clients take tcp://host:8786."""
    out = tmp_path / "o"
    assert main(["sweep", "--vary", "k1=1000", "--scheduler", address, "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--scheduler {address} is a web address" in err and f"'dask worker {tcp} --nthreads 1'" in err
    assert f"give its tcp:// address, {tcp} for the default port" in err
    assert "dask worker http" not in err and err.count("\n") == 1 and not out.exists()


def test_a_sweep_never_removes_the_scene_file_it_reads(scene, tmp_path, capsys):
    """cfm sweep --scene run/scene.toml --out run removed the run's files, scene.toml among them, before the first run."""
    from cfm_core.post.staging import staged_folder
    from cfm_core.scene.scene import scene_to_toml

    out = tmp_path / "run"
    with staged_folder(out) as stage:
        (stage / "scene.toml").write_text(scene_to_toml(scene))
        (stage / "summary.json").write_text("{}")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    rc = main(["sweep", "--scene", str(out / "scene.toml"), "--vary", "k1=1000,1320", "--serial", "--quiet",
               "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "scene.toml is a file of the earlier cfm output there" in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
