"""Direct stiffness summation (HOMME ``bndry_exchangev`` + ``rspheremp`` scaling), gather form.

Every element-local copy of a unique node gathers the sum over all copies, so
the kernel needs no atomics and gives the same bits on CPU and CUDA.
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def dss(
    x: wp.array2d(dtype=f64),
    weighted: int,
    spheremp: wp.array(dtype=f64),
    rspheremp: wp.array(dtype=f64),
    gid: wp.array(dtype=wp.int32),
    offsets: wp.array(dtype=wp.int32),
    copies: wp.array(dtype=wp.int32),
    out: wp.array2d(dtype=f64),
):
    """out[r, p] = rspheremp[p] · Σ_copies c of p's node (spheremp[c] if weighted else 1) · x[r, c].

    ``weighted = 1`` for a strong-form field (mass-weighted average: continuous
    result, area integral kept); ``0`` for a weak form already integrated
    against the test functions. ``out`` must not alias ``x``. Dim (rows, N).
    """
    r, p = wp.tid()
    g = gid[p]
    s = f64(0.0)
    for k in range(offsets[g], offsets[g + 1]):
        c = copies[k]
        if weighted != 0:
            s += spheremp[c] * x[r, c]
        else:
            s += x[r, c]
    out[r, p] = rspheremp[p] * s


@wp.kernel
def assemble(
    x: wp.array2d(dtype=f64),
    row: int,
    spheremp: wp.array(dtype=f64),
    offsets: wp.array(dtype=wp.int32),
    copies: wp.array(dtype=wp.int32),
    out: wp.array(dtype=f64),
):
    """Unique-node vector out[g] = Σ_copies c of g spheremp[c]·x[row, c]: the assembled
    mass matrix times a continuous field (m² × units of x). Dim nunique."""
    g = wp.tid()
    s = f64(0.0)
    for k in range(offsets[g], offsets[g + 1]):
        c = copies[k]
        s += spheremp[c] * x[row, c]
    out[g] = s


@wp.kernel
def scatter(y: wp.array(dtype=f64), gid: wp.array(dtype=wp.int32), row: int, out: wp.array2d(dtype=f64)):
    """Element-local out[row, p] = y[gid[p]] from a unique-node vector. Dim N."""
    p = wp.tid()
    out[row, p] = y[gid[p]]
