"""Renumbering for locality (cfm_backends.explicit.renumber) and the numba scatter plan: the
permutation is invisible (same histories, user numbering in frames and errors)."""

import numpy as np
import pytest

from cfm_backends.explicit import renumber
from cfm_backends.numba_explicit import scatter
from fixtures.hand_derived import block_mesh


def shuffled_block(nx=6, ny=5, nz=4, seed=3):
    """A block mesh with nodes and elements in random order (as an unstructured mesher may write it)."""
    nodes, hexes = block_mesh(6e-3, 5e-3, 4e-3, nx, ny, nz)
    rng = np.random.default_rng(seed)
    pn = rng.permutation(len(nodes))
    inv = np.argsort(pn)
    return nodes[pn], inv[hexes][rng.permutation(len(hexes))]


@pytest.mark.parametrize("method", renumber.METHODS)
def test_plan_is_a_permutation_and_model_maps_back(method):
    nodes, hexes = shuffled_block()
    r = renumber.plan(nodes, hexes, method)
    assert np.array_equal(np.sort(r.elements), np.arange(len(hexes)))
    assert np.array_equal(np.sort(r.nodes), np.arange(len(nodes)))
    idx = r.node_index
    # internal element i is user element elements[i], with its corners renumbered
    internal_hexes = idx[hexes[r.elements]]
    assert np.array_equal(r.nodes[internal_hexes], hexes[r.elements])
    x = np.random.default_rng(0).normal(size=(len(nodes), 3))
    assert np.array_equal(r.to_user_nodes(r.to_internal_nodes(x)), x)
    # first-touch order: each node's first use comes after all lower-numbered nodes' first use
    first = np.full(len(nodes), -1)
    for k, j in enumerate(internal_hexes.ravel()):
        if first[j] < 0:
            first[j] = k
    assert np.all(np.diff(first) > 0)


def test_morton_improves_locality_of_a_shuffled_mesh():
    nodes, hexes = shuffled_block(10, 10, 8)
    r = renumber.plan(nodes, hexes, "morton")
    internal = r.node_index[hexes[r.elements]]
    assert renumber.locality(internal, 32) < 0.5 * renumber.locality(hexes, 32)


@pytest.mark.parametrize("n_chunks", [1, 3, 7])
def test_scatter_plan_sums_like_add_at(n_chunks):
    """Element corner forces scattered through the plan (chunk-private rows, then halo rows per
    node) equal np.add.at over the connectivity; no row is written by two chunks."""
    nodes, hexes = shuffled_block()
    r = renumber.plan(nodes, hexes, "morton")
    conn = r.node_index[hexes[r.elements]]
    n, block = len(nodes), 4
    sp = scatter.plan(conn, n, block, n_chunks)
    f = np.random.default_rng(1).normal(size=(len(conn), 8, 6))
    fb = np.zeros((sp.rows, 6))
    writer = np.full(sp.rows, -1)
    for c in range(sp.chunks.shape[0] - 1):
        b0, b1 = sp.chunks[c, 0], sp.chunks[c + 1, 0]
        for e in range(b0 * block, min(b1 * block, len(conn))):
            for a in range(8):
                row = sp.slot[e, a]
                assert writer[row] in (-1, c)
                writer[row] = c
                # a chunk writes only its own node range and its own halo range
                assert (sp.chunks[c, 1] <= row < sp.chunks[c + 1, 1]) or (sp.chunks[c, 2] <= row < sp.chunks[c + 1, 2])
                fb[row] += f[e, a]
    total = fb[:n].copy()
    for j in range(n):
        total[j] += fb[sp.hrow[sp.hptr[j]:sp.hptr[j + 1]]].sum(axis=0)
    ref = np.zeros((n, 6))
    np.add.at(ref, conn.ravel(), f.reshape(-1, 6))
    np.testing.assert_allclose(total, ref, rtol=1e-13, atol=1e-13)
    if n_chunks > 1:
        assert sp.rows > n     # the test really crosses chunk boundaries


def test_scatter_plan_refuses_nodes_not_in_first_touch_order():
    nodes, hexes = shuffled_block()
    with pytest.raises(ValueError, match="first-touch"):
        scatter.plan(hexes, len(nodes), 4, 3)


def _numba():
    pytest.importorskip("numba")
    from cfm_backends.numba_explicit import NumbaExplicitBackend

    return NumbaExplicitBackend()


def _crushed_corner_model():
    """A shuffled 3 x 3 x 2 block whose far top corner node moves at 200 m/s into the block: the
    one element holding that node inverts. (model, initial velocity, that element's user index)."""
    from fixtures.hand_derived import NeoHookeanStandIn
    from cfm_core.scene.model import Model

    nodes, hexes = shuffled_block(3, 3, 2, seed=5)
    corner = int(np.argmin(np.linalg.norm(nodes - [6e-3, 5e-3, 4e-3], axis=1)))
    user_e = int(np.flatnonzero((hexes == corner).any(axis=1))[0])
    v0 = np.zeros_like(nodes)
    v0[corner] = [-4000.0, -4000.0, -4000.0]
    model = Model(name="crush", nodes=nodes, hexes=hexes, density=1000.0, end_time=1e-3, output_interval=1e-4,
                  material=NeoHookeanStandIn(mu=5.0e3, kappa=100.0e3))
    return model, v0, user_e


def test_errors_name_the_users_element():
    from cfm_backends.numba_explicit import codegen, solver
    from cfm_backends.numba_explicit.kernels import layout as K
    from cfm_backends.numba_explicit.options import NumbaOptions
    from cfm_core.errors import NumericalError

    be = _numba()
    model, v0, user_e = _crushed_corner_model()
    prep = solver.prepare(model, NumbaOptions())
    internal = int(np.flatnonzero(prep.ren.elements == user_e)[0])
    assert internal != user_e                      # the renumbering really moved it
    # the compiled loop's failure (internal index) is reported with the user's index
    codegen.load(model.material)
    prep.sc[K.S_ERRE] = internal
    err = solver._error(K.R_INVERTED, prep, model)
    assert err.element == user_e and f"element {user_e} inverted" in str(err)
    # end to end: the kernel's inversion check or the corner-fold check, both in user numbering
    with pytest.raises(NumericalError, match=rf"element {user_e} (inverted|is folded) at t = ") as info:
        be.run(model, initial_velocity=v0)
    assert info.value.element == user_e


def test_drop_test_histories_do_not_depend_on_the_numbering():
    """The paper's drop test (2 mm elements, first 4 ms) in the mesh's order, along the Morton curve
    and in RCM order: the same histories up to round-off (summation order; measured ~1e-14 of the
    peak force), the frames in the user's node order."""
    from fixtures.hand_derived import drop_test_model
    from cfm_core.material.registry import make_material

    be = _numba()
    model = drop_test_model(make_material("cfm", {}, "long-term", False), h=2e-3, end_time=4e-3)
    runs = {m: be.run(model, renumber=m, frame_interval=2e-3) for m in renumber.METHODS}
    ref = runs["none"]
    for m, r in runs.items():
        assert r.steps == ref.steps
        np.testing.assert_allclose(r.t, ref.t, rtol=1e-13)
        np.testing.assert_allclose(r.contact_force, ref.contact_force, rtol=0, atol=1e-11 * np.abs(ref.contact_force).max())
        u, u_ref = r.frames[-1][1], ref.frames[-1][1]
        np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-11 * np.abs(u_ref).max())
    assert np.abs(ref.frames[-1][1]).max() > 1e-4   # the frame really is deformed


def test_frame_state_is_in_the_users_numbering():
    """Velocities and Prony history stored at frames (for --vtu fields) do not depend on the
    internal numbering: renumber='morton' gives the values of renumber='none', node by node and
    element by element."""
    from cfm_core.runs.pipeline import run_model
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    model = build_model(builtin_scene("drop-test").with_overrides(thickness=0.004, element_size=0.002, width=0.012,
                                                                  end_time=1.5e-3))
    a, b = (run_model(model, "numba", renumber=m, frame_interval=5e-4) for m in ("none", "morton"))
    assert len(a.frame_state) == len(b.frame_state) >= 3
    for sa, sb in zip(a.frame_state, b.frame_state):
        for key in ("velocity", "prony_H", "prony_S0"):
            scale = max(np.abs(sa[key]).max(), 1e-30)
            assert np.abs(sa[key] - sb[key]).max() <= 1e-9 * scale, key
    assert np.abs(b.frame_state[-1]["prony_S0"]).max() > 1.0  # a loaded specimen (Pa)
