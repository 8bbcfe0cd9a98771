"""The tracers' shape-preserving limiter: Guba, Taylor & St-Cyr (2014, J. Comput. Phys. 267,
176)'s optimisation-based limiter as HOMME iterates it (``limiter_optim_iter_full``, its
``limiter_option = 8``), one thread an element.

Each tracer's mixing ratio q = hq / h in an element is moved, keeping the element's tracer mass
Σ c_i q_i (c = spheremp·h, the element-local mass weights) to round-off, into the bounds
[q_min, q_max] of the element and its neighbours at the step's start: values beyond a bound are
clipped to it and the mass they held spread over the nodes still inside, in proportion to c,
until no mass is left over (a bound the element's mean lies beyond is moved to the mean: the
problem's only feasible point). Dim nelem; ``offset`` counts elements.
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def element_bounds(x: wp.array2d(dtype=f64), npp: int, bounds: wp.array2d(dtype=f64), offset: int):
    """bounds[2k], bounds[2k + 1] (nelem) = min, max over the element of tracer k's q = x[3 + k]
    / x[2]; ``npp`` = np² nodes an element."""
    e = wp.tid() + offset
    base = e * npp
    for k in range(x.shape[0] - 3):
        lo = x[3 + k, base] / x[2, base]
        hi = lo
        for i in range(1, npp):
            q = x[3 + k, base + i] / x[2, base + i]
            lo = wp.min(lo, q)
            hi = wp.max(hi, q)
        bounds[2 * k, e] = lo
        bounds[2 * k + 1, e] = hi


@wp.kernel
def neighbour_bounds(
    bounds: wp.array2d(dtype=f64), table: wp.array2d(dtype=wp.int32), npp: int, out: wp.array2d(dtype=f64), offset: int
):
    """out = ``bounds`` over the element and every element sharing a node with it: rows 2k the
    least, 2k + 1 the greatest (``table``: the DSS's copies of each node, −1-padded, all local)."""
    e = wp.tid() + offset
    base = e * npp
    for r in range(bounds.shape[0]):
        v = bounds[r, e]
        for i in range(npp):
            for j in range(table.shape[1]):
                c = table[base + i, j]
                if c >= 0:
                    b = bounds[r, c / npp]
                    if r % 2 == 0:
                        v = wp.min(v, b)
                    else:
                        v = wp.max(v, b)
        out[r, e] = v


@wp.kernel
def limit_element(
    x: wp.array2d(dtype=f64),
    spheremp: wp.array(dtype=f64),
    bounds: wp.array2d(dtype=f64),
    npp: int,
    iterations: int,
    tol: f64,
    out: wp.array2d(dtype=f64),
    offset: int,
):
    """out[k] = h·q̃ of tracer k, q̃ its q = x[3 + k] / x[2] limited into [bounds[2k, e],
    bounds[2k + 1, e]] keeping Σ c q (c = spheremp·h) (module docstring): at most ``iterations``
    passes of clipping and spreading, done when the mass left over is ≤ ``tol`` of the element's."""
    e = wp.tid() + offset
    base = e * npp
    for k in range(out.shape[0]):
        qmin = bounds[2 * k, e]
        qmax = bounds[2 * k + 1, e]
        mass = f64(0.0)
        total = f64(0.0)
        for i in range(npp):
            p = base + i
            c = spheremp[p] * x[2, p]
            q = x[3 + k, p] / x[2, p]
            out[k, p] = q
            mass += c * q
            total += c
        qmin = wp.min(qmin, mass / total)  # the mean lies within the bounds, or is one
        qmax = wp.max(qmax, mass / total)
        it = int(0)  # noqa: UP018 (a dynamic int: Warp keeps a bare literal constant)
        while it < iterations:
            it += 1
            extra = f64(0.0)  # the mass clipped off (> 0: above qmax), to spread
            for i in range(npp):
                p = base + i
                c = spheremp[p] * x[2, p]
                q = out[k, p]
                if q > qmax:
                    extra += (q - qmax) * c
                    out[k, p] = qmax
                elif q < qmin:
                    extra -= (qmin - q) * c
                    out[k, p] = qmin
            if wp.abs(extra) <= tol * wp.abs(mass):
                it = iterations
            else:
                room = f64(0.0)  # the weight of the nodes that can take it
                for i in range(npp):
                    p = base + i
                    q = out[k, p]
                    if (extra > f64(0.0) and q < qmax) or (extra < f64(0.0) and q > qmin):
                        room += spheremp[p] * x[2, p]
                for i in range(npp):
                    p = base + i
                    q = out[k, p]
                    if (extra > f64(0.0) and q < qmax) or (extra < f64(0.0) and q > qmin):
                        out[k, p] = q + extra / room
        for i in range(npp):
            p = base + i
            out[k, p] = out[k, p] * x[2, p]
