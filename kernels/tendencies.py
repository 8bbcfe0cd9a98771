"""Per-term tendencies of the vector-invariant shallow-water equations
(Williamson et al. 1992, eqs. 2–3 in vector-invariant form; HOMME
``sweq_mod``/``compute_and_apply_rhs``):

    ∂v/∂t = −(ζ + f) k×v − ∇(½|v|² + g(h + hs)),    ∂h/∂t = −∇·(h v).

Each kernel adds one term to the element-local tendency ``tend`` (rows
du/dt, dv/dt, dh/dt; k×v = (−v, u)); the model launches only the terms its
scene names, then applies the DSS. Dim N.
"""

import warp as wp

from .operators import d_eta, d_xi, element_node, vorticity_at

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def continuity(x: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, tend: wp.array2d(dtype=f64), offset: int):
    """dh/dt −= ∇·(h v)."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np)
    s = f64(0.0)
    for m in range(np):
        q = base + j * np + m
        s += dvv[i, m] * metdet[q] * x[2, q] * (Dinv[0, q] * x[0, q] + Dinv[1, q] * x[1, q])
        q = base + m * np + i
        s += dvv[j, m] * metdet[q] * x[2, q] * (Dinv[2, q] * x[0, q] + Dinv[3, q] * x[1, q])
    tend[2, p] = tend[2, p] - s / metdet[p]


@wp.kernel
def momentum_advection(x: wp.array2d(dtype=f64), D: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, tend: wp.array2d(dtype=f64), offset: int):
    """dv/dt += −ζ k×v − ∇(½|v|²)."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np)
    a = f64(0.0)
    b = f64(0.0)
    for m in range(np):
        q = base + j * np + m
        a += dvv[i, m] * f64(0.5) * (x[0, q] * x[0, q] + x[1, q] * x[1, q])
        q = base + m * np + i
        b += dvv[j, m] * f64(0.5) * (x[0, q] * x[0, q] + x[1, q] * x[1, q])
    zeta = vorticity_at(x, p, np, D, metdet, dvv)
    tend[0, p] = tend[0, p] + zeta * x[1, p] - (Dinv[0, p] * a + Dinv[2, p] * b)
    tend[1, p] = tend[1, p] - zeta * x[0, p] - (Dinv[1, p] * a + Dinv[3, p] * b)


@wp.kernel
def coriolis(x: wp.array2d(dtype=f64), fcor: wp.array(dtype=f64), tend: wp.array2d(dtype=f64), offset: int):
    """dv/dt += −f k×v."""
    p = wp.tid() + offset
    tend[0, p] = tend[0, p] + fcor[p] * x[1, p]
    tend[1, p] = tend[1, p] - fcor[p] * x[0, p]


@wp.kernel
def pressure_gradient(x: wp.array2d(dtype=f64), g: f64, Dinv: wp.array2d(dtype=f64), dvv: wp.array2d(dtype=f64), np: int, tend: wp.array2d(dtype=f64), offset: int):
    """dv/dt += −g ∇h."""
    p = wp.tid() + offset
    base, i, j = element_node(p, np)
    a = d_xi(x, 2, base, i, j, np, dvv)
    b = d_eta(x, 2, base, i, j, np, dvv)
    tend[0, p] = tend[0, p] - g * (Dinv[0, p] * a + Dinv[2, p] * b)
    tend[1, p] = tend[1, p] - g * (Dinv[1, p] * a + Dinv[3, p] * b)


@wp.kernel
def add_wind_forcing(forcing: wp.array2d(dtype=f64), tend: wp.array2d(dtype=f64), offset: int):
    """dv/dt += a time-independent forcing (rows 0, 1), e.g. the topographic −g∇hs."""
    p = wp.tid() + offset
    tend[0, p] = tend[0, p] + forcing[0, p]
    tend[1, p] = tend[1, p] + forcing[1, p]
