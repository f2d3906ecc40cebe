"""skfem backend: Newton converges quadratically near the solution (consistent tangent)."""

import math

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_core.scene.builder import build_model
from cfm_core.simulation.registry import get_backend
from cfm_core.scene.scene import builtin_scene


def _orders(res, floor):
    r = np.asarray(res)
    r = r[r > floor]
    return [math.log(r[k + 1] / r[k]) / math.log(r[k] / r[k - 1]) for k in range(1, r.size - 1)]


@pytest.mark.parametrize("scene, kw", [
    ("single-element", dict(stretch=0.5)),          # uniaxial compression, viscoelastic
    ("relaxation", dict(stretch=1.5, hold=0.01)),   # tension
])
def test_newton_is_quadratic(scene, kw):
    m = build_model(builtin_scene(scene).with_overrides(**kw))
    r = get_backend("skfem").run(m, quasi_static=True, record_newton=True, segment_steps=2,
                                 dt=m.prescribed.times[1] / 2)
    t, dt, res = r.info["newton"][0]  # a large first step: several iterations
    print(f"{scene}: residual norms (N) of the step to t = {t:g} s:", ", ".join(f"{x:.3e}" for x in res))
    assert len(res) >= 4
    p = _orders(res, floor=1e-8 * res[0])
    print("orders:", ", ".join(f"{x:.2f}" for x in p))
    assert p[-1] > 1.8  # asymptotically quadratic
    assert res[-1] < 1e-9 * res[0]
