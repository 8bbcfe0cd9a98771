"""The per-node terms of an error estimate's weighted RMS norm (``steppers.control.ErrorNorm``)."""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def weighted_squares(
    e: wp.array2d(dtype=f64),
    x0: wp.array2d(dtype=f64),
    x1: wp.array2d(dtype=f64),
    first: wp.array(dtype=wp.int32),
    atol: wp.array(dtype=f64),
    rtol: f64,
    check_depth: int,
    block: int,
    out: wp.array(dtype=f64),
    offset: int,
):
    """out[i] = Σ_r (e[r, p] / (atol[r] + rtol·max(|x0[r, p]|, |x1[r, p]|)))² over the rows r of the
    states (3, N), at the unique node p = first[i] (its first copy); +inf where (``check_depth``
    ≠ 0) x1's depth h = x1[2, p] ≤ 0, so that a finite sum is a state whose every node is finite
    and wet. Dim ceil(len(first) / block): ``block`` consecutive i a thread (a CPU thread's
    fixed cost against its work; 1 on CUDA), the blocks from ``offset`` on (``core.parallel``)."""
    start = (wp.tid() + offset) * block
    for i in range(start, wp.min(start + block, first.shape[0])):
        p = first[i]
        s = f64(0.0)
        for r in range(3):
            q = e[r, p] / (atol[r] + rtol * wp.max(wp.abs(x0[r, p]), wp.abs(x1[r, p])))
            s += q * q
        if check_depth != 0 and not x1[2, p] > f64(0.0):
            s = f64(wp.inf)
        out[i] = s


@wp.kernel
def courant_squares(
    x: wp.array2d(dtype=f64),
    rdx2: wp.array(dtype=f64),
    g: f64,
    check_depth: int,
    block: int,
    out: wp.array2d(dtype=f64),
    offset: int,
):
    """Over the ``block`` element-local nodes p of block k = tid + offset of the state x (3, N):
    out[0, k] = max (u² + v²)/Δx², out[1, k] = max g·max(h, 0)/Δx² (``rdx2`` = 1/Δx², m⁻²),
    out[2, k] = 1 where a node is bad (u, v or h not finite, or with ``check_depth`` h ≤ 0), else
    0: the squares of ``model.diagnostics.courant_numbers``' maxima over Δt (s⁻²), a slot a block
    (no race, the same maxima however the blocks are split)."""
    k = wp.tid() + offset
    adv, grav, bad = f64(0.0), f64(0.0), f64(0.0)
    for p in range(k * block, wp.min((k + 1) * block, x.shape[1])):
        u, v, h = x[0, p], x[1, p], x[2, p]
        if not ((u - u) + (v - v) + (h - h) == f64(0.0)) or (check_depth != 0 and not h > f64(0.0)):
            bad = f64(1.0)
        adv = wp.max(adv, (u * u + v * v) * rdx2[p])
        grav = wp.max(grav, g * wp.max(h, f64(0.0)) * rdx2[p])
    out[0, k] = adv
    out[1, k] = grav
    out[2, k] = bad


@wp.kernel
def pairwise_leaves(
    terms: wp.array(dtype=f64),
    starts: wp.array(dtype=wp.int32),
    lengths: wp.array(dtype=wp.int32),
    out: wp.array(dtype=f64),
    offset: int,
):
    """out[i] = the sum of terms[starts[i] : starts[i] + lengths[i]] (at most 128 terms) in
    numpy's order for such a leaf of its pairwise summation (``pairwise_sum`` in numpy's
    ``loops_utils.h``): under 8 terms one after another from 0; else eight running sums of
    every eighth term, added as ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7)), then the
    terms past the last multiple of 8 one after another. Additions only (nothing to contract
    into an FMA), so the same bits on a CPU and CUDA. Dim the leaves, from ``offset`` on."""
    i = wp.tid() + offset
    s = starts[i]
    n = lengths[i]
    res = f64(0.0)
    if n < 8:
        for j in range(n):
            res += terms[s + j]
    else:
        r0 = terms[s]
        r1 = terms[s + 1]
        r2 = terms[s + 2]
        r3 = terms[s + 3]
        r4 = terms[s + 4]
        r5 = terms[s + 5]
        r6 = terms[s + 6]
        r7 = terms[s + 7]
        m = n - n % 8
        for j in range(8, m, 8):
            k = s + j
            r0 += terms[k]
            r1 += terms[k + 1]
            r2 += terms[k + 2]
            r3 += terms[k + 3]
            r4 += terms[k + 4]
            r5 += terms[k + 5]
            r6 += terms[k + 6]
            r7 += terms[k + 7]
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        for j in range(m, n):
            res += terms[s + j]
    out[i] = res
