"""Pointwise pieces of the linear gravity-wave operator about a mean depth H
(``steppers.helmholtz.GravityWave``): L_v = −g G h, L_h = −H D v, with
G = DSS∘grad and D = DSS∘div the model's strong operators, and the two
element-wise halves of the Schur-complement solve of (I − aL) z = s·r:

    (I − a²gH DG) z_h = s (r_h − aH D r_v),    z_v = s r_v − a g G z_h,

the latter also writing L z = (z − s r)/a for an IMEX stage (``schur_wind_implicit``).

Dim (3, N/block) with trailing ``block`` and ``offset``, as ``blas.axpby``.
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def apply(
    Gh: wp.array2d(dtype=f64), Dv: wp.array2d(dtype=f64), g: f64, H: f64, out: wp.array2d(dtype=f64), block: int, offset: int,
):
    """out = L x from G h (rows 0, 1) and D v (row 0): (−g G h, −H D v)."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        if r < 2:
            out[r, p] = -g * Gh[r, p]
        else:
            out[r, p] = -H * Dv[0, p]


@wp.kernel
def schur_height(
    rhs: wp.array2d(dtype=f64), Dr: wp.array2d(dtype=f64), s: f64, aH: f64, z: wp.array2d(dtype=f64), block: int, offset: int,
):
    """z_h = s (r_h − aH D r_v): the Helmholtz right-hand side (row 2 only)."""
    r, k = wp.tid()
    if r == 2:
        start = (k + offset) * block
        for p in range(start, start + block):
            z[2, p] = s * (rhs[2, p] - aH * Dr[0, p])


@wp.kernel
def schur_wind(
    rhs: wp.array2d(dtype=f64), Gz: wp.array2d(dtype=f64), s: f64, ag: f64, z: wp.array2d(dtype=f64), block: int, offset: int,
):
    """z_v = s r_v − a g G z_h (rows 0, 1 only)."""
    r, k = wp.tid()
    if r < 2:
        start = (k + offset) * block
        for p in range(start, start + block):
            z[r, p] = s * rhs[r, p] - ag * Gz[r, p]



@wp.kernel
def schur_wind_implicit(
    rhs: wp.array2d(dtype=f64), Gz: wp.array2d(dtype=f64), s: f64, ag: f64, z: wp.array2d(dtype=f64), ia: f64, mis: f64,
    lz: wp.array2d(dtype=f64), block: int, offset: int,
):
    """``schur_wind`` (z_v = s r_v − a g G z_h; z_h already in row 2), and lz = L z = (z − s r)/a
    as ia·z + mis·r (ia = 1/a, mis = −s/a: ``blas.axpby``'s bits) in all rows: an IMEX stage's
    implicit tendency with no pass of its own. lz may alias rhs, not z."""
    r, k = wp.tid()
    start = (k + offset) * block
    for p in range(start, start + block):
        rp = rhs[r, p]
        zp = z[2, p]
        if r < 2:
            zp = s * rp - ag * Gz[r, p]
            z[r, p] = zp
        lz[r, p] = ia * zp + mis * rp
