"""Fits that claim more than the data hold (shared case calibrate-unidentifiable): parameters that act
only through a combination are reported, with the combination, and their intervals widened to the
valley instead of the tiny linearised ones. Truths are constructed: residuals linear in the
parameters, so the valley and the determined combination are known exactly."""

from pathlib import Path

import numpy as np
import pytest

from cfm_core.studies import calibrate, identifiability

DATA = Path(__file__).resolve().parents[2] / "data" / "calibrate-unidentifiable"


def _coords(names, log=None, lower=0.0, upper=1.0):
    p = len(names)
    return calibrate.Coordinates(tuple(names), ("-",) * p, tuple(log or (False,) * p),
                                 np.full(p, lower), np.full(p, upper))


def test_a_sum_only_model_names_the_pair_the_sum_and_widens_to_the_valley():
    """r(g2, g3) = f(t) (g2 + g3 - 0.529) + 1e-4 h(t) g3: the data hold g2 + g3 (almost only)."""
    t = np.linspace(0.0, 1.0, 200)
    f, h = np.sin(3 * t), np.cos(7 * t)
    jac = np.column_stack([f, f + 1e-4 * h])
    x = np.array([0.3247, 0.2043])  # a point on the valley, away from the truth (0.435, 0.094)
    noise = 1e-6 * np.random.default_rng(1).standard_normal(t.size)
    conf = calibrate.confidence(x, jac, noise, _coords(["g2", "g3"]))
    ident = conf["identifiability"]
    assert not ident["identifiable"] and ident["unidentified"] == ["g2", "g3"]
    (combo,) = ident["combinations"]
    assert combo["parameters"] == ["g2", "g3"] and combo["coefficients"][1] == pytest.approx(1.0, abs=1e-3)
    assert combo["value"] == pytest.approx(0.529, abs=1e-3)
    assert conf["warnings"] and "g2 and g3 are not separately identifiable" in conf["warnings"][0]
    for name, truth in (("g2", 0.435), ("g3", 0.094)):
        lo, hi = conf["parameters"][name]["ci"]
        assert lo <= truth <= hi and conf["parameters"][name]["std"] is None
        assert 0.0 <= lo and hi <= 0.53  # the valley within the bounds [0, 1], not the whole range


def test_independent_parameters_keep_their_intervals_and_no_warning():
    t = np.linspace(0.0, 1.0, 200)
    jac = np.column_stack([np.sin(3 * t), np.cos(7 * t)])
    r = 1e-3 * np.random.default_rng(2).standard_normal(t.size)
    conf = calibrate.confidence(np.array([0.4, 0.1]), jac, r, _coords(["a", "b"]))
    assert conf["warnings"] == [] and conf["identifiability"]["identifiable"]
    s = np.sqrt(r @ r / (t.size - 2) / (jac[:, 0] @ jac[:, 0]))  # orthogonal-ish columns: sd = s / |col|
    lo, hi = conf["parameters"]["a"]["ci"]
    assert (hi - lo) / 2 == pytest.approx(1.97 * s, rel=0.05)


def test_a_near_singular_triple_without_a_correlated_pair_is_reported():
    """c = a + b: no pair is correlated beyond 0.99, yet J^T J is singular in one direction."""
    t = np.linspace(0.0, 1.0, 300)
    a, b = np.sin(3 * t), np.cos(5 * t)
    jac = np.column_stack([a, b, a + b + 1e-9 * t])
    ident = identifiability.analyse(np.zeros(3), jac, 1e-6, 2.0, ["p", "q", "s"], (False,) * 3,
                                    {"p": 1.0, "q": 1.0, "s": 1.0})
    assert not ident["identifiable"] and set(ident["unidentified"]) == {"p", "q", "s"}
    assert ident["undetermined"] and "near-singular" in ident["warnings"][-1]


@pytest.mark.slow
def test_shared_case_twin_g2_g3(tmp_path, capsys):
    """The shared case itself: noise-free twin data, g2 and g3 fitted from (0.3, 0.2)."""
    pytest.importorskip("numba")
    import json

    from cfm_core.cli import main

    out = tmp_path / "fit"
    assert main(["calibrate", "--scene", str(DATA / "scene.toml"), "--data", f"{DATA / 'meas_twin8.csv'}:0.008",
                 f"{DATA / 'meas_twin5.csv'}:0.005", "--fit", "g2,g3", "--param", "g2=0.3", "--param", "g3=0.2",
                 "--serial", "--out", str(out), "--quiet"]) == 0
    assert "not separately identifiable" in capsys.readouterr().err
    d = json.loads((out / "fit.json").read_text())
    assert d["warnings"] and not d["identifiability"]["identifiable"]
    for name, truth in (("g2", 0.435), ("g3", 0.094)):
        lo, hi = d["parameters"][name]["ci95"]
        assert lo <= truth <= hi
