"""Octahedrally symmetric quadrature rules on the unit sphere (Lebedev type), written for this project.

A rule approximates the mean over the unit sphere S^2 of a function of a direction n,

    <f> = 1/(4 pi) int_{S^2} f(n) dOmega  ~=  sum_j w_j f(n_j),     sum_j w_j = 1,

exactly for every polynomial of degree <= ``degree``. Every rule here is invariant under the
48 symmetries of the cube (sign changes and permutations of the axes). A function of the squared
components (n1^2, n2^2, n3^2), such as a fibre's squared stretch I4 = sum_a l_a^2 n_a^2 in the
principal frame, then needs one point per distinct squared triple: the sign images give the same
value. :func:`squared_directions` returns those triples with their summed weights; because the
set of triples is closed under permutations with equal weights, any symmetric law gives a
function symmetric in (l1, l2, l3), as isotropic terms must be.

The orbits (Lebedev 1976; points on the full sphere / distinct squared triples):

- a1: (1, 0, 0)                   6 / 3
- a2: (1, 1, 0) / sqrt 2         12 / 3
- a3: (1, 1, 1) / sqrt 3          8 / 1
- b(l): (l, l, sqrt(1 - 2 l^2))  24 / 3
- c(p): (p, sqrt(1 - p^2), 0)    24 / 6

The orbit weights and parameters below were computed for this project by
:func:`solve_rule` (moment equations of all even monomials up to the degree, solved with
``scipy.optimize.least_squares`` from random starts, accepted when every moment holds to 1e-13
with positive weights); ``tests/plugins/test_septa.py`` checks the stored values against the
exact moments (:func:`exact_moment`). The degree-11 rule is Lebedev's 50-point rule
(b-orbit l = 1/sqrt(11)).

Source: V. I. Lebedev, "Quadratures on a sphere", USSR Comput. Math. Math. Phys. 16 (1976) 10-24.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

#: degree -> ((orbit, total weight of the orbit, orbit parameter or None), ...); points on the sphere.
RULES = {
    11: (("a1", 0.07619047619047475, None), ("a2", 0.2708994708994709, None),
         ("a3", 0.16875000000000037, None), ("b", 0.48416005291005393, 0.30151134457776296)),
    15: (("a1", 0.06926406926407742, None), ("a3", 0.09555127268685744, None),
         ("b", 0.2850360310688938, 0.6943540066026657), ("b", 0.26665333705448074, 0.36960284645413705),
         ("c", 0.28349528992569023, 0.3742430390903522)),
    17: (("a1", 0.02296962296990793, None), ("a3", 0.0783499000998044, None),
         ("b", 0.19708169479659027, 0.18511563534506983), ("b", 0.23029131206556003, 0.395689473056123),
         ("b", 0.23862755738821975, 0.6904210483822956), ("c", 0.2326799126799175, 0.8781589106040563)),
}
POINTS = {11: 50, 15: 86, 17: 110}


def _orbit_squares(kind: str, q, bits=None) -> list[tuple[float, float, float]]:
    """Distinct squared triples (n1^2, n2^2, n3^2) of an orbit (sorted, permutation-closed).

    bits: round the free squared component to a multiple of 2^-bits first, so that every component
    and every partial sum is exact in float64 and the components sum to exactly 1.
    """
    def r(x):
        return x if bits is None else round(x * 2.0**bits) / 2.0**bits

    base = {"a1": (1.0, 0.0, 0.0), "a2": (0.5, 0.5, 0.0)}.get(kind)
    if kind == "a3":
        base = (r(1 / 3), r(1 / 3), 1.0 - 2.0 * r(1 / 3))
    elif kind == "b":
        base = (r(q * q), r(q * q), 1.0 - 2.0 * r(q * q))
    elif kind == "c":
        base = (r(q * q), 1.0 - r(q * q), 0.0)
    if base is None:
        raise ValueError(f"unknown orbit {kind!r}; known: a1, a2, a3, b, c")
    return sorted(set(itertools.permutations(base)))


def _assemble(orbits, bits=None) -> tuple[np.ndarray, np.ndarray]:
    weights, squares = [], []
    for kind, total, q in orbits:
        sq = _orbit_squares(kind, q, bits)
        squares += sq
        weights += [total / len(sq)] * len(sq)
    return np.array(weights), np.array(squares)


def squared_directions(degree: int = 17, bits: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Weights (k,) and squared direction components (k, 3) of the rule of ``degree``.

    Parameters
    ----------
    degree : int
        Polynomial degree of exactness, one of 11, 15, 17 (50, 86, 110 points on the sphere).
    bits : int, optional
        Round the squared components to multiples of 2^-bits (components and their sums then exact
        in float64, each row summing to exactly 1; the a3 orbit becomes 3 triples). With bits = 40
        the moments change by about 1e-12. None: unrounded.

    Returns
    -------
    weights : ndarray, shape (k,)
        Summed weights of the points sharing a squared triple (-); they sum to 1.
    squares : ndarray, shape (k, 3)
        (n1^2, n2^2, n3^2) of each distinct triple (-), each row summing to 1.

    Raises
    ------
    ValueError
        For a degree without a stored rule.
    """
    if degree not in RULES:
        raise ValueError(f"no sphere rule of degree {degree!r}; available degrees: {sorted(RULES)}")
    return _assemble(RULES[degree], bits)


def exact_moment(a: int, b: int, c: int) -> float:
    """Mean of n1^(2a) n2^(2b) n3^(2c) over the unit sphere.

    Parameters
    ----------
    a, b, c : int
        Half exponents (>= 0).

    Returns
    -------
    float
        (2a-1)!! (2b-1)!! (2c-1)!! / (2(a+b+c)+1)!! (-), the exact mean.
    """
    def dfact(n):
        return math.prod(range(n, 0, -2)) if n > 0 else 1

    return dfact(2 * a - 1) * dfact(2 * b - 1) * dfact(2 * c - 1) / dfact(2 * (a + b + c) + 1)


def moment_errors(weights, squares, degree: int) -> np.ndarray:
    """Rule minus exact mean for every even monomial up to ``degree``.

    Parameters
    ----------
    weights : ndarray, shape (k,)
        Weights of the squared triples (-).
    squares : ndarray, shape (k, 3)
        Squared direction components (-).
    degree : int
        Largest total degree 2(a+b+c) checked (monomials n1^2a n2^2b n3^2c with a >= b >= c).

    Returns
    -------
    ndarray
        Rule minus exact mean (-), one entry per monomial.
    """
    out = []
    for a in range(degree // 2 + 1):
        for b in range(a + 1):
            for c in range(b + 1):
                if 2 * (a + b + c) <= degree:
                    value = np.sum(weights * squares[:, 0] ** a * squares[:, 1] ** b * squares[:, 2] ** c)
                    out.append(value - exact_moment(a, b, c))
    return np.array(out)


def solve_rule(kinds, degree: int, tries: int = 400, seed: int = 0):
    """Find orbit weights and parameters of an octahedral rule with the given orbits (how RULES was made).

    Parameters
    ----------
    kinds : sequence of str
        Orbits ("a1", "a2", "a3", "b", "c"), e.g. ("a1", "a2", "a3", "b") for degree 11.
    degree : int
        Polynomial degree the rule must integrate exactly.
    tries : int
        Random starts of ``scipy.optimize.least_squares`` at most.
    seed : int
        Seed of the random starts.

    Returns
    -------
    tuple or None
        ((kind, weight, parameter), ...) as in :data:`RULES`, or None when no start converged to a rule
        with positive weights whose moments hold to 1e-13. Takes seconds to minutes.
    """
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)

    def orbits(x):
        out, i = [], 0
        for k in kinds:
            width = 2 if k in ("b", "c") else 1
            out.append((k, x[i], x[i + 1] if width == 2 else None))
            i += width
        return out

    for _ in range(tries):
        x0 = []
        for k in kinds:
            x0.append(rng.uniform(0.02, 0.4))
            if k in ("b", "c"):
                x0.append(rng.uniform(0.05, 0.7))
        res = least_squares(lambda x: moment_errors(*_assemble(orbits(x)), degree), x0,
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        w, sq = _assemble(orbits(res.x))
        if np.abs(res.fun).max() < 1e-13 and (w > 0).all() and (sq >= -1e-15).all():
            return tuple(orbits(res.x))
    return None
