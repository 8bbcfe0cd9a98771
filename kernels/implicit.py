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
    x: wp.array2d(dtype=f64),
    b: wp.array2d(dtype=f64),
    F: wp.array2d(dtype=f64),
    inv_dt: f64,
    beta: f64,
    R: wp.array2d(dtype=f64),
    block: int,
    offset: int,
):
    """R = (x − b)/Δt − β F(x). Dim (3, N/block), as ``blas.axpby``."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        R[r, p] = (x[r, p] - b[r, p]) * inv_dt - beta * F[r, p]


@wp.kernel
def gather(
    a: f64, v: wp.array2d(dtype=f64), first: wp.array(dtype=wp.int32), nu: int, out: wp.array(dtype=f64), offset: int
):
    """out = a·v at one copy of each unique node (v continuous). Dim (3, nunique)."""
    r, g = wp.tid()
    g = g + offset
    out[r * nu + g] = a * v[r, first[g]]


@wp.kernel
def jacobian_vector(
    w: wp.array(dtype=f64),
    F: wp.array2d(dtype=f64),
    Fp: wp.array2d(dtype=f64),
    first: wp.array(dtype=wp.int32),
    nu: int,
    shift: f64,
    eps: wp.array(dtype=f64),
    out: wp.array(dtype=f64),
    offset: int,
):
    """out = shift·w + c (F(x + εw) − F(x)) on unique nodes, c = eps[1] (scale/ε, from
    ``fd_epsilon``). Dim (3, nunique)."""
    r, g = wp.tid()
    g = g + offset
    q = first[g]
    out[r * nu + g] = w[r * nu + g] * shift + eps[1] * (Fp[r, q] - F[r, q])


@wp.kernel
def fd_epsilon(ww: wp.array(dtype=f64), xx: wp.array(dtype=f64), sqrt_eps: f64, scale: f64, eps: wp.array(dtype=f64)):
    """The forward difference's step from ww[0] = ‖w‖² and xx[0] = ‖x‖²: eps[0] = ε =
    sqrt(ε_mach)(1 + ‖x‖)/‖w‖, eps[1] = scale/ε; both 0 for w = 0 (then J w = 0). Dim 1."""
    eps[0] = f64(0.0)
    eps[1] = f64(0.0)
    if ww[0] > f64(0.0):
        e = sqrt_eps * (f64(1.0) + wp.sqrt(xx[0])) / wp.sqrt(ww[0])
        eps[0] = e
        eps[1] = scale / e


@wp.kernel
def add_scaled(x: wp.array2d(dtype=f64), eps: wp.array(dtype=f64), out: wp.array2d(dtype=f64), block: int, offset: int):
    """out = x + eps[0]·out (x + εw from the scattered w). Dim (3, N/block), as ``blas.axpby``."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        out[r, p] = x[r, p] + eps[0] * out[r, p]
