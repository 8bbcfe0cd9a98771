"""The linear gravity-wave operator about a mean depth H in one element pass (``linear``,
``linear_element``: both halves before their DSS; ``model.gravity_wave.GravityWaveOperator``):
L_v = −g G h, L_h = −H D v, with G = DSS∘grad and D = DSS∘div the model's strong
operators, and the two pointwise halves of the Schur-complement solve of (I − aL) z = s·r
(``model.helmholtz.HelmholtzSolver``):

    (I − a²gH DG) z_h = s (r_h − aH D r_v),    z_v = s r_v − a g G z_h,

the latter also writing L z = (z − s r)/a for an IMEX stage (``schur_wind_implicit``).

Dim (3, N/block) with trailing ``block`` and ``offset``, as ``blas.axpby``.
"""

import functools

import warp as wp

from .operators import CPU_FAST, d_eta, d_xi, element_node, over, row_derivatives, times

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def linear(
    x: wp.array2d(dtype=f64),
    Dinv: wp.array2d(dtype=f64),
    metdet: wp.array(dtype=f64),
    dvv: wp.array2d(dtype=f64),
    np_: int,
    g: f64,
    H: f64,
    out: wp.array2d(dtype=f64),
    offset: int,
):
    """out[:, p] = (−g ∇h, −H ∇·v) element-local at node p of x = (u, v, h) (one thread a
    node, for CUDA): ``operators.gradient_sphere`` of row 2 and ``divergence_sphere`` of
    rows 0, 1 in one pass, each before its DSS. Dim N."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np_)
    a = d_xi(x, 2, base, i, j, np_, dvv)
    b = d_eta(x, 2, base, i, j, np_, dvv)
    div = f64(0.0)
    for m in range(np_):
        q = base + j * np_ + m  # along ξ through (i, j)
        r = base + m * np_ + i  # along η
        div += dvv[i, m] * metdet[q] * (Dinv[0, q] * x[0, q] + Dinv[1, q] * x[1, q])
        div += dvv[j, m] * metdet[r] * (Dinv[2, r] * x[0, r] + Dinv[3, r] * x[1, r])
    out[0, p] = -g * (Dinv[0, p] * a + Dinv[2, p] * b)
    out[1, p] = -g * (Dinv[1, p] * a + Dinv[3, p] * b)
    out[2, p] = -H * div / metdet[p]


@functools.cache
def linear_element(np_: int):
    """``linear`` with one thread per element, on GLL rows (``operators.row_vectors``
    views), for the CPU: x (3, N/np), Dinv (4, N/np), metdet (N/np), g, H, dvv
    (``operators.dvv_matrix``), out (3, N/np), offset (in elements). Dim nelem."""
    vec, mat, along, across = row_derivatives(np_)
    NP = int(np_)

    def linear_element(
        x: wp.array2d(dtype=vec),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        g: f64,
        H: f64,
        dvv: mat,
        out: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        h = mat()  # the depth, and metdet c¹, metdet c² (the contravariant wind c = Dinv v)
        f1 = mat()
        f2 = mat()
        for j in range(NP):
            q = base + j
            h[j] = x[2, q]
            f1[j] = times(metdet[q], times(Dinv[0, q], x[0, q]) + times(Dinv[1, q], x[1, q]))
            f2[j] = times(metdet[q], times(Dinv[2, q], x[0, q]) + times(Dinv[3, q], x[1, q]))
        for j in range(NP):
            q = base + j
            a = along(h[j], dvvT)
            b = across(h, j, dvv)
            out[0, q] = -g * (times(Dinv[0, q], a) + times(Dinv[2, q], b))
            out[1, q] = -g * (times(Dinv[1, q], a) + times(Dinv[3, q], b))
            out[2, q] = -H * over(along(f1[j], dvvT) + across(f2, j, dvv), metdet[q])

    linear_element.__qualname__ = "linear_element"  # the kernel's key
    return wp.kernel(linear_element, enable_backward=False, module="unique", module_options=CPU_FAST)


@wp.kernel
def schur_height(
    rhs: wp.array2d(dtype=f64),
    Dr: wp.array2d(dtype=f64),
    s: f64,
    aH: f64,
    z: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """z_h = s (r_h − aH D r_v): the Helmholtz right-hand side (row 2 only)."""
    r, k = wp.tid()
    if r == 2:
        start = (k + offset) * block
        for p in range(start, start + block):
            z[2, p] = s * (rhs[2, p] - aH * Dr[0, p])


@wp.kernel
def schur_wind(
    rhs: wp.array2d(dtype=f64),
    Gz: wp.array2d(dtype=f64),
    s: f64,
    ag: f64,
    z: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """z_v = s r_v − a g G z_h (rows 0, 1 only)."""
    r, k = wp.tid()
    if r < 2:
        start = (k + offset) * block
        for p in range(start, start + block):
            z[r, p] = s * rhs[r, p] - ag * Gz[r, p]


@wp.kernel
def schur_wind_implicit(
    rhs: wp.array2d(dtype=f64),
    Gz: wp.array2d(dtype=f64),
    s: f64,
    ag: f64,
    z: wp.array2d(dtype=f64),
    ia: f64,
    mis: f64,
    lz: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """``schur_wind`` (z_v = s r_v − a g G z_h; z_h already in row 2), and lz = L z = (z − s r)/a
    as ia·z + mis·r (ia = 1/a, mis = −s/a: ``blas.axpby``'s bits) in all rows: an IMEX stage's
    implicit tendency with no pass of its own. lz may alias rhs, not z."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        rp = rhs[r, p]
        zp = z[2, p]
        if r < 2:
            zp = s * rp - ag * Gz[r, p]
            z[r, p] = zp
        lz[r, p] = ia * zp + mis * rp
