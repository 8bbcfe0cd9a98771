"""The Helmholtz operator M + cK on unique nodes, matrix-free, and the
preconditioned CG that inverts it (``solvers.helmholtz.HelmholtzSolver``).

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

The CG is Chronopoulos & Gear's (1989, J. Comput. Appl. Math. 25, 153)
one-reduction form: one fused vector update (``cg_update``) and one operator
product an iteration, the three inner products it needs computed by the update
(r·u, r·r) and the assembly (w·u) as they write. Inner products are per-chunk
partial sums over ``chunk`` unique nodes in index order (a launch argument,
``backend.Backend.reduction_chunk``), added on the device in index order
(``Topology.device_sums``): the bits do not depend on the CPU threads a launch
is split over. The scalar recurrences and the convergence test are one-thread
kernels (``cg_check`` after an update, ``cg_alpha`` after a product, and
``refine_check`` for float64 refinement of a float32 solve) writing the solve's
scalars to small device arrays that the update reads and ``wp.capture_while``
tests: no host read in a solve (one rank). The test comes between the update
and the product, so a solve of k iterations costs k products (k + 1 from a warm
start: its residual).

Every kernel of the solve is made for a float type (the factories' ``dtype``:
float64, or float32 for the float32 CG that float64 refinement corrects,
``steppers.helmholtz``); inner products are summed in float64 either way, and
the exchanges between ranks stay float64 (``dss.pack`` converts).
"""

import functools
from typing import Any

import warp as wp

from .operators import CPU_FAST, over, row_derivatives, times

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


def _name(kernel, name: str, dtype):
    """Key a factory's kernel by its name and float type (Warp keys kernels by qualname)."""
    kernel.__qualname__ = name + ("" if dtype is f64 else f"_{dtype.__name__}")
    return kernel


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
        _name(helmholtz_gradient, "helmholtz_gradient", dtype),
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
        _name(helmholtz_divergence, "helmholtz_divergence", dtype),
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
        _name(helmholtz_assemble, "helmholtz_assemble", dtype),
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
        _name(helmholtz_rhs, "helmholtz_rhs", f64), enable_backward=False, module="unique", module_options=CPU_FAST
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
        _name(helmholtz_back_substitution, name, f64),
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


@functools.cache
def cg_update(dtype=f64):
    """The kernel of one Chronopoulos–Gear step on unique ``dtype`` vectors: p = u + βp,
    s = w + βs, x += αp, r −= αs, u = minv·r (minv: the Jacobi preconditioner), α and
    β from the solve's scalars ``cs`` (``cg_check``, ``cg_alpha``; float64) or, with
    ``start``, α = 1 and β = 0 (from r = b, u = 0 and w = A x: r = b − Ax, u = M⁻¹r, the
    start and the refinement's residual; then also partial[1] = Σ b·b); partial[0] and
    partial[2] per chunk: Σ r·u and Σ r·r, summed in float64. Dim ceil(nunique / chunk)."""

    def cg_update(
        cs: wp.array(dtype=f64),
        start: int,
        p: wp.array(dtype=dtype),
        s: wp.array(dtype=dtype),
        x: wp.array(dtype=dtype),
        r: wp.array(dtype=dtype),
        u: wp.array(dtype=dtype),
        w: wp.array(dtype=dtype),
        minv: wp.array(dtype=dtype),
        partial: wp.array2d(dtype=f64),
        chunk: int,
        offset: int,
    ):
        t = wp.tid() + offset
        alpha = dtype(1.0)
        beta = dtype(0.0)
        if start == 0:
            alpha = dtype(cs[ALPHA])
            beta = dtype(cs[BETA])
        ru = f64(0.0)
        rr = f64(0.0)
        bb = f64(0.0)
        for i in range(t * chunk, wp.min(x.shape[0], (t + 1) * chunk)):
            pi = u[i] + beta * p[i]
            si = w[i] + beta * s[i]
            p[i] = pi
            s[i] = si
            x[i] = x[i] + alpha * pi
            bi = r[i]
            ri = bi - alpha * si
            r[i] = ri
            ui = minv[i] * ri
            u[i] = ui
            ru += f64(ri) * f64(ui)
            rr += f64(ri) * f64(ri)
            bb += f64(bi) * f64(bi)
        partial[0, t] = ru
        partial[2, t] = rr
        if start != 0:
            partial[1, t] = bb

    return wp.kernel(_name(cg_update, "cg_update", dtype), enable_backward=False, module="unique")


# The scalars of a solve on the device (``cs``, float64; ``ic``, int32) and the
# counters it shares with the solves of one HelmholtzSolver until the host reads
# them (``stats``, float64): indices.
GAMMA, DELTA, RR, ALPHA, BETA, BB, BOUND, TOL2 = (wp.constant(k) for k in range(8))
GO, IT, MAXIT = (wp.constant(k) for k in range(3))  # GO first: ``wp.capture_while`` tests ic[0]
ITERATIONS, FAILURES, RESIDUAL = (wp.constant(k) for k in range(3))


@wp.func
def _begin(sums: wp.array(dtype=f64), tol2: f64, maxiter: int, cs: wp.array(dtype=f64), ic: wp.array(dtype=wp.int32)):
    """A solve's start from sums[1] = b·b (the start's update): the bound r·r ≤ tol²·b·b, no
    iterations yet; tol2 and maxiter > 0 stored, ≤ 0: those ``refine_check`` left."""
    if tol2 > f64(0.0):
        cs[TOL2] = tol2
    if maxiter > 0:
        ic[MAXIT] = maxiter
    cs[BB] = sums[1]
    cs[BOUND] = cs[TOL2] * sums[1]
    ic[IT] = 0


@wp.func
def _fail(stats: wp.array(dtype=f64), rr: f64, bb: f64):
    """Count a failed solve; the first one's relative residual ‖r‖/‖b‖ kept for the message."""
    if stats[FAILURES] == f64(0.0):
        stats[RESIDUAL] = wp.sqrt(rr / bb)
    stats[FAILURES] = stats[FAILURES] + f64(1.0)


@wp.kernel
def cg_check(
    sums: wp.array(dtype=f64),
    first: int,
    tol2: f64,
    maxiter: int,
    cs: wp.array(dtype=f64),
    ic: wp.array(dtype=wp.int32),
    stats: wp.array(dtype=f64),
):
    """Chronopoulos & Gear's CG (1989, J. Comput. Appl. Math. 25, 153) after an update, from
    sums = (r·u, ·, r·r) over all ranks: the convergence test and β. ``first`` (after the
    start's update r = b − Ay, with sums[1] = b·b): the bound (``_begin``), β = 0;
    else an iteration counted (ic[IT], stats[ITERATIONS]) and β = γ/γ_old. γ = r·u.
    ic[GO] = 1 while r·r > cs[BOUND] within ic[MAXIT] iterations; past it a failure
    (stats[FAILURES]; stats[RESIDUAL] = ‖r‖/‖b‖ of the first). Dim 1."""
    g = sums[0]
    rr = sums[2]
    beta = f64(0.0)
    if first != 0:
        _begin(sums, tol2, maxiter, cs, ic)
    else:
        ic[IT] = ic[IT] + 1
        stats[ITERATIONS] = stats[ITERATIONS] + f64(1.0)
        beta = g / cs[GAMMA]
    go = 0
    if rr > cs[BOUND]:
        if ic[IT] >= ic[MAXIT]:
            _fail(stats, rr, cs[BB])
        else:
            go = 1
    cs[GAMMA] = g
    cs[RR] = rr
    cs[BETA] = beta
    ic[GO] = go


@wp.kernel
def cg_alpha(sums: wp.array(dtype=f64), cs: wp.array(dtype=f64), ic: wp.array(dtype=wp.int32)):
    """α of the next update after the product w = Au, sums[1] = δ = w·u: γ/δ in the first
    iteration, else γ/(δ − βγ/α_old) (Chronopoulos & Gear's recurrence). Dim 1."""
    g = cs[GAMMA]
    delta = sums[1]
    cs[DELTA] = delta
    if ic[IT] == 0:
        cs[ALPHA] = g / delta
    else:
        cs[ALPHA] = g / (delta - cs[BETA] * g / cs[ALPHA])


@wp.kernel
def refine_check(
    sums: wp.array(dtype=f64),
    first: int,
    tol2: f64,
    maxiter: int,
    cs: wp.array(dtype=f64),
    ic: wp.array(dtype=wp.int32),
    low_cs: wp.array(dtype=f64),
    low_ic: wp.array(dtype=wp.int32),
    floor2: f64,
    stats: wp.array(dtype=f64),
):
    """Iterative refinement's test after the float64 residual r = b − Ay (sums[2] = r·r;
    ``first``: the bound from sums[1] = b·b, ``_begin``; else the last float32 pass's
    iterations low_ic[IT] added to ic[IT]): done when r·r ≤ cs[BOUND]; past ic[MAXIT] a
    failure as ``cg_check``; else ic[GO] = 1 and the next float32 pass's relative
    tol² = max(tol²·b·b / r·r, floor2) to its own right-hand side r, and the iterations left. Dim 1."""
    rr = sums[2]
    if first != 0:
        _begin(sums, tol2, maxiter, cs, ic)
    else:
        ic[IT] = ic[IT] + low_ic[IT]
    it = ic[IT]
    go = 0
    if rr > cs[BOUND]:
        if it >= ic[MAXIT]:
            _fail(stats, rr, cs[BB])
        else:
            low_cs[TOL2] = wp.max(cs[TOL2] * cs[BB] / rr, floor2)
            low_ic[MAXIT] = ic[MAXIT] - it
            go = 1
    cs[RR] = rr
    ic[GO] = go


@functools.cache
def inner3(dtype=f64):
    """The kernel of out[k, t] = Σ a_k·b_k over chunk t's ``chunk`` unique nodes of
    ``dtype`` vectors, in index order, summed in float64 (three inner products in one
    pass). Dim ceil(nunique / chunk)."""

    def inner3(
        a0: wp.array(dtype=dtype),
        b0: wp.array(dtype=dtype),
        a1: wp.array(dtype=dtype),
        b1: wp.array(dtype=dtype),
        a2: wp.array(dtype=dtype),
        b2: wp.array(dtype=dtype),
        out: wp.array2d(dtype=f64),
        chunk: int,
        offset: int,
    ):
        t = wp.tid() + offset
        n = a0.shape[0]
        s0 = f64(0.0)
        s1 = f64(0.0)
        s2 = f64(0.0)
        for i in range(t * chunk, wp.min(n, (t + 1) * chunk)):
            s0 += f64(a0[i]) * f64(b0[i])
            s1 += f64(a1[i]) * f64(b1[i])
            s2 += f64(a2[i]) * f64(b2[i])
        out[0, t] = s0
        out[1, t] = s1
        out[2, t] = s2

    return wp.kernel(_name(inner3, "inner3", dtype), enable_backward=False, module="unique")


@wp.kernel
def add_mean_difference(x: wp.array(dtype=f64), sums: wp.array(dtype=f64), total_area: f64, offset: int):
    """x += (sums[0] − sums[1]) / total_area: the area integral of x (sums[1], m² × units of
    x) set to sums[0] (the right-hand side's: Σ b over unique nodes, b mass-weighted).
    Dim nunique."""
    i = wp.tid() + offset
    x[i] = x[i] + (sums[0] - sums[1]) / total_area


@wp.kernel
def add_converted(x: wp.array(dtype=f64), e: wp.array(dtype=Any), offset: int):
    """x += e, e of another float type (the refinement's correction). Dim nunique."""
    i = wp.tid() + offset
    x[i] = x[i] + f64(e[i])


wp.overload(add_converted, {"e": wp.array(dtype=wp.float32)})


@functools.cache
def converted(dtype):
    """The kernel of out = x (float64) as ``dtype`` (the refinement's residual). Dim len(x)."""

    def converted(x: wp.array(dtype=f64), out: wp.array(dtype=dtype), offset: int):
        i = wp.tid() + offset
        out[i] = dtype(x[i])

    return wp.kernel(_name(converted, "converted", dtype), enable_backward=False, module="unique")


# The projection of a solve's start onto past solutions (Fischer 1998, Comput. Methods Appl.
# Mech. Engrg. 163, 193; ``steppers.helmholtz.GuessHistory``): X (k, nunique) an A-orthonormal
# basis (Xᵢ·A Xⱼ = δᵢⱼ) and AX its products, the first count[COUNT] rows in use. The device
# integers (``hic``) and the store's coefficients (``hcs``): indices.
COUNT, MODE, SLOT = (wp.constant(k) for k in range(3))
KEEP, RESTART, APPEND, RESTART2 = (
    wp.constant(k) for k in range(4)
)  # MODE: the basis kept, restarted from the solution (and its start), or the increment appended


@wp.kernel
def history_dots(
    X: wp.array2d(dtype=f64),
    b: wp.array(dtype=f64),
    hic: wp.array(dtype=wp.int32),
    partial: wp.array2d(dtype=f64),
    chunk: int,
    offset: int,
):
    """partial[j, t] = Σ Xⱼ·b over chunk t's ``chunk`` unique nodes for j < hic[COUNT], 0 for
    the other rows < k (the projection's coefficients αⱼ = Xⱼ·b, A-orthonormal X). Dim
    ceil(nunique / chunk)."""
    t = wp.tid() + offset
    n = hic[COUNT]
    for j in range(X.shape[0]):
        s = f64(0.0)
        if j < n:
            for i in range(t * chunk, wp.min(b.shape[0], (t + 1) * chunk)):
                s += X[j, i] * b[i]
        partial[j, t] = s


@wp.kernel
def history_guess(
    X: wp.array2d(dtype=f64),
    AX: wp.array2d(dtype=f64),
    alpha: wp.array(dtype=f64),
    hic: wp.array(dtype=wp.int32),
    y: wp.array(dtype=f64),
    w: wp.array(dtype=f64),
    y0: wp.array(dtype=f64),
    w0: wp.array(dtype=f64),
    offset: int,
):
    """The projected start y = Σ αⱼ Xⱼ and its product w = A y = Σ αⱼ AXⱼ over j < hic[COUNT]
    (0 with no basis), kept in y0, w0 for the store after the solve. Dim nunique."""
    i = wp.tid() + offset
    s = f64(0.0)
    a = f64(0.0)
    for j in range(hic[COUNT]):
        s += alpha[j] * X[j, i]
        a += alpha[j] * AX[j, i]
    y[i] = s
    w[i] = a
    y0[i] = s
    w0[i] = a


@wp.kernel
def history_increment_dots(
    X: wp.array2d(dtype=f64),
    y: wp.array(dtype=f64),
    y0: wp.array(dtype=f64),
    b: wp.array(dtype=f64),
    r: wp.array(dtype=f64),
    w0: wp.array(dtype=f64),
    hic: wp.array(dtype=wp.int32),
    partial: wp.array2d(dtype=f64),
    chunk: int,
    offset: int,
):
    """After a solve from the projected start y0 (A y0 = w0) to y with residual r (A y = b − r):
    per chunk t, with the increment d = y − y0 and A d = b − r − w0, partial[j, t] = Σ Xⱼ·A d
    for j < hic[COUNT] (0 for the other j < k), partial[k, t] = Σ d·A d, partial[k + 1, t]
    = Σ y·A y, partial[k + 2, t] = Σ y0·A y0 and partial[k + 3, t] = Σ y0·A d (k = X.shape[0]).
    Dim ceil(nunique / chunk)."""
    t = wp.tid() + offset
    k = X.shape[0]
    n = hic[COUNT]
    lo = t * chunk
    hi = wp.min(b.shape[0], (t + 1) * chunk)
    for j in range(k):
        s = f64(0.0)
        if j < n:
            for i in range(lo, hi):
                s += X[j, i] * (b[i] - r[i] - w0[i])
        partial[j, t] = s
    dd = f64(0.0)
    yy = f64(0.0)
    ss = f64(0.0)
    sd = f64(0.0)
    for i in range(lo, hi):
        ay = b[i] - r[i]
        ad = ay - w0[i]
        dd += (y[i] - y0[i]) * ad
        yy += y[i] * ay
        ss += y0[i] * w0[i]
        sd += y0[i] * ad
    partial[k, t] = dd
    partial[k + 1, t] = yy
    partial[k + 2, t] = ss
    partial[k + 3, t] = sd


@wp.kernel
def history_coefficients(sums: wp.array(dtype=f64), k: int, hic: wp.array(dtype=wp.int32), hcs: wp.array(dtype=f64)):
    """How the last solution joins the basis of n = hic[COUNT] vectors, from
    ``history_increment_dots``' totals. With none, the solution y A-normalised (MODE RESTART,
    hcs[0] = 1/‖y‖_A). With n < k, the increment d A-orthogonalised against the basis
    (classical Gram–Schmidt, βⱼ = Xⱼ·A d into hcs[1 + j]) and A-normalised (hcs[0] = 1/‖d'‖_A,
    ‖d'‖²_A = d·A d − Σβⱼ²) into row n (MODE APPEND, SLOT n). Full, the basis restarts from
    two vectors spanning y and its start y0 (MODE RESTART2: y0/‖y0‖_A, hcs[0] = 1/‖y0‖_A, and d
    A-orthogonalised against it, β = y0·A d/‖y0‖_A into hcs[1], hcs[2] = 1/‖d'‖_A), with k = 1
    from y alone (RESTART, Fischer's restart). An increment of A-norm ≤ 1e-10 of the
    solution's (the solution in the basis's span) or a zero solution keeps the basis as it is
    (MODE KEEP). Dim 1."""
    n = hic[COUNT]
    yy = sums[k + 1]
    small = f64(1e-20) * yy
    mode = KEEP
    if n == 0:
        if yy > f64(0.0):
            mode = RESTART
    elif n < k:
        dd = sums[k]
        for j in range(n):
            hcs[1 + j] = sums[j]
            dd -= sums[j] * sums[j]
        if dd > small:
            mode = APPEND
            hcs[0] = f64(1.0) / wp.sqrt(dd)
            hic[SLOT] = n
            hic[COUNT] = n + 1
    elif sums[k] > small:  # full, and the solution not in its span
        mode = RESTART
        ss = sums[k + 2]
        if k >= 2 and ss > small:
            beta = sums[k + 3] / wp.sqrt(ss)
            dd = sums[k] - beta * beta
            if dd > small:
                mode = RESTART2
                hcs[0] = f64(1.0) / wp.sqrt(ss)
                hcs[1] = beta
                hcs[2] = f64(1.0) / wp.sqrt(dd)
                hic[COUNT] = 2
    if mode == RESTART:
        hcs[0] = f64(1.0) / wp.sqrt(yy)
        hic[COUNT] = 1
    hic[MODE] = mode


@wp.kernel
def history_store(
    X: wp.array2d(dtype=f64),
    AX: wp.array2d(dtype=f64),
    y: wp.array(dtype=f64),
    y0: wp.array(dtype=f64),
    b: wp.array(dtype=f64),
    r: wp.array(dtype=f64),
    w0: wp.array(dtype=f64),
    hic: wp.array(dtype=wp.int32),
    hcs: wp.array(dtype=f64),
    offset: int,
):
    """The basis vectors ``history_coefficients`` chose: row 0 = y/‖y‖_A (RESTART), rows 0, 1 =
    y0/‖y0‖_A, (d − β·row 0)/‖d'‖_A (RESTART2), or row hic[SLOT] = (d − Σ βⱼ Xⱼ)/‖d'‖_A over
    the rows before it (APPEND), d = y − y0; AX's rows alike from A y = b − r, A y0 = w0,
    A d = b − r − w0. Dim nunique."""
    i = wp.tid() + offset
    mode = hic[MODE]
    s = hcs[0]
    if mode == RESTART:
        X[0, i] = s * y[i]
        AX[0, i] = s * (b[i] - r[i])
    elif mode == RESTART2:
        x0 = s * y0[i]
        ax0 = s * w0[i]
        X[0, i] = x0
        AX[0, i] = ax0
        X[1, i] = hcs[2] * (y[i] - y0[i] - hcs[1] * x0)
        AX[1, i] = hcs[2] * (b[i] - r[i] - w0[i] - hcs[1] * ax0)
    elif mode == APPEND:
        slot = hic[SLOT]
        d = y[i] - y0[i]
        ad = b[i] - r[i] - w0[i]
        for j in range(slot):
            d -= hcs[1 + j] * X[j, i]
            ad -= hcs[1 + j] * AX[j, i]
        X[slot, i] = s * d
        AX[slot, i] = s * ad
