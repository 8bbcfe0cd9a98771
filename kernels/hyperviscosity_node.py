"""The ∇⁴'s weak Laplacians on CUDA, a thread a node: ``laplacian_flux``, the flux pass before
each weak Laplacian (the first forming the Cartesian wind as it reads the state), and
``laplacian_node``, its weak divergence and pointwise part (``hyperviscosity``'s module
docstring: six passes)."""

import functools
from typing import Any

import warp as wp

from .hyperviscosity import add_divergent, frame_type, scale_first, shift_second
from .operators import d_eta, d_xi, element_node, suffix, weak_divergence, weak_flux

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


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

    def value(src: wp.array2d(dtype=Any), hs: wp.array(dtype=f64), f: NodeFrame, n: int):
        X = v4()
        if wp.static(CART):  # src the state: float64, or a float32 one's u, v, h − H₀ (H₀ 0: ``model.held``)
            for c in range(3):
                X[c] = dtype(src[0, n]) * f.east[c, n] + dtype(src[1, n]) * f.north[c, n]
            if wp.static(SHIFT):  # h + hs − H₀ formed in float64 before it is rounded
                X[3] = dtype(f64(src[2, n]) + hs[n] - f.h0)
            else:
                X[3] = f64(src[2, n]) + hs[n]
        else:
            for r in range(4):
                X[r] = dtype(src[r, n])
        return X

    value.__qualname__ = value.__name__ = f"hv_source__{'cartesian' if CART else 'rows'}" + suffix(dtype)
    source = wp.func(value)

    def kernel(
        src: wp.array2d(dtype=Any if CART else f64),  # the state (of any float type), or Y₁
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
