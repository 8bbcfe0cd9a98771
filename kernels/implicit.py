"""Pointwise pieces of the Jacobian-free Newton–Krylov stepper (HOMME ``implicit_mod``,
``residual``): residual, finite-difference Jacobian-vector product and the
gravity-wave (Helmholtz) preconditioner's element-wise updates. Dim (3, N) or N.
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
def jacobian_vector(
    v: wp.array2d(dtype=f64), F: wp.array2d(dtype=f64), Fp: wp.array2d(dtype=f64), inv_dt: f64, beta_over_eps: f64,
    out: wp.array2d(dtype=f64), block: int, offset: int,
):
    """J v ≈ v/Δt − β (F(x + εv) − F(x))/ε. Dim (3, N/block), as ``blas.axpby``."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        out[r, p] = v[r, p] * inv_dt - beta_over_eps * (Fp[r, p] - F[r, p])


@wp.kernel
def precond_height(r: wp.array2d(dtype=f64), Dr: wp.array2d(dtype=f64), dt: f64, beta_dt_H: f64, out: wp.array2d(dtype=f64)):
    """out[0] = Δt (r_h − βΔtH D r_v): the Helmholtz right-hand side. Dim N."""
    p = wp.tid()
    out[0, p] = dt * (r[2, p] - beta_dt_H * Dr[0, p])


@wp.kernel
def precond_wind(r: wp.array2d(dtype=f64), Gz: wp.array2d(dtype=f64), dt: f64, beta_g: f64, z: wp.array2d(dtype=f64)):
    """z_v = Δt (r_v − βg G z_h). Dim N."""
    p = wp.tid()
    for c in range(2):
        z[c, p] = dt * (r[c, p] - beta_g * Gz[c, p])
