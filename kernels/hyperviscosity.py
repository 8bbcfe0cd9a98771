"""Pointwise pieces of the ∇⁴ hyperviscosity (HOMME ``advance_hypervis``).

The wind is diffused through its 3-D Cartesian components, which are smooth
across the poles and panel edges; the tangential projection of the
componentwise Laplacian is the vector Laplacian ∇(∇·v) − ∇×∇×v. The height
diffused is the free surface h + hs (smooth over the TC5 cone, unlike h).
Rows of the work array X: 0..2 Cartesian wind, 3 free surface. Dim N.
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def to_cartesian(x: wp.array2d(dtype=f64), hs: wp.array(dtype=f64), east: wp.array2d(dtype=f64), north: wp.array2d(dtype=f64), X: wp.array2d(dtype=f64), offset: int):
    """X[0:3] = u·east + v·north; X[3] = h + hs."""
    p = wp.tid() + offset
    for c in range(3):
        X[c, p] = x[0, p] * east[c, p] + x[1, p] * north[c, p]
    X[3, p] = x[2, p] + hs[p]


@wp.kernel
def project_tangent(X: wp.array2d(dtype=f64), xyz: wp.array2d(dtype=f64), offset: int):
    """X[0:3] −= (X·r̂) r̂: keep the part of the Cartesian vector tangent to the sphere."""
    p = wp.tid() + offset
    d = X[0, p] * xyz[0, p] + X[1, p] * xyz[1, p] + X[2, p] * xyz[2, p]
    for c in range(3):
        X[c, p] = X[c, p] - d * xyz[c, p]


@wp.kernel
def apply(Y: wp.array2d(dtype=f64), coef: f64, east: wp.array2d(dtype=f64), north: wp.array2d(dtype=f64), x: wp.array2d(dtype=f64), offset: int):
    """x += coef·Y with Y's Cartesian wind taken back to (east, north) components."""
    p = wp.tid() + offset
    ye = f64(0.0)
    yn = f64(0.0)
    for c in range(3):
        ye += Y[c, p] * east[c, p]
        yn += Y[c, p] * north[c, p]
    x[0, p] = x[0, p] + coef * ye
    x[1, p] = x[1, p] + coef * yn
    x[2, p] = x[2, p] + coef * Y[3, p]
