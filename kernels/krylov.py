"""The work of a Krylov basis (``steppers.krylov.KrylovBasis``: FGMRES's,
KIOPS's) stored as the rows of a 2-D array (k, n), n this process's part of a
unique-node vector: the vector passes of the CUDA backend (``KernelVectors``; on
a CPU the same passes run in numpy, ``HostVectors``, Warp's CPU kernels being
7–15× slower at them), and FGMRES's small dense work on every device.

Two vector kernels, each one pass over the vectors it reads:

* ``project_dots``: w −= Σ_{i<k_sub} h_i B_i, then the partial inner products
  B_i·w (i < k_dot) and w·w of the updated w — classical Gram–Schmidt's
  projection of one pass fused with the inner products of the next;
* ``lincomb``: out = c_k·x + Σ_{i<k} c_i B_i (a new basis vector, the update of
  the solution, the residual at a restart), every coefficient read from the
  device, so that FGMRES's come from its one-thread kernels without a host read.

Inner products are per-chunk partial sums over ``chunk`` entries in index order,
added in index order (on the device by ``Topology.device_sums``, as the Helmholtz
CG's): the bits do not depend on the CPU threads a launch is split over.

One-thread kernels (dim 1) keep FGMRES's Hessenberg matrix, Givens rotations
and residual estimate on the device (Saad 1993; Saad, *Iterative Methods for
Sparse Linear Systems*, 2nd ed., Alg. 6.9 and 9.6): ``fgmres_start`` (‖b‖, the
target), ``fgmres_cycle`` (a restart cycle's first vector), ``arnoldi_column``
(the column of H from the two Gram–Schmidt passes, its rotation, |g_{j+1}|, the
flag that ends the cycle) and ``fgmres_end`` (the triangular solve for y and the
residual's combination). ``info`` holds the solve's scalars (``INFO_*``).
"""

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@wp.kernel
def project_dots(
    B: wp.array2d(dtype=f64),
    k_sub: int,
    h: wp.array(dtype=f64),
    w: wp.array(dtype=f64),
    k_dot: int,
    partial: wp.array2d(dtype=f64),
    chunk: int,
    offset: int,
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
    B: wp.array2d(dtype=f64),
    k: int,
    c: wp.array(dtype=f64),
    x: wp.array(dtype=f64),
    out: wp.array(dtype=f64),
    offset: int,
):
    """out = c[k]·x + Σ_{i<k} c[i]·B[i] (out may alias x). Dim n."""
    p = wp.tid() + offset
    acc = c[k] * x[p]
    for i in range(k):
        acc += c[i] * B[i, p]
    out[p] = acc


# the solve's scalars in ``info``: |g| (the residual estimate), the target rtol·‖b‖, products
# with A so far, the steps of the current cycle, 1 after a breakdown (h_{j+1,j} = 0), maxiter
INFO_RESIDUAL = wp.constant(0)
INFO_TARGET = wp.constant(1)
INFO_ITS = wp.constant(2)
INFO_STEPS = wp.constant(3)
INFO_BREAKDOWN = wp.constant(4)
INFO_MAXITER = wp.constant(5)
INFO_SIZE = 6


@wp.kernel
def fgmres_start(bb: wp.array(dtype=f64), rtol: f64, maxiter: int, info: wp.array(dtype=f64)):
    """The solve's start from x = 0: |g| = ‖b‖ (bb[0] = b·b), target rtol·‖b‖. Dim 1."""
    beta = wp.sqrt(bb[0])
    info[INFO_RESIDUAL] = beta
    info[INFO_TARGET] = rtol * beta
    info[INFO_ITS] = f64(0.0)
    info[INFO_STEPS] = f64(0.0)
    info[INFO_BREAKDOWN] = f64(0.0)
    info[INFO_MAXITER] = f64(maxiter)


@wp.kernel
def fgmres_cycle(
    info: wp.array(dtype=f64), g: wp.array(dtype=f64), coef: wp.array(dtype=f64), go: wp.array(dtype=wp.int32)
):
    """A restart cycle's start from the residual r, β = |g| = ‖r‖: g = β e₁, coef[0] = 1/β
    (V₀ = r/β by ``lincomb`` with k = 0), and go = 1 unless ‖r‖ is already within
    the target (or zero) or the products are spent. Dim 1."""
    beta = info[INFO_RESIDUAL]
    for i in range(g.shape[0]):
        g[i] = f64(0.0)
    g[0] = beta
    info[INFO_STEPS] = f64(0.0)
    coef[0] = f64(0.0)
    go[0] = 0
    if beta > info[INFO_TARGET] and info[INFO_ITS] < info[INFO_MAXITER]:
        coef[0] = f64(1.0) / beta
        go[0] = 1


@wp.kernel
def arnoldi_column(
    j: int,
    h1: wp.array(dtype=f64),
    h2: wp.array(dtype=f64),
    H: wp.array2d(dtype=f64),
    cs: wp.array(dtype=f64),
    sn: wp.array(dtype=f64),
    g: wp.array(dtype=f64),
    coef: wp.array(dtype=f64),
    info: wp.array(dtype=f64),
    go: wp.array(dtype=wp.int32),
):
    """Arnoldi step j's column of H from classical Gram–Schmidt's two passes (h1[i], h2[i]
    = V_i·w of each, i ≤ j; h2[j+1] = ‖w‖² after the first), h_{j+1,j} = ‖w‖ after the
    second by Pythagoras (‖w₁‖² − ‖h2‖², exact for an orthonormal basis: no third pass);
    coef = (−h2/h_{j+1,j}, 1/h_{j+1,j}) for V_{j+1} (zeros after a breakdown); the
    earlier rotations and a new one on the column, g rotated; go = 0 once |g_{j+1}| is
    within the target, the products are spent, H breaks down or the cycle is full. Dim 1."""
    hh = f64(0.0)
    for i in range(j + 1):
        H[i, j] = h1[i] + h2[i]
        hh += h2[i] * h2[i]
    hn = wp.sqrt(wp.max(h2[j + 1] - hh, f64(0.0)))
    inv = f64(0.0)
    if hn > f64(0.0):
        inv = f64(1.0) / hn
    for i in range(j + 1):
        coef[i] = -h2[i] * inv
    coef[j + 1] = inv
    for i in range(j):  # the earlier Givens rotations on the new column
        a = H[i, j]
        b = H[i + 1, j]
        H[i, j] = cs[i] * a + sn[i] * b
        H[i + 1, j] = -sn[i] * a + cs[i] * b
    hjj = H[j, j]
    d = wp.sqrt(hjj * hjj + hn * hn)
    cs[j] = hjj / d
    sn[j] = hn / d
    H[j, j] = d
    H[j + 1, j] = f64(0.0)
    gj = g[j]
    g[j] = cs[j] * gj
    g[j + 1] = -sn[j] * gj
    its = info[INFO_ITS] + f64(1.0)
    info[INFO_ITS] = its
    info[INFO_STEPS] = f64(j + 1)
    info[INFO_RESIDUAL] = wp.abs(g[j + 1])
    if hn == f64(0.0):
        info[INFO_BREAKDOWN] = f64(1.0)
    if wp.abs(g[j + 1]) <= info[INFO_TARGET] or its >= info[INFO_MAXITER] or hn == f64(0.0) or j + 1 == cs.shape[0]:
        go[0] = 0


@wp.kernel
def fgmres_end(
    H: wp.array2d(dtype=f64),
    cs: wp.array(dtype=f64),
    sn: wp.array(dtype=f64),
    g: wp.array(dtype=f64),
    info: wp.array(dtype=f64),
    y: wp.array(dtype=f64),
    e: wp.array(dtype=f64),
):
    """A cycle's end after k = info[INFO_STEPS] steps: y (k) from the rotated triangular
    H[:k, :k] y = g[:k] (back substitution), y[k] = 1 (x += Σ y_i Z_i by ``lincomb``);
    e (k + 1) the residual's combination b − A x = V_{k+1} Qᵀ (0, …, 0, g_k) (no product
    with A), e[k+1] = 0. Dim 1."""
    k = int(info[INFO_STEPS])
    for ii in range(k):
        i = k - 1 - ii
        s = g[i]
        for l in range(i + 1, k):
            s -= H[i, l] * y[l]
        y[i] = s / H[i, i]
    y[k] = f64(1.0)
    for i in range(k):
        e[i] = f64(0.0)
    e[k] = g[k]
    for ii in range(k):
        i = k - 1 - ii
        ei = e[i]
        en = e[i + 1]
        e[i] = cs[i] * ei - sn[i] * en
        e[i + 1] = sn[i] * ei + cs[i] * en
    e[k + 1] = f64(0.0)
