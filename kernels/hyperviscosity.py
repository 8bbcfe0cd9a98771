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
    Y₁[0:3] = ν (P ΔX + 2v/a²) + (ν_div − ν) ∇(∇·v),   Y₁[3] = ν_s Δ(h + hs)
with X the Cartesian wind, P the tangent projection and every Δ the DSS'd weak
Laplacian. Rows of the work arrays: 0..2 Cartesian wind, 3 free surface.

Two layouts, as for the tendency: on CUDA the pointwise kernels below
(dim N) around ``operators.laplace_wk_flux``/``laplace_wk_div``; on the CPU
``laplacian_element`` (dim nelem), which does the pointwise step and the whole
weak Laplacian of an element in one pass.
"""

import functools

import warp as wp

from .operators import CPU_FAST, dvv_constant, reference_gradient

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.func
def first_laplacian_scaled(
    X: wp.array2d(dtype=f64),
    x: wp.array2d(dtype=f64),
    G: wp.array2d(dtype=f64),
    east: wp.array2d(dtype=f64),
    north: wp.array2d(dtype=f64),
    xyz: wp.array2d(dtype=f64),
    q: int,
    c: wp.vec4d,
):
    """Y₁ at node q from the DSS'd first Laplacian X, the state x and the DSS'd
    ∇(∇·v) G (east, north); c = (ν, ν_div − ν, ν_s, 2/a²)."""
    d = X[0, q] * xyz[0, q] + X[1, q] * xyz[1, q] + X[2, q] * xyz[2, q]
    y = wp.vec4d()
    for r in range(3):
        v = x[0, q] * east[r, q] + x[1, q] * north[r, q]
        gd = G[0, q] * east[r, q] + G[1, q] * north[r, q]
        y[r] = c[0] * (X[r, q] - d * xyz[r, q] + c[3] * v) + c[1] * gd
    y[3] = c[2] * X[3, q]
    return y


@functools.cache
def laplacian_element(second: bool, dvv: tuple):
    """Element-local weak Laplacian (``operators.laplace_wk_*`` in one pass,
    one thread per element, ``dvv`` compiled in) of four rows:
    ``second=False``: X = (u·east + v·north, h + hs) of the state ``src``;
    ``second=True``: Y₁ = ``first_laplacian_scaled(src, x, G, ..., c)``, which
    it also stores in Y.
    Arguments: src (3 or 4, N), x (3, N), G (2, N), c, hs (N), east, north,
    xyz (3, N), metric (3, N) (``laplacian_metric``), Y (4, N), L (4, N) output, offset
    (in elements). Dim nelem."""
    NP = len(dvv)
    NPP = NP * NP
    vec = wp.types.vector(length=NPP, dtype=f64)
    DVV = dvv_constant(dvv)
    grad = reference_gradient(dvv)
    S = bool(second)

    def weak_laplacian(f: vec, G11: vec, G12: vec, G22: vec, L: wp.array2d(dtype=f64), r: int, base: int):
        fx = vec()  # G ∇_ref f: the quadrature-weighted contravariant gradient
        fy = vec()
        for j in range(NP):
            for i in range(NP):
                a, b = grad(f, i, j)
                k = j * NP + i
                fx[k] = G11[k] * a + G12[k] * b
                fy[k] = G12[k] * a + G22[k] * b
        for n in range(NP):
            for m in range(NP):
                s = f64(0.0)
                for k in range(NP):
                    s += DVV[k, m] * fx[n * NP + k] + DVV[k, n] * fy[k * NP + m]
                L[r, base + n * NP + m] = -s

    weak_laplacian.__qualname__ = weak_laplacian.__name__ = f"weak_laplacian_np{NP}"
    lap = wp.func(weak_laplacian)

    def kernel(
        src: wp.array2d(dtype=f64),
        x: wp.array2d(dtype=f64),
        G: wp.array2d(dtype=f64),
        c: wp.vec4d,
        hs: wp.array(dtype=f64),
        east: wp.array2d(dtype=f64),
        north: wp.array2d(dtype=f64),
        xyz: wp.array2d(dtype=f64),
        metric: wp.array2d(dtype=f64),
        Y: wp.array2d(dtype=f64),
        L: wp.array2d(dtype=f64),
        offset: int,
    ):
        base = (wp.tid() + offset) * NPP
        X0 = vec()  # the four rows of X
        X1 = vec()
        X2 = vec()
        X3 = vec()
        G11 = vec()  # the weak Laplacian's metric (``laplacian_metric``), once for all rows
        G12 = vec()
        G22 = vec()
        for k in range(NPP):
            q = base + k
            if wp.static(S):
                y = first_laplacian_scaled(src, x, G, east, north, xyz, q, c)
                for r in range(4):
                    Y[r, q] = y[r]
                X0[k] = y[0]
                X1[k] = y[1]
                X2[k] = y[2]
                X3[k] = y[3]
            else:
                X0[k] = src[0, q] * east[0, q] + src[1, q] * north[0, q]
                X1[k] = src[0, q] * east[1, q] + src[1, q] * north[1, q]
                X2[k] = src[0, q] * east[2, q] + src[1, q] * north[2, q]
                X3[k] = src[2, q] + hs[q]
            G11[k] = metric[0, q]
            G12[k] = metric[1, q]
            G22[k] = metric[2, q]
        lap(X0, G11, G12, G22, L, 0, base)
        lap(X1, G11, G12, G22, L, 1, base)
        lap(X2, G11, G12, G22, L, 2, base)
        lap(X3, G11, G12, G22, L, 3, base)

    kernel.__qualname__ = kernel.__name__ = "laplacian_element__second" if S else "laplacian_element__first"
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)


def _laplacian_metric(Dinv: wp.array2d(dtype=f64), spheremp: wp.array(dtype=f64), metric: wp.array2d(dtype=f64), offset: int):
    """metric[0:3] = spheremp · (Dinv Dinvᵀ)₁₁, ₁₂, ₂₂ (symmetric): the weak
    Laplacian's quadrature-weighted contravariant metric. Dim N."""
    q = wp.tid() + offset
    d0 = Dinv[0, q]
    d1 = Dinv[1, q]
    d2 = Dinv[2, q]
    d3 = Dinv[3, q]
    w = spheremp[q]
    metric[0, q] = w * (d0 * d0 + d1 * d1)
    metric[1, q] = w * (d0 * d2 + d1 * d3)
    metric[2, q] = w * (d2 * d2 + d3 * d3)


# compiled as laplacian_element (CPU_FAST: the same contractions as when it computed these itself)
laplacian_metric = wp.kernel(_laplacian_metric, enable_backward=False, module="unique", module_options=CPU_FAST)


@wp.kernel
def to_cartesian(x: wp.array2d(dtype=f64), hs: wp.array(dtype=f64), east: wp.array2d(dtype=f64), north: wp.array2d(dtype=f64), X: wp.array2d(dtype=f64), offset: int):
    """X[0:3] = u·east + v·north; X[3] = h + hs."""
    p = wp.tid() + offset
    for c in range(3):
        X[c, p] = x[0, p] * east[c, p] + x[1, p] * north[c, p]
    X[3, p] = x[2, p] + hs[p]


@wp.kernel
def scale_first(
    X: wp.array2d(dtype=f64),
    x: wp.array2d(dtype=f64),
    G: wp.array2d(dtype=f64),
    c: wp.vec4d,
    east: wp.array2d(dtype=f64),
    north: wp.array2d(dtype=f64),
    xyz: wp.array2d(dtype=f64),
    Y: wp.array2d(dtype=f64),
    offset: int,
):
    """Y[:, p] = Y₁ (``first_laplacian_scaled``)."""
    p = wp.tid() + offset
    y = first_laplacian_scaled(X, x, G, east, north, xyz, p, c)
    for r in range(4):
        Y[r, p] = y[r]


@wp.kernel
def apply(
    X: wp.array2d(dtype=f64),
    Y: wp.array2d(dtype=f64),
    shift: f64,
    coef: f64,
    east: wp.array2d(dtype=f64),
    north: wp.array2d(dtype=f64),
    x: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """x += coef·Y₂ with Y₂ = X + shift·Y (wind rows; X the DSS'd Laplacian of
    Y = Y₁) and its Cartesian wind taken back to (east, north) components.
    Dim N/block, ``block`` consecutive nodes a thread (as ``blas.axpby``)."""
    start = (wp.tid() + offset) * block
    for p in range(start, start + block):
        ye = f64(0.0)
        yn = f64(0.0)
        for c in range(3):
            y = X[c, p] + shift * Y[c, p]
            ye += y * east[c, p]
            yn += y * north[c, p]
        x[0, p] = x[0, p] + coef * ye
        x[1, p] = x[1, p] + coef * yn
        x[2, p] = x[2, p] + coef * X[3, p]
