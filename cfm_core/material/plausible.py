"""Plausibility of a bound material's values: unit slips (kPa for Pa) and near-liquid Prony series.

:meth:`MaterialSpec.bind <cfm_core.material.MaterialSpec.bind>` accepts every value inside a
parameter's range; some legal values are almost surely a unit written wrongly: ``k1 = 1.32``
typed in kPa is read as 1.32 Pa and gives a plausible, wrong drop test. :func:`check_material`
says so before anything runs, one paragraph per finding, and the run goes ahead as given (a
legal value is never refused on a guess). Works for any registered material, from its parameter
declarations (:attr:`Parameter.scale <cfm_core.material.parameters.Parameter.scale>`):

- a modulus (unit Pa) more than :data:`SCALE_FACTOR` = 100 times below (or above) its typical
  value (the declaration's ``typical``, else its default: Table 1 for ``cfm``), with the unit
  (kPa, MPa) that brings it back to that scale;
- a small-strain Poisson ratio nu = (3K - 2G) / (2 (3K + G)) below :data:`NU_WARN` = 0.45 and
  more than :data:`NU_MARGIN` below the material's own with its defaults (K, G: instantaneous
  bulk and shear moduli of the tangent at F = I): soft tissue is nearly incompressible
  (Table 1: nu = 0.476), so a bulk modulus in kPa (666.1 for 666.1e3 Pa) gives nu < 0;
  a built-in whose defaults are compressible (cfm-septa: 0.33) is not warned about as given;
- a Prony long-term coefficient gamma_inf in [1e-6, 1e-3) (below 1e-6 it is refused, see
  :mod:`cfm_core.material.prony`).
"""

from __future__ import annotations

import math

import numpy as np

from .prony import GAMMA_INF_MIN, GAMMA_INF_WARN

#: A modulus this many times below (or above) its typical value is warned about.
SCALE_FACTOR = 100.0
#: Units a modulus is often typed in instead of Pa, with their factor to Pa.
MODULUS_SLIPS = (("kPa", 1e3), ("MPa", 1e6))
#: Small-strain Poisson ratios below this are warned about (when also below the defaults' by NU_MARGIN).
NU_WARN = 0.45
#: How far below the material's own default Poisson ratio a value must be to be warned about (-).
NU_MARGIN = 0.05


def small_strain_moduli(material) -> tuple[float, float]:
    """Instantaneous small-strain bulk and shear moduli (K, G) of a material, from its tangent at F = I.

    The isochoric and the volumetric parts of the tangent are formed separately. K comes from the
    volumetric part alone: the isochoric part is deviatoric (CC_1111 + 2 CC_1122 = 4G/3 - 4G/3 = 0
    in exact arithmetic), so adding it contributes only round-off of order 1e-16 G, which swamped
    K when G >> K (mu = 1e306 Pa with kappa = 666.1 kPa gave K = 0). G is CC_1212 of the whole
    tangent, :func:`cfm_core.material.reference.tangent` (the volumetric part adds -U'(1) = 0 for a
    stress-free reference: no cancellation).

    Parameters
    ----------
    material : Material
        A bound (isotropic, decoupled isochoric + volumetric) material.

    Returns
    -------
    K : float
        Bulk modulus (Pa): (CC_1111 + 2 CC_1122) / 3 of the volumetric part, U''(1).
    G : float
        Shear modulus (Pa): CC_1212, the instantaneous one (long-term moduli times 1 / gamma_inf).
    """
    from . import kinematics as kin
    from .reference import principal_response  # deferred: imports the generated kernels

    m, Q, _ = kin.principal(np.eye(3))
    g, h = principal_response(material, m, "psi_grad", "psi_hess")
    vol = kin.tangent_from_principal(m, Q, g[:, 3:], h[:, 6:])[0]
    full = kin.tangent_from_principal(m, Q, g[:, :3] + g[:, 3:], h[:, :6] + h[:, 6:])[0]  # reference.tangent's sum
    return float(vol[0, 0, 0, 0] + 2.0 * vol[0, 0, 1, 1]) / 3.0, float(full[0, 1, 0, 1])


def poisson_ratio(K: float, G: float) -> float:
    """Small-strain Poisson ratio nu = (3K - 2G) / (2 (3K + G)) (-).

    Evaluated with K and G divided by the larger of |K|, |G| (the same ratio), so that 3K or 3K + G
    cannot overflow (K = 1e308 Pa gave inf / inf = nan).

    Parameters
    ----------
    K, G : float
        Bulk and shear moduli (Pa).

    Returns
    -------
    float
        nu (-); 0.5 for an incompressible material, -1 where G >> K, nan when 3K + G = 0 or a
        modulus is not finite.
    """
    scale = max(abs(K), abs(G))
    if not (math.isfinite(scale) and scale > 0.0):
        return math.nan
    k, g = K / scale, G / scale
    den = 2.0 * (3.0 * k + g)
    return (3.0 * k - 2.0 * g) / den if den else math.nan


def check_material(material, above: bool = True) -> list[str]:
    """Warnings about a bound material's values that are probably unit slips or near-liquid.

    Parameters
    ----------
    material : Material
        A bound material (any registered spec).
    above : bool
        Also warn about moduli far above their typical values (default). False for the layers and
        parts of a specimen, which are often stiffer tissues than the typical values describe (skin
        at mu = 4e5 Pa in a Neo-Hookean material whose typical mu is fat's 1000 Pa): a kPa slip
        leaves a value far below, which is still warned about.

    Returns
    -------
    list of str
        One paragraph per finding (see the module text), naming the parameter, its value, the
        unit, the typical value and the likely slip, e.g. "[material] k1 = 1.32 Pa is 1000x below
        the typical 1320 Pa of material 'cfm' (Table 1): was it kPa? Write k1 = 1320 ...". Empty
        when nothing looks wrong. The run goes ahead as given.
    """
    warnings = {}
    for p in material.spec.energy_parameters:
        if p.unit == "Pa":
            text = _scale_warning(material, p, above)
            if text:
                warnings[p.name] = text
        elif p.unit == "-" and above:
            text = _ratio_warning(material, p)
            if text:
                warnings[p.name] = text
    poisson = _poisson_warning(material)
    if poisson:
        name, text, short = poisson
        warnings[name] = f"{warnings[name]} {short}" if name in warnings else f"[material] {text}"
    out = list(warnings.values())
    if not material.elastic and material.spec.prony is not None:
        g_inf = material.gamma_inf
        if GAMMA_INF_MIN <= g_inf < GAMMA_INF_WARN:
            out.append(f"[material] the Prony coefficients leave gamma_inf = 1 - sum g_i = {g_inf:.3g} (-), below "
                       f"{GAMMA_INF_WARN:g}: the tissue relaxes to almost a liquid and, with long-term moduli, the "
                       f"instantaneous moduli are {1.0 / g_inf:.3g} times the written ones (Table 1: gamma_inf = "
                       f"0.021). It runs as given; values below {GAMMA_INF_MIN:g} are refused.")
    return out


#: Relative round-off of J = det F in float64 (-): about the machine epsilon; times a volumetric modulus,
#: the noise in the pressure (kappa = 6.7e20 Pa: rotations gave +-1.5e5 Pa of pressure, each backend its own).
ROUNDOFF_J = float(np.finfo(np.float64).eps)


def _scale_warning(material, p, above: bool = True) -> str:
    """The warning for a modulus more than SCALE_FACTOR times away from its typical value (below it
    only, unless ``above``), or ""."""
    value, scale = float(material.values[p.name]), p.scale
    if not (value > 0.0 and scale > 0.0):
        return ""
    ratio = scale / value
    src = " (Table 1)" if "Table 1" in p.description else ""
    where = f"the typical {scale:g} Pa of material '{material.name}'{src}"
    if ratio > SCALE_FACTOR:
        unit, factor = min(MODULUS_SLIPS, key=lambda s: abs(math.log10(value * s[1] / scale)))
        hint = ""
        if abs(math.log10(value * factor / scale)) <= 1.0:
            hint = (f" Was it {unit}? Write {p.name} = {value * factor:g} (--param {p.name}={value * factor:g}); "
                    f"every value is in SI units.")
        return f"[material] {p.name} = {value:g} Pa is {_times(ratio)}x below {where}.{hint} It runs as given."
    if above and ratio < 1.0 / SCALE_FACTOR:
        unit, factor = min(MODULUS_SLIPS, key=lambda s: abs(math.log10(value / s[1] / scale)))
        hint = ""
        if abs(math.log10(value / factor / scale)) <= 1.0:
            hint = (f" Was it converted from {unit} to Pa twice? Then write {p.name} = {value / factor:g}; every "
                    f"value is in SI units.")
        vol = material.spec.volumetric
        if vol is not None and p in vol.parameters:
            noise = value * ROUNDOFF_J
            hint += (f" The pressure it gives carries the round-off of J in float64 times {p.name}: about {noise:.2g} "
                     f"Pa, so stresses below that are noise, even under a pure rotation.")
        return f"[material] {p.name} = {value:g} Pa is {_times(1.0 / ratio)}x above {where}.{hint} It runs as given."
    return ""


def _ratio_warning(material, p) -> str:
    """The warning for a dimensionless energy parameter (an exponent such as the fibres' k2) more
    than SCALE_FACTOR times its typical value, or "": no unit can slip there, but the value is
    far outside what the material was fitted with (k2 = 500 against Table 1's 1.66 ran a drop test
    to 207 g without a word)."""
    value, scale = float(material.values[p.name]), p.scale
    if not (scale > 0.0 and value > SCALE_FACTOR * scale):
        return ""
    src = " (Table 1)" if "Table 1" in p.description else ""
    what = p.description.replace(" (Table 1)", "").strip()
    return (f"[material] {p.name} = {value:g} (-, {what}) is {_times(value / scale)}x the typical {scale:g} of "
            f"material '{material.name}'{src}: far outside the values the material was fitted with. It runs as given.")


def _times(ratio: float) -> str:
    """A ratio above 100 to 3 significant digits, without exponent up to 1e15: 1000.0000000000001 -> "1,000";
    1.5e294 -> "1.5e+294"."""
    if not math.isfinite(ratio):  # a value near the smallest float: 5e-324 Pa is "inf times" below
        return "more than 1e308"
    return f"{float(f'{ratio:.3g}'):,.0f}" if ratio < 1e15 else f"{ratio:.3g}"  # not 300 digits for 1e300


def _poisson_warning(material):
    """(volumetric parameter name, sentence, shorter sentence added to that parameter's scale
    warning) when the small-strain Poisson ratio is far below 0.5, or None."""
    vol = material.spec.volumetric
    if vol is None or not vol.parameters:
        return None
    try:
        K, G = small_strain_moduli(material)
        K0, G0 = small_strain_moduli(material.spec.bind(None, material.moduli, material.elastic))
    except (ValueError, ArithmeticError):  # InputError, NumericalError: the run reports them
        return None
    nu, nu0 = poisson_ratio(K, G), poisson_ratio(K0, G0)
    if not (nu < NU_WARN and nu < nu0 - NU_MARGIN):
        return None
    name = vol.parameters[0].name
    named = ", ".join(f"{n} = {material.values[n]:g} Pa" for n in (q.name for q in vol.parameters if q.unit == "Pa"))
    iso = ", ".join(q.name for q in material.spec.energy_parameters
                    if q.unit == "Pa" and q not in vol.parameters) or "the isochoric parameters"
    scaled = " over gamma_inf" if material.iso_scale != 1.0 else ""
    k_needed = 2.0 * G * (1.0 + NU_WARN) / (3.0 * (1.0 - 2.0 * NU_WARN))
    moduli = (f"the small-strain Poisson ratio nu = {nu:.3g} (bulk modulus K = {K:.4g} Pa, shear modulus "
              f"G = {G:.4g} Pa instantaneous, from {iso}{scaled}; material '{material.name}' with its defaults: "
              f"nu = {nu0:.3g})")
    default_scale = material.spec.bind(None, material.moduli, material.elastic).iso_scale
    prony_cause = ""
    if material.iso_scale > 2.0 * default_scale:  # the Prony series, not kappa, lowered nu
        prony_cause = (f" The Prony coefficients leave gamma_inf = {1.0 / material.iso_scale:.3g} "
                       f"({1.0 / default_scale:.3g} with the defaults), which raises the instantaneous shear modulus "
                       f"{material.iso_scale / default_scale:.3g}x: check the g_i too.")
    text = (f"{named or name} gives {moduli}, far from 0.5: tissue is nearly incompressible. nu >= {NU_WARN:g} "
            f"needs K >= {k_needed:.4g} Pa; check {name} (in Pa, not kPa) and {iso}.{prony_cause} It runs as given.")
    return name, text, f"It makes {moduli}."
