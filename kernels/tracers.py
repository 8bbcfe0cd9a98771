"""Pointwise kernels of the passive tracers' ∇⁴ (``model.hyperviscosity.Hyperviscosity.apply_tracers``).

A tracer's mass hq takes the ∇⁴ the depth takes, acting on q(h + hs) = hq + q·hs where the
depth's acts on h + hs: the weak ∇⁴ of any field sums to zero over the sphere, so the tracer's
mass is conserved, and where q = 1 (hq = h to the bit) it is h's ∇⁴ to the bit, so q = 1
stays 1 (HOMME keeps that consistency by a tracer flux of the depth's dissipation,
``prim_advection_mod``'s dpdiss; here the field the ∇⁴ acts on carries it).
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def tracer_surface(
    x: wp.array2d(dtype=f64),
    row: int,
    hs: wp.array(dtype=f64),
    w: wp.array2d(dtype=f64),
    hs_q: wp.array(dtype=f64),
    block: int,
    offset: int,
):
    """w[2] = x[row] (a tracer's mass hq, m) and hs_q = (hq / h)·hs (m), the surface term the
    ∇⁴ adds to w[2] (q·hs: hs itself, to the bit, where hq = h). Dim N/block."""
    k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        hq = x[row, p]
        w[2, p] = hq
        hs_q[p] = hq / x[2, p] * hs[p]
