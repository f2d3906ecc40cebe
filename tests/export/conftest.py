"""Fixtures of the export harness: the generated routines compiled once per session, and the
deformation histories they are driven along.

Without gfortran the tests skip with the reason; with ``CFM_REQUIRE_GFORTRAN=1`` (set by .ci/run)
a missing compiler fails them instead.
"""

import os

import numpy as np
import pytest

from cfm_core.export.generate import generate, sizes
from cfm_core.export.harness import compile_library, gfortran
from cfm_core.material import make_material


def _need_gfortran():
    if gfortran() is None:
        why = "gfortran is not installed (apt-get install gfortran); the export harness compiles the generated Fortran"
        if os.environ.get("CFM_REQUIRE_GFORTRAN") == "1":
            pytest.fail(why + " and CFM_REQUIRE_GFORTRAN=1 requires it")
        pytest.skip(why)


@pytest.fixture(scope="session")
def cfm():
    """The CFM with Table 1 values (long-term moduli)."""
    return make_material("cfm")


@pytest.fixture(scope="session")
def nstate(cfm):
    """Number of state variables of the CFM's routines (25)."""
    return sizes(cfm.spec)["NS"]


@pytest.fixture(scope="session")
def libs(cfm):
    """target -> compiled library of the CFM (compiled once per session, cached by source hash)."""
    _need_gfortran()
    out = {}
    for target in ("abaqus-umat", "abaqus-vumat", "lsdyna-umat"):
        ex = generate(cfm, target)
        out[target] = compile_library(ex.files[ex.manifest["source"]], target)
    return out


@pytest.fixture(scope="session")
def compiled():
    """(material name, target) -> compiled library, for other materials (compiled on demand)."""
    _need_gfortran()
    cache = {}

    def get(material, target):
        key = (material.name, target)
        if key not in cache:
            ex = generate(material, target)
            cache[key] = compile_library(ex.files[ex.manifest["source"]], f"{material.name}-{target}")
        return cache[key]

    return get


def uniaxial(rate, stretch, hold=0.0, n=40):
    """Uniaxial path at an engineering strain rate (1/s) to ``stretch``, optionally held (s);
    lateral stretch lam^-0.45 (slightly compressible), starting at F = I."""
    t_load = abs(stretch - 1.0) / rate
    t = np.linspace(0.0, t_load, n + 1)
    lam = np.linspace(1.0, stretch, n + 1)
    if hold:
        t = np.concatenate([t, t_load + np.geomspace(hold / 1e4, hold, n)])
        lam = np.concatenate([lam, np.full(n, stretch)])
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = lam, lam ** -0.45, lam ** -0.45
    return t, F


def simple_shear(rate, gamma, n=40):
    """Simple shear F = I + gamma e1 (x) e2 at a shear rate (1/s)."""
    t = np.linspace(0.0, gamma / rate, n + 1)
    F = np.tile(np.eye(3), (n + 1, 1, 1))
    F[:, 0, 1] = np.linspace(0.0, gamma, n + 1)
    return t, F


def random_path(seed, n=30, size=0.35, dt=2e-3):
    """A smooth random path from F = I through random deformation gradients (det F > 0)."""
    rng = np.random.default_rng(seed)
    knots = np.eye(3) + size * rng.standard_normal((4, 3, 3))
    knots[0] = np.eye(3)
    s = np.linspace(0.0, 3.0, n + 1)
    F = np.empty((n + 1, 3, 3))
    for k, x in enumerate(s):
        i = min(int(x), 2)
        w = x - i
        F[k] = (1 - w) * knots[i] + w * knots[i + 1]
    assert (np.linalg.det(F) > 0.2).all()
    return np.arange(n + 1) * dt, F


HISTORIES = {
    "compression 1/s": lambda: uniaxial(1.0, 0.6),
    "compression 100/s": lambda: uniaxial(100.0, 0.5),
    "tension 10/s": lambda: uniaxial(10.0, 1.4),
    "tension 1000/s": lambda: uniaxial(1000.0, 1.3),
    "relaxation": lambda: uniaxial(100.0, 0.7, hold=20.0),
    "simple shear": lambda: simple_shear(50.0, 0.8),
    "random 1": lambda: random_path(1),
    "random 2": lambda: random_path(2),
}
