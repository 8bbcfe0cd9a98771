"""The element filter's kernel (HOMME ``filter_mod``'s ``filter_P``; Fischer & Mullen 2001).

The filter is the tensor product F ⊗ F of one np × np matrix (``swe_sphere.model.filter``) applied
to an element's fields, Z = F X Fᵀ with X[j, i] the value at GLL node (i, j), one thread per
element on GLL rows (``operators.row_vectors`` views, as the CPU's element kernels). The wind is
filtered through its 3-D Cartesian components (smooth across the poles and panel edges, as the
∇⁴'s), the height as the free surface h + hs (smooth over TC5's cone, as the ∇⁴'s) with the
element's mass put back as a constant: h_f = Z − hs + c, c = Σ spheremp·(X − Z) / Σ spheremp over
the element, so that Σ spheremp·h is kept to round-off and a constant is kept exactly (F keeps
constants; filtering metdet·h instead would keep the mass but not a fluid at rest). The weighted
DSS that follows (``swe_sphere.model.filter``) restores continuity and keeps both.
"""

import functools

import warp as wp

from .operators import CPU_FAST, row_derivatives, times

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


@functools.cache
def element_filter(np_: int):
    """The filter kernel for np = ``np_``: y (3, N) = the filtered state x (3, N) (rows u, v in
    m s⁻¹ east/north and h in m) element by element, not yet continuous. Arguments, all as GLL
    rows (``operators.row_vectors``): x, hs (N; m), spheremp (N; the element-local mass, m²),
    east, north (3, N; unit vectors); then F (``operators.dvv_matrix`` of
    ``grid.gll.boyd_vandeven``), Z (4, N) work (the filtered Cartesian wind and h + hs), y (output,
    not aliasing x), offset (in elements). Dim nelem."""
    NP = int(np_)
    vec, mat, _, _ = row_derivatives(NP)

    def field(
        x: wp.array2d(dtype=vec),
        hs: wp.array(dtype=vec),
        east: wp.array2d(dtype=vec),
        north: wp.array2d(dtype=vec),
        r: int,
        q: int,
    ):
        """Row q of field r: the Cartesian wind's component r < 3, or h + hs."""
        if r < 3:
            return times(x[0, q], east[r, q]) + times(x[1, q], north[r, q])
        return x[2, q] + hs[q]

    field = wp.func(field)

    def kernel(
        x: wp.array2d(dtype=vec),
        hs: wp.array(dtype=vec),
        spheremp: wp.array(dtype=vec),
        east: wp.array2d(dtype=vec),
        north: wp.array2d(dtype=vec),
        F: mat,
        Z: wp.array2d(dtype=vec),
        y: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        FT = wp.transpose(F)
        # one field at a time, in a loop clang does not unroll (as the ∇⁴'s weak Laplacians)
        for r in range(Z.shape[0]):
            W = mat()  # along ξ: (X Fᵀ)[j]
            for j in range(NP):
                X = field(x, hs, east, north, r, base + j)
                Wj = vec()
                for m in range(NP):
                    Wj += FT[m] * X[m]
                W[j] = Wj
            for j in range(NP):  # along η: (F W)[j]
                Zj = vec()
                for m in range(NP):
                    Zj += W[m] * F[j, m]
                Z[r, base + j] = Zj
        lost = f64(0.0)  # the element's mass the filter moved, and its area
        area = f64(0.0)
        for j in range(NP):
            q = base + j
            lost += wp.dot(spheremp[q], x[2, q] + hs[q] - Z[3, q])
            for i in range(NP):
                area += spheremp[q][i]
        c = lost / area
        for j in range(NP):
            q = base + j
            y[0, q] = times(Z[0, q], east[0, q]) + times(Z[1, q], east[1, q]) + times(Z[2, q], east[2, q])
            y[1, q] = times(Z[0, q], north[0, q]) + times(Z[1, q], north[1, q]) + times(Z[2, q], north[2, q])
            h = Z[3, q] - hs[q]
            for i in range(NP):
                h[i] = h[i] + c
            y[2, q] = h

    kernel.__qualname__ = kernel.__name__ = f"element_filter_np{NP}"
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
