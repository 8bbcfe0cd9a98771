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

Each layout's kernels are a module of their own: the CPU's ``hyperviscosity_element``
(``laplacian_element``) and ``hyperviscosity_across`` (``laplacian_across``) and CUDA's ``hyperviscosity_node`` (``laplacian_flux``,
``laplacian_node``); here what they share (``frame_type``, the pointwise parts, ``laplacian_metric``)
and the second DSS, ``dss_apply``. A kernel's Warp key and content hash (its compiled cache entry)
name no Python module: they are the same wherever its factory lives.

Each factory takes ``dtype``, the ∇⁴'s float type (``ShallowWater``'s precision; float64 the
code and bits it always had): in float32 the weak Laplacians, their work arrays and the
geometry they read are float32, the float64 state (and hs, δ) read and rounded on load, the free
surface formed as h + hs − H₀ in float64 before it is rounded (``frame_type``'s h0: Δ of a
constant is 0, so the operator is the same and float32 keeps the digits of h's variation); the
DSSs sum the float32 copies in float64 (``dss.gather``), and ``dss_apply`` adds coef·Y₂ to the
float64 state in float64.
"""

import functools
from typing import Any

import warp as wp

from .dss import Copies, Edges, gather, gather_rows, rkl_weighted
from .operators import CPU_FAST, row_type, suffix, times

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
def _applied(mode: str):
    """A ``wp.func`` (y, east, north, coef, out, src, prev, nu, p): ``dss_apply``'s update at
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
        nu: f64,
    ):
        # in float64 (z's type), stored in the state's: float64, or a float32 state kept between
        # steps (``model.held``), rounded once
        o = out[r, p]
        if wp.static(ADD):
            out[r, p] = type(o)(type(z)(o) + coef * z)
        else:
            t = type(z)(src[r, p]) + coef * z
            if wp.static(RKL):
                t = rkl_weighted(t, type(z)(prev[r, p]), nu)
            out[r, p] = type(o)(t)

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
        put(out, src, prev, 0, p, ye, coef, nu)
        put(out, src, prev, 1, p, yn, coef, nu)
        put(out, src, prev, 2, p, y[3], coef, nu)

    applied.__qualname__ = applied.__name__ = f"dss_applied_{mode}"
    return wp.func(applied)


@functools.cache
def dss_apply(copies: int, ghosts: bool = False, mode: str = "add", dtype=f64, state=f64):
    """The second DSS of the ∇⁴, applied as it sums Y₂ = DSS(L) (``dss.gather``, unweighted,
    4 rows: the weak-form Y₂ of ``laplacian_element``/``laplacian_node``), its Cartesian wind
    taken back to (east, north) components, by ``mode``: "add", out += coef·Y₂ (out may be the
    state the Laplacians came from: only L is read at other nodes); "euler", out = src +
    coef·Y₂; "rkl", out = t + ν·(prev − t), t = src + coef·Y₂, an RKL1 stage μ·t + ν·prev with
    μ = 1 − ν (``Hyperviscosity.rkl1``: unbiased, where μ·t + ν·prev rounded h's mass up). src
    is the state the Laplacians came from; out may alias src and prev (each read at its own
    node). Arguments: L (4, N), d (``dss.Copies``), coef, f (``Frame``), out (3, N), src (3, N; read by "euler" and "rkl"),
    prev (3, N), nu (read by "rkl"), block, offset. ValueError for another mode.
    Dim N/block (as ``dss.dss_rows``). ``dtype``: the ∇⁴'s float type, of L and f; the sums
    (``dss.gather``) and the update float64; ``state`` the state's float type (out, src, prev:
    float64, or a float32 state kept between steps, ``model.held``, the update rounded once).
    """
    sum_copies = gather(4, False, copies, ghosts, dtype)
    applied = _applied(mode)

    def dss_apply(
        L: wp.array2d(dtype=dtype),
        d: Copies,
        coef: f64,
        f: frame_type(dtype),
        out: wp.array2d(dtype=state),
        src: wp.array2d(dtype=state),
        prev: wp.array2d(dtype=state),
        nu: f64,
        block: int,
        offset: int,
    ):
        start = (wp.tid() + offset) * block
        for p in range(start, start + block):
            applied(sum_copies(L, d, p), f.east, f.north, coef, out, src, prev, nu, p)

    kept = "" if state is f64 else "__state" + suffix(state)  # a float32 state kept between steps (``model.held``)
    dss_apply.__qualname__ = "dss_apply" + ("" if mode == "add" else "__" + mode) + suffix(dtype) + kept  # the key
    return wp.kernel(dss_apply, enable_backward=False, module="unique")


@functools.cache
def dss_apply_elements(copies: int, ghosts: bool, np_: int, mode: str = "add", dtype=f64, state=f64):
    """``dss_apply`` by element on GLL rows (``dss.gather_rows``, the node gather's bits), for
    the CPU (``Topology.by_element``): arguments Lr, L (L as rows and as it is), d
    (``dss.Copies``), g (``dss.Edges``), wr, rsr (spheremp's first N and rspheremp as rows),
    coef, f (``frame_type`` of rows), out, src, prev as rows, nu, offset; dim nelem.
    ``dtype`` as ``dss_apply``'s (of Lr, L and f; the rest float64)."""
    NP = int(np_)
    vec = row_type(NP)
    RowFrame = frame_type(row_type(NP, dtype))
    rows_dss = gather_rows(4, False, copies, ghosts, NP, dtype)
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
        out: wp.array2d(dtype=row_type(NP, state)),
        src: wp.array2d(dtype=row_type(NP, state)),
        prev: wp.array2d(dtype=row_type(NP, state)),
        nu: f64,
        offset: int,
    ):
        e = wp.tid() + offset
        for j in range(NP):
            y = rows_dss(Lr, L, d, g, wr, rsr, e, j)
            applied(y, f.east, f.north, coef, out, src, prev, nu, e * NP + j)

    kept = "" if state is f64 else "__state" + suffix(state)
    dss_apply.__qualname__ = (
        "dss_apply" + ("" if mode == "add" else "__" + mode) + suffix(dtype) + kept
    )  # the node kernel's key
    return wp.kernel(dss_apply, enable_backward=False, module="unique")
