"""The scale benchmark's rows run and print what they measure (small models; timings not judged)."""

import re

from cfm_verification.benchmarks import scale


def test_busy_core_rows_print_the_default_threads_for_numba_torch_and_a_torch_batch():
    lines = []
    tiny = scale.drop_model(2.5e-3, end_time=5e-5)
    scale.busy_rows(tiny, 1, True, say=lines.append, small=tiny)
    assert [ln.split(":")[0].split(", ")[-1] for ln in lines] == ["numba", "torch single run", "torch batch of 4"]
    for ln in lines:
        m = re.search(r"default \((\d+) threads?\) ([\d.]+) s, 1 thread ([\d.]+) s, 2 threads ([\d.]+) s", ln)
        assert m and 1 <= int(m[1]) <= 2 and all(float(v) >= 0 for v in m.groups()[1:])
        assert "never slower: met" in ln or "never slower: not met" in ln


def test_the_busy_verdict():
    """Where the default took one thread the rows are the same run (met, the ratio called noise);
    with two threads it is met only when not slower than one."""
    same = scale.busy_verdict({"best": {None: 0.84, 1: 0.77, 2: 0.82}, "used": {None: 1, 1: 1, 2: 2}})
    assert "default (1 thread) 0.84 s" in same and "1 thread / default 0.92" in same
    assert "met: the default chose one thread" in same and "noise, 8 %" in same
    slower = scale.busy_verdict({"best": {None: 2.0, 1: 1.0, 2: 2.0}, "used": {None: 2, 1: 1, 2: 2}})
    assert "not met: the default's 2 threads are slower than one" in slower
    faster = scale.busy_verdict({"best": {None: 0.6, 1: 1.0, 2: 0.6}, "used": {None: 2, 1: 1, 2: 2}})
    assert faster.endswith("never slower: met)")


def test_rows_measured_in_turns():
    """per_cycle_rounds gives one row per model, in order, each from its own prepared run."""
    small, block = scale.drop_model(2.5e-3, end_time=5e-5), scale.block_model(6)
    rows = scale.per_cycle_rounds([(small, None, None), (block, None, scale.prestrain(None))], rounds=2,
                                  segments=1, budget=0.02)
    assert [r["ne"] for r in rows] == [small.n_elements, 216]
    assert all(r["ns"] > 0 and 300 < r["bytes"] < 3000 for r in rows)


def test_per_cycle_and_memory_of_a_small_block():
    r = scale.per_cycle(scale.block_model(6), None, deform=scale.prestrain(None), segments=1, budget=0.05)
    assert r["ne"] == 216 and r["ns"] > 0 and 300 < r["bytes"] < 3000


def test_the_machines_own_two_thread_ceiling_is_a_plausible_ratio():
    assert 0.3 < scale.ceiling(0.05) < 3.0


def test_the_torch_ratio_leaves_out_the_periodic_scans_on_both_sides_and_restores_them(monkeypatch):
    from cfm_core.simulation import checks

    calls = []
    check = checks.Monitor.check
    monkeypatch.setattr(checks.Monitor, "check", lambda self, *a: (calls.append(a[0]), check(self, *a))[1])
    tiny = scale.drop_model(2.5e-3, end_time=5e-5)
    n, t = scale.torch_ratio(tiny, 2e-4)
    assert n > 0 and t > 0
    assert len(calls) == 3 and min(calls) >= 2e-4    # the final check of each of the 3 runs only
    from cfm_backends.numba_explicit import NumbaExplicitBackend
    from dataclasses import replace
    NumbaExplicitBackend().run(replace(tiny, end_time=2e-4), threads=1)
    assert len(calls) > 3 + 3 and min(calls[3:]) < 1e-4   # outside, the periodic checks run


def test_each_rounds_rows_and_the_copy_rate_are_reported():
    """The best of each round is kept per case (the overall best is their minimum) with the probe
    run at each round's start; round_lines prints one line per round with every case."""
    small = scale.drop_model(2.5e-3, end_time=5e-5)
    calls = []
    rows = scale.per_cycle_rounds([(small, None, None), (small, None, None)], rounds=3, segments=1, budget=0.01,
                                  on_round=lambda: calls.append(1) or 7.5 * len(calls))
    assert len(calls) == 3
    for r in rows:
        assert len(r["rounds"]) == 3 and r["ns"] == min(r["rounds"]) and r["probe"] == [7.5, 15.0, 22.5]
    lines = scale.round_lines(rows).splitlines()
    assert len(lines) == 4 and lines[3].startswith("    round 3:") and lines[3].endswith("copy  22.5 GB/s")
    assert len(re.findall(r"\d+", lines[1].split(":")[1].split("copy")[0])) == 2


def test_the_copy_rate_is_a_plausible_bandwidth():
    assert 0.1 < scale.copy_rate(8, 1) < 1000.0
