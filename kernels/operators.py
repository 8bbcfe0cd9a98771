"""Spectral-element operators on the sphere (HOMME ``derivative_mod``).

``gradient_sphere``, ``divergence_sphere``, ``vorticity_sphere`` are the strong
forms (one thread per node, for CUDA; ``gradient_element`` and
``divergence_element`` are the same for the CPU, one thread per element); ``laplace_wk_flux`` + ``laplace_wk_div`` the weak Laplacian
``∫ φ Δf = −∫ ∇φ·∇f`` (HOMME ``laplace_sphere_wk``), which gives the
Laplacian after the DSS. Reference derivatives use ``dvv[i, m] = l_m'(ξ_i)``.
"""

import functools

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})

# Module options of the CPU per-element kernels: Warp's CPU flags plus FMA
# contraction (results change at round-off only; +15 % on the tendency).
CPU_FAST = {"cpu_compiler_flags": (wp.config.cpu_compiler_flags or "-march=native") + " -ffp-contract=fast"}


@wp.func
def element_node(p: int, np: int):
    """Node p = e*np*np + j*np + i → (e*np*np, i, j): its element's first index and GLL indices."""
    npp = np * np
    e = p / npp
    k = p - e * npp
    j = k / np
    return e * npp, k - j * np, j


@wp.func
def d_xi(f: wp.array2d(dtype=f64), row: int, base: int, i: int, j: int, np: int, dvv: wp.array2d(dtype=f64)):
    """∂f/∂ξ at node (i, j) of the element starting at ``base``."""
    s = f64(0.0)
    for m in range(np):
        s += dvv[i, m] * f[row, base + j * np + m]
    return s


@wp.func
def d_eta(f: wp.array2d(dtype=f64), row: int, base: int, i: int, j: int, np: int, dvv: wp.array2d(dtype=f64)):
    """∂f/∂η at node (i, j) of the element starting at ``base``."""
    s = f64(0.0)
    for m in range(np):
        s += dvv[j, m] * f[row, base + m * np + i]
    return s


@wp.func
def vorticity_at(x: wp.array2d(dtype=f64), p: int, np: int, D: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64)):
    """Relative vorticity (s⁻¹) at node p of the wind in rows 0, 1 of x:
    ζ = (∂ξ v₂ − ∂η v₁)/metdet with covariant components v_c = Dᵀ v."""
    base, i, j = element_node(p, np)
    dv2 = f64(0.0)
    dv1 = f64(0.0)
    for m in range(np):
        q = base + j * np + m
        dv2 += dvv[i, m] * (D[1, q] * x[0, q] + D[3, q] * x[1, q])
        q = base + m * np + i
        dv1 += dvv[j, m] * (D[0, q] * x[0, q] + D[2, q] * x[1, q])
    return (dv2 - dv1) / metdet[p]


@wp.kernel
def gradient_sphere(f: wp.array2d(dtype=f64), row: int, Dinv: wp.array2d(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, out: wp.array2d(dtype=f64), offset: int):
    """out[0:2, p] = ∇f (east, north; units of f per m) = Dinvᵀ (∂ξ f, ∂η f)."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np)
    a = d_xi(f, row, base, i, j, np, dvv)
    b = d_eta(f, row, base, i, j, np, dvv)
    out[0, p] = Dinv[0, p] * a + Dinv[2, p] * b
    out[1, p] = Dinv[1, p] * a + Dinv[3, p] * b


@wp.kernel
def divergence_sphere(x: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, out: wp.array(dtype=f64), offset: int):
    """out[p] = ∇·v (s⁻¹) of the wind in rows 0, 1 of x:
    (∂ξ(metdet c¹) + ∂η(metdet c²))/metdet with contravariant c = Dinv v."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np)
    s = f64(0.0)
    for m in range(np):
        q = base + j * np + m
        s += dvv[i, m] * metdet[q] * (Dinv[0, q] * x[0, q] + Dinv[1, q] * x[1, q])
        q = base + m * np + i
        s += dvv[j, m] * metdet[q] * (Dinv[2, q] * x[0, q] + Dinv[3, q] * x[1, q])
    out[p] = s / metdet[p]


@wp.kernel
def vorticity_sphere(x: wp.array2d(dtype=f64), D: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, out: wp.array(dtype=f64), offset: int):
    """out[p] = k·∇×v (s⁻¹) of the wind in rows 0, 1 of x."""
    p = wp.tid() + offset
    out[p] = vorticity_at(x, p, np, D, metdet, dvv)


@wp.kernel
def laplace_wk_flux(f: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), spheremp: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, flux: wp.array2d(dtype=f64), offset: int):
    """First half of the weak Laplacian, for every row r of f:
    flux[2r:2r+2, p] = spheremp · Dinv Dinvᵀ (∂ξ f, ∂η f), the quadrature-weighted
    contravariant gradient. Launch with dim N (each thread does every row of its node)."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np)
    d0 = Dinv[0, p]
    d1 = Dinv[1, p]
    d2 = Dinv[2, p]
    d3 = Dinv[3, p]
    w = spheremp[p]
    for r in range(f.shape[0]):
        a = d_xi(f, r, base, i, j, np, dvv)
        b = d_eta(f, r, base, i, j, np, dvv)
        gx = d0 * a + d2 * b
        gy = d1 * a + d3 * b
        flux[2 * r, p] = w * (d0 * gx + d1 * gy)
        flux[2 * r + 1, p] = w * (d2 * gx + d3 * gy)


@wp.func
def weak_divergence(flux: wp.array2d(dtype=f64), r: int, dvv: wp.array2d(dtype=f64), np: int, p: int):
    """The second half of the weak Laplacian of row r at node p = (m, n):
    −Σ_i dvv[i, m] flux¹(i, n) − Σ_j dvv[j, n] flux²(m, j), i.e. −∫ ∇φ_mn·∇f
    over the element (m² × units of f / m²), from ``laplace_wk_flux``'s flux."""
    base, m, n = element_node(p, np)
    s = f64(0.0)
    for q in range(np):
        s += dvv[q, m] * flux[2 * r, base + n * np + q] + dvv[q, n] * flux[2 * r + 1, base + q * np + m]
    return -s


@wp.kernel
def laplace_wk_div(flux: wp.array2d(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, out: wp.array2d(dtype=f64), offset: int):
    """Second half: out[r, p] = ``weak_divergence`` of row r. Launch with dim N
    (each thread does every row of its node)."""
    p = wp.tid() + offset
    for r in range(out.shape[0]):
        out[r, p] = weak_divergence(flux, r, dvv, np, p)


def dvv_constant(dvv: tuple):
    """``dvv`` (np rows of np values) as a compile-time constant matrix."""
    n = len(dvv)
    return wp.constant(wp.types.matrix(shape=(n, n), dtype=f64)(*[float(a) for row in dvv for a in row]))


@functools.cache
def reference_gradient(dvv: tuple):
    """A ``wp.func`` (v, i, j) → (∂ξ v, ∂η v) at node (i, j) of an element's
    values v (a vector of np² in element order), ``dvv`` compiled in."""
    NP = len(dvv)
    DVV = dvv_constant(dvv)
    vec = wp.types.vector(length=NP * NP, dtype=f64)

    def reference_gradient(v: vec, i: int, j: int):
        a = f64(0.0)
        b = f64(0.0)
        for m in range(NP):
            a += DVV[i, m] * v[j * NP + m]
            b += DVV[j, m] * v[m * NP + i]
        return a, b

    reference_gradient.__qualname__ = reference_gradient.__name__ = f"reference_gradient_np{NP}"
    return wp.func(reference_gradient)


@functools.cache
def reference_divergence(dvv: tuple):
    """A ``wp.func`` (f1, f2, i, j) → ∂ξ f1 + ∂η f2 at node (i, j) of an element's
    values (vectors of np² in element order), ``dvv`` compiled in."""
    NP = len(dvv)
    DVV = dvv_constant(dvv)
    vec = wp.types.vector(length=NP * NP, dtype=f64)

    def reference_divergence(f1: vec, f2: vec, i: int, j: int):
        s = f64(0.0)
        for m in range(NP):
            s += DVV[i, m] * f1[j * NP + m] + DVV[j, m] * f2[m * NP + i]
        return s

    reference_divergence.__qualname__ = reference_divergence.__name__ = f"reference_divergence_np{NP}"
    return wp.func(reference_divergence)


@functools.cache
def gradient_element(dvv: tuple):
    """``gradient_sphere`` with one thread per element and ``dvv`` compiled in:
    out[0:2] = ∇ f[row]. Arguments: f, row, Dinv, out, offset (in elements). Dim nelem."""
    NP = len(dvv)
    NPP = NP * NP
    grad = reference_gradient(dvv)
    vec = wp.types.vector(length=NPP, dtype=f64)

    def gradient_element(f: wp.array2d(dtype=f64), row: int, Dinv: wp.array2d(dtype=f64), out: wp.array2d(dtype=f64), offset: int):
        base = (wp.tid() + offset) * NPP
        v = vec()
        for k in range(NPP):
            v[k] = f[row, base + k]
        for j in range(NP):
            for i in range(NP):
                a, b = grad(v, i, j)
                p = base + j * NP + i
                out[0, p] = Dinv[0, p] * a + Dinv[2, p] * b
                out[1, p] = Dinv[1, p] * a + Dinv[3, p] * b

    gradient_element.__qualname__ = "gradient_element"  # the kernel's key
    return wp.kernel(gradient_element, enable_backward=False, module="unique", module_options=CPU_FAST)


@functools.cache
def divergence_element(dvv: tuple):
    """``divergence_sphere`` with one thread per element and ``dvv`` compiled in:
    out = ∇·v of the wind in rows 0, 1 of x. Arguments: x, Dinv, metdet, out (N),
    offset (in elements). Dim nelem."""
    NP = len(dvv)
    NPP = NP * NP
    div = reference_divergence(dvv)
    vec = wp.types.vector(length=NPP, dtype=f64)

    def divergence_element(x: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64), out: wp.array(dtype=f64), offset: int):
        base = (wp.tid() + offset) * NPP
        f1 = vec()  # metdet c¹, metdet c²
        f2 = vec()
        for k in range(NPP):
            q = base + k
            f1[k] = metdet[q] * (Dinv[0, q] * x[0, q] + Dinv[1, q] * x[1, q])
            f2[k] = metdet[q] * (Dinv[2, q] * x[0, q] + Dinv[3, q] * x[1, q])
        for j in range(NP):
            for i in range(NP):
                p = base + j * NP + i
                out[p] = div(f1, f2, i, j) / metdet[p]

    divergence_element.__qualname__ = "divergence_element"  # the kernel's key
    return wp.kernel(divergence_element, enable_backward=False, module="unique", module_options=CPU_FAST)
