"""fit_peaks: the least-squares logic on a stand-in runner whose "drop test" peak is a known function."""

import math

import pytest

from cfm_core.scene.scene import builtin_scene
from cfm_core.studies.dask_runner import Done
from cfm_core.studies.peaks import fit_peaks


class PowerLawRunner:
    """peak(h) = 100 g (k1s / 1000 Pa)^-0.2 (h / 5 mm)^(-1 - 0.1 ln k2s): a smooth stand-in with a
    unique solution, so the optimiser can be checked without drop tests."""

    label = "stand-in"

    def map(self, fn, items):
        for i, (scene, params, _backend) in enumerate(items):
            h = scene.specimen.thickness
            peak = 100.0 * (params["k1s"] / 1000.0) ** -0.2 * (h / 0.005) ** (-1.0 - 0.1 * math.log(params["k2s"]))
            yield Done(i, {"summary": {"peak_g": peak}})


def test_fit_peaks_recovers_the_parameters_of_two_target_peaks():
    truth = {"k1s": 4000.0, "k2s": 2.0}
    runner = PowerLawRunner()
    scene = builtin_scene("drop-test").with_overrides(material="cfm-septa")
    targets = {}
    for h in (0.005, 0.008):
        (done,) = runner.map(None, [(scene.with_overrides(thickness=h), truth, "numba")])
        targets[h] = done.value["summary"]["peak_g"]
    result = fit_peaks(scene, targets, ["k1s", "k2s"], {"k1s": 1000.0, "k2s": 1.0}, runner=runner, rel_step=1e-6)
    for name, value in truth.items():
        assert result.fitted[name] == pytest.approx(value, rel=1e-3)
    assert len(result.singular_values) == 2 and result.jacobian.shape == (2, 2)
