"""Direct stiffness summation (HOMME ``bndry_exchangev`` + ``rspheremp`` scaling), gather form.

Every element-local copy of a unique node gathers the sum over all copies, so
the kernel needs no atomics and gives the same bits on CPU and CUDA. Copies
held by other processes arrive in a ghost buffer (``pack`` on the sender,
``swe_sphere.topology`` exchanges), and the sum runs over all copies in one
global order, so the bits do not depend on which process holds which copy.
"""

import functools

import warp as wp

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@functools.cache
def dss_rows(rows: int, weighted: bool, copies: int, ghosts: bool = False):
    """The DSS kernel for ``rows`` rows and ``copies`` columns of the
    ``dss_table`` (its own Warp module, kernel key ``dss``):
    out[r, p] = rspheremp[p] · Σ_copies c of p's node (spheremp[c] if weighted
    else 1) · x[r, c]. ``weighted`` for a strong-form field (mass-weighted
    average: continuous result, area integral kept); unweighted for a weak form
    already integrated against the test functions. ``out`` must not alias ``x``.
    Every copy sums in the same order, so all copies get the same bits. The
    copies come from one table row per node (no CSR indirection) and the row
    sums stay in registers: 2.6× faster on the CPU than a CSR gather. Dim N.

    With ``ghosts``, a copy c ≥ ``nlocal`` is another process's, read from
    ghost[(c − nlocal)·rows + r] (``pack``'s layout); spheremp has an entry
    for every c. Without, ghost and nlocal are not read."""
    R, W, C, G = int(rows), bool(weighted), int(copies), bool(ghosts)
    acc = wp.types.vector(length=R, dtype=f64)

    def dss(
        x: wp.array2d(dtype=f64),
        ghost: wp.array(dtype=f64),
        nlocal: int,
        spheremp: wp.array(dtype=f64),
        rspheremp: wp.array(dtype=f64),
        table: wp.array2d(dtype=wp.int32),
        out: wp.array2d(dtype=f64),
        offset: int,
    ):
        p = wp.tid() + offset
        s = acc()
        for k in range(C):
            c = table[p, k]
            if c >= 0:
                w = f64(1.0)
                if wp.static(W):
                    w = spheremp[c]
                for r in range(R):
                    v = f64(0.0)
                    if wp.static(G):
                        if c >= nlocal:
                            v = ghost[(c - nlocal) * R + r]
                        else:
                            v = x[r, c]
                    else:
                        v = x[r, c]
                    if wp.static(W):
                        s[r] += w * v
                    else:
                        s[r] += v
        rs = rspheremp[p]
        for r in range(R):
            out[r, p] = rs * s[r]

    dss.__qualname__ = "dss"  # the kernel's key, as the generic kernel's
    return wp.kernel(dss, enable_backward=False, module="unique")


@wp.kernel
def assemble(
    x: wp.array2d(dtype=f64),
    ghost: wp.array(dtype=f64),
    nlocal: int,
    row: int,
    spheremp: wp.array(dtype=f64),
    table: wp.array2d(dtype=wp.int32),
    first: wp.array(dtype=wp.int32),
    out: wp.array(dtype=f64),
    offset: int,
):
    """Unique-node vector out[g] = Σ_copies c of g spheremp[c]·x[row, c] (in the
    ``dss_table`` order of node first[g]): the assembled mass matrix times a
    continuous field (m² × units of x). A copy c ≥ ``nlocal`` is another
    process's, read from ghost[(c − nlocal)·rows + row] (``pack``'s layout of
    all x.shape[0] rows). Dim nunique."""
    g = wp.tid() + offset
    p = first[g]
    rows = x.shape[0]
    s = f64(0.0)
    for k in range(table.shape[1]):
        c = table[p, k]
        if c >= 0:
            v = f64(0.0)
            if c >= nlocal:
                v = ghost[(c - nlocal) * rows + row]
            else:
                v = x[row, c]
            s += spheremp[c] * v
    out[g] = s


@wp.kernel
def pack(x: wp.array2d(dtype=f64), rows: int, index: wp.array(dtype=wp.int32), buf: wp.array(dtype=f64), offset: int):
    """buf[k·rows + r] = x[r, index[k]] for r < rows: the copies another process
    needs, node by node (HOMME ``edgeVpack``). Dim len(index)."""
    k = wp.tid() + offset
    p = index[k]
    for r in range(rows):
        buf[k * rows + r] = x[r, p]


@wp.kernel
def scatter(y: wp.array2d(dtype=f64), halo: wp.array(dtype=f64), gid: wp.array(dtype=wp.int32), row: int, out: wp.array2d(dtype=f64), offset: int):
    """Element-local out[row + r, p] = y[r, gid[p]] for r < rows = y.shape[0],
    from a unique-node vector of ``rows`` rows (rows, nunique). A node owned by
    another process (gid[p] ≥ nunique) is read from halo[(gid[p] − nunique)·rows + r]
    (``pack``'s layout). Dim N."""
    p = wp.tid() + offset
    g = gid[p]
    n = y.shape[1]
    for r in range(y.shape[0]):
        if g < n:
            out[row + r, p] = y[r, g]
        else:
            out[row + r, p] = halo[(g - n) * y.shape[0] + r]
