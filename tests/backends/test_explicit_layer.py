"""The shared explicit layer (cfm_backends.explicit): numpy only, one declaration of the options,
reference geometry against closed forms."""

import math
import subprocess
import sys

import numpy as np
import pytest

from cfm_backends.explicit import geometry
from cfm_backends.explicit.options import ExplicitOptions
from cfm_core.errors import InputError


def test_importing_the_layer_imports_neither_numba_nor_torch():
    code = ("import sys, cfm_backends.explicit.geometry, cfm_backends.explicit.options, "
            "cfm_backends.explicit.history, cfm_backends.explicit.errors, cfm_backends.explicit.checks; "
            "print('numba' in sys.modules, 'torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_options_checked_at_construction():
    assert ExplicitOptions().safety == 0.9 and ExplicitOptions().dt_max == math.inf
    with pytest.raises(InputError, match=r"option collapse = 1.0 is not allowed; expected a number in \[0, 1\)"):
        ExplicitOptions.from_mapping({"collapse": 1.0})
    with pytest.raises(InputError, match="hourglass_wave"):
        ExplicitOptions(hourglass_wave="bulk")


def test_sheared_brick_geometry_against_closed_forms():
    """A brick a x b x c sheared by x += s z: V0 = a b c, L = 1 / sqrt(2 sum |B_I|^2), the patch
    identities sum_I B_I = 0 and sum_I X_I (x) B_I = I, hourglass vectors orthogonal to linear fields."""
    a, b, c, s = 2e-3, 1e-3, 3e-3, 0.3
    X = np.array([[0, 0, 0], [a, 0, 0], [a, b, 0], [0, b, 0], [0, 0, c], [a, 0, c], [a, b, c], [0, b, c]], float)
    X[:, 0] += s * X[:, 2]
    V0, B, G, L = geometry.hex_geometry(X, np.arange(8)[None])
    assert V0[0] == pytest.approx(a * b * c, rel=1e-14)
    np.testing.assert_allclose(B[0].sum(0), 0.0, atol=1e-9)
    np.testing.assert_allclose(X.T @ B[0], np.eye(3), atol=1e-13)
    np.testing.assert_allclose(X.T @ G[0], 0.0, atol=1e-15)
    # for a parallelepiped the mean gradient is the exact gradient: B_I = J^-T dN_I/dxi at the centre
    Jm = np.array([[a, 0, s * c], [0, b, 0], [0, 0, c]]) / 2.0
    xi = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]])
    np.testing.assert_allclose(B[0], xi / 8.0 @ np.linalg.inv(Jm), rtol=1e-12, atol=1e-9)
    assert L[0] == pytest.approx(1.0 / math.sqrt(2.0 * (B[0] ** 2).sum()), rel=1e-15)
    _, _, _, Lc = geometry.hex_geometry((xi + 1) / 2 * a, np.arange(8)[None])
    assert Lc[0] == pytest.approx(a / math.sqrt(3.0), rel=1e-14)


def test_inverted_element_is_an_input_error_naming_it():
    X = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    with pytest.raises(InputError, match="element 0 has a non-positive Jacobian"):
        geometry.hex_geometry(X, np.array([[4, 5, 6, 7, 0, 1, 2, 3]]))


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_histories_are_recorded_at_least_at_the_output_rate(backend):
    """A 1 m single element (its size given in mm): the stable step (0.04 s) exceeded the load time,
    so the run took one step past its end time and wrote two rows with a 66 % energy error (exit 0),
    while the scene promises histories at least every 1 / output_rate."""
    import cfm_core as cfm

    scene = cfm.builtin_scene("single-element").with_overrides(size=1.0)
    model = cfm.build_model(scene)
    result = cfm.run_model(model, backend)
    t = np.asarray(result.t)
    interval = 1.0 / scene.settings.output_rate
    assert t.size > 200 and np.diff(t).max() <= interval * (1 + 1e-12)
    assert t[-1] <= float(model.end_time) + interval


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_prescribed_motion_ends_on_the_end_time(backend):
    """The last row of a prescribed-motion run is the state at the end time (as skfem's), not a row
    one stable step past it (5.0035 ms after a row at 4.9996 ms): it is interpolated between the
    rows around the end time, and every row before it is the run's own (a longer run's)."""
    import dataclasses

    import cfm_core as cfm

    model = cfm.build_model(cfm.builtin_scene("single-element"))
    result = cfm.run_model(model, backend)
    t = np.asarray(result.t)
    assert t[-1] == float(model.end_time) and np.all(np.diff(t) > 0.0)
    longer = cfm.run_model(dataclasses.replace(model, end_time=2 * model.end_time), backend)
    n = t.size - 1
    np.testing.assert_array_equal(np.asarray(longer.t)[:n], t[:n])
    f, tl = np.asarray(longer.reaction_force), np.asarray(longer.t)
    np.testing.assert_array_equal(f[:n], np.asarray(result.reaction_force)[:n])
    assert result.reaction_force[-1] == pytest.approx(np.interp(t[-1], tl, f), rel=1e-12)
    assert tl[n - 1] < t[-1] < tl[n]
