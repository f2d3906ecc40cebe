"""The paper's drop test with the real CFM material on the numba backend (coarse mesh)."""

import pytest

pytest.importorskip("numba")
from cfm_backends.numba_explicit import NumbaExplicitBackend
from fixtures.hand_derived import drop_test_model


def test_cfm_drop_test_coarse():
    """The paper's drop test, 8 mm, 2 mm elements: a plausible, balanced, hourglass-free impact."""
    from cfm_core.material.registry import make_material

    mat = make_material("cfm", {}, "long-term", False)
    r = NumbaExplicitBackend().run(drop_test_model(mat, thickness=8e-3, h=2e-3))
    peak = r.acceleration.max() / 9.81
    assert 30.0 < peak < 120.0, peak
    assert r.info["stop_reason"] == "separated"
    assert r.energy_error() < 1e-2 and r.hourglass_ratio() < 0.1
    assert r.info["max_sphere_penetration"] < 1e-14
