"""The shallow-water tendency, compiled for the terms a scene names
(Williamson et al. 1992, eqs. 2–3 in vector-invariant form; HOMME
``sweq_mod``/``compute_and_apply_rhs``):

    ∂v/∂t = −(ζ + f) k×v − ∇(½|v|² + g(h + hs)),    ∂h/∂t = −∇·(h v).

Each term's code sits under ``wp.static``, so a term the scene does not name
is not compiled at all (the kernel key, ``tendency__<term>__<term>...``, lists
the terms it holds). The kernel writes the element-local tendency (rows du/dt,
dv/dt, dh/dt; k×v = (−v, u)); the model then applies the DSS. Two layouts of
the same arithmetic:

* ``tendency(terms)``: one thread per node (dim N), for CUDA: coalesced loads,
  each thread re-reads its element's row and column.
* ``tendency_element(terms, dvv)``: one thread per element (dim nelem), for the
  CPU, where a launch is one serial loop: each node's fluxes are formed once
  into local rows and differentiated from there, with FMA contraction on, on
  whole GLL rows (``operators.row_vectors``) so that it runs as packed SIMD.

With ``tracers`` K > 0 (compiled in only then: the key ends ``__q<K>``) the continuity's
kernels also write rows 3..3+K−1, the flux-form tendency ∂(hq)/∂t = −∇·(hq v) of each passive
tracer's mass hq, by the continuity's own arithmetic on hq in h's place (HOMME's tracers ride
the dynamics' mass flux: ``prim_advection_mod``'s euler_step), so that hq = h stays hq = h.
"""

import functools
from typing import Any

import warp as wp

from .operators import (
    CPU_FAST,
    across_as_along,
    covariant_inverse,
    element_node,
    over,
    row_derivatives,
    row_type,
    suffix,
    times,
)

f64 = wp.float64

TENDENCY_TERMS = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography")


def term_flags(terms):
    """Which of ``TENDENCY_TERMS`` are in ``terms``; ValueError for an unknown one."""
    unknown = set(terms) - set(TENDENCY_TERMS)
    if unknown:
        raise ValueError(f"unknown tendency terms {sorted(unknown)}")
    return tuple(t in terms for t in TENDENCY_TERMS)


@functools.cache
def absolute_vorticity(terms: tuple):
    """ζ + f, the parts of the absolute vorticity that ``terms`` name, at p from the curl's
    reference derivatives cx − cy = ∂ξ v₂ − ∂η v₁ (covariant wind): (cx − cy)/metdet[p] with
    momentum advection, + fcor[p] with Coriolis. Generic as ``finish``: shared by the tendency's
    end and its transposes (``tendency_adjoint``), so that they weigh the same ζ + f."""
    _, ADV, COR, _, _ = term_flags(terms)

    def rot_terms(
        p: int,
        cx: Any,
        cy: Any,
        metdet: wp.array(dtype=Any),
        fcor: wp.array(dtype=Any),
    ):
        rot = type(cx)(0.0)
        if wp.static(ADV):
            rot += over(cx - cy, metdet[p])
        if wp.static(COR):
            rot += fcor[p]
        return rot

    rot_terms.__qualname__ = rot_terms.__name__ = "absolute_vorticity__" + "__".join(terms)
    return wp.func(rot_terms)


@wp.func
def inverse_det(D: wp.array2d(dtype=Any), p: int):
    """1 / det D at p of D (4, ·) as (D₀₀, D₀₁, D₁₀, D₁₁) rows (``CubedSphere``'s layout)."""
    d = times(D[0, p], D[3, p]) - times(D[1, p], D[2, p])
    return over(type(d)(1.0), d)


@functools.cache
def finish(terms: tuple, weighted: bool = False, inverted: bool = False, determinant: bool = False):
    """The pointwise end of the tendency, shared by the three layouts: from the
    reference derivatives div = Σ∂(metdet h c), (bx, by) = ∂(Bernoulli), and
    cx − cy = ∂ξ v₂ − ∂η v₁ (covariant wind), write tend[:, s], times mass[p] (the element
    mass spheremp) if ``weighted``; p indexes the geometry (Dinv, metdet, fcor, forcing, mass),
    s the state x and tend (p itself but in ``tendency_lanes.tendency_across``, whose x and tend are a thread's
    scratch). Generic: p is a node and the values scalars (per-node kernel), a row and the
    values rows (``operators.row_vectors``, the element kernel), or a node of a block of elements
    and the values vectors of them (``tendency_lanes.tendency_across``), of the tendency's float type; the
    state x float64 or of that type, its wind read in that type. ``inverted``: the argument Dinv
    holds D, and D⁻¹ = adj(D)/det D is formed from it (``tendency_lanes.tendency_across`` in float32);
    ``determinant`` (with ``inverted``): metdet taken as det D (``CubedSphere``'s metdet is det D
    times one global area factor, 1 + 4e-15), the one 1/det D of the node dividing the
    continuity, the gradient and the vorticity (``tendency_lanes.tendency_across`` on the float32 state: one
    division a node where there were three, and metdet not read)."""
    CONT, ADV, COR, PG, TOPO = term_flags(terms)
    W, INV = bool(weighted), bool(inverted)
    DET = INV and bool(determinant)
    GRAD = ADV or PG

    def finish_terms(
        p: int,
        s: int,
        div: Any,
        bx: Any,
        by: Any,
        cx: Any,
        cy: Any,
        x: wp.array2d(dtype=Any),
        Dinv: wp.array2d(dtype=Any),
        metdet: wp.array(dtype=Any),
        fcor: wp.array(dtype=Any),
        forcing: wp.array2d(dtype=Any),
        mass: wp.array(dtype=Any),
        tend: wp.array2d(dtype=Any),
    ):
        zero = type(div)(0.0)
        du = zero
        dv = zero
        dh = zero
        r = zero
        if wp.static(INV and (GRAD or DET)):
            r = inverse_det(Dinv, p)
        if wp.static(CONT and DET):
            dh = -times(div, r)
        elif wp.static(CONT):
            dh = -over(div, metdet[p])
        if wp.static(GRAD and INV):  # D⁻¹ᵀ∇ = (D₁₁ bx − D₁₀ by, D₀₀ by − D₀₁ bx) / det D
            du = -times(r, times(Dinv[3, p], bx) - times(Dinv[2, p], by))
            dv = -times(r, times(Dinv[0, p], by) - times(Dinv[1, p], bx))
        elif wp.static(GRAD):
            du = -(times(Dinv[0, p], bx) + times(Dinv[2, p], by))
            dv = -(times(Dinv[1, p], bx) + times(Dinv[3, p], by))
        if wp.static(ADV or COR):  # −(ζ + f) k×v
            rot = zero
            if wp.static(DET):  # ζ = (cx − cy)/det D
                if wp.static(ADV):
                    rot = times(cx - cy, r)
                if wp.static(COR):
                    rot += fcor[p]
            else:
                rot = wp.static(absolute_vorticity(terms))(p, cx, cy, metdet, fcor)
            du += times(rot, type(rot)(x[1, s]))  # the state's wind in the tendency's float type
            dv -= times(rot, type(rot)(x[0, s]))
        if wp.static(TOPO):
            du += forcing[0, p]
            dv += forcing[1, p]
        if wp.static(W):
            w = mass[p]
            du = times(w, du)
            dv = times(w, dv)
            dh = times(w, dh)
        tend[0, s] = du
        tend[1, s] = dv
        tend[2, s] = dh

    finish_terms.__qualname__ = finish_terms.__name__ = (
        "finish__"
        + "__".join(terms)
        + ("__mass" if W else "")
        + ("__inverted" if INV else "")
        + ("__determinant" if DET else "")
    )
    return wp.func(finish_terms)


@functools.cache
def tracer_finish(weighted: bool):
    """``finish``'s continuity row for a tracer: tend[row, p] = −div/metdet[p] (times mass[p]
    if ``weighted``), the bits of dh for the same div. Generic over nodes and rows as ``finish``."""
    W = bool(weighted)

    def finish_tracer(
        p: int, row: int, div: Any, metdet: wp.array(dtype=Any), mass: wp.array(dtype=Any), tend: wp.array2d(dtype=Any)
    ):
        dq = -over(div, metdet[p])
        if wp.static(W):
            dq = times(mass[p], dq)
        tend[row, p] = dq

    finish_tracer.__qualname__ = finish_tracer.__name__ = "finish_tracer" + ("__mass" if W else "")
    return wp.func(finish_tracer)


def tracer_suffix(tracers: int) -> str:
    """What a tendency kernel's key adds for ``tracers`` K rows of tracer mass: nothing for 0."""
    return f"__q{int(tracers)}" if tracers else ""


def reads_departed(departed: bool, dtype, tracers: int) -> bool:
    """Whether a tendency kernel reads the float32 state (``departed``); ValueError for one
    under float64 or with tracers (its continuity is written for u, v and h alone)."""
    if departed and (dtype is f64 or tracers):
        raise ValueError("a departed (float32) state is read by a float32 tendency without tracers")
    return bool(departed)


@functools.cache
def tendency(
    terms: tuple, np_static: int = 0, weighted: bool = False, dtype=f64, tracers: int = 0, departed: bool = False
):
    """The tendency kernel for ``terms`` (a tuple in ``TENDENCY_TERMS`` order). Arguments:
    x (3, N) state, Dinv (4, N) (the vorticity's covariant wind formed from it and metdet,
    ``operators.covariant_inverse``: D is not read), metdet, fcor (N), forcing (2, N) topographic −g∇hs,
    mass (N) the element mass spheremp (read if ``weighted``: tend = spheremp·F, whose
    unweighted DSS is F's weighted one), dvv (np, np), np, g, h0, tend (3, N) output, offset.
    ``np_static`` > 0: compiled for that np
    (the np argument unread): its loops along the element's rows unrolled, its node indices
    divided by a constant; 0: np read at run time. The same arithmetic either way. ``dtype``:
    the float type of every array but the state x (float64) and of g (float64, or float32:
    ``ShallowWater``'s precision). Under float32 the Bernoulli function's g h is g (h − h0), h0
    (m) a reference depth subtracted in float64 before the rounding (∇(g h0) = 0: the pressure
    gradient keeps the digits of h's variation, not of its 10 km); under float64 h0 is unread.
    ``tracers`` K: with the continuity, rows 3..3+K−1 of x and tend are tracer masses hq and
    their tendencies (the module's note); ValueError for K > 0 without the continuity.
    ``departed``: the float32 state (``precision = "float32_state"``): x in ``dtype``, its h row
    the departure h − h0 (h0 of ``dtype``), which the Bernoulli function takes as it is and the
    continuity's flux as (h − h0) + h0; ValueError with tracers or under float64."""
    CONT, ADV, _, PG, _ = term_flags(terms)
    GRAD = ADV or PG  # ∇ of the Bernoulli function ½|v|² + g h
    NP = int(np_static)
    SHIFT = dtype is not f64
    K = int(tracers)
    DEPARTED = reads_departed(departed, dtype, K)
    if K and not CONT:
        raise ValueError("tracers ride the continuity: a tendency with tracers needs the continuity term")
    xtype = dtype if DEPARTED else f64

    def kernel(
        x: wp.array2d(dtype=xtype),
        Dinv: wp.array2d(dtype=dtype),
        metdet: wp.array(dtype=dtype),
        fcor: wp.array(dtype=dtype),
        forcing: wp.array2d(dtype=dtype),
        mass: wp.array(dtype=dtype),
        dvv: wp.array2d(dtype=dtype),
        np_: int,
        g: dtype,
        h0: xtype,
        tend: wp.array2d(dtype=dtype),
        offset: int,
    ):
        p = wp.tid() + offset
        n = np_
        if wp.static(NP > 0):
            n = wp.static(NP)
        base, i, j = element_node(p, n)
        div = dtype(0.0)  # Σ ∂(metdet c)        (continuity)
        bx = dtype(0.0)  # ∂ξ, ∂η of the Bernoulli function
        by = dtype(0.0)
        cx = dtype(0.0)  # ∂ξ v₂, ∂η v₁ of the covariant wind (vorticity)
        cy = dtype(0.0)
        for m in range(n):
            q = base + j * n + m  # along ξ through (i, j)
            r = base + m * n + i  # along η
            uq, vq, hq = dtype(x[0, q]), dtype(x[1, q]), dtype(x[2, q])  # the state in the tendency's type
            ur, vr, hr = dtype(x[0, r]), dtype(x[1, r]), dtype(x[2, r])
            if wp.static(CONT):
                dq, dr = hq, hr  # the depth, h0 added back to a departed state's h − h0
                if wp.static(DEPARTED):
                    dq, dr = hq + h0, hr + h0
                div += dvv[i, m] * metdet[q] * dq * (Dinv[0, q] * uq + Dinv[1, q] * vq)
                div += dvv[j, m] * metdet[r] * dr * (Dinv[2, r] * ur + Dinv[3, r] * vr)
            if wp.static(GRAD):
                eq = dtype(0.0)
                er = dtype(0.0)
                if wp.static(ADV):
                    eq += dtype(0.5) * (uq * uq + vq * vq)
                    er += dtype(0.5) * (ur * ur + vr * vr)
                if wp.static(PG):
                    if wp.static(DEPARTED):  # the state's h − H₀ as it is stored
                        eq += g * hq
                        er += g * hr
                    elif wp.static(SHIFT):  # h − H₀ formed in float64 before it is rounded
                        eq += g * dtype(x[2, q] - h0)
                        er += g * dtype(x[2, r] - h0)
                    else:
                        eq += g * hq
                        er += g * hr
                bx += dvv[i, m] * eq
                by += dvv[j, m] * er
            if wp.static(ADV):
                _, w2 = covariant_inverse(Dinv, metdet, uq, vq, q)
                w1, _ = covariant_inverse(Dinv, metdet, ur, vr, r)
                cx += dvv[i, m] * w2
                cy += dvv[j, m] * w1
        wp.static(finish(terms, weighted))(p, p, div, bx, by, cx, cy, x, Dinv, metdet, fcor, forcing, mass, tend)
        for k in range(wp.static(K)):  # each tracer's mass hq by the continuity's arithmetic on h
            dq = dtype(0.0)
            for m in range(n):
                q = base + j * n + m
                r = base + m * n + i
                uq, vq, hq = dtype(x[0, q]), dtype(x[1, q]), dtype(x[3 + k, q])
                ur, vr, hr = dtype(x[0, r]), dtype(x[1, r]), dtype(x[3 + k, r])
                dq += dvv[i, m] * metdet[q] * hq * (Dinv[0, q] * uq + Dinv[1, q] * vq)
                dq += dvv[j, m] * metdet[r] * hr * (Dinv[2, r] * ur + Dinv[3, r] * vr)
            wp.static(tracer_finish(weighted))(p, 3 + k, dq, metdet, mass, tend)

    kernel.__qualname__ = kernel.__name__ = (
        "tendency__"
        + "__".join(terms)
        + ("__mass" if weighted else "")
        + (f"__np{NP}" if NP else "")
        + tracer_suffix(K)
        + ("__departed" if DEPARTED else "")
        + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def tendency_element(
    terms: tuple, np_: int, weighted: bool = False, dtype=f64, tracers: int = 0, departed: bool = False
):
    """The tendency kernel for ``terms``, one thread per element, on GLL rows
    (``operators.row_vectors`` views). Arguments: x (3, N/np) state, Dinv (4, N/np; D not
    read, as ``tendency``'s), metdet, fcor (N/np), forcing (2, N/np) topographic −g∇hs, mass (N/np)
    (``weighted``: as ``tendency``'s), g, h0 (a float64 row of the reference depth),
    dvv (``operators.dvv_matrix``), tend (3, N/np) output, offset (in elements). Dim nelem.
    ``dtype``, h0, ``tracers`` and ``departed`` as ``tendency``'s (h0 a row of x's type)."""
    CONT, ADV, _, PG, _ = term_flags(terms)
    GRAD = ADV or PG
    NP = int(np_)
    K = int(tracers)
    DEPARTED = reads_departed(departed, dtype, K)
    if K and not CONT:
        raise ValueError("tracers ride the continuity: a tendency with tracers needs the continuity term")
    vec, mat, along, across = row_derivatives(NP, dtype)
    state = row_type(NP, dtype if DEPARTED else f64)  # the state's rows
    SHIFT = dtype is not f64
    ROW = across_as_along(NP)  # ∂η as along(dvv[j], F)
    fluxes = wp.types.matrix(shape=(max(K, 1) * NP, NP), dtype=dtype)  # K tracers' rows (unread without)

    def kernel(
        x: wp.array2d(dtype=state),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        fcor: wp.array(dtype=vec),
        forcing: wp.array2d(dtype=vec),
        mass: wp.array(dtype=vec),
        g: dtype,
        h0: state,
        dvv: mat,
        tend: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        f1 = mat()  # metdet h c¹, metdet h c²: the mass flux (continuity)
        f2 = mat()
        E = mat()  # the Bernoulli function
        v1 = mat()  # covariant wind (vorticity)
        v2 = mat()
        # each tracer's mass flux metdet hq c¹, c² (tracer k's rows from k·np), formed beside h's where
        # metdet, c¹ and c² are at hand (was: c¹, c² kept and the fluxes formed in a pass of their
        # own; TC5 ne16 np4 with one tracer, one thread, the kernel alone: 143.5 → 139.0 µs a call)
        Q1 = fluxes()
        Q2 = fluxes()
        for j in range(NP):
            q = base + j
            u = vec(x[0, q])  # the state's rows in the tendency's type
            v = vec(x[1, q])
            h = vec(x[2, q])
            if wp.static(CONT):
                depth = h  # h0 added back to a departed state's h − h0
                if wp.static(DEPARTED):
                    depth = h + h0
                Jh = times(metdet[q], depth)
                c1 = times(Dinv[0, q], u) + times(Dinv[1, q], v)
                c2 = times(Dinv[2, q], u) + times(Dinv[3, q], v)
                f1[j] = times(Jh, c1)
                f2[j] = times(Jh, c2)
                for k in range(wp.static(K)):  # by h's arithmetic on hq, while c¹, c² and metdet are at hand
                    Jq = times(metdet[q], vec(x[3 + k, q]))
                    Q1[k * NP + j] = times(Jq, c1)
                    Q2[k * NP + j] = times(Jq, c2)
            if wp.static(ADV):
                E[j] = dtype(0.5) * (times(u, u) + times(v, v))
                c1, c2 = covariant_inverse(Dinv, metdet, u, v, q)
                v1[j] = c1
                v2[j] = c2
            if wp.static(PG):
                if wp.static(DEPARTED):  # the state's h − H₀ as it is stored
                    E[j] = E[j] + g * h
                elif wp.static(SHIFT):  # h − H₀ formed in float64 before it is rounded
                    E[j] = E[j] + g * vec(x[2, q] - h0)
                else:
                    E[j] = E[j] + g * h
        # a loop over the rows with a run-time start, which Warp does not unroll: unrolled,
        # the four rows' derivatives and finish in one block were half scalar after
        # clang's SLP vectorizer (measured: 0.6 of the scalar kernel's time, rolled 0.5)
        for q in range(base, base + NP):
            j = q - base
            div = vec()
            bx = vec()
            by = vec()
            cx = vec()
            cy = vec()
            if wp.static(CONT):
                if wp.static(ROW):
                    div = along(f1[j], dvvT) + along(dvv[j], f2)
                else:
                    div = along(f1[j], dvvT) + across(f2, j, dvv)
            if wp.static(GRAD):
                bx = along(E[j], dvvT)
                if wp.static(ROW):
                    by = along(dvv[j], E)
                else:
                    by = across(E, j, dvv)
            if wp.static(ADV):
                cx = along(v2[j], dvvT)
                if wp.static(ROW):
                    cy = along(dvv[j], v1)
                else:
                    cy = across(v1, j, dvv)
            wp.static(finish(terms, weighted))(q, q, div, bx, by, cx, cy, x, Dinv, metdet, fcor, forcing, mass, tend)
        for k in range(wp.static(K)):  # each tracer's divergence, as h's
            g1 = mat()
            g2 = mat()
            for j in range(NP):
                g1[j] = Q1[k * NP + j]
                g2[j] = Q2[k * NP + j]
            for q in range(base, base + NP):
                j = q - base
                div = vec()
                if wp.static(ROW):
                    div = along(g1[j], dvvT) + along(dvv[j], g2)
                else:
                    div = along(g1[j], dvvT) + across(g2, j, dvv)
                wp.static(tracer_finish(weighted))(q, 3 + k, div, metdet, mass, tend)

    kernel.__qualname__ = kernel.__name__ = (
        "tendency__"
        + "__".join(terms)
        + ("__mass" if weighted else "")
        + tracer_suffix(K)
        + ("__departed" if DEPARTED else "")
        + suffix(dtype)
    )
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
