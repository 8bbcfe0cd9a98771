"""The passive tracers' ∇⁴ (``model.hyperviscosity.Hyperviscosity.build_tracers``): a scalar
∇⁴ of each tracer alone, without the wind's three Cartesian fields (HOMME applies its tracers'
biharmonic to the tracer mass alone: ``biharmonic_wk_scalar`` in ``advance_hypervis_scalar``).

A tracer's mass hq takes the ∇⁴ the depth takes, acting on q(h + hs) = hq + q·hs where the
depth's acts on h + hs: the weak ∇⁴ of any field sums to zero over the sphere, so the tracer's
mass is conserved, and where q = 1 (hq = h to the bit) the field is h + hs to the bit, its weak
Laplacians the depth's own arithmetic (``hyperviscosity_element.weak_laplacian_rows``), so q = 1
stays 1 to round-off (HOMME keeps that consistency by a tracer flux of the depth's dissipation,
``prim_advection_mod``'s dpdiss; here the field the ∇⁴ acts on carries it).

``tracer_laplacian`` is one weak Laplacian of every tracer of an element, a thread an element on
its GLL rows, the first forming q·hs = (hq / h)·hs of the state it reads (hs itself, to the bit,
where hq = h) (the CPU's SIMD rows; on CUDA the same kernel, a thread an element): the DSSs
between and after are the topology's (``grid.topology.Topology.dss``, ``dss_update``). Its second
can instead subtract its result from a stage's element-local tendency (``into``: the ∇⁴ inside
every stage's right-hand side, HOMME's ``advance_nonstag_rk``), whose DSS is then the stage's.
"""

import functools

import warp as wp

from .hyperviscosity_element import weak_laplacian_rows
from .operators import CPU_FAST, row_derivatives

f64 = wp.float64
wp.set_module_options({"enable_backward": False})


INTO = ("", "weighted", "pointwise")  # the second Laplacian's output: L itself, or subtracted from a tendency


@functools.cache
def tracer_laplacian(first: bool, np_: int, row: int = 3, into: str = ""):
    """c · the weak Laplacian −Σ ∂ᵀ(G ∇_ref f) of each tracer's field f into L (K, ·), HOMME's
    ``laplace_sphere_wk`` (its quadrature-weighted contravariant metric G, as
    ``hyperviscosity.laplacian_metric``: rows 0..2 of ``metric``). ``first``: f = q(h + hs) =
    hq + (hq / h)·hs of field k, hq row ``row`` + k of the state ``src`` (3 + K, ·: from 3 the
    tracers, from 2 the depth and then the tracers), h its row 2: the first Laplacian, ``c`` = ν_s
    (q·hs formed here, not in a pass of its own: 0.11 ms of a TC5 ne16 ∇⁴ application, one
    thread); else f = row k of ``src`` (K, ·), the DSS'd first Laplacian Y₁: the second, ``c``
    unread, ``metric`` the tensor ∇⁴'s where it has one. ``into`` (the second alone, one of
    ``INTO``): "" writes L; "weighted" subtracts the result from L, a stage's spheremp-weighted
    element-local tendency rows (``model.shallow_water``'s unforced tendency), "pointwise"
    subtracts it divided by ``mass`` (spheremp), from a pointwise one (a forced tendency): the
    ∇⁴'s −ν_s ∇⁴ f in the stage's right-hand side. Arguments on GLL rows
    (``operators.row_vectors``): src, hs (m; read by the first alone), metric (4, ·), dvv
    (``operators.dvv_matrix``), c, L (K, ·) output, mass (read with "pointwise" alone), offset (in
    elements). Dim nelem. float64. ValueError for an ``into`` not in ``INTO`` or given to the first."""
    NP, FIRST, R, INTO_ = int(np_), bool(first), int(row), str(into)
    if INTO_ not in INTO or (FIRST and INTO_):
        raise ValueError(f"into must be one of {INTO} and the second Laplacian's (got {into!r}, first={first})")
    vec, mat = row_derivatives(NP)[:2]
    lap = weak_laplacian_rows(NP)

    def kernel(
        src: wp.array2d(dtype=vec),
        hs: wp.array(dtype=vec),
        metric: wp.array2d(dtype=vec),
        dvv: mat,
        c: f64,
        L: wp.array2d(dtype=vec),
        mass: wp.array(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        G11 = mat()
        G12 = mat()
        G22 = mat()
        for j in range(NP):
            G11[j] = metric[0, base + j]
            G12[j] = metric[1, base + j]
            G22[j] = metric[2, base + j]
        for k in range(L.shape[0]):  # a tracer at a time, in a loop clang does not unroll
            F = mat()
            for j in range(NP):
                q = base + j
                if wp.static(FIRST):  # hq + q·hs: h + hs itself where hq = h (q = 1 to the bit)
                    hq = src[wp.static(R) + k, q]
                    F[j] = hq + wp.cw_mul(wp.cw_div(hq, src[2, q]), hs[q])
                else:
                    F[j] = src[k, q]
            Lk = lap(F, G11, G12, G22, dvv, dvvT, base)
            for j in range(NP):
                if wp.static(FIRST):
                    L[k, base + j] = c * Lk[j]
                elif wp.static(INTO_ == "weighted"):
                    L[k, base + j] = L[k, base + j] - Lk[j]
                elif wp.static(INTO_ == "pointwise"):
                    L[k, base + j] = L[k, base + j] - wp.cw_div(Lk[j], mass[base + j])
                else:
                    L[k, base + j] = Lk[j]

    kernel.__qualname__ = kernel.__name__ = (
        f"tracer_laplacian__{'first' if FIRST else 'second'}"
        + ("" if R == 3 or not FIRST else f"__row{R}")
        + (f"__into_{INTO_}" if INTO_ else "")
    )
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
