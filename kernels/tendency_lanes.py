"""The shallow-water tendency in vector lanes: ``kernels.tendencies``' arithmetic with W elements
a vector, the element index innermost (as the ∇⁴'s ``hyperviscosity_across.laplacian_across``),
for the CPU's wide registers (``model.lanes`` decides where it runs). Its own module beside
``tendencies``, whose ``finish`` and term flags it reads, so that each stays a readable size.
"""

import functools

import warp as wp

from .operators import CPU_FAST, covariant_inverse, row_derivatives, row_type, suffix, times, transpose16
from .tendencies import f64, finish, inverse_det, reads_departed, term_flags


def across_views(np_: int, lanes: int, dtype, departed: bool) -> tuple[int, int]:
    """The values a vector of ``tendency_across``'s views of x and tend (``operators.row_vectors``
    widths): 16 where a block's rows move by 16 × 16 transposes (float32 on 16 lanes, np² a
    multiple of 16; x only where it is the float32 state's), else an element's np²."""
    nn = int(np_) ** 2
    shuffled = dtype is wp.float32 and int(lanes) == 16 and nn % 16 == 0
    return (16 if shuffled and departed else nn), (16 if shuffled else nn)


@functools.cache
def tendency_across(terms: tuple, np_: int, lanes: int, weighted: bool = False, dtype=f64, departed: bool = False):
    """The tendency kernel for ``terms`` with W = ``lanes`` elements a vector (the element index
    innermost, as the ∇⁴'s ``hyperviscosity_across.laplacian_across``): a thread a block of W
    consecutive elements e = W·(tid + offset) + w, each node's value a ``wp.types.vector(W)`` of
    theirs, so that at np 4 a float32 vector of 16 fills a 512-bit register, where a GLL row of
    ``tendency_element`` fills a quarter. The state and the tendency stay in the node layout,
    viewed as an element's np² values a row (``operators.row_vectors(a, np²)``): each element's
    rows go into the thread's scratch S (9, np²) of W-vectors and come back from it, in float32 on
    16 lanes as 16 × 16 transposes in registers (``operators.transpose16``: the tendency 0.39 →
    0.23 ms at TC5 ne30, one thread; np² a multiple of 16, np 8's element rows four of them),
    else lane by lane. On the float32 state (``departed``) metdet is det D (``finish``'s
    determinant: one division a node, the tendency alone at TC5 ne30 np4 0.204–0.212 → 0.179–0.195
    ms, Galewsky ne12 np8 0.248 → 0.171–0.176). The geometry is in the across layout: [k, b np² + n][w] the value at node n of
    element W b + w (``operators.across_layout`` with its last block padded). Each sum is
    ``tendency_element``'s, its products commuted, in its order (HOMME's ``sweq_mod``
    arithmetic): float64 gives the rows' bits (tests/model/test_tendency_lanes.py); in float32
    clang contracts other products into FMAs, so the two agree to float32's round-off.

    Arguments: x (3, N/np²) the state, metric (4, ·) D in float32 (D⁻¹ formed from it) and D⁻¹ in
    float64 (D not read: ``operators.covariant_inverse``), metdet, fcor, forcing (2, ·) topographic
    −g∇hs, mass (·) spheremp in the across layout (W-vectors of ``dtype``), g, h0 (``tendency``'s,
    a row of np² values of x's type), dvv (``operators.dvv_matrix``), S (a thread's scratch,
    ``parallel.record``'s ``per_part``), tend (3, N/np²) output, nelem (the last block's lanes
    past it read its last element again and are not written), offset (in blocks). Dim
    ⌈nelem/W⌉. ``weighted``, ``dtype`` and ``departed`` as ``tendency``'s; no tracers (a model with
    tracers runs ``tendency_element``)."""
    CONT, ADV, _, PG, _ = term_flags(terms)
    NP, W = int(np_), int(lanes)
    NN = NP * NP
    DEPARTED = reads_departed(departed, dtype, 0)
    SHIFT = dtype is not f64 and not DEPARTED  # the mixed float32: h − H₀ formed in float64
    xtype = dtype if DEPARTED else f64
    vw = wp.types.vector(length=W, dtype=dtype)
    node = row_type(NN, dtype)  # an element's np² values in the tendency's type
    mat = row_derivatives(NP, dtype)[1]
    # float32 forms D⁻¹ from D (``finish``'s inverted): 4 of the 13 geometry vectors a node not
    # read; float64 reads it (its lanes give the rows' bits)
    INV = dtype is wp.float32
    # the float32 state's: metdet as det D (``finish``'s determinant), the mass flux metdet h D⁻¹v
    # = h adj(D) v with no division (the mixed float32's lanes keep their bits)
    DET = INV and DEPARTED
    end = finish(terms, weighted, INV, DET)
    # float32 on 16 lanes at np 4 and 8: a block's rows moved by ``operators.transpose16``, 16
    # nodes at a time (CH of them an element's row), the state's too where it is float32 (a
    # float32 state's departure; the mixed float32's float64 x goes lane by lane, rounded as it goes)
    SHUFFLED = dtype is wp.float32 and W == 16 and NN % 16 == 0
    SHUFFLED_IN = SHUFFLED and xtype is wp.float32
    CH = NN // 16
    xrow, trow = across_views(NP, W, dtype, DEPARTED)  # x and tend viewed so: an element's row, or its 16s
    state = row_type(xrow, xtype)
    node_out = row_type(trow, dtype)

    def kernel(
        x: wp.array2d(dtype=state),
        metric: wp.array2d(dtype=vw),
        metdet: wp.array(dtype=vw),
        fcor: wp.array(dtype=vw),
        forcing: wp.array2d(dtype=vw),
        mass: wp.array(dtype=vw),
        g: dtype,
        h0: state,
        dvv: mat,
        S: wp.array2d(dtype=vw),
        tend: wp.array2d(dtype=node_out),
        nelem: int,
        offset: int,
    ):
        b = wp.tid() + offset
        bn = b * NN
        e0 = b * W
        # the metric under the names its formulas use: D under float32 (INV), D⁻¹ under float64
        D = metric
        Dinv = metric
        # S's rows: u, v, h (the depth, or a departed state's h − H₀), g's height (the mixed
        # float32's h − H₀), then the mass flux metdet h c¹, c², the Bernoulli function and the
        # covariant wind v₁, v₂; finish writes du, dv, dh over u, v, h at its node, which no
        # other node reads after the fluxes are formed
        if wp.static(SHUFFLED_IN):  # the block's 16 rows of u, v, h, transposed in registers
            for r in range(3):
                for k in range(CH):
                    transpose16(x, r, e0 * CH + k, (nelem - 1) * CH + k, CH, S, r, 16 * k, 1, 16)
        else:
            for w in range(W):  # the state in, lane by lane (unrolled: each lane's stores at fixed offsets)
                p = wp.min(e0 + w, nelem - 1)  # the last block's lanes past it read its last element again
                xu = node(x[0, p])
                xv = node(x[1, p])
                xh = node(x[2, p])
                xg = node()
                if wp.static(SHIFT and PG):
                    xg = node(x[2, p] - h0)  # g's height: h − H₀ in float64, then rounded
                for n in range(NN):
                    S[0, n][w] = xu[n]
                    S[1, n][w] = xv[n]
                    S[2, n][w] = xh[n]
                    if wp.static(SHIFT and PG):
                        S[3, n][w] = xg[n]
        for q in range(bn, bn + NN):  # the fluxes, a node of the block at a time (not unrolled)
            n = q - bn
            u = S[0, n]
            v = S[1, n]
            h = S[2, n]
            if wp.static(CONT and DET):  # metdet h D⁻¹(u, v) = h (D₁₁ u − D₀₁ v, D₀₀ v − D₁₀ u)
                depth = h + vw(h0[0])
                S[4, n] = times(depth, times(D[3, q], u) - times(D[1, q], v))
                S[5, n] = times(depth, times(D[0, q], v) - times(D[2, q], u))
            elif wp.static(CONT):
                depth = h  # h0 added back to a departed state's h − h0
                if wp.static(DEPARTED):
                    depth = h + vw(h0[0])
                Jh = times(metdet[q], depth)
                if wp.static(INV):  # metdet h D⁻¹(u, v) = metdet h (D₁₁ u − D₀₁ v, D₀₀ v − D₁₀ u) / det D
                    Jh = times(Jh, inverse_det(D, q))
                    S[4, n] = times(Jh, times(D[3, q], u) - times(D[1, q], v))
                    S[5, n] = times(Jh, times(D[0, q], v) - times(D[2, q], u))
                else:
                    S[4, n] = times(Jh, times(Dinv[0, q], u) + times(Dinv[1, q], v))
                    S[5, n] = times(Jh, times(Dinv[2, q], u) + times(Dinv[3, q], v))
            E = vw()
            if wp.static(ADV):
                E = dtype(0.5) * (times(u, u) + times(v, v))
                if wp.static(INV):  # D read, D⁻¹ formed from it
                    S[7, n] = times(D[0, q], u) + times(D[2, q], v)
                    S[8, n] = times(D[1, q], u) + times(D[3, q], v)
                else:  # the rows' form: D⁻¹ read, D not (``operators.covariant_inverse``)
                    c1, c2 = covariant_inverse(Dinv, metdet, u, v, q)
                    S[7, n] = c1
                    S[8, n] = c2
            if wp.static(PG):
                if wp.static(SHIFT):
                    E = E + g * S[3, n]
                else:
                    E = E + g * h
            S[6, n] = E
        for q in range(bn, bn + NN):  # the derivatives along ξ and η and the pointwise end
            n = q - bn
            j = n / NP
            i = n - j * NP
            div = vw()
            bx = vw()
            by = vw()
            cx = vw()
            cy = vw()
            if wp.static(CONT):
                a = vw()
                c = vw()
                for m in range(NP):
                    a += dvv[i, m] * S[4, j * NP + m]
                for m in range(NP):
                    c += dvv[j, m] * S[5, m * NP + i]
                div = a + c
            if wp.static(ADV or PG):
                for m in range(NP):
                    bx += dvv[i, m] * S[6, j * NP + m]
                for m in range(NP):
                    by += dvv[j, m] * S[6, m * NP + i]
            if wp.static(ADV):
                for m in range(NP):
                    cx += dvv[i, m] * S[8, j * NP + m]
                for m in range(NP):
                    cy += dvv[j, m] * S[7, m * NP + i]
            end(q, n, div, bx, by, cx, cy, S, metric, metdet, fcor, forcing, mass, S)
        if wp.static(SHUFFLED):  # the tendency out likewise, the last block's lanes past nelem left
            for r in range(3):
                for k in range(CH):
                    transpose16(S, r, 16 * k, 16 * k + 15, 1, tend, r, e0 * CH + k, CH, wp.min(W, nelem - e0))
        else:
            for w in range(W):  # the tendency out, lane by lane (unrolled), the last block's lanes past nelem left
                if e0 + w < nelem:
                    du = node()
                    dv = node()
                    dh = node()
                    for n in range(NN):
                        du[n] = S[0, n][w]
                        dv[n] = S[1, n][w]
                        dh[n] = S[2, n][w]
                    tend[0, e0 + w] = du
                    tend[1, e0 + w] = dv
                    tend[2, e0 + w] = dh

    kernel.__qualname__ = kernel.__name__ = (
        f"tendency_across__np{NP}_w{W}__"
        + "__".join(terms)
        + ("__mass" if weighted else "")
        + ("__departed" if DEPARTED else "")
        + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
