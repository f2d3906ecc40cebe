"""cfm.calibrate, cfm.fit and cfm.uniaxial: tables with units, the command line's files, provenance."""

import json

import numpy as np
import pytest

import cfm_core as cfm
from cfm_core.cli import main
from cfm_core.material import make_material
from cfm_core.simulation import point
from cfm_core.studies import calibrate as cal

pytest.importorskip("numba")


def _lab_test(path, rate=10.0, stretch=0.6, steps=200):  # ramp steps below lab_tests.MAX_STEP
    t, lam, P, _ = point.uniaxial(make_material("cfm"), rate, stretch, steps=steps)
    path.write_text("t [s],stretch [-],stress [Pa]\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t, lam, P)))
    return f"{path}:uniaxial:{rate:g}"


def test_uniaxial_api_writes_the_bytes_of_cfm_point(tmp_path):
    result = cfm.uniaxial("cfm", rate=100.0, stretch=0.7, steps=40)
    df = result.to_dataframe()
    assert list(df.columns) == ["t [s]", "stretch [-]", "nominal_stress [Pa]", "lateral_stretch [-]"]
    assert df["stretch [-]"].iloc[-1] == pytest.approx(0.7) and df["nominal_stress [Pa]"].iloc[-1] < 0
    result.save(tmp_path / "api.csv")
    assert main(["point", "--material", "cfm", "--uniaxial", "--rate", "100", "--stretch", "0.7", "--steps", "40",
                 "--out", str(tmp_path / "cli.csv")]) == 0
    assert (tmp_path / "api.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    assert (tmp_path / "api.png").stat().st_size > 0


def test_fit_api_far_start_ends_on_the_search_range_and_writes_fit_json_naming_it(tmp_path):
    """k1 started at 0.01 Pa: the search range ends at 0.01 x 1e4 = 100 Pa, far below the truth (1320 Pa)."""
    spec = _lab_test(tmp_path / "u.csv")
    outcome = cfm.fit("cfm", tests=[spec], fit="k1", start={"k1": 0.01}, out=tmp_path / "fit")
    assert outcome.result.confidence["at_bound"]["k1"]["side"] == "upper"
    assert outcome.fitted["k1"] == pytest.approx(100.0, rel=1e-5)
    df = outcome.to_dataframe()
    assert list(df.columns) == ["k1 [Pa]"] and np.isnan(df.loc["ci95_low", "k1 [Pa]"])
    data = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert data["at_bound"]["k1"] == {"side": "upper", "bound": pytest.approx(100.0, rel=1e-9), "unit": "Pa"}
    assert any("upper end of its search range 100 Pa" in w for w in data["identifiability_warnings"])
    assert list(data["provenance"]["input_files"]) == [str(tmp_path / "u.csv")]
    assert data["provenance"]["material"]["definition_digest"] and "backend" not in data["provenance"]
    # near the truth the same fit converges inside the range with an interval around 1320 Pa
    near = cfm.fit("cfm", tests=[spec], fit="k1", start={"k1": 1000.0})
    assert near.result.confidence["at_bound"] == {} and near.fitted["k1"] == pytest.approx(1320.0, rel=1e-6)


def test_calibrate_api_twin_and_files(tmp_path):
    scene = cfm.builtin_scene("drop-test").with_overrides(element_size=0.0025, width=0.03, thickness=0.005)
    truth = cfm.drop_test(scene.with_overrides(parameters={"k2": 2.0}))
    data = tmp_path / "meas.csv"
    data.write_text("t,a\n" + "".join(f"{float(t)!r},{float(a)!r}\n" for t, a in zip(truth.t, truth.a_raw)))
    outcome = cfm.calibrate(scene, data=[(str(data), 0.005)], fit="k2", start={"k2": 1.7}, out=tmp_path / "cal",
                            progress=False)
    assert outcome.fitted["k2"] == pytest.approx(2.0, rel=2e-3)
    df = outcome.to_dataframe()
    assert list(df.columns) == ["k2 [-]"] and df.loc["ci95_low", "k2 [-]"] < df.loc["fitted", "k2 [-]"]
    record = json.loads((tmp_path / "cal" / "fit.json").read_text())
    assert record["provenance"]["input_files"] == {str(data): "sha256:" + cfm.fingerprint.file_digest(data)}
    assert record["provenance"]["backend"]["options"]["hourglass"] is not None
    assert isinstance(record["max_evaluations"], int)  # a fit stopped by the limit is repeatable from fit.json
    assert {"fit.json", "objective.png", "fitted-scene.toml", ".cfm-output.json"} <= {
        p.name for p in (tmp_path / "cal").iterdir()}


def test_confidence_of_a_nearly_flat_log_coordinate_is_withheld_not_an_overflow():
    """A parameter the data hardly see (column 1e-7 of the other): its interval exp(x +- q sd) is beyond
    the float range; reported as withheld (the command used to stop with OverflowError, no fit.json)."""
    t = np.linspace(0.0, 1.0, 50)
    jac = np.column_stack([np.sin(3 * t), 1e-7 * np.cos(5 * t)])
    r = 1e-3 * np.random.default_rng(0).standard_normal(t.size)
    coords = cal.Coordinates(("k1", "tau1"), ("Pa", "s"), (True, True), np.full(2, -50.0), np.full(2, 50.0))
    conf = cal.confidence(np.array([7.0, 0.0]), jac, r, coords)
    assert conf["parameters"]["tau1"]["ci"] is None and "float range" in conf["parameters"]["tau1"]["withheld"]
    assert conf["parameters"]["k1"]["ci"] is not None
