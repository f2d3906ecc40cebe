"""Numbers written as people read them (issue 24, part 4): the resampled times are k / rate (so
they print as 6e-05, not 6.000000000000001e-05), every CSV value is the shortest text that reads
back to the same float, and the histories themselves are what they always were."""

import math
import re

import numpy as np
import pytest

import cfm_core as cfm
from cfm_core.post import resample_acceleration
from cfm_core.simulation.result import Result
from cfm_core.studies.sweep import Axis
from cfm_core.studies.sweep_output import SUMMARY_COLUMNS, write_table

MASS = 0.22


def _result(t_end: float = 6e-3, m: int = 977):
    t = np.linspace(0.0, t_end, m)
    t[1:-1] += 1e-7 * np.sin(np.arange(1, m - 1))  # solver times: not on any grid
    impulse = 0.22 * 2.0 * (1.0 - np.cos(np.pi * np.clip(t / 5e-3, 0.0, 1.0))) / 2.0
    return Result(t=t, backend="test", steps=m - 1, wall_time=0.0, impulse=impulse)


def significant_digits(text: str) -> int:
    mantissa = re.sub(r"[eE].*$", "", text).replace("-", "").replace(".", "").lstrip("0")
    return len(mantissa.rstrip("0")) if "e" not in text.lower() else len(mantissa)


@pytest.mark.parametrize("rate", [50_000.0, 10_000.0, 30_000.0, 1e6])
def test_times_are_k_over_rate(rate):
    t, _ = resample_acceleration(_result(), MASS, rate)
    k = np.arange(t.size)
    assert np.array_equal(t, k / rate)  # not k * (1 / rate): 3 * 2e-05 = 6.000000000000001e-05
    assert t[-1] <= 6e-3 * (1 + 1e-12) < t[-1] + 1 / rate


def test_default_grid_prints_at_most_6_significant_digits():
    t, _ = resample_acceleration(_result(), MASS)  # 50 kHz, the paper's rate
    texts = [repr(v) for v in t.tolist()]
    assert "6e-05" in texts and "6.000000000000001e-05" not in texts
    assert max(significant_digits(s) for s in texts) <= 6, max(texts, key=significant_digits)


def test_the_box_averages_are_unchanged():
    """The boxes are centred where they always were (k h, h = 1/rate): the histories' bytes do
    not change with the printed times. Independent: the box average of the impulse by hand."""
    r = _result()
    rate, h = 50_000.0, 1.0 / 50_000.0
    t, a = resample_acceleration(r, MASS, rate)
    centre = np.arange(t.size) * h
    impulse = np.interp(centre + 0.5 * h, r.t, r.impulse, left=0.0, right=r.impulse[-1]) - \
        np.interp(centre - 0.5 * h, r.t, r.impulse, left=0.0, right=r.impulse[-1])
    assert np.array_equal(a, impulse / (h * MASS))
    assert np.max(np.abs(t - centre)) <= np.spacing(t[-1])  # the written times: within one ulp of the centres


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    scene = cfm.builtin_scene("drop-test").with_overrides(thickness=0.005, width=0.02, element_size=0.0025)
    outcome = cfm.drop_test(scene, "numba")
    folder = tmp_path_factory.mktemp("numbers") / "run"
    outcome.save(folder, plot=False)
    return outcome, folder


def test_acceleration_csv_of_a_run_reads_as_written(tiny_run):
    outcome, folder = tiny_run
    lines = (folder / "acceleration.csv").read_text().splitlines()
    assert lines[0] == "t [s],a_raw [m/s^2],a_cfc600 [m/s^2]"
    rows = [line.split(",") for line in lines[1:]]
    assert len(rows) == outcome.t.size > 100
    rate = outcome.summary.get("sample_rate", 50_000.0)
    for k, (t, raw, cfc) in enumerate(rows):
        assert t == repr(k / rate) and significant_digits(t) <= 6, (k, t)
        for text, value in ((t, outcome.t[k]), (raw, outcome.a_raw[k]), (cfc, outcome.a_cfc[k])):
            assert float(text) == value and text == repr(float(value))  # bit-identical, shortest form


def test_sweep_csv_echoes_inputs_in_their_shortest_form(tmp_path):
    axes = [Axis("k2", "-", (1.66, 3.0)), Axis("thickness", "m", (0.005, 0.008))]
    rows = []
    for k2 in axes[0].values:
        for h in axes[1].values:
            row = {"run_id": f"id{len(rows)}", "k2": k2, "thickness": h, "status": "ok", "error": ""}
            row.update({c: math.pi * (1 + len(rows)) * 1e-3 for c in SUMMARY_COLUMNS})
            row.update(steps=689.0, elements=128, t_peak=276 / 50_000.0)
            rows.append(row)
    rows[-1].update(status="failed", error="diverged", peak_g=None)  # a failed run: empty cells
    write_table(tmp_path, rows, axes)
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert header[:3] == ["run_id", "k2 [-]", "thickness [m]"]
    text = "\n".join(lines[1:])
    assert "1.6599999999999999" not in text and "0.0050000000000000001" not in text
    cells = [dict(zip(header, line.split(","))) for line in lines[1:]]
    assert [c["k2 [-]"] for c in cells] == ["1.66", "1.66", "3", "3"]
    assert [c["thickness [m]"] for c in cells] == ["0.005", "0.008", "0.005", "0.008"]
    assert {c["steps [-]"] for c in cells} == {"689"} and cells[0]["t_peak [s]"] == "0.00552"
    assert cells[-1]["peak_g [g]"] == "" and cells[-1]["status"] == "failed"
    heads = {c: next(h for h in header if h.startswith(c + " [")) for c in ("k2", "thickness", *SUMMARY_COLUMNS)}
    for row, cell in zip(rows, cells):  # every number reads back bit-identical
        for key, head in heads.items():
            if row[key] is not None:
                assert float(cell[head]) == float(row[key]), (key, cell[head])
