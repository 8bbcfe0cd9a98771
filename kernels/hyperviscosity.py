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

In four passes, as HOMME (``vlaplace_sphere_wk_cartesian``) forms each
Laplacian: everything pointwise in Y₁ and Y₂ is done on the element's weak form
before its DSS, where the mass is a factor (2v/a² enters as 2·spheremp·v/a²,
∇δ as spheremp·∇δ, whose unweighted DSS is the mass-weighted one of ∇δ; P and
the coefficients commute with the DSS); the first DSS then gives Y₁ itself and
the second DSS, ``dss_apply``, adds coef·Y₂ to the state as it sums. ∇δ is
compiled in only when ν_div ≠ ν. Changes the last bits against applying them
after each DSS.

Two layouts, as for the tendency: on CUDA ``to_cartesian``,
``operators.laplace_wk_flux`` and ``laplacian_node`` (dim N); on the CPU
``laplacian_element`` (dim nelem), the whole weak Laplacian of an element in
one pass. Both finish the node with the same ``scale_first`` / ``shift_second``.
"""

import functools

import warp as wp

from .dss import Copies, gather
from .operators import CPU_FAST, d_eta, d_xi, dvv_constant, element_node, reference_gradient, weak_divergence

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.struct
class Frame:
    """A node's frame: Dinv (4, N), the unit vectors east, north and the
    position xyz (3, N, Cartesian, unit sphere); a kernel is given those it
    reads (``ShallowWater._frame``), the others null."""

    Dinv: wp.array2d(dtype=f64)
    east: wp.array2d(dtype=f64)
    north: wp.array2d(dtype=f64)
    xyz: wp.array2d(dtype=f64)


@wp.func
def scale_first(L: wp.vec4d, X: wp.vec4d, w: f64, r: wp.vec3d, c: wp.vec4d):
    """The weak-form Y₁ at a node from the weak Laplacian L of X = (Cartesian
    wind, h + hs), the mass w and the position r: ν(PL + (2/a²)·w·X) for the
    wind, ν_s·L for the height, c = (ν, ν_div − ν, ν_s, 2/a²) (the ∇δ term
    apart: ``divergent_part``)."""
    d = L[0] * r[0] + L[1] * r[1] + L[2] * r[2]
    y = wp.vec4d()
    for k in range(3):
        y[k] = c[0] * (L[k] - d * r[k] + c[3] * w * X[k])
    y[3] = c[2] * L[3]
    return y


@wp.func
def shift_second(L: wp.vec4d, Y: wp.vec4d, w: f64, shift: f64):
    """The weak-form Y₂ at a node: L + shift·w·Y for the wind, L for the
    height (L the weak Laplacian of Y = Y₁, w the mass, shift = 2/a²)."""
    return wp.vec4d(L[0] + shift * w * Y[0], L[1] + shift * w * Y[1], L[2] + shift * w * Y[2], L[3])


@wp.func
def divergent_part(a: f64, b: f64, q: int, f: Frame):
    """The Cartesian ∇δ at node q from δ's reference derivatives (a, b) = (∂ξ δ, ∂η δ)."""
    ge = f.Dinv[0, q] * a + f.Dinv[2, q] * b
    gn = f.Dinv[1, q] * a + f.Dinv[3, q] * b
    return wp.vec3d(ge * f.east[0, q] + gn * f.north[0, q], ge * f.east[1, q] + gn * f.north[1, q], ge * f.east[2, q] + gn * f.north[2, q])


@wp.func
def position(f: Frame, q: int):
    """The unit position vector of node q."""
    return wp.vec3d(f.xyz[0, q], f.xyz[1, q], f.xyz[2, q])


@functools.cache
def laplacian_element(second: bool, divergent: bool, dvv: tuple):
    """The weak form of Y₁ (``second=False``, from the state ``src`` = x (3, N)
    and hs) or of Y₂ (``second=True``, from ``src`` = Y₁ (4, N)) of the elements
    (the module docstring), one thread per element, ``dvv`` compiled in;
    ``divergent``: with the (ν_div − ν)·spheremp·∇δ term, δ the DSS'd
    divergence in ``delta`` (1, N) (first only). Arguments: src, hs (N), delta,
    c (``scale_first``), f (``Frame``), metric (4, N) (``laplacian_metric``),
    L (4, N) output, offset (in elements). Dim nelem."""
    NP = len(dvv)
    NPP = NP * NP
    vec = wp.types.vector(length=NPP, dtype=f64)
    DVV = dvv_constant(dvv)
    grad = reference_gradient(dvv)
    S, DIV = bool(second), bool(divergent) and not second

    def weak_laplacian(f: vec, G11: vec, G12: vec, G22: vec):
        fx = vec()  # G ∇_ref f: the quadrature-weighted contravariant gradient
        fy = vec()
        for j in range(NP):
            for i in range(NP):
                a, b = grad(f, i, j)
                k = j * NP + i
                fx[k] = G11[k] * a + G12[k] * b
                fy[k] = G12[k] * a + G22[k] * b
        out = vec()
        for n in range(NP):
            for m in range(NP):
                s = f64(0.0)
                for k in range(NP):
                    s += DVV[k, m] * fx[n * NP + k] + DVV[k, n] * fy[k * NP + m]
                out[n * NP + m] = -s
        return out

    weak_laplacian.__qualname__ = weak_laplacian.__name__ = f"weak_laplacian_np{NP}"
    lap = wp.func(weak_laplacian)

    def kernel(
        src: wp.array2d(dtype=f64), hs: wp.array(dtype=f64), delta: wp.array2d(dtype=f64), c: wp.vec4d, f: Frame,
        metric: wp.array2d(dtype=f64), L: wp.array2d(dtype=f64), offset: int,
    ):
        base = (wp.tid() + offset) * NPP
        X0 = vec()  # the four rows of X (first) or Y₁ (second)
        X1 = vec()
        X2 = vec()
        X3 = vec()
        G11 = vec()  # the weak Laplacian's metric (``laplacian_metric``), once for all rows
        G12 = vec()
        G22 = vec()
        D = vec()  # δ
        for k in range(NPP):
            q = base + k
            if wp.static(S):
                X0[k] = src[0, q]
                X1[k] = src[1, q]
                X2[k] = src[2, q]
                X3[k] = src[3, q]
            else:
                X0[k] = src[0, q] * f.east[0, q] + src[1, q] * f.north[0, q]
                X1[k] = src[0, q] * f.east[1, q] + src[1, q] * f.north[1, q]
                X2[k] = src[0, q] * f.east[2, q] + src[1, q] * f.north[2, q]
                X3[k] = src[2, q] + hs[q]
            if wp.static(DIV):
                D[k] = delta[0, q]
            G11[k] = metric[0, q]
            G12[k] = metric[1, q]
            G22[k] = metric[2, q]
        L0 = lap(X0, G11, G12, G22)
        L1 = lap(X1, G11, G12, G22)
        L2 = lap(X2, G11, G12, G22)
        L3 = lap(X3, G11, G12, G22)
        for j in range(NP):
            for i in range(NP):
                k = j * NP + i
                q = base + k
                Lk = wp.vec4d(L0[k], L1[k], L2[k], L3[k])
                Xk = wp.vec4d(X0[k], X1[k], X2[k], X3[k])
                if wp.static(S):
                    y = shift_second(Lk, Xk, metric[3, q], c[3])
                else:
                    y = scale_first(Lk, Xk, metric[3, q], position(f, q), c)
                    if wp.static(DIV):
                        a, b = grad(D, i, j)
                        g = divergent_part(a, b, q, f)
                        for r in range(3):
                            y[r] = y[r] + c[1] * metric[3, q] * g[r]
                for r in range(4):
                    L[r, q] = y[r]

    kernel.__qualname__ = kernel.__name__ = "laplacian_element__" + ("second" if S else "first__divergent" if DIV else "first")
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)


@functools.cache
def laplacian_node(second: bool, divergent: bool):
    """``laplacian_element`` with one thread per node, for CUDA: from the flux
    (8, N) of ``operators.laplace_wk_flux`` of src = X (``to_cartesian``) or Y₁.
    Arguments: flux, src (4, N), delta (1, N), c, f (``Frame``), spheremp (N),
    dvv (np, np), np, L (4, N) output, offset. Dim N."""
    S, DIV = bool(second), bool(divergent) and not second

    def kernel(
        flux: wp.array2d(dtype=f64), src: wp.array2d(dtype=f64), delta: wp.array2d(dtype=f64), c: wp.vec4d, f: Frame,
        spheremp: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, L: wp.array2d(dtype=f64), offset: int,
    ):
        p = wp.tid() + offset
        Lp = wp.vec4d()
        for r in range(4):
            Lp[r] = weak_divergence(flux, r, dvv, np, p)
        Xp = wp.vec4d(src[0, p], src[1, p], src[2, p], src[3, p])
        y = wp.vec4d()
        if wp.static(S):
            y = shift_second(Lp, Xp, spheremp[p], c[3])
        else:
            y = scale_first(Lp, Xp, spheremp[p], position(f, p), c)
            if wp.static(DIV):
                base, i, j = element_node(p, np)
                g = divergent_part(d_xi(delta, 0, base, i, j, np, dvv), d_eta(delta, 0, base, i, j, np, dvv), p, f)
                for r in range(3):
                    y[r] = y[r] + c[1] * spheremp[p] * g[r]
        for r in range(4):
            L[r, p] = y[r]

    kernel.__qualname__ = kernel.__name__ = "laplacian_node__" + ("second" if S else "first__divergent" if DIV else "first")
    return wp.kernel(kernel, enable_backward=False, module="unique")


def _laplacian_metric(Dinv: wp.array2d(dtype=f64), spheremp: wp.array(dtype=f64), metric: wp.array2d(dtype=f64), offset: int):
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


@wp.kernel
def to_cartesian(x: wp.array2d(dtype=f64), hs: wp.array(dtype=f64), east: wp.array2d(dtype=f64), north: wp.array2d(dtype=f64), X: wp.array2d(dtype=f64), offset: int):
    """X[0:3] = u·east + v·north; X[3] = h + hs."""
    p = wp.tid() + offset
    for c in range(3):
        X[c, p] = x[0, p] * east[c, p] + x[1, p] * north[c, p]
    X[3, p] = x[2, p] + hs[p]


@functools.cache
def dss_apply(copies: int, ghosts: bool = False):
    """The second DSS of the ∇⁴, applied as it sums: out += coef·Y₂ with
    Y₂ = DSS(L) (``dss.gather``, unweighted, 4 rows: the weak-form Y₂ of
    ``laplacian_element``/``laplacian_node``), its Cartesian wind taken back to
    (east, north) components. Arguments: L (4, N), d (``dss.Copies``), coef,
    f (``Frame``), out (3, N) (may be the state the Laplacians came from: only
    L is read at other nodes), block, offset. Dim N/block (as ``dss.dss_rows``)."""
    sum_copies = gather(4, False, copies, ghosts)

    def dss_apply(L: wp.array2d(dtype=f64), d: Copies, coef: f64, f: Frame, out: wp.array2d(dtype=f64), block: int, offset: int):
        start = (wp.tid() + offset) * block
        for p in range(start, start + block):
            y = sum_copies(L, d, p)
            ye = y[0] * f.east[0, p] + y[1] * f.east[1, p] + y[2] * f.east[2, p]
            yn = y[0] * f.north[0, p] + y[1] * f.north[1, p] + y[2] * f.north[2, p]
            out[0, p] = out[0, p] + coef * ye
            out[1, p] = out[1, p] + coef * yn
            out[2, p] = out[2, p] + coef * y[3]

    dss_apply.__qualname__ = "dss_apply"  # the kernel's key
    return wp.kernel(dss_apply, enable_backward=False, module="unique")
