"""The numba backend's parallel scan of a state (cfm_backends.numba_explicit.scan) against the numpy
reference (cfm_core.simulation.scan.Scan, whose impactor depth is cfm_core.scene.impactor.gap's):
the same extremes, values to the bit and the same indices, on random deformed states of every
impactor shape, on states built to fail each check, on exact ties, with 1 and 2 threads; and a
numba run that fails names the same node or element as a run monitored by the numpy scan."""

import functools

import numpy as np
import pytest

numba = pytest.importorskip("numba")
from cfm_backends.explicit import renumber
from cfm_backends.numba_explicit import NumbaExplicitBackend
from cfm_backends.numba_explicit import scan as nscan
from cfm_core.errors import NumericalError
from cfm_core.runs.pipeline import run_model
from cfm_core.scene import builtin_scene
from cfm_core.scene.builder import build_model
from cfm_core.scene.impactor import gap
from cfm_core.scene.mesh import structured_hex_mesh
from cfm_core.scene.model import Model, RigidPlane, RigidSphere
from cfm_core.simulation import checks
from cfm_core.simulation.scan import NEIGHBOURS, Extremes, Scan

SHAPES = [("hemisphere", 0.0), ("sphere", 0.0), ("flat", 3e-3), ("plane", 0.0)]
L, T = 0.02, 0.012           # block 20 x 20 x 12 mm
NX, NZ = 20, 12              # 4800 elements, 5733 nodes: more than one chunk of nodes and of elements


def block(shape="hemisphere", edge=0.0):
    """Block on the plate z = 0 with three symmetry planes: x = 0 (side +1), y = L (side -1), z = 0
    (+1, its bottom held in z), the impactor's lowest point 0.5 mm into the top face."""
    nodes, hexes = structured_hex_mesh(L, L, T, NX, NX, NZ)
    fixed = ([(i, 0) for i in np.flatnonzero(nodes[:, 0] == 0.0)] + [(i, 1) for i in np.flatnonzero(nodes[:, 1] == L)]
             + [(i, 2) for i in np.flatnonzero(nodes[:, 2] == 0.0)])
    R = 0.01
    cz = T - 0.5e-3 + (0.0 if shape in ("flat", "plane") else R)
    sph = RigidSphere(R, 0.22, (0.004, 0.016, cz), -1.0, shape=shape, edge_radius=edge)
    return Model(name="block", nodes=nodes, hexes=hexes, density=950.0, material=None, end_time=1e-3,
                 output_interval=1e-4, fixed_dofs=np.array(fixed), plane=RigidPlane(0.0), sphere=sph)


def scans(model, method="morton"):
    """(numpy scan, numba scan, renumbering) of a model."""
    mon = checks.Monitor(model)
    ren = renumber.plan(model.nodes, model.hexes, method)
    return mon.scan, nscan.NumbaScan(model, mon.tol, mon.planes, ren=ren), ren


def both(model, x, centre, method="morton"):
    ref, fast, ren = scans(model, method)
    return ref(x, centre), fast(np.ascontiguousarray(ren.to_internal_nodes(x)), centre)


def deformed(model, seed, scale=0.4):
    """A random state: nodes moved by up to ``scale`` element edges (some corners fold)."""
    h = L / NX
    rng = np.random.default_rng(seed)
    return model.nodes + rng.uniform(-scale * h, scale * h, size=model.nodes.shape)


def test_the_scan_knows_the_three_planes_and_the_corner_neighbours():
    m = block()
    assert checks.Monitor(m).planes == [(0, 0.0, 1.0), (1, L, -1.0), (2, 0.0, 1.0)]
    tri = np.array([[1, 3, 4], [0, 2, 5], [3, 1, 6], [2, 0, 7], [5, 7, 0], [4, 6, 1], [7, 5, 2], [6, 4, 3]])
    np.testing.assert_array_equal(NEIGHBOURS.T, tri)   # the corner triples written out in scan_state


@pytest.mark.parametrize("shape,edge", SHAPES)
def test_the_compiled_impactor_depth_is_the_numpy_gap_to_the_bit(shape, edge):
    rng = np.random.default_rng(5)
    R = 0.01
    p = rng.uniform(-1.5 * R, 1.5 * R, size=(20_000, 3))
    p[:50] = 0.0                                    # the reference point itself
    p[50:100, 2] = 0.0                              # a hemisphere's centre plane
    g = gap(shape, R, edge, np.zeros(3), p)[0]
    got = np.array([nscan._depth(nscan.SHAPES[shape], R, edge, *q) for q in p])
    assert (g < 0).sum() > 1000
    np.testing.assert_array_equal(got, -g)


@pytest.mark.parametrize("shape,edge", SHAPES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_numba_scan_equals_numpy_scan_on_random_states(shape, edge, seed):
    m = block(shape, edge)
    x = deformed(m, seed)
    centre = np.array(m.sphere.center) + np.random.default_rng(seed).uniform(-1e-3, 1e-3, 3)
    ref, got = both(m, x, centre)
    assert ref.impactor is not None and ref.corner[0] < 0.0   # nodes in the box, a folded corner
    assert got == ref, (got, ref)


@pytest.mark.parametrize("shape,edge", SHAPES)
def test_numba_scan_equals_numpy_scan_on_states_built_to_fail(shape, edge):
    m = block(shape, edge)
    n = m.nodes
    centre = np.array(m.sphere.center)
    cases = {}
    x = n.copy()
    x[777] = np.nan
    x[4000, 1] = np.inf
    cases["nan"] = x
    x = n.copy()
    bottom = np.flatnonzero(n[:, 2] == 0.0)
    x[bottom[17], 2] = -0.3e-3
    cases["plate"] = x
    for axis, coord, side in ((0, 0.0, 1.0), (1, L, -1.0), (2, 0.0, 1.0)):
        x = n.copy()
        on = np.flatnonzero(n[:, axis] == coord)
        x[on[len(on) // 2], axis] -= side * 0.2e-3
        cases[f"plane {axis}"] = x
    x = n.copy()
    top = np.flatnonzero(n[:, 2] == T)
    inner = top[np.argmin(np.linalg.norm(n[top, :2] - centre[:2], axis=1))]
    x[inner, 2] = T + 1e-3             # 1.5 mm inside the impactor (its surface 0.5 mm into the top face)
    cases["impactor"] = x
    x = n.copy()
    e = 2345
    x[m.hexes[e, 6]] = 0.7 * n[m.hexes[e, 0]] + 0.3 * n[m.hexes[e, 6]]   # corner 6 pushed past the centre
    cases["fold"] = x
    for name, x in cases.items():
        ref, got = both(m, x, centre)
        assert got == ref, (name, got, ref)
    assert both(m, cases["nan"], centre)[1] == Extremes(nonfinite=777)
    depth, node = both(m, cases["impactor"], centre)[1].impactor
    if shape != "plane":      # the plane's deepest node is any node above its z
        assert node == inner and depth > 0.9e-3
    ratio, element, corner = both(m, cases["fold"], centre)[1].corner
    assert ratio < 0.0 and element == 2345


def test_ties_go_to_the_smallest_user_index_whatever_the_numbering():
    """The reference state: every bottom node is 0 behind the plate, every corner ratio is 1,
    every node of a plane 0 across it; two nodes pushed equally deep: the smaller user index."""
    m = block()
    x = m.nodes.copy()
    centre = np.array(m.sphere.center)
    for method in ("morton", "rcm", "none"):
        ref, got = both(m, x, centre, method)
        assert got == ref and got.corner == (1.0, 0, 0) and got.plate == (0.0, 0)
    bottom = np.flatnonzero(m.nodes[:, 2] == 0.0)
    x[bottom[[300, 40]], 2] = -0.2e-3
    for method in ("morton", "rcm"):
        ref, got = both(m, x, centre, method)
        assert got == ref and got.plate == (0.2e-3, int(bottom[40]))


@pytest.mark.parametrize("shape,edge", SHAPES[:3])
def test_one_and_two_threads_give_the_same_extremes(shape, edge):
    m = block(shape, edge)
    ref, fast, ren = scans(m)
    x = deformed(m, 11, scale=0.3)
    xi = np.ascontiguousarray(ren.to_internal_nodes(x))
    centre = np.array(m.sphere.center)
    before = numba.get_num_threads()
    try:
        got = []
        for threads in (1, 2):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            got.append(fast(xi, centre))
    finally:
        numba.set_num_threads(before)
    assert got[0] == got[1] == ref(x, centre)


def test_a_node_named_in_a_message_is_at_its_own_position():
    """The monitor's messages read the reported node's position through the scan (internal order)."""
    m = block()
    mon = checks.Monitor(m, scan=functools.partial(nscan.NumbaScan, ren=renumber.plan(m.nodes, m.hexes)))
    x = m.nodes.copy()
    node = 1234
    x[node] = [-0.3e-3, 0.0101, 0.0061]      # across x = 0 by 0.3 mm
    xi = np.ascontiguousarray(x[mon.scan.unode])
    with pytest.raises(NumericalError, match=r"node 1234 has crossed the symmetry plane x = 0 m by 0.3 mm "
                                             r"\(now at \(-0.3, 10.1, 6.1\) mm\)"):
        mon.check(1e-4, xi)


class NumpyInTheSolversNumbering:
    """The numpy reference scan behind the numba scan's interface: the positions renumbered back."""

    def __init__(self, model, tol, planes, ren):
        self.scan, self.ren = Scan(model, tol, planes), ren

    def __call__(self, x, centre=None):
        return self.scan(self.ren.to_user_nodes(x), centre)

    def position(self, x, node):
        return self.ren.to_user_nodes(x)[node]


def _error(run):
    with pytest.raises(NumericalError) as err:
        run()
    e = err.value
    return str(e), getattr(e, "node", None), e.element, e.time, e.quantity


def test_a_failing_numba_run_names_what_a_numpy_monitored_run_names(monkeypatch):
    """220 kg on the coarse drop test: the same message, node or element, and time from the
    compiled scan as from the numpy reference watching the same (unchanged) states."""
    model = build_model(builtin_scene("drop-test").with_overrides(width=0.02, thickness=0.005, element_size=0.0025,
                                                                  mass=220.0, end_time=0.006))
    fast = _error(lambda: run_model(model, "numba"))
    monkeypatch.setattr(nscan, "NumbaScan", NumpyInTheSolversNumbering)
    slow = _error(lambda: run_model(model, "numba"))
    assert fast == slow
    assert fast[1] is not None or fast[2] is not None or fast[4] == "bottoming out"


def test_a_folded_element_is_named_alike_by_both_scans(monkeypatch):
    """A corner crushed within a few steps (tests/backends/test_numba_solver.py): element 1 both ways."""
    from fixtures.hand_derived import NeoHookeanStandIn, block_mesh

    nodes, hexes = block_mesh(2e-3, 1e-3, 1e-3, 2, 1, 1)
    v0 = np.zeros_like(nodes)
    v0[int(np.argmin(np.linalg.norm(nodes - [2e-3, 1e-3, 1e-3], axis=1)))] = [-200.0, -200.0, -200.0]
    model = Model(name="crush", nodes=nodes, hexes=hexes, density=1000.0, end_time=1e-3, output_interval=1e-4,
                  material=NeoHookeanStandIn(mu=5.0e3, kappa=100.0e3))
    fast = _error(lambda: NumbaExplicitBackend().run(model, initial_velocity=v0))
    monkeypatch.setattr(nscan, "NumbaScan", NumpyInTheSolversNumbering)
    slow = _error(lambda: NumbaExplicitBackend().run(model, initial_velocity=v0))
    assert fast == slow
    if fast[4] == "corner Jacobian":
        assert fast[2] == 1
