"""Pointwise pieces of the Jacobian-free Newton–Krylov stepper (HOMME ``implicit_mod``,
``residual``): residual, finite-difference Jacobian-vector product, the moves
between element-local (3, N) states and the Krylov vectors (3·nunique, row r
of unique node g at r·nunique + g; the state is continuous, so one copy per
node carries it all).
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def residual(
    x: wp.array2d(dtype=f64), b: wp.array2d(dtype=f64), F: wp.array2d(dtype=f64), inv_dt: f64, beta: f64, R: wp.array2d(dtype=f64),
    block: int, offset: int,
):
    """R = (x − b)/Δt − β F(x). Dim (3, N/block), as ``blas.axpby``."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        R[r, p] = (x[r, p] - b[r, p]) * inv_dt - beta * F[r, p]


@wp.kernel
def gather(a: f64, v: wp.array2d(dtype=f64), first: wp.array(dtype=wp.int32), nu: int, out: wp.array(dtype=f64), offset: int):
    """out = a·v at one copy of each unique node (v continuous). Dim (3, nunique)."""
    r, g = wp.tid()
    g = g + offset
    out[r * nu + g] = a * v[r, first[g]]


@wp.kernel
def jacobian_vector(
    w: wp.array(dtype=f64), F: wp.array2d(dtype=f64), Fp: wp.array2d(dtype=f64), first: wp.array(dtype=wp.int32), nu: int,
    inv_dt: f64, beta_over_eps: f64, out: wp.array(dtype=f64), offset: int,
):
    """J w ≈ w/Δt − β (F(x + εw) − F(x))/ε on unique nodes. Dim (3, nunique)."""
    r, g = wp.tid()
    g = g + offset
    q = first[g]
    out[r * nu + g] = w[r * nu + g] * inv_dt - beta_over_eps * (Fp[r, q] - F[r, q])
