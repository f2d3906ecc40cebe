"""The paper's drop test with the real CFM material on the numba backend (coarse mesh)."""

import numpy as np
import pytest

pytest.importorskip("numba")
try:
    import cfm_backends.numba_explicit  # noqa: F401
except ImportError:  # package not installed: map the backends/ folder to cfm_backends
    import importlib.util
    import pathlib
    import sys

    _root = pathlib.Path(__file__).resolve().parents[2] / "backends"
    _spec = importlib.util.spec_from_file_location("cfm_backends", _root / "__init__.py",
                                                   submodule_search_locations=[str(_root)])
    sys.modules["cfm_backends"] = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(sys.modules["cfm_backends"])

from cfm_backends.numba_explicit import NumbaExplicitBackend  # noqa: E402
from cfm_backends.numba_explicit.fixtures import drop_test_model  # noqa: E402


def test_cfm_drop_test_coarse():
    """The paper's drop test, 8 mm, 2 mm elements: a plausible, balanced, hourglass-free impact."""
    from cfm_core.material import make_material

    mat = make_material("cfm", {}, "long-term", False)
    r = NumbaExplicitBackend().run(drop_test_model(mat, thickness=8e-3, h=2e-3))
    peak = r.acceleration.max() / 9.81
    assert 30.0 < peak < 120.0, peak
    assert r.info["stop_reason"] == "separated"
    assert r.energy_error() < 1e-2 and r.hourglass_ratio() < 0.1
    assert r.info["max_sphere_penetration"] < 1e-14
