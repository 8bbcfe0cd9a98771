"""The vector work of a Krylov basis (``steppers.krylov.KrylovBasis``: FGMRES's,
KIOPS's) stored as the rows of a 2-D array (k, n), n this process's part of a
unique-node vector: the CUDA backend (``KernelVectors``; on a CPU the same work
runs in numpy, ``HostVectors``, Warp's CPU kernels being 7–15× slower at it).

Two kernels, each one pass over the vectors it reads:

* ``project_dots``: w −= Σ_{i<k_sub} h_i B_i, then the partial inner products
  B_i·w (i < k_dot) and w·w of the updated w — classical Gram–Schmidt's
  projection of one pass fused with the inner products of the next;
* ``lincomb``: out = a·x + Σ_{i<k} c_i B_i (a new basis vector, the update of
  the solution, the residual at a restart).

Inner products are per-chunk partial sums over ``chunk`` entries in index order,
added on the host in a fixed order (as the Helmholtz CG's, ``kernels.helmholtz``):
the bits do not depend on the CPU threads a launch is split over.
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def project_dots(
    B: wp.array2d(dtype=f64), k_sub: int, h: wp.array(dtype=f64), w: wp.array(dtype=f64), k_dot: int,
    partial: wp.array2d(dtype=f64), chunk: int, offset: int,
):
    """w −= Σ_{i<k_sub} h[i]·B[i]; partial[i, t] = Σ B[i]·w over chunk t (i < k_dot),
    partial[k_dot, t] = Σ w·w. Dim ceil(n / chunk)."""
    t = wp.tid() + offset
    lo = t * chunk
    hi = wp.min(w.shape[0], lo + chunk)
    for p in range(lo, hi):
        acc = w[p]
        for i in range(k_sub):
            acc -= h[i] * B[i, p]
        w[p] = acc
    for i in range(k_dot):
        s = f64(0.0)
        for p in range(lo, hi):
            s += B[i, p] * w[p]
        partial[i, t] = s
    s = f64(0.0)
    for p in range(lo, hi):
        s += w[p] * w[p]
    partial[k_dot, t] = s


@wp.kernel
def lincomb(
    B: wp.array2d(dtype=f64), k: int, c: wp.array(dtype=f64), a: f64, x: wp.array(dtype=f64), out: wp.array(dtype=f64),
    offset: int,
):
    """out = a·x + Σ_{i<k} c[i]·B[i] (out may alias x). Dim n."""
    p = wp.tid() + offset
    acc = a * x[p]
    for i in range(k):
        acc += c[i] * B[i, p]
    out[p] = acc
