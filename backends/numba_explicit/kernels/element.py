"""Element and node loops of the explicit solver (numba, parallel over element blocks / nodes).

Total Lagrangian hex8 with one-point integration (Flanagan & Belytschko 1981):

    F = sum_I x_I (x) B_I,  B_I = (1/V0) int dN_I/dX dV0   (uniform gradient, reference config.)
    f_I^int = V0 P B_I,  P = F S                           (N)

Viscous hourglass control with the 4 hourglass vectors gamma_alpha (orthogonal to the linear
field in the reference configuration):

    q_alpha = sum_I v_I gamma_alpha,I  (m/s),   f_I^hg = -c_hg sum_alpha q_alpha gamma_alpha,I
    c_hg = Q_hg rho c V0^(2/3) / 4  (kg/s)

with c the current isochoric ("shear-type") wave speed sqrt(M_iso / rho) by default, or the
full longitudinal one.

Elements are processed in blocks of ``BLOCK`` (layout.py): the update of a block is a sequence
of stages, each one loop over the block's elements with no calls and no branches (selects
instead), in a function of its own so that LLVM vectorises it across elements (8 doubles per
AVX-512 instruction): kinematics (F, hourglass modes), eigen-decomposition of C, the material's
derivatives, principal stresses and moduli, Prony update, forces and stress work. The rare
cases the branch-free eigen-decomposition does not cover (C isotropic to round-off but not
exactly diagonal; the undeformed state C = I is covered) go through the scalar :func:`eig3` one
by one. The node gather before the stages and the force scatter after them, which LLVM leaves
scalar (loads and stores through the corner table), go 8 elements at a time through two
intrinsics written at the level of LLVM's IR (:func:`gather8`, :func:`scatter8`), with the scalar
loops' results to the bit.

Calls: :func:`element_block` and the per-corner force stages (:func:`corner_forces`,
:func:`scatter_corner`, 16 calls per block) are inlined into the chunk loop of :func:`element_pass`
and the node gather (:func:`gather_corners`) into :func:`kinematics_block` (numba's
``inline="always"``, at the level of numba's IR). As calls, each block paid for passing
16 arrays by value, incrementing and decrementing their reference counts (atomic operations) and
allocating its scratch; inlined, with one scratch per chunk, the element pass is 10-13 % faster
with the same bits (docs/user/performance.md). The larger stages stay calls: inlining all of them
gained no more and made the first compilation 40 s longer; and an inlined function takes its
caller's fast-math flags, so the stages compiled with other flags (:func:`material_block`, IEEE;
the corner sums, without nsz) must stay calls.

Scatter: the elements (renumbered for locality before the run, ``cfm_backends.explicit.renumber``)
are split into chunks of consecutive blocks, one parallel task each. A chunk adds its element
forces straight onto a force buffer: onto the rows of the nodes it touches first (its own, a
contiguous range: nodes are numbered in first-touch order) and onto private halo rows for the
nodes an earlier chunk owns. No two chunks write the same row, so no atomics, no per-element
force array and no serial pass; the node loop then adds each node's halo rows (few: only nodes
on a chunk boundary have any) to its own row.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from llvmlite import ir
from numba import njit, prange, types
from numba.core.extending import intrinsic
from cfm_backends.numba_cache import key_on_folder

from .constitutive import first_piola, psi_grad_hess_diag_v
from .eigen import eig3, eig3_hybrid
from .layout import *  # noqa: F401,F403
from .vmath import vsqrt

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@intrinsic
def parallel_chunksize(typingctx, n):
    """numba's ``set_parallel_chunksize(n)``: the iterations a thread takes at a time from the
    next prange loop this thread starts (0: the default static split); returns the previous
    value. Direct calls of the threading layer's C functions by their symbols, declared as
    numba's parfor lowering declares them (uint64 -> void, () -> uint64): numba's own function
    reaches them through a ctypes pointer, which keeps a kernel out of numba's disk cache."""
    def emit(context, builder, signature, args):
        mod = builder.module
        u = ir.IntType(64)
        get = mod.globals.get("get_parallel_chunksize") or ir.Function(mod, ir.FunctionType(u, []),
                                                                      "get_parallel_chunksize")
        put = mod.globals.get("set_parallel_chunksize") or ir.Function(mod, ir.FunctionType(ir.VoidType(), [u]),
                                                                      "set_parallel_chunksize")
        old = builder.call(get, [])
        builder.call(put, [args[0]])
        return old
    return types.int64(types.int64), emit


@intrinsic
def prefetch(typingctx, arr, i):
    """Ask the processor to bring the cache line of arr[i] (a 1-D array) into its L2 cache
    (``llvm.prefetch``: read, locality 2, data; x86 ``prefetcht1``). A hint: no fault, no result,
    nothing changes if it is dropped."""
    def emit(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        mod = builder.module
        fn = mod.globals.get("llvm.prefetch.p0i8") or ir.Function(
            mod, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]), "llvm.prefetch.p0i8")
        builder.call(fn, [builder.bitcast(builder.gep(ary.data, [args[1]]), i8p), i32(0), i32(2), i32(1)])
        return context.get_dummy_value()
    return types.none(arr, types.intp), emit


def _column_pointer(context, builder, aryty, ary, flat):
    """Pointer to element ``flat`` (i64, counted in the array's C order) of a numba array value."""
    return builder.gep(context.make_array(aryty)(context, builder, ary).data, [flat])


def _corner_entry(context, builder, ty, table, e, j, a):
    """table[e + j, a] of a C-contiguous (e, 8) int32 corner table (conn or slot) as an LLVM i64
    (e, a: i64 values; j: a Python int)."""
    i64 = ir.IntType(64)
    flat = builder.add(builder.mul(builder.add(e, i64(j)), i64(8)), a)
    return builder.sext(builder.load(_column_pointer(context, builder, ty, table, flat)), i64)


def _block_row(context, builder, ty, wk, w0, c, width=8):
    """Pointer, as a vector of ``width`` doubles, to wk[w0 + c BLOCK ...] (w0: an i64 value)."""
    ptr = _column_pointer(context, builder, ty, wk, builder.add(w0, ir.IntType(64)(c * BLOCK)))
    return builder.bitcast(ptr, ir.VectorType(ir.DoubleType(), width).as_pointer())


def _as_i64(context, builder, ty, value):
    """An integer argument of numba type ``ty`` as an LLVM i64."""
    return context.cast(builder, value, ty, types.int64)


def _masked_load(builder, width):
    """The declaration of ``llvm.masked.load`` of ``width`` doubles."""
    vec = ir.VectorType(ir.DoubleType(), width)
    name = f"llvm.masked.load.v{width}f64.p0v{width}f64"
    return builder.module.globals.get(name) or ir.Function(
        builder.module, ir.FunctionType(vec, [vec.as_pointer(), ir.IntType(32), ir.VectorType(ir.IntType(1), width),
                                              vec]), name)


def _integers(*tys):
    """Whether every numba type of ``tys`` is an integer."""
    return all(isinstance(t, types.Integer) for t in tys)


def _c_array(ty, dtype, ndim):
    """Whether numba type ``ty`` is a C-contiguous array of ``dtype`` with ``ndim`` dimensions."""
    return isinstance(ty, types.Array) and ty.layout == "C" and ty.dtype == dtype and ty.ndim == ndim


@intrinsic
def gather8(typingctx, wk, w0, x, v, conn, e, a):
    """Rows of 8 columns from the corner-a nodes of elements e .. e + 7: wk[w0 + c BLOCK + j] =
    x[conn[e + j, a], c] and wk[w0 + (3 + c) BLOCK + j] = v[conn[e + j, a], c] (c < 3, j < 8).

    Each node's x and v are read as one 3-of-4 masked vector load each (the fourth lane is not
    touched), the 6 rows assembled in vector registers and stored 8 wide: 16 loads and 6 stores
    for what the scalar loop does with 48 of each. wk, x, v: C-contiguous float64 (wk flat, x and v
    (n, 3)); conn: C-contiguous (e, 8) int32; w0, e, a integers (the shapes are the caller's to
    keep: they are not checked at run time). The same values as the scalar loop, bit for bit.
    Other argument types: numba's TypingError at compilation."""
    if not (_c_array(wk, types.float64, 1) and _c_array(x, types.float64, 2) and _c_array(v, types.float64, 2)
            and _c_array(conn, types.int32, 2) and _integers(w0, e, a)):
        return None

    def emit(context, builder, signature, args):
        tw, tw0, tx, tv, tc, te, ta = signature.args
        wka, w0, xa, va, ca, ev, av = args
        f64 = ir.DoubleType()
        i64 = ir.IntType(64)
        i32 = ir.IntType(32)
        v4 = ir.VectorType(f64, 4)
        v8 = ir.VectorType(f64, 8)
        load3 = _masked_load(builder, 4)
        lanes = ir.Constant(ir.VectorType(ir.IntType(1), 4), [1, 1, 1, 0])
        zero4 = ir.Constant(v4, [0.0] * 4)
        w0 = _as_i64(context, builder, tw0, w0)
        e = _as_i64(context, builder, te, ev)
        a = _as_i64(context, builder, ta, av)
        rows = [ir.Constant(v8, [0.0] * 8) for _ in range(6)]
        for j in range(8):
            first = builder.mul(_corner_entry(context, builder, tc, ca, e, j, a), i64(3))
            for k, (ty, arr) in enumerate(((tx, xa), (tv, va))):
                ptr = builder.bitcast(_column_pointer(context, builder, ty, arr, first), v4.as_pointer())
                val = builder.call(load3, [ptr, i32(8), lanes, zero4])
                for c in range(3):
                    rows[3 * k + c] = builder.insert_element(rows[3 * k + c], builder.extract_element(val, i32(c)),
                                                             i32(j))
        for c in range(6):
            builder.store(rows[c], _block_row(context, builder, tw, wka, w0, c), align=8)
        return context.get_dummy_value()
    return types.none(wk, w0, x, v, conn, e, a), emit


@intrinsic
def scatter8(typingctx, wk, w0, fb, slot, e, a):
    """The forces of 8 columns onto their buffer rows: fb[NF slot[e + j, a] + c] += wk[w0 + c BLOCK
    + j] (c < 6, j < 8), element j after element j - 1, each value added as the scalar loop adds
    it (the same bits, whichever elements share a row).

    The 6 rows are read 8 wide and transposed in vector registers; each element's 6 forces are
    added onto its row by a 4-wide and a 2-wide load, add and store (not masked: a masked store
    does not forward to the next element's load of the same row, and that stall costs more than
    the scalar loop). wk, fb: C-contiguous float64 (flat); slot: C-contiguous (e, 8) int32; w0, e, a
    integers (shapes unchecked at run time, as for :func:`gather8`). Other argument types: numba's
    TypingError at compilation."""
    if not (_c_array(wk, types.float64, 1) and _c_array(fb, types.float64, 1) and _c_array(slot, types.int32, 2)
            and _integers(w0, e, a)):
        return None

    def emit(context, builder, signature, args):
        tw, tw0, tf, ts, te, ta = signature.args
        wka, w0, fba, sla, ev, av = args
        f64 = ir.DoubleType()
        i64 = ir.IntType(64)
        i32 = ir.IntType(32)
        w0 = _as_i64(context, builder, tw0, w0)
        e = _as_i64(context, builder, te, ev)
        a = _as_i64(context, builder, ta, av)
        rows = [builder.load(_block_row(context, builder, tw, wka, w0, c), align=8) for c in range(6)]
        for j in range(8):
            row = _corner_entry(context, builder, ts, sla, e, j, a)
            base = _column_pointer(context, builder, tf, fba, builder.mul(row, i64(NF)))
            for lo, width in ((0, 4), (4, 2)):
                vec = ir.Constant(ir.VectorType(f64, width), [0.0] * width)
                for c in range(width):
                    vec = builder.insert_element(vec, builder.extract_element(rows[lo + c], i32(j)), i32(c))
                ptr = builder.bitcast(builder.gep(base, [i64(lo)]), ir.VectorType(f64, width).as_pointer())
                builder.store(builder.fadd(builder.load(ptr, align=8), vec), ptr, align=8)
        return context.get_dummy_value()
    return types.none(wk, w0, fb, slot, e, a), emit


@njit(inline="always")
def line_share(n, j, parts):
    """Values [lo, hi) of part j of ``parts`` near-equal parts of n float64 values, cut at
    multiples of 8 (64-byte cache lines); the parts j = 0 .. parts - 1 tile [0, n) in order."""
    m = 8 * ((n + 8 * parts - 1) // (8 * parts))
    return min(j * m, n), min((j + 1) * m, n)


@njit(inline="always")
def prefetch_part(ed, eh, j, parts):
    """Prefetch part j of ``parts`` (:func:`line_share`) of the cache lines of ed and eh."""
    lo, hi = line_share(ed.shape[0], j, parts)
    for r in range(lo, hi, 8):
        prefetch(ed, r)
    lo, hi = line_share(eh.shape[0], j, parts)
    for r in range(lo, hi, 8):
        prefetch(eh, r)


@njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def element_pass(x, v, conn, slot, chunks, ed, eh, fb, p, decay, gain, ginf, bdt, bemin, status, errv, rho, hg, hgwave):
    """Stresses, nodal forces, stable steps and the stress work of all elements at one state.

    x, v: (n, 3) positions x^n and velocities v^{n-1/2}; conn (e, 8) the corner nodes; slot (e, 8)
    the row of the force buffer fb that each corner adds to (``forces.scatter_plan``); chunks
    (c + 1, 3): per chunk of consecutive blocks, its first block, the first buffer row of the nodes
    it owns, the first buffer row of its halo (the last row ends each range); ed, eh: the block
    arrays (layout.py: geometry and state of each element; Prony state); fb (rows * NF,): the
    force buffer (N), each chunk's rows zeroed and summed into by that chunk alone; decay, gain:
    Prony factors of the step since the previous call (``prony_step``); hg: Q_hg; hgwave: 0
    isochoric, 1 full modulus. Writes bdt, bemin (nblk,): the smallest L / c of each block (s)
    and its element, status (e,) at failures (1 inverted, 2 non-finite) and errv (nblk, 4) =
    (J, m0, m1, m2) of the block's first failure; updates the Prony state and the previous-step
    S and E. Returns (stress work increment (J), number of failures).

    Parallel over the chunks, handed out one at a time (a thread that finishes takes the next
    free chunk, so that threads whose chunks cost more, or a thread the OS descheduled, do not
    hold the others back at the end of the pass): no two chunks write the same buffer row, so the
    scatter needs no atomics and no serial pass. Each chunk's stress work and failure count are
    kept apart and summed in chunk order afterwards, so that every result, the work included,
    is the same bits whatever the thread count and whichever thread ran which chunk.
    """
    ne = conn.shape[0]
    nblk = (ne + BLOCK - 1) // BLOCK
    k6 = 6 * decay.shape[0] * BLOCK
    nch = chunks.shape[0] - 1
    cwork = np.empty(nch)
    cbad = np.empty(nch, dtype=np.int64)
    old = parallel_chunksize(1)
    for c in prange(nch):
        for r in range(chunks[c, 1] * NF, chunks[c + 1, 1] * NF):
            fb[r] = 0.0
        for r in range(chunks[c, 2] * NF, chunks[c + 1, 2] * NF):
            fb[r] = 0.0
        wc = 0.0
        nc = 0
        wk = np.empty(W_N * BLOCK)          # the chunk's scratch, reused block after block
        for blk in range(chunks[c, 0], chunks[c + 1, 0]):
            e0 = blk * BLOCK
            nx = blk + 2 if nblk >= PREFETCH_BLOCKS else nblk     # past the end: empty stretches, no prefetch
            wb, nb = element_block(wk, e0, min(BLOCK, ne - e0), blk, x, v, conn, slot,
                                   ed[blk * ED_N * BLOCK:(blk + 1) * ED_N * BLOCK], eh[blk * k6:(blk + 1) * k6],
                                   fb, p, decay, gain, ginf, bdt, bemin, status, errv, rho, hg, hgwave,
                                   ed[nx * ED_N * BLOCK:(nx + 1) * ED_N * BLOCK], eh[nx * k6:(nx + 1) * k6])
            wc += wb
            nc += nb
        cwork[c] = wc
        cbad[c] = nc
    parallel_chunksize(old)
    work = 0.0
    nbad = 0
    for c in range(nch):
        work += cwork[c]
        nbad += cbad[c]
    return work, nbad


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def element_block(wk, e0, n, blk, x, v, conn, slot, ed, eh, fb, p, decay, gain, ginf, bdt, bemin, status, errv,
                  rho, hg, hgwave, edn, ehn):
    """:func:`element_pass` for the n elements from e0 (block blk, its stretches ed, eh of the
    block arrays), the forces added onto fb; returns (stress work (J), number of failures).
    wk: the chunk's scratch (W_N BLOCK values, layout.py), overwritten. Inlined into
    :func:`element_pass` (module docstring, "Calls").

    edn, ehn: the stretches of the block after the next, prefetched an eighth at a time during the
    corner stage (:func:`prefetch_part`), so that their memory traffic overlaps this block's and
    the next block's arithmetic: on a mesh whose state outgrows the caches the processor's own
    prefetchers leave the stages waiting for it (docs/user/performance.md; two blocks ahead 2-5 %
    faster than one on an AMD EPYC, December 2026). Empty near the last block and below
    ``PREFETCH_BLOCKS`` blocks: nothing is prefetched."""
    kinematics_block(wk, ed, x, v, conn, e0, n)
    eigen_block(wk, n)
    eigen_fallback(wk, n)
    material_block(wk, p, n)
    stress_block(wk, n)
    prony_block(wk, ed, eh, decay, gain, ginf, n)
    forces_block(wk, ed, rho, hg, hgwave, n)
    for a in range(8):
        corner_forces(wk, ed, a, n)
        scatter_corner(wk, fb, slot, e0, a, n)
        prefetch_part(edn, ehn, a, 8)
    wb = 0.0
    nb = 0
    dmin = np.inf
    emin = e0
    for i in range(n):
        e = e0 + i
        d = wk[W_DTE * BLOCK + i]
        if d < dmin:
            dmin = d
            emin = e
        st = wk[W_ST * BLOCK + i]
        if st != 0.0:
            status[e] = 1 if st == 1.0 else 2
            if nb == 0:
                errv[blk, 0] = wk[W_J * BLOCK + i]
                for r in range(3):
                    errv[blk, 1 + r] = 0.0 if st == 1.0 else wk[(W_M + r) * BLOCK + i]
            nb += 1
        else:
            wb += wk[W_WORK * BLOCK + i]
    bdt[blk] = dmin
    bemin[blk] = emin
    return wb, nb


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def scatter_corner(wk, fb, slot, e0, a, n):
    """Add corner a's forces of the block's elements (wk rows W_FN + c, N) onto the force buffer
    rows slot[e, a] (value NF row + c), element by element in order: 8 elements at a time by
    :func:`scatter8`, the rest of a short last block one by one."""
    n8 = n - n % 8
    for i in range(0, n8, 8):
        scatter8(wk, W_FN * BLOCK + i, fb, slot, e0 + i, a)
    for i in range(n8, n):
        r = slot[e0 + i, a] * NF
        fb[r] += wk[W_FN * BLOCK + i]
        fb[r + 1] += wk[(W_FN + 1) * BLOCK + i]
        fb[r + 2] += wk[(W_FN + 2) * BLOCK + i]
        fb[r + 3] += wk[(W_FN + 3) * BLOCK + i]
        fb[r + 4] += wk[(W_FN + 4) * BLOCK + i]
        fb[r + 5] += wk[(W_FN + 5) * BLOCK + i]


@njit(inline="always")
def put_rows9(wk, row, i, a00, a01, a02, a10, a11, a12, a20, a21, a22):
    """A 3x3 matrix into rows row .. row + 8 (row-major) of column i of the block scratch wk."""
    wk[row * BLOCK + i] = a00
    wk[(row + 1) * BLOCK + i] = a01
    wk[(row + 2) * BLOCK + i] = a02
    wk[(row + 3) * BLOCK + i] = a10
    wk[(row + 4) * BLOCK + i] = a11
    wk[(row + 5) * BLOCK + i] = a12
    wk[(row + 6) * BLOCK + i] = a20
    wk[(row + 7) * BLOCK + i] = a21
    wk[(row + 8) * BLOCK + i] = a22


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def kinematics_block(wk, ed, x, v, conn, e0, n):
    """F = sum_a x_a (x) B_a (rows W_F) and the hourglass modes q_alpha = sum_a v_a gamma_a,alpha
    (rows W_Q, m/s) of the block's n elements from e0, with gamma_a,alpha = h_alpha,a - sum_k
    (h_alpha . X_k) B_a,k: q_alpha = sum_a h_alpha,a v_a - sum_k (h_alpha . X_k) L_:k (L the
    velocity gradient sum_a v_a (x) B_a), from 12 stored values per element instead of 32.

    The corners' nodes are gathered into rows first (:func:`gather_corners`); the sums over the
    8 corners then run as loops over the block's elements that LLVM vectorises
    (:func:`deformation_block`, :func:`velocity_block`), with the corner loop unrolled by the
    code generator (``codegen.unroll_corners``: LLVM does not vectorise a loop over elements with
    a loop over corners inside). The same sums in the same order, as fused multiply-adds as in a
    loop (compiled without nsz, ``FASTMATH_SUMS``), so the same bits as element by element;
    5-14 % faster per element-cycle (docs/user/performance.md)."""
    gather_corners(wk, x, v, conn, e0, n)
    deformation_block(wk, ed, n)
    velocity_block(wk, ed, n)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def gather_corners(wk, x, v, conn, e0, n):
    """Rows W_G + 6 a + c of the block's n elements from e0: x[conn[e, a], c] and v[conn[e, a],
    c] (c + 3) (m, m/s), corner by corner: 8 elements at a time by :func:`gather8`, the rest of a
    short last block one by one."""
    n8 = n - n % 8
    for a in range(8):
        for i in range(0, n8, 8):
            gather8(wk, (W_G + 6 * a) * BLOCK + i, x, v, conn, e0 + i, a)
        for i in range(n8, n):
            nd = conn[e0 + i, a]
            wk[(W_G + 6 * a) * BLOCK + i] = x[nd, 0]
            wk[(W_G + 6 * a + 1) * BLOCK + i] = x[nd, 1]
            wk[(W_G + 6 * a + 2) * BLOCK + i] = x[nd, 2]
            wk[(W_G + 6 * a + 3) * BLOCK + i] = v[nd, 0]
            wk[(W_G + 6 * a + 4) * BLOCK + i] = v[nd, 1]
            wk[(W_G + 6 * a + 5) * BLOCK + i] = v[nd, 2]


@njit(inline="always", fastmath=FASTMATH_SUMS, error_model="numpy")
def corner_gradient(wk, ed, i, c):
    """sum_a u_a (x) B_a (the 9 values row-major) of column i, u_a the gathered corner values in
    rows W_G + 6 a + c .. + 2: F for c = 0 (positions), L for c = 3 (velocities). The loop over the
    corners is unrolled in the generated module (UNROLLED_CORNERS)."""
    g00 = 0.0
    g01 = 0.0
    g02 = 0.0
    g10 = 0.0
    g11 = 0.0
    g12 = 0.0
    g20 = 0.0
    g21 = 0.0
    g22 = 0.0
    for a in range(8):
        u0 = wk[(W_G + 6 * a + c) * BLOCK + i]
        u1 = wk[(W_G + 6 * a + c + 1) * BLOCK + i]
        u2 = wk[(W_G + 6 * a + c + 2) * BLOCK + i]
        b0 = ed[(ED_B + 3 * a) * BLOCK + i]
        b1 = ed[(ED_B + 3 * a + 1) * BLOCK + i]
        b2 = ed[(ED_B + 3 * a + 2) * BLOCK + i]
        g00 += u0 * b0
        g01 += u0 * b1
        g02 += u0 * b2
        g10 += u1 * b0
        g11 += u1 * b1
        g12 += u1 * b2
        g20 += u2 * b0
        g21 += u2 * b1
        g22 += u2 * b2
    return g00, g01, g02, g10, g11, g12, g20, g21, g22


@njit(cache=True, fastmath=FASTMATH_SUMS, error_model="numpy")
def deformation_block(wk, ed, n):
    """F = sum_a x_a (x) B_a (rows W_F) from the gathered positions (rows W_G)."""
    for i in range(n):
        f00, f01, f02, f10, f11, f12, f20, f21, f22 = corner_gradient(wk, ed, i, 0)
        put_rows9(wk, W_F, i, f00, f01, f02, f10, f11, f12, f20, f21, f22)


@njit(cache=True, fastmath=FASTMATH_SUMS, error_model="numpy")
def velocity_block(wk, ed, n):
    """The hourglass modes q_alpha,i = sum_a h_alpha,a v_a,i - sum_k (h_alpha . X_k) L_ik (rows
    W_Q, m/s), L_ik = sum_a v_a,i B_a,k, from the gathered velocities (rows W_G + 6 a + 3..5). The
    loop over the corners is unrolled in the generated module (UNROLLED_CORNERS)."""
    for i in range(n):
        l00, l01, l02, l10, l11, l12, l20, l21, l22 = corner_gradient(wk, ed, i, 3)
        s00 = 0.0
        s01 = 0.0
        s02 = 0.0
        s10 = 0.0
        s11 = 0.0
        s12 = 0.0
        s20 = 0.0
        s21 = 0.0
        s22 = 0.0
        s30 = 0.0
        s31 = 0.0
        s32 = 0.0
        for a in range(8):
            v0 = wk[(W_G + 6 * a + 3) * BLOCK + i]
            v1 = wk[(W_G + 6 * a + 4) * BLOCK + i]
            v2 = wk[(W_G + 6 * a + 5) * BLOCK + i]
            h0 = H0[a]
            h1 = H1[a]
            h2 = H2[a]
            h3 = H3[a]
            s00 += v0 * h0
            s01 += v1 * h0
            s02 += v2 * h0
            s10 += v0 * h1
            s11 += v1 * h1
            s12 += v2 * h1
            s20 += v0 * h2
            s21 += v1 * h2
            s22 += v2 * h2
            s30 += v0 * h3
            s31 += v1 * h3
            s32 += v2 * h3
        x00 = ed[ED_HX * BLOCK + i]
        x01 = ed[(ED_HX + 1) * BLOCK + i]
        x02 = ed[(ED_HX + 2) * BLOCK + i]
        x10 = ed[(ED_HX + 3) * BLOCK + i]
        x11 = ed[(ED_HX + 4) * BLOCK + i]
        x12 = ed[(ED_HX + 5) * BLOCK + i]
        x20 = ed[(ED_HX + 6) * BLOCK + i]
        x21 = ed[(ED_HX + 7) * BLOCK + i]
        x22 = ed[(ED_HX + 8) * BLOCK + i]
        x30 = ed[(ED_HX + 9) * BLOCK + i]
        x31 = ed[(ED_HX + 10) * BLOCK + i]
        x32 = ed[(ED_HX + 11) * BLOCK + i]
        wk[W_Q * BLOCK + i] = s00 - (x00 * l00 + x01 * l01 + x02 * l02)
        wk[(W_Q + 1) * BLOCK + i] = s01 - (x00 * l10 + x01 * l11 + x02 * l12)
        wk[(W_Q + 2) * BLOCK + i] = s02 - (x00 * l20 + x01 * l21 + x02 * l22)
        wk[(W_Q + 3) * BLOCK + i] = s10 - (x10 * l00 + x11 * l01 + x12 * l02)
        wk[(W_Q + 4) * BLOCK + i] = s11 - (x10 * l10 + x11 * l11 + x12 * l12)
        wk[(W_Q + 5) * BLOCK + i] = s12 - (x10 * l20 + x11 * l21 + x12 * l22)
        wk[(W_Q + 6) * BLOCK + i] = s20 - (x20 * l00 + x21 * l01 + x22 * l02)
        wk[(W_Q + 7) * BLOCK + i] = s21 - (x20 * l10 + x21 * l11 + x22 * l12)
        wk[(W_Q + 8) * BLOCK + i] = s22 - (x20 * l20 + x21 * l21 + x22 * l22)
        wk[(W_Q + 9) * BLOCK + i] = s30 - (x30 * l00 + x31 * l01 + x32 * l02)
        wk[(W_Q + 10) * BLOCK + i] = s31 - (x30 * l10 + x31 * l11 + x32 * l12)
        wk[(W_Q + 11) * BLOCK + i] = s32 - (x30 * l20 + x31 * l21 + x32 * l22)


#: Functions whose ``for a in range(8)`` corner loop the code generator unrolls (codegen.unroll_corners).
UNROLLED_CORNERS = ("corner_gradient", "velocity_block")


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def put_eigen(wk, i, m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22):
    """Eigenvalues m (rows W_M) and eigenvectors Q (rows W_V, row-major) of column i."""
    wk[W_M * BLOCK + i] = m0
    wk[(W_M + 1) * BLOCK + i] = m1
    wk[(W_M + 2) * BLOCK + i] = m2
    put_rows9(wk, W_V, i, q00, q01, q02, q10, q11, q12, q20, q21, q22)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eigen_block(wk, n):
    """J = det F, C = F^T F and the branch-free eigen-decomposition of C for the first n columns
    of a block's work array (rows W_F in; W_C, W_J, W_M, W_V, W_OK out). A function of its own:
    LLVM vectorises this loop alone, not inside the larger element_block."""
    for i in range(n):
        f00 = wk[W_F * BLOCK + i]
        f01 = wk[(W_F + 1) * BLOCK + i]
        f02 = wk[(W_F + 2) * BLOCK + i]
        f10 = wk[(W_F + 3) * BLOCK + i]
        f11 = wk[(W_F + 4) * BLOCK + i]
        f12 = wk[(W_F + 5) * BLOCK + i]
        f20 = wk[(W_F + 6) * BLOCK + i]
        f21 = wk[(W_F + 7) * BLOCK + i]
        f22 = wk[(W_F + 8) * BLOCK + i]
        J = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
             + f02 * (f10 * f21 - f11 * f20))
        c00 = f00 * f00 + f10 * f10 + f20 * f20
        c11 = f01 * f01 + f11 * f11 + f21 * f21
        c22 = f02 * f02 + f12 * f12 + f22 * f22
        c01 = f00 * f01 + f10 * f11 + f20 * f21
        c12 = f01 * f02 + f11 * f12 + f21 * f22
        c02 = f00 * f02 + f10 * f12 + f20 * f22
        (ok, m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22) = eig3_hybrid(
            c00, c01, c02, c11, c12, c22)
        wk[W_C * BLOCK + i] = c00
        wk[(W_C + 1) * BLOCK + i] = c11
        wk[(W_C + 2) * BLOCK + i] = c22
        wk[(W_C + 3) * BLOCK + i] = c01
        wk[(W_C + 4) * BLOCK + i] = c12
        wk[(W_C + 5) * BLOCK + i] = c02
        wk[W_J * BLOCK + i] = J
        put_eigen(wk, i, m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22)
        wk[W_OK * BLOCK + i] = 1.0 if ok else 0.0


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eigen_fallback(wk, n):
    """The scalar :func:`eig3` for the columns :func:`eigen_block` did not cover (C isotropic to
    round-off but not exactly diagonal, or non-finite values); an inverted element (J <= 0) gets finite
    placeholders m = 1 for the material stage (its status says inverted)."""
    for i in range(n):
        J = wk[W_J * BLOCK + i]
        if wk[W_OK * BLOCK + i] == 0.0 or not (J > 0.0):
            m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22 = eig3(
                wk[W_C * BLOCK + i], wk[(W_C + 3) * BLOCK + i], wk[(W_C + 5) * BLOCK + i],
                wk[(W_C + 1) * BLOCK + i], wk[(W_C + 4) * BLOCK + i], wk[(W_C + 2) * BLOCK + i])
            if not (J > 0.0) or not math.isfinite(J):
                m0 = 1.0
                m1 = 1.0
                m2 = 1.0
            put_eigen(wk, i, m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22)


@njit(cache=True, fastmath=False, error_model="numpy")  # explicitly False: callees inherit the caller's
def material_block(wk, p, n):
    """The material's derivatives for the first n columns: rows W_M.. W_M+2 hold the
    eigenvalues m of C, rows W_R..W_R+11 receive psi_grad_hess_diag's 12 values (Pa). IEEE
    maths, no fast-math flags (as the scalar material functions: zero stress at the reference
    state to the bit), with the vectorisable variant of the generated code
    (``codegen.vector_source``)."""
    for i in range(n):
        r = psi_grad_hess_diag_v(wk[W_M * BLOCK + i], wk[(W_M + 1) * BLOCK + i], wk[(W_M + 2) * BLOCK + i], p)
        wk[W_R * BLOCK + i] = r[0]
        wk[(W_R + 1) * BLOCK + i] = r[1]
        wk[(W_R + 2) * BLOCK + i] = r[2]
        wk[(W_R + 3) * BLOCK + i] = r[3]
        wk[(W_R + 4) * BLOCK + i] = r[4]
        wk[(W_R + 5) * BLOCK + i] = r[5]
        wk[(W_R + 6) * BLOCK + i] = r[6]
        wk[(W_R + 7) * BLOCK + i] = r[7]
        wk[(W_R + 8) * BLOCK + i] = r[8]
        wk[(W_R + 9) * BLOCK + i] = r[9]
        wk[(W_R + 10) * BLOCK + i] = r[10]
        wk[(W_R + 11) * BLOCK + i] = r[11]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def stress_block(wk, n):
    """Principal-basis stresses, moduli and status (docs/conventions.md section 2).

    From C = Q diag(m) Q^T and the material's derivatives (d psi_iso / d m_a = i_a, d psi_vol /
    d m_a = v_a and their second derivatives h_a, w_a):

        S0_iso = Q diag(2 i) Q^T (rows W_SI),   S_vol = Q diag(2 v) Q^T (rows W_S)      (Pa)

    and the longitudinal moduli along the principal directions, M_a = 2 psi_a + 4 m_a psi_aa
    (d^2 Psi / d lambda_a^2 with lambda_a = sqrt(m_a), instantaneous isochoric energy: the Prony
    series only lowers the stiffness within a step): W_MT the largest, W_MI its isochoric part.
    W_ST: 0 ok, 1 inverted (J <= 0 or not finite), 2 non-finite derivative.
    """
    for i in range(n):
        J = wk[W_J * BLOCK + i]
        m0 = wk[W_M * BLOCK + i]
        m1 = wk[(W_M + 1) * BLOCK + i]
        m2 = wk[(W_M + 2) * BLOCK + i]
        q00 = wk[W_V * BLOCK + i]
        q01 = wk[(W_V + 1) * BLOCK + i]
        q02 = wk[(W_V + 2) * BLOCK + i]
        q10 = wk[(W_V + 3) * BLOCK + i]
        q11 = wk[(W_V + 4) * BLOCK + i]
        q12 = wk[(W_V + 5) * BLOCK + i]
        q20 = wk[(W_V + 6) * BLOCK + i]
        q21 = wk[(W_V + 7) * BLOCK + i]
        q22 = wk[(W_V + 8) * BLOCK + i]
        i0 = wk[W_R * BLOCK + i]
        i1 = wk[(W_R + 1) * BLOCK + i]
        i2 = wk[(W_R + 2) * BLOCK + i]
        v0 = wk[(W_R + 3) * BLOCK + i]
        v1 = wk[(W_R + 4) * BLOCK + i]
        v2 = wk[(W_R + 5) * BLOCK + i]
        h0 = wk[(W_R + 6) * BLOCK + i]
        h1 = wk[(W_R + 7) * BLOCK + i]
        h2 = wk[(W_R + 8) * BLOCK + i]
        w0 = wk[(W_R + 9) * BLOCK + i]
        w1 = wk[(W_R + 10) * BLOCK + i]
        w2 = wk[(W_R + 11) * BLOCK + i]
        chk = i0 + i1 + i2 + v0 + v1 + v2 + h0 + h1 + h2 + w0 + w1 + w2
        ok_j = (J > 0.0) & (J - J == 0.0)         # x - x == 0 is false for inf and NaN
        ok_d = chk - chk == 0.0
        wk[W_ST * BLOCK + i] = 0.0 if ok_j & ok_d else (2.0 if ok_j else 1.0)
        a0 = 2.0 * i0
        a1 = 2.0 * i1
        a2 = 2.0 * i2
        wk[W_SI * BLOCK + i] = a0 * q00 * q00 + a1 * q01 * q01 + a2 * q02 * q02
        wk[(W_SI + 1) * BLOCK + i] = a0 * q10 * q10 + a1 * q11 * q11 + a2 * q12 * q12
        wk[(W_SI + 2) * BLOCK + i] = a0 * q20 * q20 + a1 * q21 * q21 + a2 * q22 * q22
        wk[(W_SI + 3) * BLOCK + i] = a0 * q00 * q10 + a1 * q01 * q11 + a2 * q02 * q12
        wk[(W_SI + 4) * BLOCK + i] = a0 * q10 * q20 + a1 * q11 * q21 + a2 * q12 * q22
        wk[(W_SI + 5) * BLOCK + i] = a0 * q00 * q20 + a1 * q01 * q21 + a2 * q02 * q22
        b0 = 2.0 * v0
        b1 = 2.0 * v1
        b2 = 2.0 * v2
        wk[W_S * BLOCK + i] = b0 * q00 * q00 + b1 * q01 * q01 + b2 * q02 * q02
        wk[(W_S + 1) * BLOCK + i] = b0 * q10 * q10 + b1 * q11 * q11 + b2 * q12 * q12
        wk[(W_S + 2) * BLOCK + i] = b0 * q20 * q20 + b1 * q21 * q21 + b2 * q22 * q22
        wk[(W_S + 3) * BLOCK + i] = b0 * q00 * q10 + b1 * q01 * q11 + b2 * q02 * q12
        wk[(W_S + 4) * BLOCK + i] = b0 * q10 * q20 + b1 * q11 * q21 + b2 * q12 * q22
        wk[(W_S + 5) * BLOCK + i] = b0 * q00 * q20 + b1 * q01 * q21 + b2 * q02 * q22
        mi0 = 2.0 * i0 + 4.0 * m0 * h0
        mi1 = 2.0 * i1 + 4.0 * m1 * h1
        mi2 = 2.0 * i2 + 4.0 * m2 * h2
        mt0 = mi0 + 2.0 * v0 + 4.0 * m0 * w0
        mt1 = mi1 + 2.0 * v1 + 4.0 * m1 * w1
        mt2 = mi2 + 2.0 * v2 + 4.0 * m2 * w2
        wk[W_MT * BLOCK + i] = max(mt0, max(mt1, mt2))
        wk[W_MI * BLOCK + i] = max(mi0, max(mi1, mi2))


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def prony_block(wk, ed, eh, decay, gain, ginf, n):
    """Prony series on the isochoric stress, exact exponential recurrence over the step dt (s):

        H_k <- exp(-dt/tau_k) H_k + gamma_k (tau_k/dt)(1 - exp(-dt/tau_k)) (S0_new - S0_old)
        S = S_vol + gamma_inf S0_iso + sum_k H_k                                  (Pa)

    decay, gain (k,): the step's factors (``prony_step``). Adds to rows W_S; updates S0_old (ed
    rows ED_S0) and H (eh rows 6 k + c) of the elements whose status is 0 (the others keep
    theirs); then a non-finite S or modulus sets status 2."""
    k = decay.shape[0]
    if k > 0:
        for c in range(6):
            for i in range(n):
                ok = wk[W_ST * BLOCK + i] == 0.0
                si = wk[(W_SI + c) * BLOCK + i]
                old = ed[(ED_S0 + c) * BLOCK + i]
                wk[(W_D + c) * BLOCK + i] = si - old
                wk[(W_S + c) * BLOCK + i] += ginf * si
                ed[(ED_S0 + c) * BLOCK + i] = si if ok else old
        for j in range(k):
            dj = decay[j]
            gj = gain[j]
            hj = eh[6 * j * BLOCK:(6 * j + 6) * BLOCK]
            for c in range(6):
                for i in range(n):
                    ok = wk[W_ST * BLOCK + i] == 0.0
                    old = hj[c * BLOCK + i]
                    h = dj * old + gj * wk[(W_D + c) * BLOCK + i]
                    hj[c * BLOCK + i] = h if ok else old
                    wk[(W_S + c) * BLOCK + i] += h
    else:
        for c in range(6):
            for i in range(n):
                wk[(W_S + c) * BLOCK + i] += wk[(W_SI + c) * BLOCK + i]
    for i in range(n):
        s = (wk[W_S * BLOCK + i] + wk[(W_S + 1) * BLOCK + i] + wk[(W_S + 2) * BLOCK + i]
             + wk[(W_S + 3) * BLOCK + i] + wk[(W_S + 4) * BLOCK + i] + wk[(W_S + 5) * BLOCK + i]
             + wk[W_MT * BLOCK + i])
        st = wk[W_ST * BLOCK + i]
        wk[W_ST * BLOCK + i] = 2.0 if (st == 0.0) & (s - s != 0.0) else st


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def forces_block(wk, ed, rho, hg, hgwave, n):
    """Stable step, P, c_hg and stress work of the block's elements for :func:`corner_forces` (status 0;
    the others get dte = inf, zero forces and keep their previous-step S and E).

    dte = L / c with c = sqrt(M / rho) the longitudinal wave speed (s, rows W_DTE);
    internal forces V0 P B_a with P = F S (N); hourglass forces -c_hg sum_alpha q_alpha
    gamma_a,alpha with c_hg = Q_hg rho c V0^(2/3) / 4, c from the isochoric (hgwave 0) or full
    modulus (:func:`corner_forces`); stress work, trapezoid in time: V0 (S_old + S) / 2 : (E - E_old),
    E = (C - I) / 2 (J, rows W_WORK)."""
    for i in range(n):
        ok = wk[W_ST * BLOCK + i] == 0.0
        mt = wk[W_MT * BLOCK + i]
        mi = wk[W_MI * BLOCK + i]
        dte = ed[ED_L * BLOCK + i] / vsqrt(mt / rho) if mt > 0.0 else np.inf
        wk[W_DTE * BLOCK + i] = dte if ok else np.inf
        mod = mi if hgwave == 0 else mt
        chg = -hg * ed[ED_HGF * BLOCK + i] * vsqrt(mod / rho) if (hg > 0.0) & (mod > 0.0) else 0.0
        s00 = wk[W_S * BLOCK + i]
        s11 = wk[(W_S + 1) * BLOCK + i]
        s22 = wk[(W_S + 2) * BLOCK + i]
        s01 = wk[(W_S + 3) * BLOCK + i]
        s12 = wk[(W_S + 4) * BLOCK + i]
        s02 = wk[(W_S + 5) * BLOCK + i]
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = first_piola(
            wk[W_F * BLOCK + i], wk[(W_F + 1) * BLOCK + i], wk[(W_F + 2) * BLOCK + i],
            wk[(W_F + 3) * BLOCK + i], wk[(W_F + 4) * BLOCK + i], wk[(W_F + 5) * BLOCK + i],
            wk[(W_F + 6) * BLOCK + i], wk[(W_F + 7) * BLOCK + i], wk[(W_F + 8) * BLOCK + i],
            s00, s11, s22, s01, s12, s02)
        vol = ed[ED_V0 * BLOCK + i]
        wk[W_P * BLOCK + i] = p00 if ok else 0.0
        wk[(W_P + 1) * BLOCK + i] = p01 if ok else 0.0
        wk[(W_P + 2) * BLOCK + i] = p02 if ok else 0.0
        wk[(W_P + 3) * BLOCK + i] = p10 if ok else 0.0
        wk[(W_P + 4) * BLOCK + i] = p11 if ok else 0.0
        wk[(W_P + 5) * BLOCK + i] = p12 if ok else 0.0
        wk[(W_P + 6) * BLOCK + i] = p20 if ok else 0.0
        wk[(W_P + 7) * BLOCK + i] = p21 if ok else 0.0
        wk[(W_P + 8) * BLOCK + i] = p22 if ok else 0.0
        wk[W_CHG * BLOCK + i] = chg if ok else 0.0
        cg = chg if ok else 0.0
        q00 = wk[W_Q * BLOCK + i] * cg
        q01 = wk[(W_Q + 1) * BLOCK + i] * cg
        q02 = wk[(W_Q + 2) * BLOCK + i] * cg
        q10 = wk[(W_Q + 3) * BLOCK + i] * cg
        q11 = wk[(W_Q + 4) * BLOCK + i] * cg
        q12 = wk[(W_Q + 5) * BLOCK + i] * cg
        q20 = wk[(W_Q + 6) * BLOCK + i] * cg
        q21 = wk[(W_Q + 7) * BLOCK + i] * cg
        q22 = wk[(W_Q + 8) * BLOCK + i] * cg
        q30 = wk[(W_Q + 9) * BLOCK + i] * cg
        q31 = wk[(W_Q + 10) * BLOCK + i] * cg
        q32 = wk[(W_Q + 11) * BLOCK + i] * cg
        wk[W_HR * BLOCK + i] = (ed[ED_HX * BLOCK + i] * q00 + ed[(ED_HX + 3) * BLOCK + i] * q10
                                    + ed[(ED_HX + 6) * BLOCK + i] * q20 + ed[(ED_HX + 9) * BLOCK + i] * q30)
        wk[(W_HR + 1) * BLOCK + i] = (ed[ED_HX * BLOCK + i] * q01 + ed[(ED_HX + 3) * BLOCK + i] * q11
                                    + ed[(ED_HX + 6) * BLOCK + i] * q21 + ed[(ED_HX + 9) * BLOCK + i] * q31)
        wk[(W_HR + 2) * BLOCK + i] = (ed[ED_HX * BLOCK + i] * q02 + ed[(ED_HX + 3) * BLOCK + i] * q12
                                    + ed[(ED_HX + 6) * BLOCK + i] * q22 + ed[(ED_HX + 9) * BLOCK + i] * q32)
        wk[(W_HR + 3) * BLOCK + i] = (ed[(ED_HX + 1) * BLOCK + i] * q00 + ed[(ED_HX + 4) * BLOCK + i] * q10
                                    + ed[(ED_HX + 7) * BLOCK + i] * q20 + ed[(ED_HX + 10) * BLOCK + i] * q30)
        wk[(W_HR + 4) * BLOCK + i] = (ed[(ED_HX + 1) * BLOCK + i] * q01 + ed[(ED_HX + 4) * BLOCK + i] * q11
                                    + ed[(ED_HX + 7) * BLOCK + i] * q21 + ed[(ED_HX + 10) * BLOCK + i] * q31)
        wk[(W_HR + 5) * BLOCK + i] = (ed[(ED_HX + 1) * BLOCK + i] * q02 + ed[(ED_HX + 4) * BLOCK + i] * q12
                                    + ed[(ED_HX + 7) * BLOCK + i] * q22 + ed[(ED_HX + 10) * BLOCK + i] * q32)
        wk[(W_HR + 6) * BLOCK + i] = (ed[(ED_HX + 2) * BLOCK + i] * q00 + ed[(ED_HX + 5) * BLOCK + i] * q10
                                    + ed[(ED_HX + 8) * BLOCK + i] * q20 + ed[(ED_HX + 11) * BLOCK + i] * q30)
        wk[(W_HR + 7) * BLOCK + i] = (ed[(ED_HX + 2) * BLOCK + i] * q01 + ed[(ED_HX + 5) * BLOCK + i] * q11
                                    + ed[(ED_HX + 8) * BLOCK + i] * q21 + ed[(ED_HX + 11) * BLOCK + i] * q31)
        wk[(W_HR + 8) * BLOCK + i] = (ed[(ED_HX + 2) * BLOCK + i] * q02 + ed[(ED_HX + 5) * BLOCK + i] * q12
                                    + ed[(ED_HX + 8) * BLOCK + i] * q22 + ed[(ED_HX + 11) * BLOCK + i] * q32)
        e00 = 0.5 * (wk[W_C * BLOCK + i] - 1.0)
        e11 = 0.5 * (wk[(W_C + 1) * BLOCK + i] - 1.0)
        e22 = 0.5 * (wk[(W_C + 2) * BLOCK + i] - 1.0)
        e01 = 0.5 * wk[(W_C + 3) * BLOCK + i]
        e12 = 0.5 * wk[(W_C + 4) * BLOCK + i]
        e02 = 0.5 * wk[(W_C + 5) * BLOCK + i]
        so0 = ed[ED_SO * BLOCK + i]
        so1 = ed[(ED_SO + 1) * BLOCK + i]
        so2 = ed[(ED_SO + 2) * BLOCK + i]
        so3 = ed[(ED_SO + 3) * BLOCK + i]
        so4 = ed[(ED_SO + 4) * BLOCK + i]
        so5 = ed[(ED_SO + 5) * BLOCK + i]
        eo0 = ed[ED_EO * BLOCK + i]
        eo1 = ed[(ED_EO + 1) * BLOCK + i]
        eo2 = ed[(ED_EO + 2) * BLOCK + i]
        eo3 = ed[(ED_EO + 3) * BLOCK + i]
        eo4 = ed[(ED_EO + 4) * BLOCK + i]
        eo5 = ed[(ED_EO + 5) * BLOCK + i]
        w = ((so0 + s00) * (e00 - eo0) + (so1 + s11) * (e11 - eo1) + (so2 + s22) * (e22 - eo2)
             + 2.0 * ((so3 + s01) * (e01 - eo3) + (so4 + s12) * (e12 - eo4) + (so5 + s02) * (e02 - eo5)))
        wk[W_WORK * BLOCK + i] = 0.5 * vol * w if ok else 0.0
        ed[ED_SO * BLOCK + i] = s00 if ok else so0
        ed[(ED_SO + 1) * BLOCK + i] = s11 if ok else so1
        ed[(ED_SO + 2) * BLOCK + i] = s22 if ok else so2
        ed[(ED_SO + 3) * BLOCK + i] = s01 if ok else so3
        ed[(ED_SO + 4) * BLOCK + i] = s12 if ok else so4
        ed[(ED_SO + 5) * BLOCK + i] = s02 if ok else so5
        ed[ED_EO * BLOCK + i] = e00 if ok else eo0
        ed[(ED_EO + 1) * BLOCK + i] = e11 if ok else eo1
        ed[(ED_EO + 2) * BLOCK + i] = e22 if ok else eo2
        ed[(ED_EO + 3) * BLOCK + i] = e01 if ok else eo3
        ed[(ED_EO + 4) * BLOCK + i] = e12 if ok else eo4
        ed[(ED_EO + 5) * BLOCK + i] = e02 if ok else eo5



@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def corner_forces(wk, ed, a, n):
    """Nodal forces at corner a of the block's elements (wk rows W_FN + c, N; zero for failed
    elements): internal V0 P B_a, hourglass -c_hg sum_alpha q_alpha gamma_a,alpha = -c_hg
    sum_alpha h_alpha,a q_alpha - sum_k B_a,k (rows W_HR + 3 k). Vectorised across elements;
    one corner at a time keeps the block's scratch within the L1 cache."""
    h0 = H0[a]
    h1 = H1[a]
    h2 = H2[a]
    h3 = H3[a]
    for i in range(n):
        vol = ed[ED_V0 * BLOCK + i]
        bb0 = ed[(ED_B + 3 * a) * BLOCK + i]
        bb1 = ed[(ED_B + 3 * a + 1) * BLOCK + i]
        bb2 = ed[(ED_B + 3 * a + 2) * BLOCK + i]
        b0 = bb0 * vol
        b1 = bb1 * vol
        b2 = bb2 * vol
        chg = wk[W_CHG * BLOCK + i]
        g0 = h0 * chg
        g1 = h1 * chg
        g2 = h2 * chg
        g3 = h3 * chg
        wk[W_FN * BLOCK + i] = (wk[W_P * BLOCK + i] * b0 + wk[(W_P + 1) * BLOCK + i] * b1
                                + wk[(W_P + 2) * BLOCK + i] * b2)
        wk[(W_FN + 1) * BLOCK + i] = (wk[(W_P + 3) * BLOCK + i] * b0 + wk[(W_P + 4) * BLOCK + i] * b1
                                      + wk[(W_P + 5) * BLOCK + i] * b2)
        wk[(W_FN + 2) * BLOCK + i] = (wk[(W_P + 6) * BLOCK + i] * b0 + wk[(W_P + 7) * BLOCK + i] * b1
                                      + wk[(W_P + 8) * BLOCK + i] * b2)
        hq = wk[W_Q * BLOCK + i] * g0 + wk[(W_Q + 3) * BLOCK + i] * g1 + wk[(W_Q + 6) * BLOCK + i] * g2
        hr = bb0 * wk[W_HR * BLOCK + i] + bb1 * wk[(W_HR + 3) * BLOCK + i] + bb2 * wk[(W_HR + 6) * BLOCK + i]
        wk[(W_FN + 3) * BLOCK + i] = hq + wk[(W_Q + 9) * BLOCK + i] * g3 - hr
        hq = wk[(W_Q + 1) * BLOCK + i] * g0 + wk[(W_Q + 4) * BLOCK + i] * g1 + wk[(W_Q + 7) * BLOCK + i] * g2
        hr = bb0 * wk[(W_HR + 1) * BLOCK + i] + bb1 * wk[(W_HR + 4) * BLOCK + i] + bb2 * wk[(W_HR + 7) * BLOCK + i]
        wk[(W_FN + 4) * BLOCK + i] = hq + wk[(W_Q + 10) * BLOCK + i] * g3 - hr
        hq = wk[(W_Q + 2) * BLOCK + i] * g0 + wk[(W_Q + 5) * BLOCK + i] * g1 + wk[(W_Q + 8) * BLOCK + i] * g2
        hr = bb0 * wk[(W_HR + 2) * BLOCK + i] + bb1 * wk[(W_HR + 5) * BLOCK + i] + bb2 * wk[(W_HR + 8) * BLOCK + i]
        wk[(W_FN + 5) * BLOCK + i] = hq + wk[(W_Q + 11) * BLOCK + i] * g3 - hr


@njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def gather_update(fb, hptr, hrow, mass, free, fint, fhg, x, v, vold, dtn, dt):
    """Sum each node's force rows, then central differences on the free dofs.

    fb: the force buffer (:func:`element_pass`): row j < n the node's own, rows hrow[hptr[j]:
    hptr[j + 1]] its halo rows in other chunks (in chunk order). fint, fhg (n, 3) receive the
    nodal internal and hourglass forces (N); vold the velocities v^{n-1/2}; v becomes v^{n+1/2} =
    v^{n-1/2} + dtn (f^hg - f^int) / m on free dofs (0 on fixed and prescribed ones); x becomes
    the trial x^{n+1} = x^n + dt v^{n+1/2}.
    """
    nn = x.shape[0]
    for n in prange(nn):
        r = n * NF
        s0 = fb[r]
        s1 = fb[r + 1]
        s2 = fb[r + 2]
        h0 = fb[r + 3]
        h1 = fb[r + 4]
        h2 = fb[r + 5]
        for k in range(hptr[n], hptr[n + 1]):
            r = hrow[k] * NF
            s0 += fb[r]
            s1 += fb[r + 1]
            s2 += fb[r + 2]
            h0 += fb[r + 3]
            h1 += fb[r + 4]
            h2 += fb[r + 5]
        fint[n, 0] = s0
        fint[n, 1] = s1
        fint[n, 2] = s2
        fhg[n, 0] = h0
        fhg[n, 1] = h1
        fhg[n, 2] = h2
        c = dtn / mass[n]
        for i in range(3):
            vo = v[n, i]
            vold[n, i] = vo
            vn = (vo + c * (fhg[n, i] - fint[n, i])) * free[n, i]
            v[n, i] = vn
            x[n, i] += dt * vn


@njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def energy_pass(mass, v, vold, fint, fhg, dvc, pmask, dtn):
    """Kinetic energy at t^n and the work of each force family around t^n (J, modelled part).

    Kinetic energy: the leapfrog's own, T^n = 1/2 sum m v^{n-1/2} . v^{n+1/2} (from the two
    mid-step velocities around t^n). Work of a force f^n: A = dtn/2 f^n . v^{n-1/2} (the part
    belonging to the interval before t^n) and B = dtn/2 f^n . v^{n+1/2} (after). Since
    m (v^{n+1/2} - v^{n-1/2}) = dtn f^n, T^n - T^{n-1} = A^n + B^{n-1} summed over all forces,
    exactly: the force works balance the kinetic energy to round-off, so the energy balance
    checks the internal energy (trapezoid stress work, independent of the nodal forces). For
    constant dt, B^{n-1} + A^n is the trapezoid rule 1/2 (f^{n-1} + f^n) . (x^n - x^{n-1}), and
    for a linear elastic model the balance is exact (the leapfrog conserves this energy).
    Forces: internal -fint, hourglass fhg, contact m dvc / dtn, and on prescribed dofs (pmask)
    the reaction imposing the motion (external).
    Returns (T, A_int, B_int, A_hg, B_hg, A_c, B_c, A_ext, B_ext, momentum_z at n+1/2).

    Summed over fixed node ranges (:data:`ENERGY_RANGE` nodes each, in parallel), then the ranges
    in order: the same bits whatever the thread count.
    """
    nn = v.shape[0]
    h = 0.5 * dtn
    nr = max(1, -(-nn // ENERGY_RANGE))
    part = np.zeros((nr, 10))
    for rg in prange(nr):
        ke = 0.0
        ai = 0.0
        bi = 0.0
        ah = 0.0
        bh = 0.0
        ac = 0.0
        bc = 0.0
        ax = 0.0
        bx = 0.0
        pz = 0.0
        for n in range(rg * ENERGY_RANGE, min(nn, (rg + 1) * ENERGY_RANGE)):
            m = mass[n]
            kn = 0.0
            ain = 0.0
            bin_ = 0.0
            ahn = 0.0
            bhn = 0.0
            acn = 0.0
            bcn = 0.0
            axn = 0.0
            bxn = 0.0
            for i in range(3):
                vo = vold[n, i]
                vh = v[n, i]
                kn += vo * vh
                fi = -h * fint[n, i]
                fhh = h * fhg[n, i]
                fc = 0.5 * m * dvc[n, i]
                ain += fi * vo
                bin_ += fi * vh
                ahn += fhh * vo
                bhn += fhh * vh
                acn += fc * vo
                bcn += fc * vh
                if pmask[n, i] != 0.0:
                    fx = 0.5 * m * (vh - vo) - (fi + fhh + fc)
                    axn += fx * vo
                    bxn += fx * vh
            ke += 0.5 * m * kn
            ai += ain
            bi += bin_
            ah += ahn
            bh += bhn
            ac += acn
            bc += bcn
            ax += axn
            bx += bxn
            pz += m * v[n, 2]
        part[rg, 0] = ke
        part[rg, 1] = ai
        part[rg, 2] = bi
        part[rg, 3] = ah
        part[rg, 4] = bh
        part[rg, 5] = ac
        part[rg, 6] = bc
        part[rg, 7] = ax
        part[rg, 8] = bx
        part[rg, 9] = pz
    tot = np.zeros(10)
    for rg in range(nr):                 # the ranges in order: the same bits on any thread count
        for j in range(10):
            tot[j] += part[rg, j]
    return tot[0], tot[1], tot[2], tot[3], tot[4], tot[5], tot[6], tot[7], tot[8], tot[9]
