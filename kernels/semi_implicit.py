"""Pointwise updates of the semi-implicit leapfrog step (HOMME ``advance_si_nonstag``).

Linear gravity-wave part about the mean depth H: L_v = −g∇h, L_h = −H∇·v;
N = F − L. With G = DSS∘grad, D = DSS∘div, c = Δt²gH:
  (I − c DG) h⁺ = R = h⁻ + 2Δt N_h − 2Δt H D(v⁻ + Δt N_v) + c DG h⁻
  v⁺ = v⁻ + 2Δt N_v − Δt g G(h⁺ + h⁻).
Dim N.
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def half_wind(x_old: wp.array2d(dtype=f64), F: wp.array2d(dtype=f64), g: f64, Gh: wp.array2d(dtype=f64), dt: f64, w: wp.array2d(dtype=f64)):
    """w = v⁻ + Δt N_v with N_v = F_v + g G h (rows 0, 1)."""
    p = wp.tid()
    for r in range(2):
        w[r, p] = x_old[r, p] + dt * (F[r, p] + g * Gh[r, p])


@wp.kernel
def height_rhs(
    x_old: wp.array2d(dtype=f64),
    F: wp.array2d(dtype=f64),
    H: f64,
    Dv: wp.array(dtype=f64),
    Dw: wp.array(dtype=f64),
    c: f64,
    DGh_old: wp.array(dtype=f64),
    dt: f64,
    R: wp.array2d(dtype=f64),
):
    """R = h⁻ + 2Δt (F_h + H D v) − 2Δt H D w + c DG h⁻ (row 0 of R)."""
    p = wp.tid()
    R[0, p] = x_old[2, p] + f64(2.0) * dt * (F[2, p] + H * Dv[p]) - f64(2.0) * dt * H * Dw[p] + c * DGh_old[p]


@wp.kernel
def new_wind(
    x_old: wp.array2d(dtype=f64),
    F: wp.array2d(dtype=f64),
    g: f64,
    Gh: wp.array2d(dtype=f64),
    Gh_new: wp.array2d(dtype=f64),
    Gh_old: wp.array2d(dtype=f64),
    dt: f64,
    x_new: wp.array2d(dtype=f64),
):
    """v⁺ = v⁻ + 2Δt (F_v + g G h) − Δt g (G h⁺ + G h⁻)."""
    p = wp.tid()
    for r in range(2):
        x_new[r, p] = x_old[r, p] + f64(2.0) * dt * (F[r, p] + g * Gh[r, p]) - dt * g * (Gh_new[r, p] + Gh_old[r, p])


@wp.kernel
def helmholtz(y: wp.array2d(dtype=f64), c: f64, DGy: wp.array2d(dtype=f64)):
    """DGy[0] = y[2] − c·DGy[0]: (I − c DG) y, element-local."""
    p = wp.tid()
    DGy[0, p] = y[2, p] - c * DGy[0, p]
