"""The ∇⁴'s weak Laplacians on the CPU with W elements a vector (the element index innermost), at
np ≥ 5: ``laplacian_across``, ``hyperviscosity_element.laplacian_element``'s passes with the same
bits, ``weak_laplacian_across`` its sweeps and ``operators.across_layout`` its metric's layout."""

import functools
from typing import Any

import warp as wp

from .dss import Copies, Edges
from .hyperviscosity import frame_type
from .hyperviscosity_element import element_parts, row_field, source_rows
from .operators import CPU_FAST, row_derivatives, row_type, suffix, transpose16

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@functools.cache
def weak_laplacian_across(np_: int, lanes: int, dtype=f64):
    """One field's weak Laplacian −Σ ∂ᵀ(G ∇_ref f) with the element index innermost, a
    ``wp.func`` (X, G, fx, fy, dvv, bn, first): X (np²) ``wp.types.vector(lanes)`` the field at an
    element block's nodes (node n = j·np + i; lane w element w of the block), overwritten by its
    weak Laplacian; G (3, ·) the metric's rows 0..2 in the across layout from node bn (the
    block's first); fx, fy (np²) scratch; dvv as ``operators.dvv_matrix``; first a run-time 0
    (the sweeps' loops start there, so Warp keeps them rolled and unrolls only the sums). Each
    sum is ``laplacian_element``'s along a row, its products commuted, in the same order: the
    same bits (``benchmarks/archive/replaced_paths.py across_elements``). HOMME's ``laplace_sphere_wk``. Values of
    ``dtype``: float32's W = 16 fill one AVX-512 register."""
    NP, W = int(np_), int(lanes)
    mat = row_derivatives(NP, dtype)[1]
    vw = wp.types.vector(length=W, dtype=dtype)

    def sweeps(
        X: wp.array(dtype=vw),
        G: wp.array2d(dtype=vw),
        fx: wp.array(dtype=vw),
        fy: wp.array(dtype=vw),
        dvv: mat,
        bn: int,
        first: int,
    ):
        # two nodes of a row an iteration, their sums interleaved (two independent chains in flight:
        # Galewsky ne12 np8 float32's second pass 0.449 → 0.386 ms; four, 0.456); at odd np the
        # row's last node alone
        for k in range(first, first + NP):  # the contravariant gradient, quadrature-weighted
            j = k - first
            for h in range(first, first + NP // 2):
                i = 2 * (h - first)
                a = vw()
                c = vw()
                a1 = vw()
                c1 = vw()
                for m in range(NP):
                    a += dvv[i, m] * X[j * NP + m]
                    a1 += dvv[i + 1, m] * X[j * NP + m]
                for m in range(NP):
                    c += dvv[j, m] * X[m * NP + i]
                    c1 += dvv[j, m] * X[m * NP + i + 1]
                n = j * NP + i
                fx[n] = wp.cw_mul(G[0, bn + n], a) + wp.cw_mul(G[1, bn + n], c)
                fy[n] = wp.cw_mul(G[1, bn + n], a) + wp.cw_mul(G[2, bn + n], c)
                fx[n + 1] = wp.cw_mul(G[0, bn + n + 1], a1) + wp.cw_mul(G[1, bn + n + 1], c1)
                fy[n + 1] = wp.cw_mul(G[1, bn + n + 1], a1) + wp.cw_mul(G[2, bn + n + 1], c1)
            if wp.static(NP % 2 == 1):  # the last node of a row alone
                n = j * NP + NP - 1
                a = vw()
                c = vw()
                for m in range(NP):
                    a += dvv[NP - 1, m] * X[j * NP + m]
                for m in range(NP):
                    c += dvv[j, m] * X[m * NP + NP - 1]
                fx[n] = wp.cw_mul(G[0, bn + n], a) + wp.cw_mul(G[1, bn + n], c)
                fy[n] = wp.cw_mul(G[1, bn + n], a) + wp.cw_mul(G[2, bn + n], c)
        for k in range(first, first + NP):  # minus its weak divergence
            j = k - first
            for h in range(first, first + NP // 2):
                i = 2 * (h - first)
                s = vw()
                t = vw()
                s1 = vw()
                t1 = vw()
                for m in range(NP):
                    s += dvv[m, i] * fx[j * NP + m]
                    s1 += dvv[m, i + 1] * fx[j * NP + m]
                for m in range(NP):
                    t += dvv[m, j] * fy[m * NP + i]
                    t1 += dvv[m, j] * fy[m * NP + i + 1]
                X[j * NP + i] = -(s + t)
                X[j * NP + i + 1] = -(s1 + t1)
            if wp.static(NP % 2 == 1):
                s = vw()
                t = vw()
                for m in range(NP):
                    s += dvv[m, NP - 1] * fx[j * NP + m]
                for m in range(NP):
                    t += dvv[m, j] * fy[m * NP + NP - 1]
                X[j * NP + NP - 1] = -(s + t)

    sweeps.__qualname__ = sweeps.__name__ = f"weak_laplacian_across_np{NP}_w{W}" + suffix(dtype)
    return wp.func(sweeps)


def shuffled(np_: int, lanes: int, dtype) -> bool:
    """Whether ``laplacian_across`` moves a block's values by 16 × 16 transposes
    (``operators.transpose16``): float32 on 16 lanes, np² a multiple of 16 (np 8, 12)."""
    return dtype is wp.float32 and int(lanes) == 16 and int(np_) ** 2 % 16 == 0


@functools.cache
def _block_laplacians(second: bool, divergent: bool, np_: int, lanes: int, dtype=f64):
    """``laplacian_across``'s weak Laplacians of a block of W = ``lanes`` elements (src, hs, f, dvv,
    L, G, Sc, R, Lw, Yw, b): each field into Sc[0] (X), ``weak_laplacian_across`` (its scratch Sc[1],
    Sc[2]), back into L's rows; in ``dtype``. Where ``shuffled``, by 16 × 16 transposes, 16 nodes
    at a time (CH of them an element's np²): the first pass's fields formed into R (Sc[1]'s memory
    as rows) and transposed into X, the second pass's transposed into X from Y₁'s rows as they lie
    (Yw: src's memory as vectors of 16, the field Y₁ itself), the Laplacians transposed from X
    straight into L's rows (Lw: L's memory as vectors of 16; a block's rows are W·np² consecutive
    values of a row of either); else lane by lane."""
    NP, W, S, DIV = int(np_), int(lanes), bool(second), bool(divergent) and not second
    vec, mat = row_derivatives(NP, dtype)[:2]
    RowFrame = frame_type(vec)
    vw = wp.types.vector(length=W, dtype=dtype)
    NN = NP * NP
    SHUFFLED = shuffled(NP, W, dtype)
    CH = NN // 16
    field = row_field(S, NP, dtype)
    tag = f"{'second' if S else 'first'}_{'div_' if DIV else ''}np{NP}_w{W}" + suffix(dtype)
    sweeps = weak_laplacian_across(NP, W, dtype)

    def block_laplacians(
        src: wp.array2d(dtype=source_rows(S, NP, dtype)),
        hs: wp.array(dtype=row_type(NP)),
        f: RowFrame,
        dvv: mat,
        L: wp.array2d(dtype=vec),
        G: wp.array2d(dtype=vw),
        Sc: wp.array2d(dtype=vw),
        R: wp.array(dtype=vec),
        Lw: wp.array2d(dtype=vw),
        Yw: wp.array2d(dtype=vw),
        b: int,
    ):
        e0 = b * W
        bn = b * NN
        first = e0 * NN  # a run-time start for the sweeps' loops
        X = Sc[0]
        for r in range(L.shape[0]):  # one field at a time, in a loop clang does not unroll
            if wp.static(SHUFFLED and S):  # Y₁'s rows of the block transposed into X in registers
                for k in range(CH):
                    transpose16(Yw, r, bn + k, bn + (W - 1) * CH + k, CH, Sc, 0, 16 * k, 1, 16)
            elif wp.static(SHUFFLED):  # the block's rows (consecutive) into R whole, then transposed
                for q in range(e0 * NP, e0 * NP + W * NP):
                    R[q - e0 * NP] = field(src, hs, f, r, q)
                for k in range(CH):
                    transpose16(Sc, 1, k, (W - 1) * CH + k, CH, Sc, 0, 16 * k, 1, 16)
            else:
                for e in range(e0, e0 + W):  # field r of the block's elements, lane by lane (not unrolled)
                    w = e - e0
                    base = e * NP
                    for k in range(base, base + NP):
                        j = k - base
                        row = field(src, hs, f, r, k)
                        for i in range(NP):
                            X[j * NP + i][w] = row[i]
            sweeps(X, G, Sc[1], Sc[2], dvv, bn, first)  # X becomes its weak Laplacian: L in the across layout
            if wp.static(SHUFFLED):  # transposed back into L's rows where they lie
                for k in range(CH):
                    transpose16(Sc, 0, 16 * k, 16 * k + 15, 1, Lw, r, bn + k, CH, 16)
            else:  # back into L's rows, the lane fixed (stores strided by np² cost what the sweeps saved)
                for w in range(W):
                    base = (e0 + w) * NP
                    for k in range(base, base + NP):
                        j = k - base
                        row = vec()
                        for i in range(NP):
                            row[i] = X[j * NP + i][w]
                        L[r, k] = row

    block_laplacians.__qualname__ = block_laplacians.__name__ = f"laplacian_block_{tag}"
    return wp.func(block_laplacians)


@functools.cache
def laplacian_across(
    second: bool, divergent: bool, np_: int, lanes: int, copies: int = 0, ghosts: bool = False, dtype=f64
):
    """``laplacian_element`` (its ``rows`` form for the second pass, a ``Topology.by_element``
    kernel) with the element index innermost in the weak Laplacians: a thread a block of W =
    ``lanes`` consecutive elements e = W·(tid + offset) + w, w < W, each node's value a
    ``wp.types.vector(W)`` of those elements' values, each derivative sweep dvv's scalars times
    such vectors (the rows' products, commuted, summed in the same order: the same bits,
    ``benchmarks/archive/replaced_paths.py across_elements``). The state, Y, L and the DSS stay in today's layout:
    each field's values (``field``, formed on rows as there) go into the scratch X, the sweeps
    go through the scratch fx, fy, and L is written back, lane by lane or, where ``shuffled``, by
    16 × 16 transposes (Galewsky ne12 np8's float32 state, one thread, least of 9 × 50
    calls: first pass 0.660 → 0.542 ms, second 0.676 → 0.553), straight into L's rows and, in
    the second pass, from Y₁'s (least of 200 calls in its steps, load 8: first 0.574 → 0.474,
    second 0.595 → 0.449); the second
    pass's row DSS and both passes' pointwise part are ``laplacian_element``'s, element by
    element. np ≥ 5 only (ValueError otherwise: np 4 keeps its unrolled rows and their bits);
    the elements past the last whole block go through ``laplacian_element``.
    Arguments: (second: xr, x, d, g, wr, rsr, as ``Topology.by_element`` gives them), src, hs,
    delta, c, f, metric, dvv, L as ``laplacian_element``'s;
    G (3, N_b) the metric's rows 0..2 in the across layout, G[k, b·np² + n][w] = metric[k,
    (W b + w) np² + n] (``operators.across_layout``); scratch (3, np²) vectors of W (X, fx, fy) and
    R its row 1's memory as W·np rows of np, a thread's private scratch (``parallel.record``'s
    ``per_part``; ``Hyperviscosity``'s); where ``shuffled``, Lw and Yw L's and (the second pass)
    Y₁'s memory as (4, N/16) vectors of 16 (``operators.row_vectors``), which the transposes write
    and read in place (Lw, and in the first pass Yw, any (·, ·) array of vectors of W otherwise:
    not read); offset (in blocks). Dim ⌊nelem/W⌋.
    HOMME's ``laplace_sphere_wk`` (its quadrature-weighted contravariant metric). ``dtype`` as
    ``laplacian_element``'s (of G, scratch, R too)."""
    NP, W = int(np_), int(lanes)
    S = bool(second)
    DIV = bool(divergent) and not S
    if NP < 5 or W < 1:
        raise ValueError(f"the weak Laplacian across elements is for np >= 5 and lanes >= 1 (got np {NP}, {W})")
    if S and copies < 1:
        raise ValueError(f"the second pass sums the copies of a node: copies must be at least 1 (got {copies})")
    parts = element_parts(S, DIV, NP, max(1, int(copies)), bool(ghosts), dtype)
    vec, mat, pointwise, row_dss = parts.vec, parts.mat, parts.pointwise, parts.row_dss
    state = row_type(NP)
    cvec = wp.types.vector(length=4, dtype=dtype)
    RowFrame = frame_type(vec)
    vw = wp.types.vector(length=W, dtype=dtype)
    block = _block_laplacians(S, DIV, NP, W, dtype)

    if S:

        def kernel(
            xr: wp.array2d(dtype=vec),
            x: wp.array2d(dtype=dtype),
            d: Copies,
            g: Edges,
            wr: wp.array(dtype=state),
            rsr: wp.array(dtype=state),
            src: wp.array2d(dtype=vec),
            hs: wp.array(dtype=state),
            delta: wp.array2d(dtype=state),
            c: cvec,
            f: RowFrame,
            metric: wp.array2d(dtype=vec),
            dvv: mat,
            L: wp.array2d(dtype=vec),
            G: wp.array2d(dtype=vw),
            scratch: wp.array2d(dtype=vw),
            R: wp.array(dtype=vec),
            Lw: wp.array2d(dtype=vw),
            Yw: wp.array2d(dtype=vw),
            offset: int,
        ):
            b = wp.tid() + offset
            for e in range(b * W, b * W + W):  # Y₁ = the first DSS at the block's elements, as ``laplacian_element``
                for j in range(NP):
                    y = row_dss(xr, x, d, g, wr, rsr, e, j)
                    for r in range(4):
                        src[r, e * NP + j] = vec(y[r])
            block(src, hs, f, dvv, L, G, scratch, R, Lw, Yw, b)
            for e in range(b * W, b * W + W):  # not unrolled
                pointwise(src, hs, delta, c, f, metric, dvv, L, e)

    else:

        def kernel(
            src: wp.array2d(dtype=Any),  # the state's rows, of any float type (``source_rows``)
            hs: wp.array(dtype=state),
            delta: wp.array2d(dtype=state),
            c: cvec,
            f: RowFrame,
            metric: wp.array2d(dtype=vec),
            dvv: mat,
            L: wp.array2d(dtype=vec),
            G: wp.array2d(dtype=vw),
            scratch: wp.array2d(dtype=vw),
            R: wp.array(dtype=vec),
            Lw: wp.array2d(dtype=vw),
            Yw: wp.array2d(dtype=vw),
            offset: int,
        ):
            b = wp.tid() + offset
            block(src, hs, f, dvv, L, G, scratch, R, Lw, Yw, b)
            for e in range(b * W, b * W + W):  # not unrolled
                pointwise(src, hs, delta, c, f, metric, dvv, L, e)

    kernel.__qualname__ = kernel.__name__ = (
        "laplacian_across__" + ("second" if S else "first__divergent" if DIV else "first") + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
