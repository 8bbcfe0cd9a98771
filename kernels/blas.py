"""Element-wise linear algebra on state arrays (rows, N) for the steppers.

Pointwise kernels over (rows, N) take ``block``: each thread does ``block``
consecutive nodes (np² on the CPU, where Warp's per-thread cost would
otherwise exceed the arithmetic; 1 on CUDA). Dim (rows, N/block); ``offset``
counts blocks.
"""

import functools
from typing import Any

import warp as wp

from .dss import combination
from .operators import suffix

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def axpby(
    a: f64,
    x: wp.array2d(dtype=f64),
    b: f64,
    y: wp.array2d(dtype=f64),
    out: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """out = a·x + b·y (out may alias x or y). Dim (rows, N/block)."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        out[r, p] = a * x[r, p] + b * y[r, p]


@wp.kernel
def axpbypcz(
    a: f64,
    x: wp.array2d(dtype=f64),
    b: f64,
    y: wp.array2d(dtype=f64),
    c: f64,
    z: wp.array2d(dtype=f64),
    out: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """out = a·x + b·y + c·z (out may alias any input). Dim (rows, N/block)."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        out[r, p] = a * x[r, p] + b * y[r, p] + c * z[r, p]


@wp.kernel
def axpbypczpdw(
    a: f64,
    x: wp.array2d(dtype=f64),
    b: f64,
    y: wp.array2d(dtype=f64),
    c: f64,
    z: wp.array2d(dtype=f64),
    d: f64,
    w: wp.array2d(dtype=f64),
    out: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """out = a·x + b·y + c·z + d·w (out may alias any input). Dim (rows, N/block)."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        out[r, p] = a * x[r, p] + b * y[r, p] + c * z[r, p] + d * w[r, p]


@wp.kernel
def axpbypczpdw_at(
    a: f64,
    x: wp.array2d(dtype=f64),
    b: f64,
    y: wp.array2d(dtype=f64),
    c: f64,
    z: wp.array2d(dtype=f64),
    d: f64,
    w: wp.array2d(dtype=f64),
    out: wp.array2d(dtype=f64),
    nodes: wp.array(dtype=wp.int32),
    block: int,
    offset: int,
):
    """``axpbypczpdw`` (the same bits) on states (3, N) at the listed nodes only: out[r, p] =
    a·x + b·y + c·z + d·w for p = nodes[i], i the thread's ``block`` consecutive entries
    of ``nodes``, every row; out's other nodes are not written (a local time step's sums
    over the nodes a level holds). The three rows in one thread, unrolled: half the CPU
    time of a thread a row. Dim ceil(len(nodes)/block)."""
    start = (wp.tid() + offset) * block
    for i in range(start, wp.min(start + block, nodes.shape[0])):
        p = nodes[i]
        for r in range(3):
            out[r, p] = a * x[r, p] + b * y[r, p] + c * z[r, p] + d * w[r, p]


@functools.cache
def combined_state(arrays: int, state):
    """out = c₀·x (``arrays`` 1) or c₀·x + c₁·y (2) of a float32 state's arrays (``state`` its
    float type; out may alias either) in the arithmetic of the float32 stages' DSS updates
    (``dss.combination``'s float32 form: the weights rounded once, two arrays as
    (c₀ + c₁)·y + c₀·(x − y), so that weights summing to 1 keep a constant to the bit): a stage's
    rows that its tendency does not write (a model without the continuity, or with it alone). Kernel
    (c, x, y, out, block, offset), c a vec3d; dim (rows, N/block)."""
    combine = combination("a" * int(arrays), state)

    def kernel(
        c: wp.vec3d,
        x: wp.array2d(dtype=state),
        y: wp.array2d(dtype=state),
        out: wp.array2d(dtype=state),
        block: int,
        offset: int,
    ):
        r, k = wp.tid()
        start = (k + offset) * block
        for p in range(start, start + block):
            out[r, p] = combine(c, state(0.0), x, y, r, p)

    kernel.__qualname__ = kernel.__name__ = f"combined_{arrays}" + suffix(state)
    return wp.kernel(kernel, enable_backward=False, module="unique")


@wp.kernel
def chunk_sums(src: wp.array2d(dtype=f64), chunk: int, dst: wp.array2d(dtype=f64)):
    """dst[r, t] = Σ src[r, t·chunk : (t+1)·chunk] in index order: partial sums of
    partial sums, so that fewer come back to the host. Dim (rows, ceil(n / chunk))."""
    r, t = wp.tid()
    lo = t * chunk
    s = f64(0.0)
    for i in range(lo, wp.min(src.shape[1], lo + chunk)):
        s += src[r, i]
    dst[r, t] = s


@wp.kernel
def row_totals(src: wp.array2d(dtype=f64), out: wp.array(dtype=f64)):
    """out[r] = Σ src[r, :] in index order, one thread: the totals of a chunked inner
    product's partial sums on the device, in the order the host would add them.
    Dim 1."""
    for r in range(src.shape[0]):
        s = f64(0.0)
        for i in range(src.shape[1]):
            s += src[r, i]
        out[r] = s


@wp.kernel
def first_bad_node(
    x: wp.array2d(dtype=Any), check_depth: int, h0: f64, first: wp.array(dtype=wp.int32), block: int, offset: int
):
    """first[0] = min index p where u, v or h is not finite, or (if check_depth) the depth
    h + h0 ≤ 0 (h0 0 for a float64 state, H₀ for a float32 one's h − H₀: ``kernels.departure``);
    unchanged if there is none. Dim N/block: a thread's first bad node of its ``block`` nodes
    only (the smallest of them)."""
    start = (wp.tid() + offset) * block
    for p in range(start, start + block):
        u, v, h = x[0, p], x[1, p], x[2, p]
        # a − a is exactly 0 for a finite a and NaN otherwise (IEEE 754, no fast-math here):
        # one comparison for the three, a fifth cheaper than three isfinite on the CPU
        ok = (u - u) + (v - v) + (h - h) == x.dtype(0.0)
        if check_depth != 0:
            ok = ok and f64(h) + h0 > f64(0.0)
        if not ok:
            wp.atomic_min(first, 0, p)
            return
