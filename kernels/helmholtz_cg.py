"""The preconditioned CG that inverts the Helmholtz operator (``helmholtz``), the float64
refinement of a float32 solve and the projection of a solve's start onto past solutions
(``model.helmholtz_cg``, ``model.helmholtz``, ``model.guess_history``).

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

from . import helmholtz
from .operators import keyed

f64 = wp.float64
# The module-level kernels and functions here stay in the operator's Warp module (no backward):
# the CG loop's kernels and the per-node product (``helmholtz.helmholtz_combine``) compile and
# load as one module, as they did before the two files were split.
MODULE = wp.get_module(helmholtz.__name__)


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

    return wp.kernel(keyed(cg_update, "cg_update", dtype), enable_backward=False, module="unique")


# The scalars of a solve on the device (``cs``, float64; ``ic``, int32) and the
# counters it shares with the solves of one HelmholtzSolver until the host reads
# them (``stats``, float64): indices.
GAMMA, DELTA, RR, ALPHA, BETA, BB, BOUND, TOL2 = (wp.constant(k) for k in range(8))
GO, IT, MAXIT = (wp.constant(k) for k in range(3))  # GO first: ``wp.capture_while`` tests ic[0]
ITERATIONS, FAILURES, RESIDUAL = (wp.constant(k) for k in range(3))


@wp.func(module=MODULE)
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


@wp.func(module=MODULE)
def _fail(stats: wp.array(dtype=f64), rr: f64, bb: f64):
    """Count a failed solve; the first one's relative residual ‖r‖/‖b‖ kept for the message."""
    if stats[FAILURES] == f64(0.0):
        stats[RESIDUAL] = wp.sqrt(rr / bb)
    stats[FAILURES] = stats[FAILURES] + f64(1.0)


@wp.kernel(module=MODULE)
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


@wp.kernel(module=MODULE)
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


@wp.kernel(module=MODULE)
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

    return wp.kernel(keyed(inner3, "inner3", dtype), enable_backward=False, module="unique")


@wp.kernel(module=MODULE)
def add_mean_difference(x: wp.array(dtype=f64), sums: wp.array(dtype=f64), total_area: f64, offset: int):
    """x += (sums[0] − sums[1]) / total_area: the area integral of x (sums[1], m² × units of
    x) set to sums[0] (the right-hand side's: Σ b over unique nodes, b mass-weighted).
    Dim nunique."""
    i = wp.tid() + offset
    x[i] = x[i] + (sums[0] - sums[1]) / total_area


@wp.kernel(module=MODULE)
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

    return wp.kernel(keyed(converted, "converted", dtype), enable_backward=False, module="unique")


# The projection of a solve's start onto past solutions (Fischer 1998, Comput. Methods Appl.
# Mech. Engrg. 163, 193; ``steppers.helmholtz.GuessHistory``): X (k, nunique) an A-orthonormal
# basis (Xᵢ·A Xⱼ = δᵢⱼ) and AX its products, the first count[COUNT] rows in use. The device
# integers (``hic``) and the store's coefficients (``hcs``): indices.
COUNT, MODE, SLOT = (wp.constant(k) for k in range(3))
KEEP, RESTART, APPEND, RESTART2 = (
    wp.constant(k) for k in range(4)
)  # MODE: the basis kept, restarted from the solution (and its start), or the increment appended


@wp.kernel(module=MODULE)
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


@wp.kernel(module=MODULE)
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


@wp.kernel(module=MODULE)
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


@wp.kernel(module=MODULE)
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


@wp.kernel(module=MODULE)
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
