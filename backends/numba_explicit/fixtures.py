"""Small models and a stand-in material for the tests and the benchmark (SI units).

``NeoHookeanStandIn`` has the interface of :class:`cfm_core.material.Material` the backend uses
(``name``, ``param_array()``, ``prony_arrays()``, ``numba_source()``) for the compressible
Neo-Hookean psi_iso = mu/2 (J^-2/3 (m1 + m2 + m3) - 3), psi_vol = kappa/2 (J - 1)^2, with the
derivatives with respect to the eigenvalues m_a of C written out by hand:

    d psi_iso / d m_a   = mu/2 J^-2/3 (1 - I1 / (3 m_a))
    d2 psi_iso / d m_a2 = mu/2 J^-2/3 (4 I1 / (9 m_a^2) - 2 / (3 m_a))
    d psi_vol / d m_a   = kappa (J - 1) J / (2 m_a),   d2 psi_vol / d m_a2 = kappa J / (4 m_a^2)

``block_model`` and ``drop_test_model`` build structured hex meshes and Models directly (the
scene builder is the normal route; these keep the backend's tests independent of it).
"""

from __future__ import annotations

import numpy as np

from cfm_core.model import Model, RigidPlane, RigidSphere

NEO_HOOKEAN_SOURCE = '''import math


def psi_energy(m1, m2, m3, p):
    mu = p[0]
    kappa = p[1]
    J = math.sqrt(m1 * m2 * m3)
    jm23 = 1.0 / J ** (2.0 / 3.0)
    return 0.5 * mu * (jm23 * (m1 + m2 + m3) - 3.0), 0.5 * kappa * (J - 1.0) ** 2


def psi_grad(m1, m2, m3, p):
    mu = p[0]
    kappa = p[1]
    J = math.sqrt(m1 * m2 * m3)
    jm23 = 1.0 / J ** (2.0 / 3.0)
    i1 = m1 + m2 + m3
    a = 0.5 * mu * jm23
    b = 0.5 * kappa * (J - 1.0) * J
    return (a * (1.0 - i1 / (3.0 * m1)), a * (1.0 - i1 / (3.0 * m2)), a * (1.0 - i1 / (3.0 * m3)),
            b / m1, b / m2, b / m3)


def psi_hess_diag(m1, m2, m3, p):
    mu = p[0]
    kappa = p[1]
    J = math.sqrt(m1 * m2 * m3)
    jm23 = 1.0 / J ** (2.0 / 3.0)
    i1 = m1 + m2 + m3
    a = 0.5 * mu * jm23
    b = 0.25 * kappa * J
    return (a * (4.0 * i1 / (9.0 * m1 * m1) - 2.0 / (3.0 * m1)),
            a * (4.0 * i1 / (9.0 * m2 * m2) - 2.0 / (3.0 * m2)),
            a * (4.0 * i1 / (9.0 * m3 * m3) - 2.0 / (3.0 * m3)),
            b / (m1 * m1), b / (m2 * m2), b / (m3 * m3))
'''


class NeoHookeanStandIn:
    """Compressible Neo-Hookean (mu, kappa in Pa) with an optional Prony series (gammas, taus in s)."""

    def __init__(self, mu: float = 1.0e3, kappa: float = 50.0e3, gammas=(), taus=(), name="neo-hookean-stand-in"):
        self.mu, self.kappa = float(mu), float(kappa)
        self.gammas = np.asarray(gammas, dtype=np.float64)
        self.taus = np.asarray(taus, dtype=np.float64)
        self.name = name

    def param_array(self) -> np.ndarray:
        return np.array([self.mu, self.kappa])

    def prony_arrays(self):
        return self.gammas.copy(), self.taus.copy()

    def numba_source(self) -> str:
        return NEO_HOOKEAN_SOURCE


def block_mesh(lx, ly, lz, nx, ny, nz, origin=(0.0, 0.0, 0.0)):
    """Structured hex mesh of the box origin + [0, lx] x [0, ly] x [0, lz] (m): (nodes, hexes)."""
    xs = origin[0] + np.linspace(0.0, lx, nx + 1)
    ys = origin[1] + np.linspace(0.0, ly, ny + 1)
    zs = origin[2] + np.linspace(0.0, lz, nz + 1)
    Z, Y, X = np.meshgrid(zs, ys, xs, indexing="ij")
    nodes = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])

    def idx(i, j, k):
        return (k * (ny + 1) + j) * (nx + 1) + i

    i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    hexes = np.column_stack([idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                             idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1),
                             idx(i, j + 1, k + 1)]).astype(np.int64)
    return nodes, hexes


def drop_test_model(material, width=50e-3, thickness=8e-3, h=1e-3, quarter=True, radius=55e-3,
                    mass=0.220, velocity=1.0, density=950.0, friction=0.0, end_time=30e-3,
                    plane=True, stop_after_separation=True, gravity=0.0):
    """The paper's drop test: specimen width x width x thickness on the plane z = 0, rigid sphere
    (radius, mass in kg) touching the top at x = y = 0 and moving down at ``velocity`` (m/s).

    quarter=True models x, y >= 0 with symmetry planes (u_x = 0 on x = 0, u_y = 0 on y = 0) and
    symmetry factor 4; h (m) is the element size.
    """
    n = int(round(width / h))
    nz = int(round(thickness / h))
    if quarter:
        nodes, hexes = block_mesh(width / 2, width / 2, thickness, n // 2, n // 2, nz)
    else:
        nodes, hexes = block_mesh(width, width, thickness, n, n, nz, (-width / 2, -width / 2, 0.0))
        half = np.linspace(0.0, width / 2, n // 2 + 1)   # exact mirror symmetry about 0
        full = np.concatenate([-half[::-1], half[1:]])
        nodes[:, 0] = full[np.searchsorted(full, nodes[:, 0] - 1e-12 * width)]
        nodes[:, 1] = full[np.searchsorted(full, nodes[:, 1] - 1e-12 * width)]
    tol = 1e-9 * h
    top = np.flatnonzero(np.abs(nodes[:, 2] - thickness) < tol)
    bottom = np.flatnonzero(np.abs(nodes[:, 2]) < tol)
    fixed = np.zeros((0, 2), dtype=np.int64)
    factor = 1.0
    if quarter:
        x0 = np.flatnonzero(np.abs(nodes[:, 0]) < tol)
        y0 = np.flatnonzero(np.abs(nodes[:, 1]) < tol)
        fixed = np.vstack([np.column_stack([x0, np.zeros_like(x0)]),
                           np.column_stack([y0, np.ones_like(y0)])]).astype(np.int64)
        factor = 4.0
    return Model(
        name="drop-test", nodes=nodes, hexes=hexes, density=density, material=material,
        end_time=end_time, output_interval=2e-5, fixed_dofs=fixed,
        sphere=RigidSphere(radius, mass / factor, (0.0, 0.0, thickness + radius), -velocity),
        plane=RigidPlane(0.0) if plane else None, sphere_nodes=top,
        plane_nodes=bottom if plane else np.zeros(0, dtype=np.int64), friction=friction,
        symmetry_factor=factor, mass_full=mass, gravity=gravity,
        stop_after_separation=stop_after_separation)
