"""The ∇⁴ hyperviscosity's kernels (HOMME ``advance_hypervis``).

The wind is diffused through its 3-D Cartesian components, which are smooth
across the poles and panel edges; the tangential projection of the
componentwise Laplacian is the vector Laplacian ∇(∇·v) − ∇×∇×v. The height
diffused is the free surface h + hs (smooth over the TC5 cone, unlike h).
Rows of the work array X: 0..2 Cartesian wind, 3 free surface.

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


@functools.cache
def laplacian_element(tangent: bool, dvv: tuple):
    """Element-local weak Laplacian (``operators.laplace_wk_*`` in one pass,
    one thread per element, ``dvv`` compiled in) of the four rows
    ``tangent=False``: X = (u·east + v·north, h + hs) of the state ``src``;
    ``tangent=True``: X = ``src`` with its wind projected tangent to the sphere.
    Arguments: src (3 or 4, N), hs (N), east, north, xyz (3, N), Dinv (4, N),
    spheremp (N), L (4, N) output, offset (in elements). Dim nelem."""
    NP = len(dvv)
    NPP = NP * NP
    vec = wp.types.vector(length=NPP, dtype=f64)
    DVV = dvv_constant(dvv)
    grad = reference_gradient(dvv)
    T = bool(tangent)

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
        hs: wp.array(dtype=f64),
        east: wp.array2d(dtype=f64),
        north: wp.array2d(dtype=f64),
        xyz: wp.array2d(dtype=f64),
        Dinv: wp.array2d(dtype=f64),
        spheremp: wp.array(dtype=f64),
        L: wp.array2d(dtype=f64),
        offset: int,
    ):
        base = (wp.tid() + offset) * NPP
        X0 = vec()  # the four rows of X
        X1 = vec()
        X2 = vec()
        X3 = vec()
        G11 = vec()  # spheremp · Dinv Dinvᵀ (symmetric): the weak Laplacian's metric, once for all rows
        G12 = vec()
        G22 = vec()
        for k in range(NPP):
            q = base + k
            if wp.static(T):
                d = src[0, q] * xyz[0, q] + src[1, q] * xyz[1, q] + src[2, q] * xyz[2, q]
                X0[k] = src[0, q] - d * xyz[0, q]
                X1[k] = src[1, q] - d * xyz[1, q]
                X2[k] = src[2, q] - d * xyz[2, q]
                X3[k] = src[3, q]
            else:
                X0[k] = src[0, q] * east[0, q] + src[1, q] * north[0, q]
                X1[k] = src[0, q] * east[1, q] + src[1, q] * north[1, q]
                X2[k] = src[0, q] * east[2, q] + src[1, q] * north[2, q]
                X3[k] = src[2, q] + hs[q]
            d0 = Dinv[0, q]
            d1 = Dinv[1, q]
            d2 = Dinv[2, q]
            d3 = Dinv[3, q]
            w = spheremp[q]
            G11[k] = w * (d0 * d0 + d1 * d1)
            G12[k] = w * (d0 * d2 + d1 * d3)
            G22[k] = w * (d2 * d2 + d3 * d3)
        lap(X0, G11, G12, G22, L, 0, base)
        lap(X1, G11, G12, G22, L, 1, base)
        lap(X2, G11, G12, G22, L, 2, base)
        lap(X3, G11, G12, G22, L, 3, base)

    kernel.__qualname__ = kernel.__name__ = "laplacian_element__tangent" if T else "laplacian_element__cartesian"
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)


@wp.kernel
def to_cartesian(x: wp.array2d(dtype=f64), hs: wp.array(dtype=f64), east: wp.array2d(dtype=f64), north: wp.array2d(dtype=f64), X: wp.array2d(dtype=f64), offset: int):
    """X[0:3] = u·east + v·north; X[3] = h + hs."""
    p = wp.tid() + offset
    for c in range(3):
        X[c, p] = x[0, p] * east[c, p] + x[1, p] * north[c, p]
    X[3, p] = x[2, p] + hs[p]


@wp.kernel
def project_tangent(X: wp.array2d(dtype=f64), xyz: wp.array2d(dtype=f64), offset: int):
    """X[0:3] −= (X·r̂) r̂: keep the part of the Cartesian vector tangent to the sphere."""
    p = wp.tid() + offset
    d = X[0, p] * xyz[0, p] + X[1, p] * xyz[1, p] + X[2, p] * xyz[2, p]
    for c in range(3):
        X[c, p] = X[c, p] - d * xyz[c, p]


@wp.kernel
def apply(Y: wp.array2d(dtype=f64), coef: f64, east: wp.array2d(dtype=f64), north: wp.array2d(dtype=f64), x: wp.array2d(dtype=f64), block: int, offset: int):
    """x += coef·Y with Y's Cartesian wind taken back to (east, north) components.
    Dim N/block, ``block`` consecutive nodes a thread (as ``blas.axpby``)."""
    start = (wp.tid() + offset) * block
    for p in range(start, start + block):
        ye = f64(0.0)
        yn = f64(0.0)
        for c in range(3):
            ye += Y[c, p] * east[c, p]
            yn += Y[c, p] * north[c, p]
        x[0, p] = x[0, p] + coef * ye
        x[1, p] = x[1, p] + coef * yn
        x[2, p] = x[2, p] + coef * Y[3, p]
