"""Vectorisable maths of the numba element pass: vexp / vlog / vpow / vsqrt against mpmath and the
C library, and the vectorisable variant of each material's generated code against the original."""

import math

import mpmath
import numpy as np
import pytest

numba = pytest.importorskip("numba")
from numba import njit  # noqa: E402

from cfm_backends.numba_explicit import codegen  # noqa: E402
from cfm_backends.numba_explicit.kernels import vmath  # noqa: E402
from cfm_core.material.registry import make_material  # noqa: E402

ULP = 2.0 ** -52


@njit(error_model="numpy")
def _apply(kind, x, y, out):
    for i in range(x.shape[0]):
        if kind == 0:
            out[i] = vmath.vexp(x[i])
        elif kind == 1:
            out[i] = vmath.vlog(x[i])
        elif kind == 2:
            out[i] = vmath.vpow(x[i], y)
        else:
            out[i] = vmath.vsqrt(x[i])
    return out


def _run(kind, x, y=0.0):
    x = np.asarray(x, dtype=np.float64)
    return _apply(kind, x, y, np.empty_like(x))


def _rel_err(got, exact):
    return max(abs(mpmath.mpf(float(g)) - e) / abs(e) for g, e in zip(got, exact))


def test_vexp_within_one_ulp_of_mpmath():
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-700, 700, 300), rng.uniform(-1, 1, 300), [1e-300, -1e-17, 0.5, 1.0]])
    with mpmath.workdps(40):
        exact = [mpmath.exp(mpmath.mpf(float(v))) for v in x]
        assert _rel_err(_run(0, x), exact) <= 1.5 * ULP


def test_vexp_special_values():
    got = _run(0, [0.0, -0.0, 710.0, np.inf, -709.0, -np.inf, np.nan])
    assert got[0] == 1.0 and got[1] == 1.0            # exp(0) = 1 exactly (zero stress at rest)
    assert got[2] == np.inf and got[3] == np.inf
    assert got[4] == 0.0 and got[5] == 0.0            # below the smallest normal: 0
    assert np.isnan(got[6])


def test_vlog_within_two_ulp_of_mpmath():
    rng = np.random.default_rng(2)
    x = np.concatenate([np.exp(rng.uniform(-700, 700, 300)), rng.uniform(0.999, 1.001, 300),
                        rng.uniform(0.2, 5.0, 300), [5e-320, 1e-310, 2.0, 0.5]])
    with mpmath.workdps(40):
        exact = [mpmath.log(mpmath.mpf(float(v))) for v in x]
        got = _run(1, x)
        # absolute error relative to max(|log x|, 1 ulp of 1): near x = 1 the result is tiny
        err = max(abs(mpmath.mpf(float(g)) - e) / max(abs(e), mpmath.mpf(ULP)) for g, e in zip(got, exact))
    assert err <= 2.5 * ULP


def test_vlog_special_values():
    got = _run(1, [1.0, 0.0, -1.0, np.inf, np.nan])
    assert got[0] == 0.0                               # log(1) = 0 exactly
    assert got[1] == -np.inf and got[3] == np.inf
    assert np.isnan(got[2]) and np.isnan(got[4])


@pytest.mark.parametrize("y", [-2.0 / 3.0, 1.7, -9.5])
def test_vpow_against_mpmath(y):
    x = np.linspace(0.1, 10.0, 200)
    with mpmath.workdps(40):
        exact = [mpmath.power(mpmath.mpf(float(v)), mpmath.mpf(y)) for v in x]
        # error bound of exp(y log x): (1 + |y log x|) ulp from log's error, ~2 ulp more
        assert _rel_err(_run(2, x, y), exact) <= (3.0 + abs(y) * math.log(10.0)) * ULP
    assert _run(2, [1.0], y)[0] == 1.0                # 1^y = 1 exactly (J = 1 at rest)


def test_vsqrt_is_the_correctly_rounded_square_root():
    x = np.random.default_rng(3).uniform(0.0, 1e3, 1000)
    assert np.array_equal(_run(3, x), np.sqrt(x))
    assert np.isnan(_run(3, [-1.0])[0])


@pytest.mark.parametrize("name", ["cfm", "ogden", pytest.param("mooney-rivlin", marks=pytest.mark.slow),
                                  pytest.param("neo-hookean", marks=pytest.mark.slow),
                                  pytest.param("cfm-septa", marks=pytest.mark.slow)])
def test_vector_variant_equals_the_material_code(name):
    """The vectorisable variant (vector_source) gives the original's 12 values to round-off, and
    exactly zero stress at the reference state."""
    material = make_material(name)
    src = material.numba_source()
    names = codegen.material_functions(src)
    scalar = {"math": math}
    exec(compile(src, "<material>", "exec"), scalar)          # plain Python, C library maths
    vector = {"math": math, "vexp": vmath.vexp, "vlog": vmath.vlog, "vpow": vmath.vpow,
              "vsqrt": vmath.vsqrt, "njit": njit}
    exec(compile(codegen.vector_source(src, names), "<vector>", "exec"), vector)
    for n in names:
        vector[n + codegen.VECTOR] = njit(error_model="numpy")(vector[n + codegen.VECTOR])
    fn = "psi_grad_hess_diag" if "psi_grad_hess_diag" in names else "psi_grad"
    fv = vector[fn + codegen.VECTOR]
    p = np.ascontiguousarray(material.param_array(), dtype=np.float64)
    rng = np.random.default_rng(4)
    for k, m in enumerate([(1.0, 1.0, 1.0), *map(tuple, rng.uniform(0.5, 1.6, (40, 3)))]):
        want = np.array(scalar[fn](*m, p.tolist()), dtype=float)
        got = np.array(fv(*m, p), dtype=float)
        scale = np.abs(want).max() + 1e-300
        assert np.abs(got - want).max() <= 1e-12 * scale, (name, m)
        if k == 0:
            assert np.all(got[:6] == want[:6])                 # stress at rest: the same bits


def test_vector_source_rewrites_powers_and_calls():
    src = ("def f(x, p):\n    return math.exp(x) + x ** (2.0 / 3.0) + x ** (-3) + x ** 2 + math.sqrt(x) + g(x)\n"
           "def g(x):\n    return math.log(x) + math.atan(x)\n")
    out = codegen.vector_source(src, ["f", "g"])
    assert "def f_v(" in out and "def g_v(" in out and "g_v(x)" in out
    assert "vexp(x)" in out and "vlog(x)" in out and "vsqrt(x)" in out
    assert "vpow(x, 0.6666666666666666)" in out
    assert "1.0 / (x * x * x)" in out and "x * x" in out
    assert "math.atan(x)" in out                               # no variant: kept as it is
    assert "**" not in out


@pytest.mark.slow  # compiles cfm-septa's kernels (~40 s of CPU)
def test_materials_too_large_to_inline_call_their_scalar_functions():
    """cfm-septa's source (110 directions) is beyond VECTOR_MAX_SOURCE: its block loop calls the
    scalar functions (compile time); cfm's is inlined in its vectorisable variant."""
    septa = codegen.module_source(make_material("cfm-septa"))
    assert len(make_material("cfm-septa").numba_source()) > codegen.VECTOR_MAX_SOURCE
    assert "psi_grad_hess_diag_v = psi_grad_hess_diag\n" in septa and "def psi_grad_hess_diag_v(" not in septa
    cfm = codegen.module_source(make_material("cfm"))
    assert "def psi_grad_hess_diag_v(" in cfm and "vexp(" in cfm
