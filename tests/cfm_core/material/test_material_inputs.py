"""Inputs that passed a check and then failed or misled (issue 20 item 5): the Prony long-term
coefficient computed one way (exact sum) for the check and the computation, with a floor; material
values far from their physical range warned about with the likely unit slip, for any material."""

import math

import numpy as np
import pytest

from cfm_core import make_material
from cfm_core.errors import InputError
from cfm_core.material import prony
from cfm_core.material.plausible import check_material, poisson_ratio, small_strain_moduli
from cfm_core.material.registry import get_material


def test_a_sum_of_one_in_decimal_arithmetic_is_refused_not_divided_by():
    """g1 = 0.471 with Table 1's g2 = 0.435, g3 = 0.094: the naive float sum 0.9999999999999999 passed
    the old check, then 1 / (1 - fsum) divided by zero; now one InputError naming gamma_inf."""
    assert sum([0.471, 0.435, 0.094]) < 1.0 and math.fsum([0.471, 0.435, 0.094]) == 1.0
    with pytest.raises(InputError, match=r"g1 = 0.471, g2 = 0.435, g3 = 0.094 leave .*gamma_inf .* = 0 \(-\).*at least 1e-06"):
        make_material("cfm", {"g1": 0.471})


def test_gamma_inf_one_ulp_above_zero_is_refused():
    """g_inf = 1.1e-16 was accepted and gave a 4.8 GPa fat specimen (shared case prony-sum-rounding)."""
    g = [0.47099999999999986, 0.435, 0.094]
    assert 0.0 < prony.gamma_inf(g) < 1e-15
    with pytest.raises(InputError, match=r"gamma_inf .* = 1.11e-16"):
        make_material("cfm", {"g1": g[0]})


@pytest.mark.parametrize("g1, refused", [(0.98 - 1e-7, True), (0.98 - 2e-6, False)])
def test_the_floor_is_gamma_inf_1e_6_with_the_exact_sum(g1, refused):
    params = {"g1": g1, "g2": 0.01, "g3": 0.01}
    if refused:
        with pytest.raises(InputError, match="at least 1e-06"):
            make_material("cfm", params)
    else:
        m = make_material("cfm", params)
        assert m.gamma_inf == 1.0 - math.fsum([g1, 0.01, 0.01]) and m.iso_scale == 1.0 / m.gamma_inf


def test_every_use_of_gamma_inf_is_the_exact_sum():
    """Gammas whose naive float sum differs from the exact one: the relaxation function's limit, the
    one-step factor and the moduli factor all use 1 - fsum (the old relaxation function used np.sum)."""
    g = np.array([0.1, 0.2, 0.3])
    exact = 1.0 - math.fsum(g)
    assert 1.0 - (g[0] + g[1] + g[2]) != exact  # the two summations differ here
    m = make_material("cfm", {"g1": 0.1, "g2": 0.2, "g3": 0.3})
    assert m.gamma_inf == exact == prony.gamma_inf(g) and m.iso_scale == 1.0 / exact
    taus = np.array([1e-3, 0.1, 10.0])
    assert prony.relaxation_function(np.array([1e6]), g, taus)[0] == exact
    assert prony.effective_factor(1e13, g, taus) == pytest.approx(exact, abs=1e-12)
    assert make_material("cfm", elastic=True).gamma_inf == 1.0


def test_numba_solver_uses_the_material_gamma_inf():
    pytest.importorskip("numba")
    from cfm_backends.numba_explicit.kernels import layout as K
    from cfm_backends.numba_explicit.options import NumbaOptions
    from cfm_backends.numba_explicit.solver import prepare
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    model = build_model(builtin_scene("single-element"), material=make_material("cfm", {"g1": 0.1, "g2": 0.2, "g3": 0.3}))
    assert prepare(model, NumbaOptions()).par[K.P_GINF] == model.material.gamma_inf


@pytest.mark.parametrize("name", ["cfm", "cfm-septa", "neo-hookean", "mooney-rivlin", "ogden"])
def test_the_defaults_of_every_builtin_material_get_no_warning(name):
    for moduli in ("long-term", "instantaneous"):
        assert check_material(make_material(name, moduli=moduli)) == []


@pytest.mark.parametrize("name, value, factor, unit", [("k1", 1.32, 1000, "kPa"), ("c", 0.01, 1000, "kPa"),
                                                       ("kappa", 0.6661, 1e6, "MPa")])
def test_a_modulus_typed_in_kpa_is_warned_about_with_the_value_to_write(name, value, factor, unit):
    notes = check_material(make_material("cfm", {name: value}))
    assert len(notes) == 1
    right = f"{value * factor:g}"
    assert f"[material] {name} = {value:g} Pa is {factor:,.0f}x below the typical {right} Pa of material 'cfm' (Table 1)" \
        in notes[0]
    assert f"Was it {unit}? Write {name} = {right} (--param {name}={right})" in notes[0]


@pytest.mark.parametrize("value, warned", [(1320 / 99, False), (1320 / 101, True), (1320 * 99, None),
                                           (1320 * 101, True)])
def test_the_scale_bound_is_100x_either_way(value, warned):
    notes = [n for n in check_material(make_material("cfm", {"k1": value})) if "k1 = " in n and "typical" in n]
    assert len(notes) == int(bool(warned))


def test_small_strain_moduli_match_the_closed_form():
    """neo-Hookean mu/2 (I1bar - 3) + Ogden volumetric: G = mu, K = kappa exactly (U''(1) = kappa)."""
    K, G = small_strain_moduli(make_material("neo-hookean", {"mu": 2000.0, "kappa": 5e4}))
    assert K == pytest.approx(5e4, rel=1e-12) and G == pytest.approx(2000.0, rel=1e-12)
    assert poisson_ratio(5e4, 2000.0) == pytest.approx((3 * 5e4 - 4000.0) / (2 * (3 * 5e4 + 2000.0)), rel=1e-15)
    # cfm, long-term moduli: the instantaneous G is the written one over gamma_inf
    K_lt, G_lt = small_strain_moduli(make_material("cfm"))
    K_in, G_in = small_strain_moduli(make_material("cfm", moduli="instantaneous"))
    assert G_lt == pytest.approx(G_in / prony.gamma_inf([0.45, 0.435, 0.094]), rel=1e-12) and K_lt == K_in == 666.1e3


def test_kappa_in_kpa_names_the_poisson_ratio_and_both_moduli():
    """kappa = 666.1 (kPa typed as Pa): nu = (3K - 2G) / (2 (3K + G)) < 0 with G = 31 905 Pa (Table 1,
    instantaneous); one warning on kappa with the ratio, the bulk and the shear modulus."""
    (note,) = check_material(make_material("cfm", {"kappa": 666.1}))
    G = 31904.761904761894  # (instantaneous Table 1)
    nu = (3 * 666.1 - 2 * G) / (2 * (3 * 666.1 + G))
    assert "kappa = 666.1 Pa is 1,000x below" in note and "Write kappa = 666100" in note
    assert f"Poisson ratio nu = {nu:.3g}" in note and "K = 666.1 Pa" in note and "G = 3.19e+04 Pa" in note


def test_a_bulk_modulus_too_low_for_the_shear_modulus_is_warned_about_with_the_k_needed():
    (note,) = check_material(make_material("cfm", {"kappa": 5e4}))
    assert note.startswith("[material] kappa = 50000 Pa gives the small-strain Poisson ratio nu = 0.237")
    G = small_strain_moduli(make_material("cfm"))[1]
    assert f"needs K >= {2 * G * 1.45 / (3 * 0.1):.4g} Pa" in note and "c, k1" in note


def test_a_near_liquid_prony_series_is_warned_about():
    (note,) = [n for n in check_material(make_material("cfm", {"g1": 0.4705})) if "1 - sum g_i" in n]
    assert "gamma_inf = 1 - sum g_i = 0.0005" in note and "below 0.001" in note


def test_typical_scale_of_a_declaration_replaces_its_default():
    from cfm_core.material.parameters import positive, Parameter

    p = Parameter("mu", "Pa", 1.0, low=0.0, typical=1e4)
    assert p.scale == 1e4 and positive("mu", "Pa", 5.0).scale == 5.0
    assert p == Parameter("mu", "Pa", 1.0, low=0.0) and "typical" not in repr(p)  # advisory only
    assert get_material("cfm").parameters[0].scale == 10.0


@pytest.mark.parametrize("name, params, G", [
    ("neo-hookean", {"mu": 1e306}, 1e306),                       # G = mu
    ("cfm", {"k1": 1e300, "c": 10.0}, 10.0 + 0.5e300),            # G = c + k1/2 (instantaneous moduli)
    ("cfm", {"k1": 1320.0, "c": 1e290}, 1e290 + 660.0),
])
def test_the_bulk_modulus_next_to_a_huge_shear_modulus_is_not_lost_to_cancellation(name, params, G):
    """K was (CC_1111 + 2 CC_1122) / 3 of the whole tangent, (K + 4G/3) + 2 (K - 2G/3): at mu = 1e306 Pa the
    warning said "bulk modulus K = 0 Pa" for kappa = 666.1 kPa. The analytic small-strain moduli of the
    CFM (docs/conventions.md section 2) and the neo-Hookean: K = kappa = U''(1), G = c + k1/2 or mu."""
    mat = make_material(name, params, moduli="instantaneous")
    K, G_found = small_strain_moduli(mat)
    assert K == pytest.approx(666.1e3, rel=1e-12) and G_found == pytest.approx(G, rel=1e-12)
    (text,) = [t for t in check_material(mat) if "Poisson" in t]
    assert "bulk modulus K = 6.661e+05 Pa" in text and "nu = -1 " in text


def test_the_poisson_ratio_neither_overflows_nor_cancels():
    """nu = (3K - 2G) / (2 (3K + G)) from the moduli over the larger one: K = 1e308 Pa gave inf / inf = nan."""
    assert poisson_ratio(1e308, 1.0) == 0.5 and poisson_ratio(1e308, 1e308) == pytest.approx(0.125, rel=1e-15)
    assert poisson_ratio(666.1e3, 1e306) == -1.0
    assert poisson_ratio(666.1e3, 31904.76) == pytest.approx((3 * 666.1e3 - 2 * 31904.76) / (2 * (3 * 666.1e3 + 31904.76)),
                                                             rel=1e-15)
    assert math.isnan(poisson_ratio(0.0, 0.0)) and math.isnan(poisson_ratio(math.inf, 1.0))


def test_a_huge_bulk_modulus_is_told_with_the_pressure_noise_that_round_off_of_j_gives():
    """kappa = 6.661e20 Pa: four rotations of float64 F (det F - 1 = -4e-16 .. 3e-16) gave pressures of
    +-1.5e5 Pa, each backend its own, with only "1e15x above typical". The warning now says the noise."""
    from cfm_core.material.reference import stress_history

    (note,) = [n for n in check_material(make_material("cfm", {"kappa": 6.661e20})) if "kappa" in n]
    assert "round-off of J in float64 times kappa: about 1.5e+05 Pa" in note
    a = 0.3
    c, s = math.cos(a), math.sin(a)
    axis = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + s * K + (1 - c) * K @ K          # a rotation, rounded to float64
    sigma = stress_history(make_material("cfm", {"kappa": 6.661e20}), np.array([1e-3]), R[None])[0]
    noise = 6.661e20 * np.finfo(np.float64).eps
    assert np.abs(sigma).max() <= 10 * noise         # the noise the warning names, not more
    assert check_material(make_material("cfm", {"kappa": 6.661e5})) == []


def test_a_dimensionless_exponent_far_above_its_typical_value_is_warned():
    """k2 = 500 (Table 1: 1.66) ran the drop test to 207 g with exit 0 and no word; no unit can slip in an
    exponent, but the value is far outside what the material was fitted with."""
    (note,) = check_material(make_material("cfm", {"k2": 500.0}))
    assert "k2 = 500 (-, fibre stiffening exponent) is 301x the typical 1.66 of material 'cfm' (Table 1)" in note
    assert check_material(make_material("cfm", {"k2": 10.0})) == []          # stiff, but within reach
    assert check_material(make_material("cfm", {"k2": 500.0}), above=False) == []   # a layer's own material
