"""The ∇⁴ hyperviscosity's kernels (HOMME ``biharmonic_wk`` + ``advance_hypervis``).

The wind is diffused through its 3-D Cartesian components, which are smooth
across the poles and panel edges; the tangential projection of the
componentwise Laplacian is the vector Laplacian Δv = ∇(∇·v) − ∇×∇×v. As in
HOMME's ``vlaplace_sphere_wk`` each vector Laplacian adds 2v/a², so that rigid
rotation (degree 1) is not damped: a rotational wind of degree l decays at
ν((l(l+1) − 2)/a²)². HOMME's ``nu_div`` scales the ∇(∇·v) part of the first
Laplacian (linearly here: the divergent wind of degree l decays at
(l(l+1) − 2)(ν_div l(l+1) − 2ν)/a⁴, ≈ ν_div (l(l+1)/a²)², HOMME's intended
``nu_div`` without the ratio² of its ``biharmonic_wk``). The height diffused is
the free surface h + hs (smooth over the TC5 cone, unlike h), with ν_s.

The operator, Y₁ = c·(first Laplacian), Y₂ = Δ Y₁ + 2Y₁/a² (wind):
    Y₁[0:3] = ν (P ΔX + 2v/a²) + (ν_div − ν) ∇δ,   Y₁[3] = ν_s Δ(h + hs)
with X the Cartesian wind, P the tangent projection, δ = DSS(∇·v) and every Δ
the DSS'd weak Laplacian. Rows of the work arrays: 0..2 Cartesian wind, 3 free
surface.

In three passes on the CPU (whose second weak Laplacian gathers the first DSS itself)
and six on CUDA (a flux pass before each weak Laplacian, the first DSS), as HOMME
(``vlaplace_sphere_wk_cartesian``) forms each Laplacian: everything pointwise in Y₁ and Y₂ is done on the element's weak form
before its DSS, where the mass is a factor (2v/a² enters as 2·spheremp·v/a²,
∇δ as spheremp·∇δ, whose unweighted DSS is the mass-weighted one of ∇δ; P and
the coefficients commute with the DSS); the first DSS then gives Y₁ itself and
the second DSS, ``dss_apply``, adds coef·Y₂ to the state as it sums. ∇δ is
compiled in only when ν_div ≠ ν. Changes the last bits against applying them
after each DSS.

HOMME's tensor ∇⁴ (``hypervis_scaling``; Guba et al. 2014) replaces the second Laplacian by
the weak ∇·(V∇Y₁) + 2vY₁/a² (V a fixed 2×2 tensor per node, v = tr V / 2): the same passes with
the fixed metric spheremp·Dinv V Dinvᵀ and mass spheremp·v in place of spheremp·Dinv Dinvᵀ and
spheremp (``model.hyperviscosity.Hyperviscosity.tensor_metric``): ``laplacian_element``
reads either; on CUDA ``laplacian_flux`` forms the flux from it, for ``laplacian_node``.

Two layouts, as for the tendency: on CUDA ``laplacian_flux`` (the first forming the Cartesian
wind as it reads it) and ``laplacian_node`` (dim N); on the CPU
``laplacian_element`` (dim nelem), the whole weak Laplacian of an element in
one pass, on whole GLL rows (packed SIMD). Both finish a node, or a row, with
the same ``scale_first`` / ``shift_second`` / ``add_divergent``. At np ≥ 5 the CPU's weak
Laplacians run with 16 elements a vector (``laplacian_across``: a thread a block of elements,
the same bits), their DSS and pointwise parts still on rows.

Each factory takes ``dtype``, the ∇⁴'s float type (``ShallowWater``'s precision; float64 the
code and bits it always had): in float32 the weak Laplacians, their work arrays and the
geometry they read are float32, the float64 state (and hs, δ) read and rounded on load, the free
surface formed as h + hs − H₀ in float64 before it is rounded (``frame_type``'s h0: Δ of a
constant is 0, so the operator is the same and float32 keeps the digits of h's variation); the
DSSs sum the float32 copies in float64 (``dss.gather``), and ``dss_apply`` adds coef·Y₂ to the
float64 state in float64.
"""

import functools
from typing import Any, NamedTuple

import warp as wp

from .dss import Copies, Edges, gather, gather_row
from .operators import (
    CPU_FAST,
    across_as_along,
    d_eta,
    d_xi,
    element_node,
    row_derivatives,
    row_type,
    suffix,
    times,
    weak_divergence,
    weak_flux,
)

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@functools.cache
def frame_type(dtype):
    """A node's frame as a struct of arrays of ``dtype`` (a float type for the per-node
    kernels, ``Frame`` the float64 one; ``operators.row_type(np, float type)`` for the element
    kernels' ``operators.row_vectors`` views): Dinv (4, ·), the unit vectors east, north and the
    position xyz (3, ·, Cartesian, unit sphere); a kernel is given those it reads
    (``Hyperviscosity._frame``), the others null. And h0 (m, float64: a scalar, or a row of
    it), the reference depth H₀ a float32 ∇⁴ takes the free surface from (h + hs − H₀ formed in
    float64 before it is rounded, ``ShallowWater``'s precision: Δ of a constant is 0); unread
    in float64."""
    rows = dtype._length_ if wp.types.type_is_vector(dtype) else 0
    depth = row_type(rows) if rows else f64

    class Frame:
        Dinv: wp.array2d(dtype=dtype)
        east: wp.array2d(dtype=dtype)
        north: wp.array2d(dtype=dtype)
        xyz: wp.array2d(dtype=dtype)
        h0: depth

    name = f"Frame_rows{rows}" if rows else "Frame"
    Frame.__qualname__ = Frame.__name__ = name + suffix(getattr(dtype, "_wp_scalar_type_", dtype))
    return wp.struct(Frame)


Frame = frame_type(f64)


# The pointwise parts below are generic: at a node q of the per-node kernels the
# values are scalars and a field stack (L, X, Y) a vector of 4; at a GLL row q of
# the element kernels the values are rows and a stack a (4, np) matrix of rows; each
# of the ∇⁴'s float type (float64, or float32: ``ShallowWater``'s precision).


@wp.func
def scale_first(L: Any, X: Any, w: Any, f: Any, q: int, c: Any):
    """The weak-form Y₁ at node (row) q from the weak Laplacian L of X = (Cartesian
    wind, h + hs), the mass w and the position f.xyz: ν(PL + (2/a²)·w·X) for the
    wind, ν_s·L for the height, c = (ν, ν_div − ν, ν_s, 2/a²) (the ∇δ term
    apart: ``add_divergent``; c of the ∇⁴'s float type)."""
    d = times(L[0], f.xyz[0, q]) + times(L[1], f.xyz[1, q]) + times(L[2], f.xyz[2, q])
    y = type(L)()
    for k in range(3):
        y[k] = c[0] * (L[k] - times(d, f.xyz[k, q]) + times(c[3] * w, X[k]))
    y[3] = c[2] * L[3]
    return y


@wp.func
def shift_second(L: Any, Y: Any, w: Any, shift: Any):
    """The weak-form Y₂ at node (row) q: L + shift·w·Y for the wind, L for the
    height (L the weak Laplacian of Y = Y₁, w the mass, shift = 2/a²)."""
    y = type(L)()
    for k in range(3):
        y[k] = L[k] + times(shift * w, Y[k])
    y[3] = L[3]
    return y


@wp.func
def add_divergent(y: Any, a: Any, b: Any, cw: Any, q: int, f: Any):
    """y[0:3] += cw·∇δ, the Cartesian gradient at node (row) q of δ from its
    reference derivatives (a, b) = (∂ξ δ, ∂η δ), cw = (ν_div − ν)·spheremp."""
    ge = times(f.Dinv[0, q], a) + times(f.Dinv[2, q], b)
    gn = times(f.Dinv[1, q], a) + times(f.Dinv[3, q], b)
    for r in range(3):
        y[r] = y[r] + times(cw, times(ge, f.east[r, q]) + times(gn, f.north[r, q]))
    return y


class _ElementParts(NamedTuple):
    """``laplacian_element``'s functions of one (second, divergent, np, dtype), shared with
    ``laplacian_across``: the row and matrix types (of the ∇⁴'s float type ``dtype``), ``source``
    the rows of what it reads (the float64 state's in the first pass, Y₁'s in the second),
    ``field`` (src, hs, f, r, q) → row q of field r, ``laplacians`` (src, hs, f, metric, dvv, L,
    e) the four weak Laplacians of element e into L's rows, ``pointwise`` (src, hs, delta, c, f,
    metric, dvv, L, e) their pointwise part in place, ``one_element`` the two, and ``row_dss``
    (``dss.gather_row``, the second pass's) and ``sum_copies`` (``dss.gather``), their sums
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
def _weak_laplacian_rows(np_: int, dtype=f64):
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


def _source(second: bool, np_: int, dtype):
    """The rows a pass reads its fields from: Y₁'s (``second``, of ``dtype``) or the state's (float64)."""
    return row_type(np_, dtype) if second else row_type(np_)


@functools.cache
def _row_field(second: bool, np_: int, dtype=f64):
    """``field`` (src, hs, f, r, q) → row q of field r (``_ElementParts``), of ``dtype``."""
    NP, S = int(np_), bool(second)
    vec = row_type(NP, dtype)
    SHIFT = dtype is not f64
    RowFrame = frame_type(vec)

    def field(
        src: wp.array2d(dtype=_source(S, NP, dtype)), hs: wp.array(dtype=row_type(NP)), f: RowFrame, r: int, q: int
    ):
        """Row q of field r of X (first: the Cartesian wind, h + hs, from the float64 state
        rounded on load) or of Y₁ (second)."""
        if wp.static(S):
            return src[r, q]
        else:
            if r < 3:
                return times(vec(src[0, q]), f.east[r, q]) + times(vec(src[1, q]), f.north[r, q])
            if wp.static(SHIFT):  # h + hs − H₀ formed in float64 before it is rounded
                return vec(src[2, q] + hs[q] - f.h0)
            else:
                return src[2, q] + hs[q]

    field.__qualname__ = field.__name__ = f"laplacian_field_{'second' if S else 'first'}_np{NP}" + suffix(dtype)
    return wp.func(field)


@functools.cache
def _row_laplacians(second: bool, np_: int, dtype=f64):
    """``laplacians`` (src, hs, f, metric, dvv, L, e): the four weak Laplacians of element e into L's rows."""
    NP, S = int(np_), bool(second)
    vec, mat = row_derivatives(NP, dtype)[:2]
    RowFrame = frame_type(vec)
    field, lap = _row_field(S, NP, dtype), _weak_laplacian_rows(NP, dtype)

    def laplacians(
        src: wp.array2d(dtype=_source(S, NP, dtype)),
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
    field = _row_field(S, NP, dtype)

    def pointwise(
        src: wp.array2d(dtype=_source(S, NP, dtype)),
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
def _element_parts(second: bool, divergent: bool, np_: int, copies: int, ghosts: bool, dtype=f64) -> _ElementParts:
    """The functions ``laplacian_element`` and ``laplacian_across`` build their kernels of, in ``dtype``."""
    NP = int(np_)
    vec, mat = row_derivatives(NP, dtype)[:2]
    S, DIV = bool(second), bool(divergent) and not second
    RowFrame = frame_type(vec)
    source = _source(S, NP, dtype)
    sum_copies = gather(4, False, max(1, int(copies)), ghosts, dtype)
    row_dss = gather_row(4, False, max(1, int(copies)), ghosts, NP, dtype)
    field = _row_field(S, NP, dtype)
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
    element on GLL rows (``dss.gather_row``, the same bits) written into src, Y's rows;
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
    parts = _element_parts(S, bool(divergent) and not S, NP, max(1, int(copies)), bool(ghosts), dtype)
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

    if ROWS:  # the first DSS by element on GLL rows (``dss.gather_row``), written into src: Y's rows

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
                for r in range(4):
                    src[r, e * NP + j] = vec(row_dss(xr, x, d, g, wr, rsr, e, j, r))
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


@functools.cache
def weak_laplacian_across(np_: int, lanes: int, dtype=f64):
    """One field's weak Laplacian −Σ ∂ᵀ(G ∇_ref f) with the element index innermost, a
    ``wp.func`` (X, G, fx, fy, dvv, bn, first): X (np²) ``wp.types.vector(lanes)`` the field at an
    element block's nodes (node n = j·np + i; lane w element w of the block), overwritten by its
    weak Laplacian; G (3, ·) the metric's rows 0..2 in the across layout from node bn (the
    block's first); fx, fy (np²) scratch; dvv as ``operators.dvv_matrix``; first a run-time 0
    (the sweeps' loops start there, so Warp keeps them rolled and unrolls only the sums). Each
    sum is ``laplacian_element``'s along a row, its products commuted, in the same order: the
    same bits (``benchmarks/across_elements.py``). HOMME's ``laplace_sphere_wk``. Values of
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
        for k in range(first, first + NP):  # the contravariant gradient, quadrature-weighted
            j = k - first
            for h in range(first, first + NP):
                i = h - first
                a = vw()
                c = vw()
                for m in range(NP):
                    a += dvv[i, m] * X[j * NP + m]
                for m in range(NP):
                    c += dvv[j, m] * X[m * NP + i]
                n = j * NP + i
                fx[n] = wp.cw_mul(G[0, bn + n], a) + wp.cw_mul(G[1, bn + n], c)
                fy[n] = wp.cw_mul(G[1, bn + n], a) + wp.cw_mul(G[2, bn + n], c)
        for k in range(first, first + NP):  # minus its weak divergence
            j = k - first
            for h in range(first, first + NP):
                i = h - first
                s = vw()
                t = vw()
                for m in range(NP):
                    s += dvv[m, i] * fx[j * NP + m]
                for m in range(NP):
                    t += dvv[m, j] * fy[m * NP + i]
                X[j * NP + i] = -(s + t)

    sweeps.__qualname__ = sweeps.__name__ = f"weak_laplacian_across_np{NP}_w{W}" + suffix(dtype)
    return wp.func(sweeps)


@functools.cache
def _block_laplacians(second: bool, divergent: bool, np_: int, lanes: int, dtype=f64):
    """``laplacian_across``'s weak Laplacians of a block of W = ``lanes`` elements (src, hs, f, dvv,
    L, G, X, fx, fy, b): each field lane by lane into X, ``weak_laplacian_across``, back into L's
    rows; in ``dtype``."""
    NP, W, S, DIV = int(np_), int(lanes), bool(second), bool(divergent) and not second
    vec, mat = row_derivatives(NP, dtype)[:2]
    RowFrame = frame_type(vec)
    vw = wp.types.vector(length=W, dtype=dtype)
    NN = NP * NP
    field = _row_field(S, NP, dtype)
    tag = f"{'second' if S else 'first'}_{'div_' if DIV else ''}np{NP}_w{W}" + suffix(dtype)
    sweeps = weak_laplacian_across(NP, W, dtype)

    def block_laplacians(
        src: wp.array2d(dtype=_source(S, NP, dtype)),
        hs: wp.array(dtype=row_type(NP)),
        f: RowFrame,
        dvv: mat,
        L: wp.array2d(dtype=vec),
        G: wp.array2d(dtype=vw),
        X: wp.array(dtype=vw),
        fx: wp.array(dtype=vw),
        fy: wp.array(dtype=vw),
        b: int,
    ):
        e0 = b * W
        bn = b * NN
        first = e0 * NN  # a run-time start for the sweeps' loops
        for r in range(L.shape[0]):  # one field at a time, in a loop clang does not unroll
            for e in range(e0, e0 + W):  # field r of the block's elements, lane by lane (not unrolled)
                w = e - e0
                base = e * NP
                for k in range(base, base + NP):
                    j = k - base
                    row = field(src, hs, f, r, k)
                    for i in range(NP):
                        X[j * NP + i][w] = row[i]
            sweeps(X, G, fx, fy, dvv, bn, first)  # X becomes its weak Laplacian: L in the across layout
            for w in range(W):  # back into L's rows, the lane fixed (stores strided by np² cost what the sweeps saved)
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
    ``benchmarks/across_elements.py``). The state, Y, L and the DSS stay in today's layout:
    each field's values (``field``, formed on rows as there) go lane by lane into the scratch X,
    the sweeps go through the scratch fx, fy, and L is written back lane by lane; the second
    pass's row DSS and both passes' pointwise part are ``laplacian_element``'s, element by
    element. np ≥ 5 only (ValueError otherwise: np 4 keeps its unrolled rows and their bits);
    the elements past the last whole block go through ``laplacian_element``.
    Arguments: (second: xr, x, d, g, wr, rsr, as ``Topology.by_element`` gives them), src, hs,
    delta, c, f, metric, dvv, L as ``laplacian_element``'s;
    G (3, N_b) the metric's rows 0..2 in the across layout, G[k, b·np² + n][w] = metric[k,
    (W b + w) np² + n] (``across_layout``); X, fx, fy (np²) vectors of W, a thread's private
    scratch (``parallel.record``'s ``per_part``); offset (in blocks). Dim ⌊nelem/W⌋.
    HOMME's ``laplace_sphere_wk`` (its quadrature-weighted contravariant metric). ``dtype`` as
    ``laplacian_element``'s (of G, X, fx, fy too)."""
    NP, W = int(np_), int(lanes)
    S = bool(second)
    DIV = bool(divergent) and not S
    if NP < 5 or W < 1:
        raise ValueError(f"the weak Laplacian across elements is for np >= 5 and lanes >= 1 (got np {NP}, {W})")
    if S and copies < 1:
        raise ValueError(f"the second pass sums the copies of a node: copies must be at least 1 (got {copies})")
    parts = _element_parts(S, DIV, NP, max(1, int(copies)), bool(ghosts), dtype)
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
            X: wp.array(dtype=vw),
            fx: wp.array(dtype=vw),
            fy: wp.array(dtype=vw),
            offset: int,
        ):
            b = wp.tid() + offset
            for e in range(b * W, b * W + W):  # Y₁ = the first DSS at the block's elements, as ``laplacian_element``
                for j in range(NP):
                    for r in range(4):
                        src[r, e * NP + j] = vec(row_dss(xr, x, d, g, wr, rsr, e, j, r))
            block(src, hs, f, dvv, L, G, X, fx, fy, b)
            for e in range(b * W, b * W + W):  # not unrolled
                pointwise(src, hs, delta, c, f, metric, dvv, L, e)

    else:

        def kernel(
            src: wp.array2d(dtype=state),
            hs: wp.array(dtype=state),
            delta: wp.array2d(dtype=state),
            c: cvec,
            f: RowFrame,
            metric: wp.array2d(dtype=vec),
            dvv: mat,
            L: wp.array2d(dtype=vec),
            G: wp.array2d(dtype=vw),
            X: wp.array(dtype=vw),
            fx: wp.array(dtype=vw),
            fy: wp.array(dtype=vw),
            offset: int,
        ):
            b = wp.tid() + offset
            block(src, hs, f, dvv, L, G, X, fx, fy, b)
            for e in range(b * W, b * W + W):  # not unrolled
                pointwise(src, hs, delta, c, f, metric, dvv, L, e)

    kernel.__qualname__ = kernel.__name__ = (
        "laplacian_across__" + ("second" if S else "first__divergent" if DIV else "first") + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)


def across_layout(a, lanes: int, np_: int):
    """The across layout of ``laplacian_across``'s G from a (rows, N) numpy array of element-local
    values: (rows, ⌊nelem/W⌋ np², W), [k, b np² + n, w] = a[k, (W b + w) np² + n]."""
    rows, nn = a.shape[0], int(np_) ** 2
    nb = a.shape[1] // nn // int(lanes)
    t = a[:, : nb * lanes * nn].reshape(rows, nb, lanes, nn)
    return t.transpose(0, 1, 3, 2).reshape(rows, nb * nn, lanes).copy()


@wp.func
def _reference_gradient(delta: wp.array2d(dtype=f64), base: int, i: int, j: int, n: int, dvv: wp.array2d(dtype=Any)):
    """(∂ξ δ, ∂η δ) at node (i, j) of the element starting at ``base``, in dvv's float type: δ
    (float64) rounded on load (``operators.d_xi``/``d_eta``'s sums; a float32 ∇⁴'s)."""
    a = type(dvv[i, j])(0.0)
    b = type(dvv[i, j])(0.0)
    for m in range(n):
        a += dvv[i, m] * type(a)(delta[0, base + j * n + m])
        b += dvv[j, m] * type(a)(delta[0, base + m * n + i])
    return a, b


@functools.cache
def laplacian_node(second: bool, divergent: bool, np_static: int = 0, dtype=f64):
    """``laplacian_element`` with one thread per node, for CUDA: from the flux
    (8, N) of ``laplacian_flux`` of X or Y₁, and src the X it wrote or Y₁.
    Arguments: flux, src (4, N), delta (1, N), c, f (``frame_type``), spheremp (N),
    dvv (np, np), np, L (4, N) output, offset. Dim N. ``np_static``: as
    ``tendencies.tendency``'s. ``dtype``: the ∇⁴'s float type, of every argument but δ and the
    second pass's src Y₁ (float64, the DSS's outputs, rounded on load)."""
    S, DIV = bool(second), bool(divergent) and not second
    NP = int(np_static)
    v4 = wp.types.vector(length=4, dtype=dtype)
    NodeFrame = frame_type(dtype)

    def kernel(
        flux: wp.array2d(dtype=dtype),
        src: wp.array2d(dtype=f64 if S else dtype),
        delta: wp.array2d(dtype=f64),
        c: v4,
        f: NodeFrame,
        spheremp: wp.array(dtype=dtype),
        dvv: wp.array2d(dtype=dtype),
        np_: int,
        L: wp.array2d(dtype=dtype),
        offset: int,
    ):
        p = wp.tid() + offset
        n = np_
        if wp.static(NP > 0):
            n = wp.static(NP)
        Lp = v4()
        for r in range(4):
            Lp[r] = weak_divergence(flux, r, dvv, n, p)
        Xp = v4(dtype(src[0, p]), dtype(src[1, p]), dtype(src[2, p]), dtype(src[3, p]))
        y = v4()
        if wp.static(S):
            y = shift_second(Lp, Xp, spheremp[p], c[3])
        else:
            y = scale_first(Lp, Xp, spheremp[p], f, p, c)
            if wp.static(DIV):
                base, i, j = element_node(p, n)
                if wp.static(dtype is f64):
                    y = add_divergent(
                        y,
                        d_xi(delta, 0, base, i, j, n, dvv),
                        d_eta(delta, 0, base, i, j, n, dvv),
                        c[1] * spheremp[p],
                        p,
                        f,
                    )
                else:
                    a, b = _reference_gradient(delta, base, i, j, n, dvv)
                    y = add_divergent(y, a, b, c[1] * spheremp[p], p, f)
        for r in range(4):
            L[r, p] = y[r]

    kernel.__qualname__ = kernel.__name__ = (
        "laplacian_node__"
        + ("second" if S else "first__divergent" if DIV else "first")
        + (f"__np{NP}" if NP else "")
        + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique")


def _laplacian_metric(
    Dinv: wp.array2d(dtype=f64), spheremp: wp.array(dtype=f64), metric: wp.array2d(dtype=f64), offset: int
):
    """metric[0:3] = spheremp · (Dinv Dinvᵀ)₁₁, ₁₂, ₂₂ (symmetric): the weak
    Laplacian's quadrature-weighted contravariant metric; metric[3] = spheremp. Dim N."""
    q = wp.tid() + offset
    d0 = Dinv[0, q]
    d1 = Dinv[1, q]
    d2 = Dinv[2, q]
    d3 = Dinv[3, q]
    w = spheremp[q]
    metric[0, q] = w * (d0 * d0 + d1 * d1)
    metric[1, q] = w * (d0 * d2 + d1 * d3)
    metric[2, q] = w * (d2 * d2 + d3 * d3)
    metric[3, q] = w


# compiled as laplacian_element (CPU_FAST: the same contractions as when it computed these itself)
laplacian_metric = wp.kernel(_laplacian_metric, enable_backward=False, module="unique", module_options=CPU_FAST)


@functools.cache
def laplacian_flux(cartesian: bool, tensor: bool, np_static: int = 0, dtype=f64):
    """The flux pass of a per-node weak Laplacian (CUDA), for every row r of its source:
    flux[2r:2r+2, p] = ``operators.weak_flux`` of (∂ξ, ∂η) of row r, or with ``tensor``
    G (∂ξ, ∂η), G = metric[0:3] (G₁₁, G₁₂, G₂₂) the fixed quadrature-weighted
    spheremp · Dinv V Dinvᵀ of the weak ∇·(V∇·) (HOMME ``laplace_sphere_wk`` with
    ``var_coef``). The source is src (4, N) (Y₁, the second Laplacian's), or with
    ``cartesian`` the first Laplacian's X = (Cartesian wind u·east + v·north, h + hs) formed
    from the state src (3, N) node by node as it is read, and written at each node to
    X (4, N) (``laplacian_node`` reads it there): no pass of its own, the bits of one.
    (The first DSS gathered the same way in the second pass cost more than its own pass
    at ne120 on an H100: 169 µs against 129, issue 83.)
    Arguments: src, hs (N), f (``frame_type``: east, north, h0; read with ``cartesian``), Dinv
    (4, N), spheremp (N), metric (4, N; read with ``tensor``), dvv (np, np), np, flux (8, N),
    X (4, N; written with ``cartesian``), offset. Dim N. ``np_static``: as ``tendencies.tendency``'s.
    ``dtype``: the ∇⁴'s float type, of every argument but src and hs (float64, the state or Y₁,
    the first DSS's output, rounded on load; h + hs − H₀ formed in float64 under float32, as
    ``laplacian_element``)."""
    CART, TENSOR = bool(cartesian), bool(tensor)
    NP = int(np_static)
    SHIFT = dtype is not f64
    v4, v2 = wp.types.vector(length=4, dtype=dtype), wp.types.vector(length=2, dtype=dtype)
    NodeFrame = frame_type(dtype)

    def value(src: wp.array2d(dtype=f64), hs: wp.array(dtype=f64), f: NodeFrame, n: int):
        X = v4()
        if wp.static(CART):
            for c in range(3):
                X[c] = dtype(src[0, n]) * f.east[c, n] + dtype(src[1, n]) * f.north[c, n]
            if wp.static(SHIFT):  # h + hs − H₀ formed in float64 before it is rounded
                X[3] = dtype(src[2, n] + hs[n] - f.h0)
            else:
                X[3] = src[2, n] + hs[n]
        else:
            for r in range(4):
                X[r] = dtype(src[r, n])
        return X

    value.__qualname__ = value.__name__ = f"hv_source__{'cartesian' if CART else 'rows'}" + suffix(dtype)
    source = wp.func(value)

    def kernel(
        src: wp.array2d(dtype=f64),
        hs: wp.array(dtype=f64),
        f: NodeFrame,
        Dinv: wp.array2d(dtype=dtype),
        spheremp: wp.array(dtype=dtype),
        metric: wp.array2d(dtype=dtype),
        dvv: wp.array2d(dtype=dtype),
        np_: int,
        flux: wp.array2d(dtype=dtype),
        X: wp.array2d(dtype=dtype),
        offset: int,
    ):
        p = wp.tid() + offset
        n = np_
        if wp.static(NP > 0):
            n = wp.static(NP)
        base, i, j = element_node(p, n)
        a = v4()  # ∂ξ, ∂η of each row, summed as ``operators.d_xi``/``d_eta``
        b = v4()
        for m in range(n):
            sq = source(src, hs, f, base + j * n + m)
            sr = source(src, hs, f, base + m * n + i)
            for r in range(4):
                a[r] = a[r] + dvv[i, m] * sq[r]
                b[r] = b[r] + dvv[j, m] * sr[r]
        for r in range(4):
            g = v2()
            if wp.static(TENSOR):
                g = v2(metric[0, p] * a[r] + metric[1, p] * b[r], metric[1, p] * a[r] + metric[2, p] * b[r])
            else:
                g = weak_flux(a[r], b[r], Dinv, spheremp, p)
            flux[2 * r, p] = g[0]
            flux[2 * r + 1, p] = g[1]
        if wp.static(CART):
            s = source(src, hs, f, p)
            for r in range(4):
                X[r, p] = s[r]

    name = "laplacian_flux__" + ("cartesian" if CART else "rows") + ("__tensor" if TENSOR else "")
    name += (f"__np{NP}" if NP else "") + suffix(dtype)
    kernel.__qualname__ = kernel.__name__ = name
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def _applied(mode: str):
    """A ``wp.func`` (y, east, north, coef, out, src, prev, mu, nu, p): ``dss_apply``'s update at
    node p from Y₂ there (y: the 4 values, a vec4d) or at row p from its rows (y: a (4, np)
    matrix, east and north row views), the same sums lane by lane, in float64 (a float32
    ∇⁴'s east and north converted as they are read). ValueError for another mode."""
    if mode not in ("add", "euler", "rkl"):
        raise ValueError(f"dss_apply's mode is 'add', 'euler' or 'rkl' (got {mode!r})")
    ADD, RKL = mode == "add", mode == "rkl"

    def update(
        out: wp.array2d(dtype=Any),
        src: wp.array2d(dtype=Any),
        prev: wp.array2d(dtype=Any),
        r: int,
        p: int,
        z: Any,
        coef: f64,
        mu: f64,
        nu: f64,
    ):
        if wp.static(ADD):
            out[r, p] = out[r, p] + coef * z
        else:
            t = src[r, p] + coef * z
            if wp.static(RKL):
                t = mu * t + nu * prev[r, p]
            out[r, p] = t

    update.__qualname__ = update.__name__ = f"dss_apply_update_{mode}"
    put = wp.func(update)

    def applied(
        y: Any,
        east: wp.array2d(dtype=Any),
        north: wp.array2d(dtype=Any),
        coef: f64,
        out: wp.array2d(dtype=Any),
        src: wp.array2d(dtype=Any),
        prev: wp.array2d(dtype=Any),
        mu: f64,
        nu: f64,
        p: int,
    ):
        # in float64: a float32 ∇⁴'s frame read in it
        ye = (
            times(y[0], type(y[0])(east[0, p]))
            + times(y[1], type(y[1])(east[1, p]))
            + times(y[2], type(y[2])(east[2, p]))
        )
        yn = (
            times(y[0], type(y[0])(north[0, p]))
            + times(y[1], type(y[1])(north[1, p]))
            + times(y[2], type(y[2])(north[2, p]))
        )
        put(out, src, prev, 0, p, ye, coef, mu, nu)
        put(out, src, prev, 1, p, yn, coef, mu, nu)
        put(out, src, prev, 2, p, y[3], coef, mu, nu)

    applied.__qualname__ = applied.__name__ = f"dss_applied_{mode}"
    return wp.func(applied)


@functools.cache
def dss_apply(copies: int, ghosts: bool = False, mode: str = "add", dtype=f64):
    """The second DSS of the ∇⁴, applied as it sums Y₂ = DSS(L) (``dss.gather``, unweighted,
    4 rows: the weak-form Y₂ of ``laplacian_element``/``laplacian_node``), its Cartesian wind
    taken back to (east, north) components, by ``mode``: "add", out += coef·Y₂ (out may be the
    state the Laplacians came from: only L is read at other nodes); "euler", out = src +
    coef·Y₂; "rkl", out = μ·(src + coef·Y₂) + ν·prev, an RKL1 stage (``Hyperviscosity.rkl1``)
    summed as a forward-Euler step into a copy of src and ``blas.axpby`` after it were (the
    same bits, without the copy and the pass). src is the state the Laplacians came from; out
    may alias src and prev (each read at its own node). Arguments: L (4, N),
    d (``dss.Copies``), coef, f (``Frame``), out (3, N), src (3, N; read by "euler" and "rkl"),
    prev (3, N), mu, nu (read by "rkl"), block, offset. ValueError for another mode.
    Dim N/block (as ``dss.dss_rows``). ``dtype``: the ∇⁴'s float type, of L and f; the sums
    (``dss.gather``) and the update float64, as the state."""
    sum_copies = gather(4, False, copies, ghosts, dtype)
    applied = _applied(mode)

    def dss_apply(
        L: wp.array2d(dtype=dtype),
        d: Copies,
        coef: f64,
        f: frame_type(dtype),
        out: wp.array2d(dtype=f64),
        src: wp.array2d(dtype=f64),
        prev: wp.array2d(dtype=f64),
        mu: f64,
        nu: f64,
        block: int,
        offset: int,
    ):
        start = (wp.tid() + offset) * block
        for p in range(start, start + block):
            applied(sum_copies(L, d, p), f.east, f.north, coef, out, src, prev, mu, nu, p)

    dss_apply.__qualname__ = "dss_apply" + ("" if mode == "add" else "__" + mode) + suffix(dtype)  # the kernel's key
    return wp.kernel(dss_apply, enable_backward=False, module="unique")


@functools.cache
def dss_apply_elements(copies: int, ghosts: bool, np_: int, mode: str = "add", dtype=f64):
    """``dss_apply`` by element on GLL rows (``dss.gather_row``, the node gather's bits), for
    the CPU (``Topology.by_element``): arguments Lr, L (L as rows and as it is), d
    (``dss.Copies``), g (``dss.Edges``), wr, rsr (spheremp's first N and rspheremp as rows),
    coef, f (``frame_type`` of rows), out, src, prev as rows, mu, nu, offset; dim nelem.
    ``dtype`` as ``dss_apply``'s (of Lr, L and f; the rest float64)."""
    NP = int(np_)
    vec = row_type(NP)
    RowFrame = frame_type(row_type(NP, dtype))
    row_dss = gather_row(4, False, copies, ghosts, NP, dtype)
    applied = _applied(mode)

    def dss_apply(
        Lr: wp.array2d(dtype=row_type(NP, dtype)),
        L: wp.array2d(dtype=dtype),
        d: Copies,
        g: Edges,
        wr: wp.array(dtype=vec),
        rsr: wp.array(dtype=vec),
        coef: f64,
        f: RowFrame,
        out: wp.array2d(dtype=vec),
        src: wp.array2d(dtype=vec),
        prev: wp.array2d(dtype=vec),
        mu: f64,
        nu: f64,
        offset: int,
    ):
        e = wp.tid() + offset
        for j in range(NP):
            y = wp.matrix_from_rows(
                row_dss(Lr, L, d, g, wr, rsr, e, j, 0),
                row_dss(Lr, L, d, g, wr, rsr, e, j, 1),
                row_dss(Lr, L, d, g, wr, rsr, e, j, 2),
                row_dss(Lr, L, d, g, wr, rsr, e, j, 3),
            )
            applied(y, f.east, f.north, coef, out, src, prev, mu, nu, e * NP + j)

    dss_apply.__qualname__ = (
        "dss_apply" + ("" if mode == "add" else "__" + mode) + suffix(dtype)
    )  # the node kernel's key
    return wp.kernel(dss_apply, enable_backward=False, module="unique")
