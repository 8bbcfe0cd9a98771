"""The ∇⁴'s weak Laplacians on the CPU, a thread an element (``hyperviscosity``'s module
docstring: three passes): ``laplacian_element`` on the element's GLL rows (packed SIMD), the
second pass gathering the first DSS itself; its parts (``element_parts``) are shared with
``hyperviscosity_across.laplacian_across``, the same with W elements a vector at np ≥ 5."""

import functools
from typing import Any, NamedTuple

import warp as wp

from .dss import Copies, Edges, gather, gather_rows
from .hyperviscosity import add_divergent, frame_type, scale_first, shift_second
from .operators import CPU_FAST, across_as_along, row_derivatives, row_type, suffix, times

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


class _ElementParts(NamedTuple):
    """``laplacian_element``'s functions of one (second, divergent, np, dtype), shared with
    ``laplacian_across``: the row and matrix types (of the ∇⁴'s float type ``dtype``), ``source``
    the rows of what it reads (the float64 state's in the first pass, Y₁'s in the second),
    ``field`` (src, hs, f, r, q) → row q of field r, ``laplacians`` (src, hs, f, metric, dvv, L,
    e) the four weak Laplacians of element e into L's rows, ``pointwise`` (src, hs, delta, c, f,
    metric, dvv, L, e) their pointwise part in place, ``one_element`` the two, and ``row_dss``
    (``dss.gather_rows``, the second pass's) and ``sum_copies`` (``dss.gather``), their sums
    float64."""

    vec: Any
    mat: Any
    source: Any
    field: Any
    laplacians: Any
    pointwise: Any
    one_element: Any
    row_dss: Any
    sum_copies: Any


@functools.cache
def weak_laplacian_rows(np_: int, dtype=f64):
    """One field's weak Laplacian on an element's rows (F, G11, G12, G22, dvv, dvvT, lo) → mat, in ``dtype``."""
    NP = int(np_)
    vec, mat, along, across = row_derivatives(NP, dtype)
    ROW = across_as_along(NP)  # rolled rows, (M F)[j] as along(M[j], F)

    def weak_laplacian(F: mat, G11: mat, G12: mat, G22: mat, dvv: mat, dvvT: mat, lo: int):
        out = mat()  # −Σ ∂ᵀ(G ∇_ref f): G ∇_ref f is the quadrature-weighted contravariant gradient
        fx = mat()
        fy = mat()
        if wp.static(ROW):  # the rows in loops with a run-time start (lo), which Warp does not unroll
            for k in range(lo, lo + NP):
                j = k - lo
                a = along(F[j], dvvT)
                b = along(dvv[j], F)
                fx[j] = times(G11[j], a) + times(G12[j], b)
                fy[j] = times(G12[j], a) + times(G22[j], b)
            for k in range(lo, lo + NP):
                j = k - lo
                out[j] = -(along(fx[j], dvv) + along(dvvT[j], fy))
        else:  # np 4: unrolled, its bits
            for j in range(NP):
                a = along(F[j], dvvT)
                b = across(F, j, dvv)
                fx[j] = times(G11[j], a) + times(G12[j], b)
                fy[j] = times(G12[j], a) + times(G22[j], b)
            for j in range(NP):
                out[j] = -(along(fx[j], dvv) + across(fy, j, dvvT))
        return out

    weak_laplacian.__qualname__ = weak_laplacian.__name__ = f"weak_laplacian_rows_np{NP}" + suffix(dtype)
    return wp.func(weak_laplacian)


def source_rows(second: bool, np_: int, dtype):
    """The rows a pass reads its fields from: Y₁'s (``second``, of ``dtype``) or the state's (any
    float type: float64, or a float32 state's u, v, h − H₀ kept between steps, ``model.held``)."""
    return row_type(np_, dtype) if second else Any


@functools.cache
def row_field(second: bool, np_: int, dtype=f64):
    """``field`` (src, hs, f, r, q) → row q of field r (``_ElementParts``), of ``dtype``."""
    NP, S = int(np_), bool(second)
    vec, state = row_type(NP, dtype), row_type(NP)
    SHIFT = dtype is not f64
    RowFrame = frame_type(vec)

    def field(
        src: wp.array2d(dtype=source_rows(S, NP, dtype)), hs: wp.array(dtype=row_type(NP)), f: RowFrame, r: int, q: int
    ):
        """Row q of field r of X (first: the Cartesian wind, h + hs, from the float64 state
        rounded on load) or of Y₁ (second)."""
        if wp.static(S):
            return src[r, q]
        else:
            if r < 3:
                return times(vec(src[0, q]), f.east[r, q]) + times(vec(src[1, q]), f.north[r, q])
            if wp.static(SHIFT):  # h + hs − H₀ formed in float64 before it is rounded (a float32 state's h − H₀, H₀ 0)
                return vec(state(src[2, q]) + hs[q] - f.h0)
            else:
                return state(src[2, q]) + hs[q]

    field.__qualname__ = field.__name__ = f"laplacian_field_{'second' if S else 'first'}_np{NP}" + suffix(dtype)
    return wp.func(field)


@functools.cache
def _row_laplacians(second: bool, np_: int, dtype=f64):
    """``laplacians`` (src, hs, f, metric, dvv, L, e): the four weak Laplacians of element e into L's rows."""
    NP, S = int(np_), bool(second)
    vec, mat = row_derivatives(NP, dtype)[:2]
    RowFrame = frame_type(vec)
    field, lap = row_field(S, NP, dtype), weak_laplacian_rows(NP, dtype)

    def laplacians(
        src: wp.array2d(dtype=source_rows(S, NP, dtype)),
        hs: wp.array(dtype=row_type(NP)),
        f: RowFrame,
        metric: wp.array2d(dtype=vec),
        dvv: mat,
        L: wp.array2d(dtype=vec),
        e: int,
    ):
        base = e * NP
        dvvT = wp.transpose(dvv)
        G11 = mat()  # the weak Laplacian's metric (``laplacian_metric``), once for all fields
        G12 = mat()
        G22 = mat()
        for j in range(NP):
            q = base + j
            G11[j] = metric[0, q]
            G12[j] = metric[1, q]
            G22[j] = metric[2, q]
        # one field at a time, in a loop clang does not unroll: four weak Laplacians
        # in one block left clang's SLP vectorizer half scalar (1.3x slower)
        for r in range(L.shape[0]):
            X = mat()
            for j in range(NP):
                X[j] = field(src, hs, f, r, base + j)
            Lr = lap(X, G11, G12, G22, dvv, dvvT, base)
            for j in range(NP):
                L[r, base + j] = Lr[j]

    laplacians.__qualname__ = laplacians.__name__ = f"laplacian_rows_{'second' if S else 'first'}_np{NP}" + suffix(
        dtype
    )
    return wp.func(laplacians)


@functools.cache
def _row_pointwise(second: bool, divergent: bool, np_: int, dtype=f64):
    """``pointwise`` (src, hs, delta, c, f, metric, dvv, L, e): the weak Laplacians' pointwise part
    in place, δ (float64) rounded on load."""
    NP, S, DIV = int(np_), bool(second), bool(divergent) and not second
    vec, mat, along, across = row_derivatives(NP, dtype)
    stack = wp.types.matrix(shape=(4, NP), dtype=dtype)  # the four fields' values on one row
    RowFrame = frame_type(vec)
    field = row_field(S, NP, dtype)

    def pointwise(
        src: wp.array2d(dtype=source_rows(S, NP, dtype)),
        hs: wp.array(dtype=row_type(NP)),
        delta: wp.array2d(dtype=row_type(NP)),
        c: wp.types.vector(length=4, dtype=dtype),
        f: RowFrame,
        metric: wp.array2d(dtype=vec),
        dvv: mat,
        L: wp.array2d(dtype=vec),
        e: int,
    ):
        base = e * NP
        dvvT = wp.transpose(dvv)
        D = mat()  # δ
        if wp.static(DIV):
            for j in range(NP):
                D[j] = vec(delta[0, base + j])
        for j in range(NP):  # the pointwise part, on the rows just written (in L1)
            q = base + j
            Lj = wp.matrix_from_rows(L[0, q], L[1, q], L[2, q], L[3, q])
            Xj = wp.matrix_from_rows(
                field(src, hs, f, 0, q), field(src, hs, f, 1, q), field(src, hs, f, 2, q), field(src, hs, f, 3, q)
            )
            y = stack()
            if wp.static(S):
                y = shift_second(Lj, Xj, metric[3, q], c[3])
            else:
                y = scale_first(Lj, Xj, metric[3, q], f, q, c)
                if wp.static(DIV):
                    y = add_divergent(y, along(D[j], dvvT), across(D, j, dvv), c[1] * metric[3, q], q, f)
            for r in range(4):
                L[r, q] = y[r]

    pointwise.__qualname__ = pointwise.__name__ = (
        f"laplacian_pointwise_{'second' if S else 'first'}_{'div_' if DIV else ''}np{NP}" + suffix(dtype)
    )
    return wp.func(pointwise)


@functools.cache
def element_parts(second: bool, divergent: bool, np_: int, copies: int, ghosts: bool, dtype=f64) -> _ElementParts:
    """The functions ``laplacian_element`` and ``laplacian_across`` build their kernels of, in ``dtype``."""
    NP = int(np_)
    vec, mat = row_derivatives(NP, dtype)[:2]
    S, DIV = bool(second), bool(divergent) and not second
    RowFrame = frame_type(vec)
    source = source_rows(S, NP, dtype)
    sum_copies = gather(4, False, max(1, int(copies)), ghosts, dtype)
    row_dss = gather_rows(4, False, max(1, int(copies)), ghosts, NP, dtype)
    field = row_field(S, NP, dtype)
    laplacians, pointwise = _row_laplacians(S, NP, dtype), _row_pointwise(S, DIV, NP, dtype)

    def element(
        src: wp.array2d(dtype=source),
        hs: wp.array(dtype=row_type(NP)),
        delta: wp.array2d(dtype=row_type(NP)),
        c: wp.types.vector(length=4, dtype=dtype),
        f: RowFrame,
        metric: wp.array2d(dtype=vec),
        dvv: mat,
        L: wp.array2d(dtype=vec),
        e: int,
    ):
        laplacians(src, hs, f, metric, dvv, L, e)
        pointwise(src, hs, delta, c, f, metric, dvv, L, e)

    element.__qualname__ = element.__name__ = (
        f"laplacian_element_{'second' if S else 'first'}_{'div_' if DIV else ''}np{NP}" + suffix(dtype)
    )
    return _ElementParts(vec, mat, source, field, laplacians, pointwise, wp.func(element), row_dss, sum_copies)


@functools.cache
def laplacian_element(
    second: bool, divergent: bool, np_: int, copies: int = 0, ghosts: bool = False, rows: bool = False, dtype=f64
):
    """The weak form of Y₁ (``second=False``, from the state ``src`` = x (3, ·)
    and hs) or of Y₂ (``second=True``, from ``src`` = Y₁ (4, ·)) of the elements
    (the module docstring), one thread per element, on GLL rows
    (``operators.row_vectors`` views, N/np rows); ``divergent``: with the
    (ν_div − ν)·spheremp·∇δ term, δ the DSS'd divergence in ``delta`` (1, ·)
    (first only). The second pass does the first DSS itself, a ``Topology.gathering``
    kernel (``copies``, ``ghosts`` as ``dss.gather``; ValueError for copies < 1): each
    element writes Y₁ = the unweighted DSS of the first pass's weak form x (4, N) at its own
    nodes into Y (4, N), the bits of ``dss.dss_rows``, and reads it back as ``src``, Y's rows,
    while it is in cache. Arguments: x, d (``dss.Copies``), Y, src, hs, delta,
    c (``scale_first``), f (``frame_type`` of rows), metric (4, ·) (``laplacian_metric``),
    dvv (``operators.dvv_matrix``), L (4, ·) output (aliasing neither x nor Y), block (np²),
    offset (in elements); the first pass reads neither x, d, Y nor block. Dim nelem.
    With ``rows`` (the second pass only) a ``Topology.by_element`` kernel instead: the DSS by
    element on GLL rows (``dss.gather_rows``, the same bits) written into src, Y's rows;
    arguments xr, x, d, g (``dss.Edges``), wr, rsr, then src … L as above, offset.
    ``laplacian_across`` is the same with several elements a vector (np ≥ 5, the same bits).
    ``dtype``: the ∇⁴'s float type (``ShallowWater``'s precision), of x, Y, c, f, metric, dvv
    and L; the state, hs, δ (float64) rounded on load, h + hs − H₀ (f.h0) formed in float64
    under float32; the DSS's sums float64 (``dss.gather``), Y₁ rounded as it is stored."""
    NP = int(np_)
    S = bool(second)
    ROWS = bool(rows) and S
    if S and copies < 1:
        raise ValueError(f"the second pass sums the copies of a node: copies must be at least 1 (got {copies})")
    parts = element_parts(S, bool(divergent) and not S, NP, max(1, int(copies)), bool(ghosts), dtype)
    vec, mat, source, row_dss, sum_copies, one_element = (
        parts.vec,
        parts.mat,
        parts.source,
        parts.row_dss,
        parts.sum_copies,
        parts.one_element,
    )
    state = row_type(NP)
    cvec = wp.types.vector(length=4, dtype=dtype)
    RowFrame = frame_type(vec)
    DIV = bool(divergent) and not S

    if ROWS:  # the first DSS by element on GLL rows (``dss.gather_rows``), written into src: Y's rows

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
            offset: int,
        ):
            e = wp.tid() + offset
            for j in range(NP):
                y = row_dss(xr, x, d, g, wr, rsr, e, j)
                for r in range(4):
                    src[r, e * NP + j] = vec(y[r])
            one_element(src, hs, delta, c, f, metric, dvv, L, e)

    else:

        def kernel(
            x: wp.array2d(dtype=dtype),
            d: Copies,
            Y: wp.array2d(dtype=dtype),
            src: wp.array2d(dtype=source),
            hs: wp.array(dtype=state),
            delta: wp.array2d(dtype=state),
            c: cvec,
            f: RowFrame,
            metric: wp.array2d(dtype=vec),
            dvv: mat,
            L: wp.array2d(dtype=vec),
            block: int,
            offset: int,
        ):
            e = wp.tid() + offset
            if wp.static(S):  # Y = the DSS of x at this element's nodes, read back (as src) in cache
                for p in range(e * block, e * block + block):
                    s = sum_copies(x, d, p)
                    for r in range(4):
                        Y[r, p] = dtype(s[r])
            one_element(src, hs, delta, c, f, metric, dvv, L, e)

    kernel.__qualname__ = kernel.__name__ = (
        "laplacian_element__" + ("second" if S else "first__divergent" if DIV else "first") + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
