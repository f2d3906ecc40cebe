"""The physics monitor's scan of a state, compiled and parallel, in the solver's own numbering.

The monitor (:class:`cfm_core.simulation.checks.Monitor`) decides from a few extremes of the state
(:class:`cfm_core.simulation.scan.Extremes`: first non-finite node, deepest node behind the
plate, across each symmetry plane and inside the impactor, smallest corner-Jacobian ratio).
:class:`NumbaScan` computes them in one parallel pass over the positions the time loop holds,
in its renumbered order (``cfm_backends.explicit.renumber``), so that no permuted copy of the
state and no (e, 8) array of corner products is made; only the indices it reports are mapped
to the user's numbering.

The formulas are those of the numpy reference :class:`cfm_core.simulation.scan.Scan` in the same
order of operations (no fast-math), so the values are the same to the bit; the impactor's gap
is :func:`cfm_core.scene.impactor.gap`'s (the contact kernels' ``shape_gap`` is compiled with
fused multiply-adds and is not used here). Each chunk of nodes or elements keeps its own
extremes and a serial pass combines them; every comparison breaks ties by the smaller *user*
index (node; element then corner), so the result is the reference's whatever the number of
threads, the chunking or the renumbering (maximum and minimum with such a tie-break do not
depend on the order they are taken in).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from cfm_core.scene.impactor import bounds
from cfm_core.simulation.scan import Extremes, corner_volumes

from .kernels.layout import SH_FLAT, SH_HEMISPHERE, SH_PLANE, SH_SPHERE

SHAPES = {"hemisphere": SH_HEMISPHERE, "sphere": SH_SPHERE, "flat": SH_FLAT, "plane": SH_PLANE}
NODE_CHUNK = 4096      # nodes per chunk of the node pass
ELEMENT_CHUNK = 1024   # elements per chunk of the corner pass
_NONE = np.iinfo(np.int64).max  # "no index yet": loses every tie


@njit(cache=True, error_model="numpy")
def _depth(shape, R, r, px, py, pz):
    """Depth -g (m) of the point p (relative to the impactor's reference point) inside the
    impactor; :func:`cfm_core.scene.impactor.gap`'s g, operation for operation."""
    if shape == SH_PLANE:
        return pz
    if shape == SH_FLAT:
        q1 = math.hypot(px, py) - (R - r)
        q2 = r - pz
        g = math.hypot(max(q1, 0.0), max(q2, 0.0)) + min(max(q1, q2), 0.0) - r
        return -g
    if shape == SH_HEMISPHERE and not pz < 0.0:
        return -math.inf
    return -(math.sqrt(px * px + py * py + pz * pz) - R)


@njit(cache=True, error_model="numpy")
def _triple(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
    """Triple product (b - a) . ((c - a) x (d - a)) (m^3) of four points, in the order of
    :func:`cfm_core.simulation.scan.corner_volumes` (the dot product summed as (x + z) + y)."""
    e10 = bx - ax
    e11 = by - ay
    e12 = bz - az
    e20 = cx - ax
    e21 = cy - ay
    e22 = cz - az
    e30 = dx - ax
    e31 = dy - ay
    e32 = dz - az
    return (e10 * (e21 * e32 - e22 * e31) + e12 * (e20 * e31 - e21 * e30)) + e11 * (e22 * e30 - e20 * e32)


@njit(cache=True, error_model="numpy")
def _smaller(v, k, bv, bk):
    """Whether (ratio v, key k) beats the best (bv, bk) of a minimum: NaN first (numpy's argmin),
    then the smaller value, then the smaller key."""
    if v != v:
        return bv == bv or k < bk
    if bv != bv:
        return False
    return v < bv or (v == bv and k < bk)


@njit(parallel=True, cache=True, error_model="numpy")
def scan_state(x, unode, conn, ref, uelem, plate, planes, box, shape, R, r, c, fout, iout):
    """The extremes of the state x (n, 3) (m, internal numbering) into fout, iout.

    unode (n,), uelem (e,): user index of each internal node and element; conn (e, 8) internal
    connectivity; ref (e, 8) reference triple products; plate (1,) its z (m; empty: no plate);
    planes (k, 3) rows (axis, coordinate m, side); box (6,) the impactor's box widened by the
    tolerance (lo, hi; m) and c (3,) its reference point (m), shape -1: no impactor check.
    fout (3 + k,): plate depth, impactor depth, ratio, plane depths; iout (5 + k,): first
    non-finite user node, plate node, impactor node, user element * 8 + corner, plane nodes
    (the int64 maximum where none), and iout[4 + k] the number of nodes in the box.
    """
    n = x.shape[0]
    ne = conn.shape[0]
    k = planes.shape[0]
    nch = (n + NODE_CHUNK - 1) // NODE_CHUNK
    ech = (ne + ELEMENT_CHUNK - 1) // ELEMENT_CHUNK
    pf = np.full((nch, 2 + k), -np.inf)
    pi = np.full((nch, 3 + k), _NONE)
    pc = np.zeros(nch, dtype=np.int64)
    ef = np.full(ech, np.inf)
    ei = np.full(ech, _NONE)
    for ch in prange(nch):
        i0 = ch * NODE_CHUNK
        i1 = min(n, i0 + NODE_CHUNK)
        bad = _NONE
        for i in range(i0, i1):
            if not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1]) and math.isfinite(x[i, 2])):
                bad = min(bad, unode[i])
        pi[ch, 0] = bad
        if plate.shape[0]:
            bd = -np.inf
            bn = _NONE
            for i in range(i0, i1):
                v = plate[0] - x[i, 2]
                if v > bd or (v == bd and unode[i] < bn):
                    bd = v
                    bn = unode[i]
            pf[ch, 0] = bd
            pi[ch, 1] = bn
        if shape >= 0:
            bd = -np.inf
            bn = _NONE
            count = 0
            for i in range(i0, i1):
                if (x[i, 0] > box[0] and x[i, 1] > box[1] and x[i, 2] > box[2]
                        and x[i, 0] < box[3] and x[i, 1] < box[4] and x[i, 2] < box[5]):
                    count += 1
                    v = _depth(shape, R, r, x[i, 0] - c[0], x[i, 1] - c[1], x[i, 2] - c[2])
                    if v > bd or (v == bd and unode[i] < bn):
                        bd = v
                        bn = unode[i]
            pf[ch, 1] = bd
            pi[ch, 2] = bn
            pc[ch] = count
        for p in range(k):
            axis = int(planes[p, 0])
            cp = planes[p, 1]
            side = planes[p, 2]
            bd = -np.inf
            bn = _NONE
            for i in range(i0, i1):
                v = -(x[i, axis] - cp) * side
                if v > bd or (v == bd and unode[i] < bn):
                    bd = v
                    bn = unode[i]
            pf[ch, 2 + p] = bd
            pi[ch, 3 + p] = bn
    for ch in prange(ech):
        bv = np.inf
        bk = _NONE
        for e in range(ch * ELEMENT_CHUNK, min(ne, (ch + 1) * ELEMENT_CHUNK)):
            n = conn[e, 0]
            x0, y0, z0 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 1]
            x1, y1, z1 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 2]
            x2, y2, z2 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 3]
            x3, y3, z3 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 4]
            x4, y4, z4 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 5]
            x5, y5, z5 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 6]
            x6, y6, z6 = x[n, 0], x[n, 1], x[n, 2]
            n = conn[e, 7]
            x7, y7, z7 = x[n, 0], x[n, 1], x[n, 2]
            # corner a with its neighbours along xi, eta, zeta (VTK order)
            r0 = _triple(x0, y0, z0, x1, y1, z1, x3, y3, z3, x4, y4, z4) / ref[e, 0]
            r1 = _triple(x1, y1, z1, x0, y0, z0, x2, y2, z2, x5, y5, z5) / ref[e, 1]
            r2 = _triple(x2, y2, z2, x3, y3, z3, x1, y1, z1, x6, y6, z6) / ref[e, 2]
            r3 = _triple(x3, y3, z3, x2, y2, z2, x0, y0, z0, x7, y7, z7) / ref[e, 3]
            r4 = _triple(x4, y4, z4, x5, y5, z5, x7, y7, z7, x0, y0, z0) / ref[e, 4]
            r5 = _triple(x5, y5, z5, x4, y4, z4, x6, y6, z6, x1, y1, z1) / ref[e, 5]
            r6 = _triple(x6, y6, z6, x7, y7, z7, x5, y5, z5, x2, y2, z2) / ref[e, 6]
            r7 = _triple(x7, y7, z7, x6, y6, z6, x4, y4, z4, x3, y3, z3) / ref[e, 7]
            # the element's smallest (first corner on ties), then against the chunk's best
            rs = (r0, r1, r2, r3, r4, r5, r6, r7)
            v, a = r0, 0
            for c in range(1, 8):
                if _smaller(rs[c], c, v, a):
                    v, a = rs[c], c
            key = uelem[e] * 8 + a
            if _smaller(v, key, bv, bk):
                bv = v
                bk = key
        ef[ch] = bv
        ei[ch] = bk
    # combine the chunks (serial, a few hundred entries)
    iout[0] = _NONE
    iout[4 + k] = 0
    for j in range(2 + k):
        fout[j if j < 2 else j + 1] = -np.inf
        iout[j + 1 if j < 2 else j + 2] = _NONE
    for ch in range(nch):
        iout[0] = min(iout[0], pi[ch, 0])
        iout[4 + k] += pc[ch]
        for j in range(2 + k):
            fj = j if j < 2 else j + 1      # fout / iout slots of the node extremes
            ij = j + 1 if j < 2 else j + 2
            v = pf[ch, j]
            u = pi[ch, 1 + j]
            if v > fout[fj] or (v == fout[fj] and u < iout[ij]):
                fout[fj] = v
                iout[ij] = u
    fout[2] = np.inf
    iout[3] = _NONE
    for ch in range(ech):
        if _smaller(ef[ch], ei[ch], fout[2], iout[3]):
            fout[2] = ef[ch]
            iout[3] = ei[ch]


class NumbaScan:
    """The parallel scan of a renumbered run's states (module docstring).

    Parameters
    ----------
    model : cfm_core.scene.Model
        The user's model (nodes (n, 3) in m, hexes (e, 8), plane, sphere).
    tol : float
        Penetration tolerance (m): the impactor's box is widened by it.
    planes : list of tuple
        Symmetry planes (axis, coordinate m, side), :func:`cfm_core.simulation.checks.symmetry_planes`.
    ren : cfm_backends.explicit.renumber.Renumbering, optional
        The solver's numbering (internal -> user); default: the user's own.

    Notes
    -----
    Called with the internal positions (n, 3) (m) and the impactor's reference point (3,) (m) or
    None, it returns :class:`cfm_core.simulation.scan.Extremes` in the user's numbering.
    """

    def __init__(self, model, tol: float, planes, ren=None):
        nodes = np.asarray(model.nodes, dtype=np.float64)
        hexes = np.asarray(model.hexes, dtype=np.int64).reshape(-1, 8)
        n, ne = nodes.shape[0], hexes.shape[0]
        self.unode = np.ascontiguousarray(ren.nodes if ren is not None else np.arange(n), dtype=np.int64)
        self.uelem = np.ascontiguousarray(ren.elements if ren is not None else np.arange(ne), dtype=np.int64)
        self.node_index = np.empty_like(self.unode)
        self.node_index[self.unode] = np.arange(n, dtype=np.int64)
        self.conn = np.ascontiguousarray(self.node_index[hexes[self.uelem]])
        self.ref = np.ascontiguousarray(corner_volumes(nodes, hexes)[self.uelem])   # the reference's values
        self.tol = float(tol)
        self.plate = np.array([] if model.plane is None else [float(model.plane.z)])
        self.planes = np.array([[a, c, s] for a, c, s in planes], dtype=np.float64).reshape(-1, 3)
        self.impactor = model.sphere
        self.fout = np.empty(3 + len(self.planes))
        self.iout = np.empty(5 + len(self.planes), dtype=np.int64)

    def __call__(self, x: np.ndarray, centre=None) -> Extremes:
        """The extremes of the internal positions ``x`` (n, 3) (m); ``centre`` (3,) (m) the impactor's
        reference point, None for no impactor check."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        sph = self.impactor
        shape, R, r = -1, 0.0, 0.0
        box = np.zeros(6)
        c = np.zeros(3)
        if sph is not None and centre is not None:
            c = np.asarray(centre, dtype=np.float64).reshape(3)
            lo, hi = bounds(sph.shape, sph.radius, c)
            box = np.concatenate([lo - self.tol, hi + self.tol])
            shape, R, r = SHAPES[sph.shape], float(sph.radius), float(sph.edge_radius)
        fo, io = self.fout, self.iout
        scan_state(x, self.unode, self.conn, self.ref, self.uelem, self.plate, self.planes, box, shape, R, r, c,
                   fo, io)
        if io[0] != _NONE:
            return Extremes(nonfinite=int(io[0]))
        k = len(self.planes)
        plate = (float(fo[0]), int(io[1])) if self.plate.size else None
        impactor = (float(fo[1]), int(io[2])) if shape >= 0 and io[4 + k] > 0 else None
        symmetry = tuple((float(fo[3 + p]), int(io[4 + p])) for p in range(k))
        corner = (float(fo[2]), int(io[3]) // 8, int(io[3]) % 8) if self.conn.shape[0] else None
        return Extremes(-1, plate, impactor, symmetry, corner)

    def position(self, x: np.ndarray, node: int) -> np.ndarray:
        """(3,) position (m) of the user's node ``node`` in the internal positions ``x``."""
        return np.asarray(x, dtype=np.float64)[self.node_index[int(node)]]
