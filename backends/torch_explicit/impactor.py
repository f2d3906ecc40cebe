"""Impactor surfaces in torch: signed gap, outward normal and the exact landing of a pushed node.

The formulas of the numpy reference :func:`cfm_core.scene.impactor.gap`, one per shape, on
tensors with the component axis first: ``P`` (3, ...) is the point minus the impactor's
reference point (m). Shapes: ``"sphere"``, ``"hemisphere"`` (lower half only, +inf above the
centre plane), ``"flat"`` (cylinder of radius R with its rim rounded by r), ``"plane"`` (the
half-space above the reference point's z).

:func:`land` gives the exact push s >= 0 of a point along a unit direction D onto the surface,
g(P + s D) = 0, and its derivative with respect to the impactor's move d (the point relative to
the moved impactor is P - d): ds/dd = N / (N . D), N the outward normal at the landing point
(implicit differentiation of g(P - d + s D) = 0, |grad g| = 1). Sphere and hemisphere: the
root of a quadratic (the one-material contact's formula); plane: linear; flat: Newton along the
ray, which for a convex body (g convex along any line) overshoots once to g >= 0 and then
decreases monotonically to the root (quadratically): a face reached in the first step is exact
after one iteration, the rounded rim to round-off in a few more (``FLAT_ITERATIONS``).
"""

from __future__ import annotations

import torch

SHAPES = ("hemisphere", "sphere", "flat", "plane")
FLAT_ITERATIONS = 8


def _norm3(P):
    return torch.sqrt(P[0] * P[0] + P[1] * P[1] + P[2] * P[2])


def _ez(P):
    """(3, ...) the unit vector -e_z (the impactor's downward normal) shaped like P."""
    n = torch.zeros_like(P)
    n[2].fill_(-1.0)        # a Python scalar in the kernel: no host tensor made (capture-safe)
    return n


def gap(shape: str, R: float, r: float, P):
    """Signed gap g (...) (m) and the impactor's outward unit normal n (3, ...) at P = x - c (3, ...).

    The formulas of :func:`cfm_core.scene.impactor.gap` (g > 0 outside, < 0 inside, +inf above a
    hemisphere's centre plane; n the direction that pushes a penetrating point out).

    Raises
    ------
    ValueError
        An unknown shape (an internal error: the model's shape is checked when it is built).
    """
    if shape in ("sphere", "hemisphere"):
        d = _norm3(P)
        pos = d > 0.0
        n = torch.where(pos, P / torch.where(pos, d, 1.0), _ez(P))
        g = d - R
        if shape == "hemisphere":
            g = torch.where(P[2] < 0.0, g, torch.inf)
        return g, n
    if shape == "plane":
        return -P[2], _ez(P)
    if shape == "flat":
        a = R - r
        rho = torch.hypot(P[0], P[1])
        pos = rho > 0.0
        rs = torch.where(pos, rho, 1.0)
        er = torch.stack([torch.where(pos, P[0] / rs, 1.0), torch.where(pos, P[1] / rs, 0.0), torch.zeros_like(rho)])
        q1, q2 = rho - a, r - P[2]
        out1, out2 = q1.clamp_min(0.0), q2.clamp_min(0.0)
        dist = torch.hypot(out1, out2)
        g = dist + torch.maximum(q1, q2).clamp_max(0.0) - r
        ez = _ez(P)
        corner = (q1 > 0.0) & (q2 > 0.0)
        side = ~corner & (q1 > q2)
        n = torch.where(side, er, ez)
        safe = torch.where(dist > 0.0, dist, 1.0)
        n = torch.where(corner, (out1 * er + out2 * ez) / safe, n)
        return g, n
    raise ValueError(f"unknown impactor shape {shape!r}; one of {SHAPES}")


def land(shape: str, R: float, r: float, P, D):
    """(s (...), ds/dd (3, ...)): the push s >= 0 along D (3, ...) (unit) with g(P + s D) = 0.

    P (3, ...): the point relative to the (moved) impactor (m). Where the point is not inside
    (g(P) >= 0, or outside a sphere) s = 0 and ds/dd = 0. ds/dd (1/1, per m of impactor move):
    N / (N . D), N the outward normal at the landing point (0 where N . D <= 0).
    """
    if shape in ("sphere", "hemisphere"):
        cq = P[0] * P[0] + P[1] * P[1] + P[2] * P[2] - R * R
        b = P[0] * D[0] + P[1] * D[1] + P[2] * D[2]
        disc = torch.sqrt(torch.clamp(b * b - cq, min=0.0))
        s = torch.where(b > 0.0, -cq / (b + disc), disc - b)
        e = P + s * D
        den = e[0] * D[0] + e[1] * D[1] + e[2] * D[2]
        ds = torch.where(den <= 0.0, 0.0, e / torch.where(den <= 0.0, 1.0, den))
        inside = cq < 0.0
    elif shape == "plane":
        inside = P[2] > 0.0
        dz = torch.where(D[2] < 0.0, D[2], -1.0)
        s = -P[2] / dz
        ds = torch.stack([torch.zeros_like(s), torch.zeros_like(s), 1.0 / dz])
    elif shape == "flat":
        g, n = gap(shape, R, r, P)
        inside = g < 0.0
        s = torch.zeros_like(g)
        for _ in range(FLAT_ITERATIONS):
            gp = (n * D).sum(0)
            s = torch.where(inside & (gp > 0.0), s - g / torch.where(gp > 0.0, gp, 1.0), s)
            g, n = gap(shape, R, r, P + s * D)
        nd = (n * D).sum(0)
        ds = torch.where(nd > 0.0, n / torch.where(nd > 0.0, nd, 1.0), 0.0)
    else:
        raise ValueError(f"unknown impactor shape {shape!r}; one of {SHAPES}")
    return torch.where(inside, s, 0.0).clamp_min(0.0), torch.where(inside, ds, 0.0)
