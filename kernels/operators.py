"""Spectral-element operators on the sphere (HOMME ``derivative_mod``).

``gradient_sphere``, ``divergence_sphere``, ``vorticity_sphere`` are the strong
forms (one thread per node, for CUDA; ``gradient_element``,
``divergence_element`` and ``vorticity_element`` are the same for the CPU, one
thread per element, on GLL rows); ``laplace_wk_flux`` + ``laplace_wk_div`` the weak Laplacian
``∫ φ Δf = −∫ ∇φ·∇f`` (HOMME ``laplace_sphere_wk``), which gives the
Laplacian after the DSS. Reference derivatives use ``dvv[i, m] = l_m'(ξ_i)``.
"""

import functools
import os
from typing import Any

import numpy as np
import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})

# SWE_SPHERE_CPU_GENERIC=1: every CPU kernel for Warp's generic target instead of
# -march=native (no FMA, narrower vectors: other round-off, the same results to
# it; the round-off tests' second target). Warp keys its kernel cache on the flags.
if os.environ.get("SWE_SPHERE_CPU_GENERIC", "") not in ("", "0"):
    wp.config.cpu_compiler_flags = ""
# Module options of the CPU per-element kernels: Warp's CPU flags (None: its
# -march=native default) plus FMA contraction (results change at round-off only;
# +15 % on the tendency).
_CPU_FLAGS = "-march=native" if wp.config.cpu_compiler_flags is None else wp.config.cpu_compiler_flags
CPU_FAST = {"cpu_compiler_flags": _CPU_FLAGS + " -ffp-contract=fast"}


@wp.func
def element_node(p: int, np_: int):
    """Node p = e*np*np + j*np + i → (e*np*np, i, j): its element's first index and GLL indices."""
    npp = np_ * np_
    e = p / npp
    k = p - e * npp
    j = k / np_
    return e * npp, k - j * np_, j


@wp.func
def d_xi(f: wp.array2d(dtype=f64), row: int, base: int, i: int, j: int, np_: int, dvv: wp.array2d(dtype=f64)):
    """∂f/∂ξ at node (i, j) of the element starting at ``base``."""
    s = f64(0.0)
    for m in range(np_):
        s += dvv[i, m] * f[row, base + j * np_ + m]
    return s


@wp.func
def d_eta(f: wp.array2d(dtype=f64), row: int, base: int, i: int, j: int, np_: int, dvv: wp.array2d(dtype=f64)):
    """∂f/∂η at node (i, j) of the element starting at ``base``."""
    s = f64(0.0)
    for m in range(np_):
        s += dvv[j, m] * f[row, base + m * np_ + i]
    return s


@wp.func
def vorticity_at(
    x: wp.array2d(dtype=f64),
    p: int,
    np_: int,
    D: wp.array2d(dtype=f64),
    metdet: wp.array(dtype=f64),
    dvv: wp.array2d(dtype=f64),
):
    """Relative vorticity (s⁻¹) at node p of the wind in rows 0, 1 of x:
    ζ = (∂ξ v₂ − ∂η v₁)/metdet with covariant components v_c = Dᵀ v."""
    base, i, j = element_node(p, np_)
    dv2 = f64(0.0)
    dv1 = f64(0.0)
    for m in range(np_):
        q = base + j * np_ + m
        dv2 += dvv[i, m] * (D[1, q] * x[0, q] + D[3, q] * x[1, q])
        q = base + m * np_ + i
        dv1 += dvv[j, m] * (D[0, q] * x[0, q] + D[2, q] * x[1, q])
    return (dv2 - dv1) / metdet[p]


@wp.kernel
def gradient_sphere(
    f: wp.array2d(dtype=f64),
    row: int,
    Dinv: wp.array2d(dtype=f64),
    dvv: wp.array2d(dtype=f64),
    np_: int,
    out: wp.array2d(dtype=f64),
    offset: int,
):
    """out[0:2, p] = ∇f (east, north; units of f per m) = Dinvᵀ (∂ξ f, ∂η f)."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np_)
    a = d_xi(f, row, base, i, j, np_, dvv)
    b = d_eta(f, row, base, i, j, np_, dvv)
    out[0, p] = Dinv[0, p] * a + Dinv[2, p] * b
    out[1, p] = Dinv[1, p] * a + Dinv[3, p] * b


@wp.kernel
def divergence_sphere(
    x: wp.array2d(dtype=f64),
    Dinv: wp.array2d(dtype=f64),
    metdet: wp.array(dtype=f64),
    dvv: wp.array2d(dtype=f64),
    np_: int,
    out: wp.array(dtype=f64),
    offset: int,
):
    """out[p] = ∇·v (s⁻¹) of the wind in rows 0, 1 of x:
    (∂ξ(metdet c¹) + ∂η(metdet c²))/metdet with contravariant c = Dinv v."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np_)
    s = f64(0.0)
    for m in range(np_):
        q = base + j * np_ + m
        s += dvv[i, m] * metdet[q] * (Dinv[0, q] * x[0, q] + Dinv[1, q] * x[1, q])
        q = base + m * np_ + i
        s += dvv[j, m] * metdet[q] * (Dinv[2, q] * x[0, q] + Dinv[3, q] * x[1, q])
    out[p] = s / metdet[p]


@wp.kernel
def vorticity_sphere(
    x: wp.array2d(dtype=f64),
    D: wp.array2d(dtype=f64),
    metdet: wp.array(dtype=f64),
    dvv: wp.array2d(dtype=f64),
    np_: int,
    out: wp.array(dtype=f64),
    offset: int,
):
    """out[p] = k·∇×v (s⁻¹) of the wind in rows 0, 1 of x."""
    p = wp.tid() + offset
    out[p] = vorticity_at(x, p, np_, D, metdet, dvv)


@wp.func
def weak_flux(a: Any, b: Any, Dinv: wp.array2d(dtype=Any), spheremp: wp.array(dtype=Any), p: int):
    """spheremp · Dinv Dinvᵀ (a, b) at node p, (a, b) = (∂ξ f, ∂η f): the quadrature-weighted
    contravariant gradient whose weak divergence (``weak_divergence``) is the weak Laplacian
    (HOMME ``laplace_sphere_wk``); a vector of 2 of the arguments' float type (float64, or a
    float32 ∇⁴'s)."""
    d0 = Dinv[0, p]
    d1 = Dinv[1, p]
    d2 = Dinv[2, p]
    d3 = Dinv[3, p]
    w = spheremp[p]
    gx = d0 * a + d2 * b
    gy = d1 * a + d3 * b
    return wp.vector(w * (d0 * gx + d1 * gy), w * (d2 * gx + d3 * gy))


@wp.kernel
def laplace_wk_flux(
    f: wp.array2d(dtype=f64),
    Dinv: wp.array2d(dtype=f64),
    spheremp: wp.array(dtype=f64),
    dvv: wp.array2d(dtype=f64),
    np_: int,
    flux: wp.array2d(dtype=f64),
    offset: int,
):
    """First half of the weak Laplacian, for every row r of f:
    flux[2r:2r+2, p] = ``weak_flux`` of (∂ξ f, ∂η f). Launch with dim N (each thread
    does every row of its node)."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np_)
    for r in range(f.shape[0]):
        g = weak_flux(d_xi(f, r, base, i, j, np_, dvv), d_eta(f, r, base, i, j, np_, dvv), Dinv, spheremp, p)
        flux[2 * r, p] = g[0]
        flux[2 * r + 1, p] = g[1]


@wp.func
def weak_divergence(flux: wp.array2d(dtype=Any), r: int, dvv: wp.array2d(dtype=Any), np_: int, p: int):
    """The second half of the weak Laplacian of row r at node p = (m, n):
    −Σ_i dvv[i, m] flux¹(i, n) − Σ_j dvv[j, n] flux²(m, j), i.e. −∫ ∇φ_mn·∇f
    over the element (m² × units of f / m²), from ``laplace_wk_flux``'s flux (in its float type:
    float64, or a float32 ∇⁴'s)."""
    base, m, n = element_node(p, np_)
    s = type(flux[r, p])(0.0)
    for q in range(np_):
        s += dvv[q, m] * flux[2 * r, base + n * np_ + q] + dvv[q, n] * flux[2 * r + 1, base + q * np_ + m]
    return -s


@wp.kernel
def laplace_wk_div(
    flux: wp.array2d(dtype=f64), dvv: wp.array2d(dtype=f64), np_: int, out: wp.array2d(dtype=f64), offset: int
):
    """Second half: out[r, p] = ``weak_divergence`` of row r. Launch with dim N
    (each thread does every row of its node)."""
    p = wp.tid() + offset
    for r in range(out.shape[0]):
        out[r, p] = weak_divergence(flux, r, dvv, np_, p)


# -- the CPU layout: an element as np rows of np nodes -------------------------
# One thread per element. Each GLL row j of an element (nodes i = 0..np−1,
# contiguous in memory) is read and written as one ``wp.types.vector(np)``
# through ``row_vectors``' view of the model's (rows, N) arrays, and every
# derivative, metric product and update works on whole rows: the C++ Warp
# generates is then loops over a row's np lanes, which clang turns into packed
# SIMD (vmulpd/vfmadd…pd), where a node at a time through runtime strides
# stayed scalar. The metric work reads its rows the same way (``times``/``over``).


def suffix(dtype) -> str:
    """What a kernel's or function's key adds for its float type: nothing for float64, else
    "_float32" (Warp keys kernels by qualname: one key a type)."""
    return "" if dtype is f64 else f"_{dtype.__name__}"


def keyed(kernel, name: str, dtype):
    """Key a factory's kernel by its name and float type (``suffix``)."""
    kernel.__qualname__ = name + suffix(dtype)
    return kernel


@functools.cache
def row_type(np_: int, dtype=f64):
    """The type of one GLL row of an element: ``wp.types.vector(np, dtype)`` (float64 but in
    the float32 Helmholtz solve)."""
    return wp.types.vector(length=int(np_), dtype=dtype)


def row_vectors(a: wp.array, np_: int) -> wp.array:
    """A zero-copy view of ``a`` ((rows, N) or (N,) float64 or float32, node p = e*np*np + j*np + i,
    unit stride along the nodes) as (rows, N/np) or (N/np,) ``row_type(np, a.dtype)``: entry
    e*np + j is GLL row j of element e. What the CPU element kernels take."""
    np_ = int(np_)
    size = wp.types.type_size_in_bytes(a.dtype)
    if a.dtype not in (f64, wp.float32) or a.strides[-1] != size or a.shape[-1] % np_:
        raise ValueError(
            f"row_vectors needs float64 or float32 with unit node stride and N divisible by np = {np_} (got {a.dtype}, {a.shape}, {a.strides})"
        )
    view = wp.array(
        ptr=a.ptr,
        dtype=row_type(np_, a.dtype),
        shape=(*a.shape[:-1], a.shape[-1] // np_),
        strides=(*a.strides[:-1], size * np_),
        capacity=a.capacity,
        device=a.device,
    )
    view._ref = a  # keeps the memory alive as long as the view
    return view


@wp.func
def times(a: f64, b: f64):
    """The pointwise product of two node values (the per-node kernels' form)."""
    return a * b


@wp.func
def times(a: wp.float32, b: wp.float32):
    """The pointwise product of two float32 node values."""
    return a * b


@wp.func
def times(a: wp.types.vector(length=Any, dtype=f64), b: wp.types.vector(length=Any, dtype=f64)):
    """The pointwise product of two rows of node values (the element kernels' form)."""
    return wp.cw_mul(a, b)


@wp.func
def times(a: wp.types.vector(length=Any, dtype=wp.float32), b: wp.types.vector(length=Any, dtype=wp.float32)):
    """The pointwise product of two float32 rows (the float32 Helmholtz solve's)."""
    return wp.cw_mul(a, b)


@wp.func
def over(a: f64, b: f64):
    """a / b at a node."""
    return a / b


@wp.func
def over(a: wp.float32, b: wp.float32):
    """a / b at a float32 node (a float32 tendency's)."""
    return a / b


@wp.func
def over(a: wp.types.vector(length=Any, dtype=f64), b: wp.types.vector(length=Any, dtype=f64)):
    """a / b on rows of node values, componentwise."""
    return wp.cw_div(a, b)


@wp.func
def over(a: wp.types.vector(length=Any, dtype=wp.float32), b: wp.types.vector(length=Any, dtype=wp.float32)):
    """a / b on float32 rows, componentwise."""
    return wp.cw_div(a, b)


@wp.func
def covariant(D: wp.array2d(dtype=Any), x: wp.array2d(dtype=Any), q: int):
    """The covariant wind (v₁, v₂) = Dᵀ (u, v) at row q of the wind in rows 0, 1 of x, in D's
    float type (x float64 under a float32 tendency: ``ShallowWater``'s precision)."""
    u = type(D[0, q])(x[0, q])
    v = type(D[0, q])(x[1, q])
    return times(D[0, q], u) + times(D[2, q], v), times(D[1, q], u) + times(D[3, q], v)


@wp.func
def covariant_inverse(Dinv: wp.array2d(dtype=Any), metdet: wp.array(dtype=Any), u: Any, v: Any, p: int):
    """The covariant wind (v₁, v₂) = Dᵀ (u, v) at p from D⁻¹ (rows D⁻¹₀₀, D⁻¹₀₁, D⁻¹₁₀, D⁻¹₁₁) and
    metdet = det D (``CubedSphere``'s, to round-off): D = metdet · adj(D⁻¹), so v₁ = metdet
    (D⁻¹₁₁ u − D⁻¹₁₀ v) and v₂ = metdet (D⁻¹₀₀ v − D⁻¹₀₁ u). The float64 tendency's form (the
    rows, the nodes and float64's lanes): D is then not read, 4 of its 13 rows of geometry
    (TC5 ne30 np4 rk4, one thread, load 4: a step 3.83 → 3.47 ms, with a tracer 5.27 → 4.50; the
    tendency alone 414 → 385 µs, with a tracer 556 → 464). ζ's bits move by round-off (metdet ·
    adj(D⁻¹) is D to a few ulps). Generic: scalars, GLL rows or vectors of elements, u, v of the
    arrays' type."""
    J = metdet[p]
    return times(J, times(Dinv[3, p], u) - times(Dinv[2, p], v)), times(J, times(Dinv[0, p], v) - times(Dinv[1, p], u))


@functools.cache
def row_derivatives(np_: int, dtype=f64):
    """The reference derivatives on an element held as rows: F a matrix of np
    ``row_type(np, dtype)`` rows, F[j, i] the value at node (i, j). Returns (row type,
    matrix type, ``along``, ``across``), two ``wp.func`` → a row:

    * ``along(F[j], M)``:  Σ_m M[m] F[j, m] = (F M)[j]  (M's rows scaled by row j's values),
    * ``across(F, j, M)``: Σ_m M[j, m] F[m] = (M F)[j]  (F's rows scaled by M's entries).

    With dvv (``dvv_matrix``; dvv[i, m] = l_m'(ξ_i)): ∂ξ f = along(F[j], dvvᵀ),
    ∂η f = across(F, j, dvv), and their transposes in the weak divergence
    along(F[j], dvv), across(F, j, dvvᵀ). ``along`` takes the row, not F and j: a Warp
    function's arguments are copies, and F indexed by the kernels' run-time row j inside
    it was copied whole (np² values) at every call (np 6 and 8: the tendency 1.2× slower;
    the same sums either way, the same bits at np 4). dvv is a kernel argument, not a
    compile-time constant: with its entries compiled in, clang folded them lane
    by lane (zeros, ±1, the GLL symmetries), the lanes of a row no longer did
    the same work, and the weak Laplacian stayed half scalar (2–2.5× slower a
    field, measured at np 4)."""
    NP = int(np_)
    vec = row_type(NP, dtype)
    mat = wp.types.matrix(shape=(NP, NP), dtype=dtype)

    def along(Fj: vec, M: mat):
        s = vec()
        for m in range(NP):
            s += M[m] * Fj[m]
        return s

    def across(F: mat, j: int, M: mat):
        s = vec()
        for m in range(NP):
            s += M[j, m] * F[m]
        return s

    funcs = []
    for f in (along, across):
        f.__qualname__ = f.__name__ = f"{f.__name__}_np{NP}" + suffix(dtype)
        funcs.append(wp.func(f))
    return (vec, mat, *funcs)


def across_as_along(np_: int) -> bool:
    """Whether the element kernels at this np form (M F)[j] as ``along(M[j], F)``, the same
    products (commuted) summed in the same order as ``across(F, j, M)``, in loops over the
    rows with a run-time start: np ≥ 5. ``across`` takes M whole and indexes it by the
    run-time j, so M was copied at every call (measured at ne12, one thread: the np 8
    tendency 13.7 → 11.4 ns a point, the ∇⁴'s weak Laplacians 56 → 39 and 61 → 47). At
    np 4 ``across`` and unrolled rows stay: clang vectorizes the other form differently and
    contracts other products into FMAs, which changes the frozen np 4 bits. Unrolled, np 6's
    weak Laplacian without ∇δ also came out wrong on the CPU (the ∇⁴ of TC5 2e5 × the per-node
    layout's; the compiler's or Warp's doing, not found;
    tests/model/test_operators.py::test_hyperviscosity_rates_at_high_np)."""
    return int(np_) > 4


def across_layout(a, lanes: int, np_: int, pad: bool = False):
    """The across layout (the element index innermost: ``hyperviscosity_across.laplacian_across``,
    ``tendency_lanes.tendency_across``) of a (rows, N) numpy array of element-local values:
    (rows, nb np², W), [k, b np² + n, w] = a[k, (W b + w) np² + n], over the nb = ⌊nelem/W⌋
    whole blocks of W = ``lanes`` elements, or with ``pad`` the ⌈nelem/W⌉ blocks, the last one's
    lanes past the last element holding that element's values."""
    rows, nn, W = a.shape[0], int(np_) ** 2, int(lanes)
    nelem = a.shape[1] // nn
    nb = -(-nelem // W) if pad else nelem // W
    e = np.minimum(np.arange(nb * W), nelem - 1)
    t = a.reshape(rows, nelem, nn)[:, e].reshape(rows, nb, W, nn)
    return t.transpose(0, 1, 3, 2).reshape(rows, nb * nn, W).copy()


def _transpose16_snippet() -> str:
    """The C++ of ``transpose16``: on the CPU 16 loads, the 16 × 16 transpose as four rounds of
    16 two-vector shuffles (round s swaps bit s of the row and the column index: rows i and
    i + 2^s exchange their off-diagonal 2^s-blocks), ``count`` stores; on CUDA (where the lanes do
    not run, but every module compiles to PTX) a value at a time."""
    names = [f"a{w}" for w in range(16)]
    lines = [
        "#if defined(__CUDA_ARCH__)",
        "for (int n = 0; n < count; ++n) {",
        "    wp::vec_t<16, wp::float32> b;",
        "    for (int w = 0; w < 16; ++w)",
        "        b.c[w] = wp::index(src, r, first + w * stride < last ? first + w * stride : last).c[n];",
        "    wp::index(dst, dr, dfirst + n * dstride) = b;",
        "}",
        "#else",
        "typedef float v16 __attribute__((ext_vector_type(16)));",
    ]
    for w, a in enumerate(names):
        lines.append(
            f"v16 {a}; __builtin_memcpy(&{a}, &wp::index(src, r, first + {w} * stride < last ? first + {w} * stride : last), 64);"
        )
    for bit in range(4):
        s = 1 << bit
        for i in range(16):
            if i & s:
                continue
            lo = [j if not j & s else 16 + j - s for j in range(16)]
            hi = [j + s if not j & s else 16 + j for j in range(16)]
            lines.append(f"{{ v16 t = __builtin_shufflevector(a{i}, a{i + s}, {', '.join(map(str, lo))});")
            lines.append(
                f"  a{i + s} = __builtin_shufflevector(a{i}, a{i + s}, {', '.join(map(str, hi))}); a{i} = t; }}"
            )
    for n, a in enumerate(names):
        lines.append(f"if ({n} < count) __builtin_memcpy(&wp::index(dst, dr, dfirst + {n} * dstride), &{a}, 64);")
    lines.append("#endif")
    return "\n".join(lines) + "\n"  # the #endif on a line of its own


_vec16f = wp.types.vector(length=16, dtype=wp.float32)


@wp.func_native(_transpose16_snippet())
def transpose16(
    src: wp.array2d(dtype=_vec16f),
    r: int,
    first: int,
    last: int,
    stride: int,
    dst: wp.array2d(dtype=_vec16f),
    dr: int,
    dfirst: int,
    dstride: int,
    count: int,
):
    """dst[dr, dfirst + n·dstride][w] = src[r, min(first + w·stride, last)][n] for w < 16 and
    n < ``count``: 16 vectors of 16 float32 transposed, in registers on the CPU (clang's vector
    shuffles, whatever the target's width) where a value at a time went through memory. What
    moves an element block's rows between the node layout and the across layout
    (``tendency_lanes.tendency_across``; the strides step over an element's np²/16 vectors of 16 at
    np 8)."""
    ...


def dvv_matrix(dvv, dtype=f64) -> object:
    """The derivative matrix dvv (np × np, dvv[i, m] = l_m'(ξ_i)) as the value the
    element kernels take (``row_derivatives``' matrix type, of ``dtype``)."""
    rows = [[float(a) for a in row] for row in dvv]
    return row_derivatives(len(rows), dtype)[1](*[a for row in rows for a in row])


@functools.cache
def gradient_element(np_: int):
    """``gradient_sphere`` with one thread per element: out[0:2] = ∇ f[row].
    Arguments (``row_vectors`` views): f (rows, N/np), row, Dinv (4, N/np), dvv
    (``dvv_matrix``), out (2, N/np), offset (in elements). Dim nelem."""
    vec, mat, along, across = row_derivatives(np_)
    NP = int(np_)

    def gradient_element(
        f: wp.array2d(dtype=vec),
        row: int,
        Dinv: wp.array2d(dtype=vec),
        dvv: mat,
        out: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        F = mat()
        for j in range(NP):
            F[j] = f[row, base + j]
        for j in range(NP):
            a = along(F[j], dvvT)
            b = across(F, j, dvv)
            q = base + j
            out[0, q] = times(Dinv[0, q], a) + times(Dinv[2, q], b)
            out[1, q] = times(Dinv[1, q], a) + times(Dinv[3, q], b)

    gradient_element.__qualname__ = "gradient_element"  # the kernel's key
    return wp.kernel(gradient_element, enable_backward=False, module="unique", module_options=CPU_FAST)


@functools.cache
def divergence_element(np_: int):
    """``divergence_sphere`` with one thread per element: out = ∇·v (s⁻¹) of the
    wind in rows 0, 1 of x. Arguments (``row_vectors`` views): x (rows, N/np),
    M = Dinv (4, N/np), metdet (N/np), dvv (``dvv_matrix``), out (N/np), offset
    (in elements). Dim nelem."""
    return _wind_element(np_, curl=False)


@functools.cache
def vorticity_element(np_: int):
    """``vorticity_sphere`` with one thread per element: out = k·∇×v (s⁻¹) of the
    wind in rows 0, 1 of x. Arguments as ``divergence_element``'s, with M = D (4, N/np)."""
    return _wind_element(np_, curl=True)


def _wind_element(np_: int, curl: bool):
    """The divergence (metdet c¹, metdet c² from the contravariant c = Dinv v;
    (∂ξ(metdet c¹) + ∂η(metdet c²))/metdet) or the vorticity (the covariant
    (v₁, v₂) = Dᵀ v; (∂ξ v₂ − ∂η v₁)/metdet) of an element's rows."""
    vec, mat, along, across = row_derivatives(np_)
    NP, CURL = int(np_), bool(curl)

    def kernel(
        x: wp.array2d(dtype=vec),
        M: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        dvv: mat,
        out: wp.array(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        fx = mat()  # differentiated along ξ (metdet c¹, or v₂) and along η (metdet c², or −v₁)
        fy = mat()
        for j in range(NP):
            q = base + j
            if wp.static(CURL):
                v1, v2 = covariant(M, x, q)
                fx[j] = v2
                fy[j] = -v1
            else:
                fx[j] = times(metdet[q], times(M[0, q], x[0, q]) + times(M[1, q], x[1, q]))
                fy[j] = times(metdet[q], times(M[2, q], x[0, q]) + times(M[3, q], x[1, q]))
        for j in range(NP):
            q = base + j
            out[q] = over(along(fx[j], dvvT) + across(fy, j, dvv), metdet[q])

    kernel.__qualname__ = kernel.__name__ = "vorticity_element" if CURL else "divergence_element"  # the kernel's key
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
