"""The run file's cells (``swe_sphere.io.dual``): spherical polygons on the unit sphere, one
thread a cell, on the CPU.

A cell is ``verts[closed[c]]`` (its vertex indices, counter-clockwise seen from outside,
padded with repeats of its last vertex: zero-length edges) fanned from a point ``centre[c]``
inside it. Triangle (n, a, b) of the fan has the area E = 2 atan2(N, D), N = n·(a × b),
D = 1 + n·a + a·b + b·n (van Oosterom & Strackee 1983, IEEE Trans. Biomed. Eng. 30:125), and
dE = 2 (D dN − N dD) / (N² + D²) with ∂N/∂a = b × n, ∂D/∂a = n + b, ∂N/∂b = n × a,
∂D/∂b = n + a.
"""

import warp as wp

f64 = wp.float64
vec3 = wp.vec3d
wp.set_module_options({"enable_backward": False})


@wp.kernel
def fan_areas(
    centre: wp.array(dtype=vec3),
    verts: wp.array(dtype=vec3),
    closed: wp.array2d(dtype=wp.int32),
    gradients: int,
    area: wp.array(dtype=f64),
    grad: wp.array2d(dtype=vec3),
    star: wp.array(dtype=wp.int32),
):
    """area[c] = Σ over the fan's triangles of 2 atan2(N, D), summed vertex by vertex; star[c] =
    1 where every triangle has N > 0 or a zero-length edge (the cell is star-shaped from its
    centre, hence simple), else 0; with ``gradients`` ≠ 0, grad[c, k] = ∂area/∂(vertex k)
    (the triangle it starts plus the one it ends, in that order). Dim ncell."""
    c = wp.tid()
    n = centre[c]
    nv = closed.shape[1]
    first = verts[closed[c, 0]]
    a = first
    s = f64(0.0)
    ok = wp.int32(1)
    ends = vec3()  # ∂E/∂b of the triangle before: its end is this triangle's start
    for k in range(nv):
        b = first
        if k + 1 < nv:
            b = verts[closed[c, k + 1]]
        N = wp.dot(n, wp.cross(a, b))
        D = f64(1.0) + wp.dot(n, a) + wp.dot(a, b) + wp.dot(n, b)
        s += wp.atan2(N, D)
        if not (N > f64(0.0) or (a[0] == b[0] and a[1] == b[1] and a[2] == b[2])):  # NaN: not star-shaped
            ok = 0
        if gradients != 0:
            q = f64(2.0) / (N * N + D * D)
            starts = q * (D * wp.cross(b, n) - N * (n + b))
            if k > 0:
                grad[c, k] = starts + ends
            else:
                grad[c, 0] = starts
            ends = q * (D * wp.cross(n, a) - N * (n + a))
        a = b
    if gradients != 0:
        grad[c, 0] = grad[c, 0] + ends
    area[c] = f64(2.0) * s
    star[c] = ok


@wp.kernel
def convex(verts: wp.array(dtype=vec3), corners: wp.array2d(dtype=wp.int32), out: wp.array(dtype=wp.int32)):
    """out[c] = 1 where cell c (``corners``: −1-padded, the −1s last) turns left at every vertex
    seen from outside, ((b − a) × (c − b)) · b = a · (b × c) > 0 for consecutive vertices a, b,
    c, else 0. Dim ncell."""
    c = wp.tid()
    count = wp.int32(0)
    for k in range(corners.shape[1]):
        if corners[c, k] >= 0:
            count += 1
    ok = wp.int32(1)
    for k in range(count):
        a = verts[corners[c, (k + count - 1) % count]]
        b = verts[corners[c, k]]
        d = verts[corners[c, (k + 1) % count]]
        if not (wp.dot(a, wp.cross(b, d)) > f64(0.0)):  # NaN: not convex
            ok = 0
    out[c] = ok
