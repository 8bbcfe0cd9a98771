"""The Helmholtz operator M + cK on unique nodes, matrix-free (``model.helmholtz.HelmholtzSolver``;
the preconditioned CG that inverts it is ``helmholtz_cg``'s).

K = −M D G with G = DSS∘grad and D = DSS∘div the model's strong operators;
on unique nodes, with P the scatter to element-local copies, W = diag(spheremp)
and S the weighted DSS, (M + cK) y = Pᵀ W (P y − c D̂ S Ĝ P y). Three launches
(and the halo exchanges between them over MPI ranks):

* ``helmholtz_gradient``: per element, y gathered from its unique nodes, the
  element gradient Ĝ P y, stored mass-weighted (spheremp·∇y) for the DSS;
* ``helmholtz_divergence``: per element, each node's DSS of that gradient
  (a gather over the node's copies in the global order, as ``dss.dss_rows``:
  the same bits on any number of ranks and threads), then the element
  divergence and z = P y − c D̂ S Ĝ P y;
* ``helmholtz_assemble`` of W z: Pᵀ W z.

Around a solve of the semi-implicit Schur complement (``HelmholtzSolver``), in the same
layout: ``helmholtz_rhs`` (with ``helmholtz_assemble``) builds its right-hand side,
and ``helmholtz_gradient`` with ``helmholtz_back_substitution`` the state from its
solution (and, for an IMEX stage, its implicit tendency L z).

The kernels made for a float type (the factories' ``dtype``) are keyed by ``operators.keyed``;
``helmholtz_cg``'s share it.
"""

import functools

import warp as wp

from .operators import CPU_FAST, keyed, over, row_derivatives, times

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@functools.cache
def gathers(dtype=f64):
    """(``copy_at``, ``unique_value``) reading ``dtype`` vectors and the float64 exchange buffers:

    * copy_at(x, r, ghost, c, nlocal): row r of copy c, x[r, c] if local (c < nlocal), else
      another process's, from ``ghost`` in ``dss.pack``'s layout (x.shape[0] rows an entry);
    * unique_value(y, halo, g): entry g of the unique-node vector y, or of ``halo`` (the
      owners' values) for g ≥ len(y).

    The exchanges stay float64 whatever the solve's type (``dss.pack`` converts)."""
    suffix = "" if dtype is f64 else f"_{dtype.__name__}"

    def copy_at(x: wp.array2d(dtype=dtype), r: int, ghost: wp.array(dtype=f64), c: int, nlocal: int):
        if c >= nlocal:
            return dtype(ghost[(c - nlocal) * x.shape[0] + r])
        return x[r, c]

    def unique_value(y: wp.array(dtype=dtype), halo: wp.array(dtype=f64), g: int):
        n = y.shape[0]
        if g < n:
            return y[g]
        return dtype(halo[g - n])

    funcs = []
    for f in (copy_at, unique_value):
        f.__qualname__ = f.__name__ = f.__name__ + suffix
        funcs.append(wp.func(f))
    return tuple(funcs)


@functools.cache
def gathered(np_: int, copies: int, dtype=f64):
    """A ``wp.func`` (wg, ghost, nlocal, table, rspheremp, y, halo, gid, base) → (gx, gy, Y),
    ``np``×``np`` matrices over the element whose GLL row j is entry base + j: the DSS of rows
    0, 1 of the mass-weighted wg (rspheremp[p] · Σ over the copies in ``table`` row p, the
    global order, −1-padded, ``copies`` columns; a copy ≥ nlocal read from ``ghost``,
    ``copy_at``: every copy of a node gets the same bits, as ``dss.gather``) and the
    unique-node y through gid (``unique_value``)."""
    NP, C = int(np_), int(copies)
    _, mat, _, _ = row_derivatives(NP, dtype)
    copy_at, unique_value = gathers(dtype)

    def gathered(
        wg: wp.array2d(dtype=dtype),
        ghost: wp.array(dtype=f64),
        nlocal: int,
        table: wp.array2d(dtype=wp.int32),
        rspheremp: wp.array(dtype=dtype),
        y: wp.array(dtype=dtype),
        halo: wp.array(dtype=f64),
        gid: wp.array(dtype=wp.int32),
        base: int,
    ):
        gx = mat()
        gy = mat()
        Y = mat()
        for j in range(NP):
            for i in range(NP):
                p = (base + j) * NP + i
                s0 = dtype(0.0)
                s1 = dtype(0.0)
                for m in range(C):
                    cp = table[p, m]
                    if cp >= 0:
                        s0 += copy_at(wg, 0, ghost, cp, nlocal)
                        s1 += copy_at(wg, 1, ghost, cp, nlocal)
                rs = rspheremp[p]
                gx[j, i] = rs * s0
                gy[j, i] = rs * s1
                Y[j, i] = unique_value(y, halo, gid[p])
        return gx, gy, Y

    gathered.__qualname__ = gathered.__name__ = f"gathered_{NP}_{C}" + ("" if dtype is f64 else f"_{dtype.__name__}")
    return wp.func(gathered)


@functools.cache
def scaled_divergence(np_: int, dtype=f64):
    """A ``wp.func`` (u, v, Dinv, metdet, base, dvv, k) → k·∇·(u, v) = k·(∂ξ(metdet c¹) +
    ∂η(metdet c²))/metdet, c = Dinv (u, v) contravariant (``operators.divergence_element``'s
    form), the ``np``×``np`` matrix over the element whose GLL row j is entry base + j; k (the
    caller's factor) is applied before the division, as the Helmholtz kernels always have."""
    NP = int(np_)
    vec, mat, along, across = row_derivatives(NP, dtype)

    def scaled_divergence(
        u: mat, v: mat, Dinv: wp.array2d(dtype=vec), metdet: wp.array(dtype=vec), base: int, dvv: mat, k: dtype
    ):
        dvvT = wp.transpose(dvv)
        f1 = mat()  # metdet c¹, metdet c²
        f2 = mat()
        for j in range(NP):
            q = base + j
            f1[j] = times(metdet[q], times(Dinv[0, q], u[j]) + times(Dinv[1, q], v[j]))
            f2[j] = times(metdet[q], times(Dinv[2, q], u[j]) + times(Dinv[3, q], v[j]))
        d = mat()
        for j in range(NP):
            d[j] = over(k * (along(f1[j], dvvT) + across(f2, j, dvv)), metdet[base + j])
        return d

    scaled_divergence.__qualname__ = scaled_divergence.__name__ = f"scaled_divergence_{NP}" + (
        "" if dtype is f64 else f"_{dtype.__name__}"
    )
    return wp.func(scaled_divergence)


@functools.cache
def helmholtz_gradient(np_: int, dtype=f64):
    """Per element: wg[0:2] = spheremp·∇y at its nodes (m² × units of y / m),
    y a unique-node vector read through gid (gid[p] ≥ nunique: from ``halo``,
    the owners' values, as ``dss.scatter``). Arguments: y, halo, gid (N), and as
    ``operators.row_vectors`` views Dinv (4, N/np), spheremp (N/np); dvv
    (``operators.dvv_matrix``); wg (2, N/np) (a view); offset (elements). Dim nelem."""
    vec, mat, along, across = row_derivatives(np_, dtype)
    _, unique_value = gathers(dtype)
    NP = int(np_)

    def helmholtz_gradient(
        y: wp.array(dtype=dtype),
        halo: wp.array(dtype=f64),
        gid: wp.array(dtype=wp.int32),
        Dinv: wp.array2d(dtype=vec),
        spheremp: wp.array(dtype=vec),
        dvv: mat,
        wg: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        F = mat()
        for j in range(NP):
            for i in range(NP):
                F[j, i] = unique_value(y, halo, gid[(base + j) * NP + i])
        for j in range(NP):
            a = along(F[j], dvvT)
            b = across(F, j, dvv)
            q = base + j
            w = spheremp[q]
            wg[0, q] = times(w, times(Dinv[0, q], a) + times(Dinv[2, q], b))
            wg[1, q] = times(w, times(Dinv[1, q], a) + times(Dinv[3, q], b))

    return wp.kernel(
        keyed(helmholtz_gradient, "helmholtz_gradient", dtype),
        enable_backward=False,
        module="unique",
        module_options=CPU_FAST,
    )


@functools.cache
def helmholtz_divergence(np_: int, copies: int, dtype=f64):
    """Per element: z[0] = spheremp·(y − c·(D̂ S wg)) at its nodes, S the DSS (Σ over the copies of
    a node of wg, times rspheremp; a copy ≥ nlocal read from ``ghost``, ``copy_at``), y read as in
    ``helmholtz_gradient``. Arguments: wg (2, N), ghost, nlocal, table, rspheremp (N), y,
    halo, gid (N), and as ``operators.row_vectors`` views Dinv (4, N/np), metdet,
    spheremp (N/np); dvv (``operators.dvv_matrix``); c (m²); z (1, N/np) (a view),
    offset (elements). Dim nelem."""
    NP = int(np_)
    vec, mat, _, _ = row_derivatives(NP, dtype)
    gather, divergence = gathered(NP, copies, dtype), scaled_divergence(NP, dtype)

    def helmholtz_divergence(
        wg: wp.array2d(dtype=dtype),
        ghost: wp.array(dtype=f64),
        nlocal: int,
        table: wp.array2d(dtype=wp.int32),
        rspheremp: wp.array(dtype=dtype),
        y: wp.array(dtype=dtype),
        halo: wp.array(dtype=f64),
        gid: wp.array(dtype=wp.int32),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        spheremp: wp.array(dtype=vec),
        dvv: mat,
        c: dtype,
        z: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        gx, gy, Y = gather(wg, ghost, nlocal, table, rspheremp, y, halo, gid, base)  # the DSS'd gradient, y
        d = divergence(gx, gy, Dinv, metdet, base, dvv, c)
        for j in range(NP):
            q = base + j
            z[0, q] = times(spheremp[q], Y[j] - d[j])

    return wp.kernel(
        keyed(helmholtz_divergence, "helmholtz_divergence", dtype),
        enable_backward=False,
        module="unique",
        module_options=CPU_FAST,
    )


@functools.cache
def helmholtz_assemble(copies: int, dtype=f64):
    """out[g] = Σ over the copies c of unique node g (in the ``dss_table`` order of its
    copy first[g]) of wz[0, c], the mass-weighted field (a copy ≥ nlocal read from
    ``ghost``, ``copy_at``): ``dss.assemble`` with the weights applied by the
    producer and the copies compiled in (a fixed-length loop; 1.6× faster on the CPU);
    and partial[1, chunk] = Σ out·y over the chunk's nodes (the CG's w·u, y the
    operator's input). Arguments: wz (1, N), ghost, nlocal, table, first, y, out
    (nunique), partial (3, nchunks), chunk, offset (chunks). Dim ceil(nunique / chunk)."""
    C = int(copies)
    copy_at, _ = gathers(dtype)

    def helmholtz_assemble(
        wz: wp.array2d(dtype=dtype),
        ghost: wp.array(dtype=f64),
        nlocal: int,
        table: wp.array2d(dtype=wp.int32),
        first: wp.array(dtype=wp.int32),
        y: wp.array(dtype=dtype),
        out: wp.array(dtype=dtype),
        partial: wp.array2d(dtype=f64),
        chunk: int,
        offset: int,
    ):
        t = wp.tid() + offset
        wy = f64(0.0)
        for g in range(t * chunk, wp.min(out.shape[0], (t + 1) * chunk)):
            p = first[g]
            s = dtype(0.0)
            for k in range(C):
                c = table[p, k]
                if c >= 0:
                    s += copy_at(wz, 0, ghost, c, nlocal)
            out[g] = s
            wy += f64(s * y[g])
        partial[1, t] = wy

    return wp.kernel(
        keyed(helmholtz_assemble, "helmholtz_assemble", dtype),
        enable_backward=False,
        module="unique",
        module_options=CPU_FAST,
    )


@functools.cache
def helmholtz_rhs(np_: int):
    """Per element: wz[0] = spheremp·s·(r_h − aH·D̂ r_v), the mass-weighted Helmholtz right-hand
    side before its assembly (``helmholtz_assemble``: b = Pᵀ wz), D̂ the element divergence (s⁻¹ ×
    units of r_v) of the wind in rows 0, 1 of r. The DSS of D̂ r_v that ``schur_height``'s form
    has is left out: the assembly of spheremp·DSS(d) is that of spheremp·d in exact arithmetic
    (rspheremp = 1/Σ spheremp over a node's copies), so one pass less. Arguments
    (``operators.row_vectors`` views): r (3, N/np), Dinv (4, N/np), metdet, spheremp (N/np);
    dvv (``operators.dvv_matrix``); s; aH (s·m); wz (1, N/np); offset (elements). Dim nelem."""
    vec, mat, _, _ = row_derivatives(np_)
    NP = int(np_)
    divergence = scaled_divergence(NP, f64)

    def helmholtz_rhs(
        r: wp.array2d(dtype=vec),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        spheremp: wp.array(dtype=vec),
        dvv: mat,
        s: f64,
        aH: f64,
        wz: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        u = mat()  # r's wind
        v = mat()
        for j in range(NP):
            u[j] = r[0, base + j]
            v[j] = r[1, base + j]
        d = divergence(u, v, Dinv, metdet, base, dvv, aH)
        for j in range(NP):
            q = base + j
            wz[0, q] = times(spheremp[q], s * (r[2, q] - d[j]))

    return wp.kernel(
        keyed(helmholtz_rhs, "helmholtz_rhs", f64), enable_backward=False, module="unique", module_options=CPU_FAST
    )


@functools.cache
def helmholtz_back_substitution(np_: int, copies: int, implicit: bool = False):
    """Per element, the solve's state from the Helmholtz solution y: z_h = P y (y read through
    gid, as ``helmholtz_gradient``) and z_v = s·r_v − ag·S wg, S wg the DSS of the mass-weighted
    gradient of y that ``helmholtz_gradient`` wrote (gathered over the node's copies in the
    global order, a copy ≥ nlocal from ``ghost``): ``scatter``, ``gradient`` and ``schur_wind``
    in one pass. With ``implicit``, also lz = L z = (z − s·r)/a as ia·z + mis·r (ia = 1/a,
    mis = −s/a), the IMEX stage's implicit tendency with no pass of its own; that variant is
    compiled without FMA contraction (``blas``'s options, not ``CPU_FAST``), so lz has
    ``blas.axpby``'s bits (and z, at s = 1, those of the plain variant: tests/steppers/test_imex.py). Arguments: wg (2, N), ghost, nlocal, table, rspheremp (N), y, halo, gid (N),
    r (3, N/np) (a ``operators.row_vectors`` view), s, ag (s·m s⁻²·s), z (3, N/np) (a view; may
    be r's), ia (s⁻¹), mis (s⁻¹), lz (3, N/np) (a view; may be r's, not z's), offset (elements).
    Dim nelem."""
    vec, mat, _, _ = row_derivatives(np_)
    NP = int(np_)
    gather = gathered(NP, copies, f64)
    IMPLICIT = bool(implicit)

    def helmholtz_back_substitution(
        wg: wp.array2d(dtype=f64),
        ghost: wp.array(dtype=f64),
        nlocal: int,
        table: wp.array2d(dtype=wp.int32),
        rspheremp: wp.array(dtype=f64),
        y: wp.array(dtype=f64),
        halo: wp.array(dtype=f64),
        gid: wp.array(dtype=wp.int32),
        r: wp.array2d(dtype=vec),
        s: f64,
        ag: f64,
        z: wp.array2d(dtype=vec),
        ia: f64,
        mis: f64,
        lz: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        gx, gy, Y = gather(wg, ghost, nlocal, table, rspheremp, y, halo, gid, base)  # the DSS'd gradient, y
        for j in range(NP):
            q = base + j
            r0 = r[0, q]
            r1 = r[1, q]
            r2 = r[2, q]
            z0 = s * r0 - ag * gx[j]
            z1 = s * r1 - ag * gy[j]
            z[0, q] = z0
            z[1, q] = z1
            z[2, q] = Y[j]
            if wp.static(IMPLICIT):
                lz[0, q] = ia * z0 + mis * r0
                lz[1, q] = ia * z1 + mis * r1
                lz[2, q] = ia * Y[j] + mis * r2

    name = "helmholtz_back_substitution" + ("_implicit" if IMPLICIT else "")
    return wp.kernel(
        keyed(helmholtz_back_substitution, name, f64),
        enable_backward=False,
        module="unique",
        module_options={} if IMPLICIT else CPU_FAST,
    )


@wp.kernel
def helmholtz_combine(
    dgy: wp.array2d(dtype=f64),
    first: wp.array(dtype=wp.int32),
    y: wp.array(dtype=f64),
    area: wp.array(dtype=f64),
    c: f64,
    out: wp.array(dtype=f64),
    partial: wp.array2d(dtype=f64),
    chunk: int,
    offset: int,
):
    """The per-node layout's last step of (M + cK) y: out[g] = area[g]·(y[g] − c·dgy[0, first[g]])
    on unique nodes, dgy = D G y continuous (the DSS'd divergence of the DSS'd gradient:
    its assembly Pᵀ W D̂ G P y is area·D G y); partial[1, t] = Σ out·y over chunk t (the CG's
    w·u, as ``helmholtz_assemble``). Dim ceil(nunique / chunk)."""
    t = wp.tid() + offset
    wy = f64(0.0)
    for g in range(t * chunk, wp.min(out.shape[0], (t + 1) * chunk)):
        s = area[g] * (y[g] - c * dgy[0, first[g]])
        out[g] = s
        wy += s * y[g]
    partial[1, t] = wy
