"""The tracers' shape-preserving limiter: Guba, Taylor & St-Cyr (2014, J. Comput. Phys. 267,
176)'s optimisation-based limiter as HOMME iterates it (``limiter_optim_iter_full``, its
``limiter_option = 8``), one thread an element.

Each tracer's mixing ratio q = hq / h in an element is moved, keeping the element's tracer mass
Σ c_i q_i (c = spheremp·h, the element-local mass weights) to round-off, into the bounds
[q_min, q_max] of the element and its neighbours at the step's start: values beyond a bound are
clipped to it and the mass they held spread over the nodes still inside, in proportion to c,
until no mass is left over (a bound the element's mean lies beyond is moved to the mean: the
problem's only feasible point). ``limit_stage`` limits an explicit stage's element-local values
before their DSS (HOMME's ``euler_step``), or an assembled state's (its only term the state).
Dim nelem; ``offset`` counts elements.
"""

import functools
from typing import Any

import warp as wp

from .dss import Copies, copy_value, rkl_weighted
from .operators import row_derivatives

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@functools.cache
def element_bounds(np_: int):
    """The kernel (x, b, offset): b[2k], b[2k + 1] (2K, ·) at each node of an element = the least
    and the greatest over the element of tracer k's q = x[3 + k] / x[2]. On GLL rows
    (``operators.row_vectors``: x and b as rows). Dim nelem."""
    NP = int(np_)
    vec = row_derivatives(NP)[0]

    def kernel(x: wp.array2d(dtype=vec), b: wp.array2d(dtype=vec), offset: int):
        base = (wp.tid() + offset) * NP
        for k in range(b.shape[0] // 2):
            least = x[3 + k, base][0] / x[2, base][0]
            most = least
            for j in range(NP):
                q = wp.cw_div(x[3 + k, base + j], x[2, base + j])
                for i in range(NP):
                    least = wp.min(least, q[i])
                    most = wp.max(most, q[i])
            for j in range(NP):
                b[2 * k, base + j] = vec(least)
                b[2 * k + 1, base + j] = vec(most)

    kernel.__qualname__ = kernel.__name__ = f"element_bounds_np{NP}"
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def neighbour_bounds(tracers: int, copies: int, ghosts: bool):
    """The kernel (b, d, npp, out, offset): out[2k, e], out[2k + 1, e] = the least of b[2k] and
    the greatest of b[2k + 1] (2K, N: ``element_bounds``') over every copy of element e's nodes,
    its own and those of the elements sharing a node with it, another rank's read from d's
    ghosts (``dss.Copies``, ``copies`` its table's columns; b exchanged first where ``ghosts``),
    each copy's index read once for every tracer: a min and a max, so the same bits on any
    ranks. Dim nelem."""
    K, C, G = int(tracers), int(copies), bool(ghosts)
    value = copy_value(2 * K, False, G)
    bounds = wp.types.vector(length=K, dtype=f64)

    def kernel(b: wp.array2d(dtype=f64), d: Copies, npp: int, out: wp.array2d(dtype=f64), offset: int):
        e = wp.tid() + offset
        base = e * npp
        lo = bounds()
        hi = bounds()
        for k in range(K):
            lo[k] = b[2 * k, base]
            hi[k] = b[2 * k + 1, base]
        for i in range(npp):
            for j in range(C):
                c = d.table[base + i, j]
                if c >= 0:
                    for k in range(K):
                        lo[k] = wp.min(lo[k], value(b, d, c, 2 * k))
                        hi[k] = wp.max(hi[k], value(b, d, c, 2 * k + 1))
        for k in range(K):
            out[2 * k, e] = lo[k]
            out[2 * k + 1, e] = hi[k]

    kernel.__qualname__ = kernel.__name__ = "neighbour_bounds" + ("__ghosts" if G else "")
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def limited(np_: int):
    """A ``wp.func`` (Q, C, qmin, qmax, iterations) → Q limited: Q (np × np, Q[j, i] q at GLL
    node (i, j) of an element, held in registers) moved into [qmin, qmax] keeping Σ C Q (C the
    nodes' mass weights spheremp·h): passes of clipping and spreading until one clips nothing
    (HOMME stops at a tolerance: HOMMEXX's ``limiter_optim_iter_full`` when the mass left is
    ≤ 5e-14 of the element's, after np² − 1 passes at most; 1e-14 here before, whose last spread
    left a node past its bound by up to that mass over the weight it went to, 4e-12 of the
    correlated tracer's range in the transport test at ne10). A pass after the first clips on one
    side only (a spread moves values away from the other bound), and a node clipped to a bound
    leaves the spread's nodes for good, so np² + 1 ``iterations`` reach a pass that clips
    nothing: every value within the bounds, the mass kept to the spreads' rounding. Past
    ``iterations`` (fewer given) the last spread is kept: the mass before the bounds. The nodes
    in memory order, as a loop over them would take them."""
    NP = int(np_)
    mat = row_derivatives(NP)[1]

    def limit(Q: mat, C: mat, qmin: f64, qmax: f64, iterations: int):
        mass = f64(0.0)
        total = f64(0.0)
        for j in range(NP):
            for i in range(NP):
                mass += C[j, i] * Q[j, i]
                total += C[j, i]
        lo = wp.min(qmin, mass / total)  # the mean lies within the bounds, or is one
        hi = wp.max(qmax, mass / total)
        it = int(0)  # noqa: UP018 (a dynamic int: Warp keeps a bare literal constant)
        while it < iterations:
            it += 1
            extra = f64(0.0)  # the mass clipped off (> 0: above hi), to spread
            for j in range(NP):
                for i in range(NP):
                    q = Q[j, i]
                    if q > hi:
                        extra += (q - hi) * C[j, i]
                        Q[j, i] = hi
                    elif q < lo:
                        extra -= (lo - q) * C[j, i]
                        Q[j, i] = lo
            if extra == f64(0.0):  # nothing clipped (most elements at the first pass): within the bounds, done
                it = iterations
            else:
                room = f64(0.0)  # the weight of the nodes that can take it
                for j in range(NP):
                    for i in range(NP):
                        q = Q[j, i]
                        if (extra > f64(0.0) and q < hi) or (extra < f64(0.0) and q > lo):
                            room += C[j, i]
                every = room == f64(0.0)  # each node on the bound: the mean on it to rounding, extra its rounding
                if every:  # spread over them all and stop, keeping the mass: a few ε of q past the bound
                    room = total
                    it = iterations
                for j in range(NP):
                    for i in range(NP):
                        q = Q[j, i]
                        if every or (extra > f64(0.0) and q < hi) or (extra < f64(0.0) and q > lo):
                            Q[j, i] = q + extra / room
        return Q

    limit.__qualname__ = limit.__name__ = f"limited_np{NP}"
    return wp.func(limit)


@functools.cache
def limit_stage(
    weighted: bool, first: int = 0, np_: int = 4, rkl: bool = False, weigh: bool = False, relative: bool = False
):
    """The kernel limiting an explicit stage's element-local values before their DSS (HOMME's
    ``euler_step``: the limiter on Qtens, then the DSS): the stage's update out = a₀·s₀ + a₁·s₁ +
    a₂·F (``ShallowWater.rhs_update``), F = M⁻¹DSS(the tendency), taken element by element as
    v = a₀·s₀ + a₁·s₁ + a₂·F_e with F_e the element's own tendency (tend / mass if ``weighted``:
    tend = spheremp·F_e) at its nodes, whose mass-weighted DSS is the update; out[k] = h·q̃ of
    tracer k, q̃ its q = v_k / h limited into its bounds keeping Σ c q (c = spheremp·h;
    ``limited``). The DSS of out then takes the stage's values: at a node a convex combination of
    its copies' q̃ (weights spheremp·h of each, h > 0); a = (1, 0, 0) and s₀ an assembled state:
    that state's values limited. h = v[2], v_k = v[3 + k]: tend's rows are the state's from
    ``first`` (0: the tendency's; 2: the ∇⁴'s of h and the tracers alone,
    ``model.hyperviscosity.Hyperviscosity.build_tracers``). A thread an element on its GLL rows
    (``operators.row_vectors``: the CPU's SIMD rows, the limiting in registers; 0.37 → 0.09 ms a
    TC5 ne16 stage with one tracer, one thread, against the node-by-node loops over the arrays
    it replaced), the same arithmetic node by node. Arguments: a (vec3), s₀, s₁ (rows, ·; a₁ = 0:
    s₁ unread but any), tend, mass, spheremp, bounds (2K, nelem: ``neighbour_bounds``), iterations
    (``limited``'s), out (K, ·), offset; all but a, bounds and iterations as rows. ``rkl``: v = t +
    a₁·(s₁ − t), t = a₀·s₀ + a₂·F_e, an RKL1 stage as ``kernels.dss.rkl_stage`` forms it (the
    ∇⁴'s, ``first`` = 2). ``weigh``: out[k] = spheremp·h·q̃, the mass-weighted DSS's own terms
    (the same products), for an unweighted DSS pass to assemble with other rows (the stage's
    dynamics rows: ``dss.dss_update``'s ``assembled``); out may then be tend's own tracer rows
    (each element reads its own before it writes them). ``relative``: what either writes less s₀'s
    (its terms of h·q̃ − s₀; s₀ an assembled state, the DSS update adds it back: ``dss.dss_update``'s
    "ak" or its ``assembled`` rows). An element within its
    bounds keeps its values; one outside them is limited in q − qmin (``limited`` with bounds 0,
    qmax − qmin) and takes the change alone, h·(q̃ − q), so that only what the limiter moves is
    rounded."""
    W, F, NP, RKL, WEIGH, REL = bool(weighted), int(first), int(np_), bool(rkl), bool(weigh), bool(relative)
    vec, mat = row_derivatives(NP)[:2]
    limit = limited(NP)

    def combined(a: wp.vec3d, x0: Any, x1: Any, f: Any):
        # the stage's value from s₀'s, s₁'s and F's at the nodes of a row
        if wp.static(RKL):
            return rkl_weighted(a[0] * x0 + a[2] * f, x1, a[1])
        return a[0] * x0 + a[1] * x1 + a[2] * f

    combined.__qualname__ = combined.__name__ = "limit_stage_value" + ("__rkl" if RKL else "")
    combined = wp.func(combined)

    def kernel(
        a: wp.vec3d,
        s0: wp.array2d(dtype=vec),
        s1: wp.array2d(dtype=vec),
        tend: wp.array2d(dtype=vec),
        mass: wp.array(dtype=vec),
        spheremp: wp.array(dtype=vec),
        bounds: wp.array2d(dtype=f64),
        iterations: int,
        out: wp.array2d(dtype=vec),
        offset: int,
    ):
        e = wp.tid() + offset
        base = e * NP
        H = mat()  # the element-local depth, the limiter's weights spheremp·h and 1 / mass
        C = mat()
        R = mat()
        for j in range(NP):
            q = base + j
            r = vec(f64(1.0))
            if wp.static(W):
                r = wp.cw_div(r, mass[q])
            h = combined(a, s0[2, q], s1[2, q], wp.cw_mul(tend[wp.static(2 - F), q], r))
            H[j] = h
            C[j] = wp.cw_mul(spheremp[q], h)
            R[j] = r
        for k in range(out.shape[0]):  # a tracer at a time, in a loop clang does not unroll
            Q = mat()
            V = mat()  # the stage's values h·q
            qmin, qmax = bounds[2 * k, e], bounds[2 * k + 1, e]
            outside = False
            for j in range(NP):
                q = base + j
                V[j] = combined(a, s0[3 + k, q], s1[3 + k, q], wp.cw_mul(tend[wp.static(3 - F) + k, q], R[j]))
                Q[j] = wp.cw_div(V[j], H[j])
                outside = outside or wp.min(Q[j]) < qmin or wp.max(Q[j]) > qmax
            # an element within its bounds (most) keeps its values; its scalar passes skipped (TC5 ne16
            # q = 1, one thread: limit_stage 0.13 → 0.09 ms)
            if outside:
                # q − qmin limited: near a bound q = 1 (q = 1's own) a spread of a few ε is kept where
                # one onto q ≥ 1 (spacing 2ε, ε below 1) rounded away, a mass bias (−0.05 ε an element)
                for j in range(NP):
                    Q[j] = Q[j] - vec(qmin)
                D = limit(Q, C, f64(0.0), qmax - qmin, iterations)
                for j in range(NP):  # the limiter's change alone: untouched nodes keep their values' bits
                    V[j] = V[j] + wp.cw_mul(D[j] - Q[j], H[j])
            for j in range(NP):
                if wp.static(REL):
                    V[j] = V[j] - s0[3 + k, base + j]
                if wp.static(WEIGH):
                    out[k, base + j] = wp.cw_mul(spheremp[base + j], V[j])
                else:
                    out[k, base + j] = V[j]

    kernel.__qualname__ = kernel.__name__ = (
        "limit_stage"
        + ("__mass" if W else "")
        + (f"__from{F}" if F else "")
        + ("__rkl" if RKL else "")
        + ("__weighed" if WEIGH else "")
        + ("__relative" if REL else "")
    )
    return wp.kernel(kernel, enable_backward=False, module="unique")
