"""The transpose of the per-node tendency kernel (``tendencies.tendency``) with respect to the
state, written by hand, for the gradients of a run (``swe_sphere.adjoint``).

Why by hand: Warp's generated adjoint of ``tendencies.tendency`` (its GLL loop bound read at
run time) was wrong (a dot product off by 23 % on TC5 ne2), and that of a copy with the bound
unrolled at compile time was right but cost 8 RHS evaluations (the forward replayed, an atomic
add a read, on every coefficient array). The tendency is T(x) = f(x, Σ ∂ of pointwise
products): the transpose is two launches, each a gather with no atomics:
- ``point``: at each node, λ = spheremp·k̄ (the DSS's transpose, see ``adjoint.explicit``),
  the adjoint of the pointwise end (``tendencies.finish``) into the reference derivatives'
  adjoints s = (d̄iv, b̄x, b̄y, c̄x, c̄y) and the pointwise part of x̄; with topography, λ's wind
  rows summed into f̄ (the adjoint of the forcing −g∇hs, for ∂J/∂hs);
- ``gather``: x̄ at node (i', j') += Σ_i dvv[i, i'] s[(i, j')] · ∂(product at (i', j'))
  along ξ, and Σ_j dvv[j, j'] s[(i', j)] · ∂(product) along η: the transposed derivative.
``element`` is the same transpose for the CPU, one thread per element on GLL rows as
``tendencies.tendency_element`` (the two launches fused, k̄ read as a combination of up to
three arrays): on the CPU Warp's cost per thread made the per-node pair 1.45 ms a stage at
Galewsky ne16 (one thread), 4× an RHS; the element kernel takes 0.26 ms there.
Checked against central differences and by dot products in ``tests/adjoint``.
"""

import functools

import warp as wp

from .operators import CPU_FAST, covariant, element_node, over, row_derivatives, times
from .tendencies import absolute_vorticity, term_flags

f64 = wp.float64


@functools.cache
def point(terms: tuple, np_: int):
    """The pointwise adjoint for ``terms`` at np = ``np_``. Arguments: x (3, N) state, D, Dinv
    (4, N), metdet, fcor, spheremp (N), dvv (np, np), kbar (3, N) the continuous adjoint of
    the tendency, s (5, N) out, xbar (3, N) out (overwritten), fbar (2, N) (+= λ's wind rows
    with topography), offset. Dim N."""
    CONT, ADV, COR, PG, TOPO = term_flags(terms)
    GRAD = ADV or PG
    NP = int(np_)

    def kernel(
        x: wp.array2d(dtype=f64),
        D: wp.array2d(dtype=f64),
        Dinv: wp.array2d(dtype=f64),
        metdet: wp.array(dtype=f64),
        fcor: wp.array(dtype=f64),
        spheremp: wp.array(dtype=f64),
        dvv: wp.array2d(dtype=f64),
        kbar: wp.array2d(dtype=f64),
        s: wp.array2d(dtype=f64),
        xbar: wp.array2d(dtype=f64),
        fbar: wp.array2d(dtype=f64),
        offset: int,
    ):
        p = wp.tid() + offset
        w = spheremp[p]
        lu = w * kbar[0, p]
        lv = w * kbar[1, p]
        lh = w * kbar[2, p]
        ub = f64(0.0)
        vb = f64(0.0)
        s[0, p] = f64(0.0)
        s[1, p] = f64(0.0)
        s[2, p] = f64(0.0)
        s[3, p] = f64(0.0)
        s[4, p] = f64(0.0)
        if wp.static(CONT):  # dh = −div/metdet
            s[0, p] = -lh / metdet[p]
        if wp.static(GRAD):  # du = −(Dinv₀ bx + Dinv₂ by), dv = −(Dinv₁ bx + Dinv₃ by)
            s[1, p] = -(Dinv[0, p] * lu + Dinv[1, p] * lv)
            s[2, p] = -(Dinv[2, p] * lu + Dinv[3, p] * lv)
        if wp.static(ADV or COR):  # du += rot·v, dv −= rot·u
            cx = f64(0.0)
            cy = f64(0.0)
            if wp.static(ADV):
                base, i, j = element_node(p, NP)
                for m in range(wp.static(NP)):
                    q = base + j * NP + m
                    r = base + m * NP + i
                    cx += dvv[i, m] * (D[1, q] * x[0, q] + D[3, q] * x[1, q])
                    cy += dvv[j, m] * (D[0, r] * x[0, r] + D[2, r] * x[1, r])
                rbar = (lu * x[1, p] - lv * x[0, p]) / metdet[p]
                s[3, p] = rbar
                s[4, p] = -rbar
            rot = wp.static(absolute_vorticity(terms))(p, cx, cy, metdet, fcor)
            ub = -rot * lv
            vb = rot * lu
        if wp.static(TOPO):
            fbar[0, p] += lu
            fbar[1, p] += lv
        xbar[0, p] = ub
        xbar[1, p] = vb
        xbar[2, p] = f64(0.0)

    kernel.__qualname__ = kernel.__name__ = f"tendency_adjoint_point_np{NP}__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def gather(terms: tuple, np_: int):
    """The transposed derivatives for ``terms`` at np = ``np_``: x̄ += what the reference
    derivatives' adjoints s (``point``'s) send back through the products they differentiate.
    Arguments: x (3, N) state, D, Dinv (4, N), metdet (N), dvv (np, np), g, s (5, N), xbar
    (3, N) (+=), offset. Dim N."""
    CONT, ADV, _, PG, _ = term_flags(terms)
    GRAD = ADV or PG
    NP = int(np_)

    def kernel(
        x: wp.array2d(dtype=f64),
        D: wp.array2d(dtype=f64),
        Dinv: wp.array2d(dtype=f64),
        metdet: wp.array(dtype=f64),
        dvv: wp.array2d(dtype=f64),
        g: f64,
        s: wp.array2d(dtype=f64),
        xbar: wp.array2d(dtype=f64),
        offset: int,
    ):
        p = wp.tid() + offset
        base, i, j = element_node(p, NP)
        div1 = f64(0.0)  # along ξ: Σ_m dvv[m, i] s[(m, j)]
        div2 = f64(0.0)  # along η: Σ_m dvv[m, j] s[(i, m)]
        bern = f64(0.0)
        c1 = f64(0.0)
        c2 = f64(0.0)
        for m in range(wp.static(NP)):
            q = base + j * NP + m
            r = base + m * NP + i
            if wp.static(CONT):
                div1 += dvv[m, i] * s[0, q]
                div2 += dvv[m, j] * s[0, r]
            if wp.static(GRAD):
                bern += dvv[m, i] * s[1, q] + dvv[m, j] * s[2, r]
            if wp.static(ADV):
                c1 += dvv[m, i] * s[3, q]
                c2 += dvv[m, j] * s[4, r]
        u = x[0, p]
        v = x[1, p]
        ub = f64(0.0)
        vb = f64(0.0)
        hb = f64(0.0)
        if wp.static(CONT):  # metdet h (Dinv₀ u + Dinv₁ v) along ξ, (Dinv₂ u + Dinv₃ v) along η
            a1 = metdet[p] * div1
            a2 = metdet[p] * div2
            h = x[2, p]
            ub += h * (a1 * Dinv[0, p] + a2 * Dinv[2, p])
            vb += h * (a1 * Dinv[1, p] + a2 * Dinv[3, p])
            hb += a1 * (Dinv[0, p] * u + Dinv[1, p] * v) + a2 * (Dinv[2, p] * u + Dinv[3, p] * v)
        if wp.static(ADV):  # ½|v|², and the covariant wind's D₁u + D₃v along ξ, D₀u + D₂v along η
            ub += bern * u + c1 * D[1, p] + c2 * D[0, p]
            vb += bern * v + c1 * D[3, p] + c2 * D[2, p]
        if wp.static(PG):  # g h
            hb += g * bern
        xbar[0, p] += ub
        xbar[1, p] += vb
        xbar[2, p] += hb

    kernel.__qualname__ = kernel.__name__ = f"tendency_adjoint_gather_np{NP}__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def _combined(np_: int, nk: int):
    """``element``'s k̄ = Σ c[t]·kt over the first ``nk`` of k0, k1, k2 at row q, a ``wp.func``
    (c, k0, k1, k2, q) → k̄'s rows 0, 1, 2 there (three rows)."""
    NP, NK = int(np_), int(nk)
    vec = row_derivatives(NP)[0]

    def combined(
        c: wp.vec3d,
        k0: wp.array2d(dtype=vec),
        k1: wp.array2d(dtype=vec),
        k2: wp.array2d(dtype=vec),
        q: int,
    ):
        kb = c[0] * k0[0, q]
        kv = c[0] * k0[1, q]
        kh = c[0] * k0[2, q]
        if wp.static(NK > 1):
            kb = kb + c[1] * k1[0, q]
            kv = kv + c[1] * k1[1, q]
            kh = kh + c[1] * k1[2, q]
        if wp.static(NK > 2):
            kb = kb + c[2] * k2[0, q]
            kv = kv + c[2] * k2[1, q]
            kh = kh + c[2] * k2[2, q]
        return kb, kv, kh

    combined.__qualname__ = combined.__name__ = f"tendency_adjoint_kbar_np{NP}_k{NK}"
    return wp.func(combined, inline=True)


@functools.cache
def _point_row(terms: tuple, np_: int, nk: int):
    """``point`` at row q of an element, a ``wp.func`` (x, Dinv, metdet, fcor, spheremp, c, k0,
    k1, k2, fbar, q, cx, cy) → (sd, sx, sy, rb, ub, vb) rows: from λ = spheremp·k̄
    (``_combined``) and the curl's reference derivatives cx, cy, the adjoints sd, sx, sy, rb of
    div, bx, by and cx (cy's is −rb) and x̄'s pointwise part ub, vb; fbar += λ's wind rows
    with topography."""
    CONT, ADV, COR, PG, TOPO = term_flags(terms)
    GRAD = ADV or PG
    NP = int(np_)
    vec = row_derivatives(NP)[0]
    kbar = _combined(NP, nk)

    def point_row(
        x: wp.array2d(dtype=vec),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        fcor: wp.array(dtype=vec),
        spheremp: wp.array(dtype=vec),
        c: wp.vec3d,
        k0: wp.array2d(dtype=vec),
        k1: wp.array2d(dtype=vec),
        k2: wp.array2d(dtype=vec),
        fbar: wp.array2d(dtype=vec),
        q: int,
        cx: vec,
        cy: vec,
    ):
        w = spheremp[q]
        kb, kv, kh = kbar(c, k0, k1, k2, q)
        lu = times(w, kb)
        lv = times(w, kv)
        lh = times(w, kh)
        sd = vec()
        sx = vec()
        sy = vec()
        rb = vec()
        ub = vec()
        vb = vec()
        if wp.static(CONT):  # dh = −div/metdet
            sd = -over(lh, metdet[q])
        if wp.static(GRAD):
            sx = -(times(Dinv[0, q], lu) + times(Dinv[1, q], lv))
            sy = -(times(Dinv[2, q], lu) + times(Dinv[3, q], lv))
        if wp.static(ADV or COR):  # du += rot·v, dv −= rot·u
            if wp.static(ADV):
                rb = over(times(lu, x[1, q]) - times(lv, x[0, q]), metdet[q])
            rot = wp.static(absolute_vorticity(terms))(q, cx, cy, metdet, fcor)
            ub = -times(rot, lv)
            vb = times(rot, lu)
        if wp.static(TOPO):
            fbar[0, q] = fbar[0, q] + lu
            fbar[1, q] = fbar[1, q] + lv
        return sd, sx, sy, rb, ub, vb

    point_row.__qualname__ = point_row.__name__ = f"tendency_adjoint_point_row_np{NP}_k{int(nk)}__" + "__".join(terms)
    return wp.func(point_row, inline=True)


@functools.cache
def _gather_row(terms: tuple, np_: int):
    """``gather`` at row q of an element, a ``wp.func`` (x, D, Dinv, metdet, g, q, uq, vq, a1, a2,
    e, w1, w2) → x̄'s rows 0, 1, 2 there: x̄'s pointwise part uq, vq + what the transposed
    derivatives of the adjoints (a1, a2 of div's along ξ and η, e of the Bernoulli's, w1, w2 of
    the curl's) send back through the products they differentiate."""
    CONT, ADV, _, PG, _ = term_flags(terms)
    vec = row_derivatives(int(np_))[0]

    def gather_row(
        x: wp.array2d(dtype=vec),
        D: wp.array2d(dtype=vec),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        g: f64,
        q: int,
        uq: vec,
        vq: vec,
        a1: vec,
        a2: vec,
        e: vec,
        w1: vec,
        w2: vec,
    ):
        u = x[0, q]
        v = x[1, q]
        hq = vec()
        if wp.static(CONT):  # metdet h (Dinv₀ u + Dinv₁ v) along ξ, (Dinv₂ u + Dinv₃ v) along η
            h = x[2, q]
            uq += times(h, times(a1, Dinv[0, q]) + times(a2, Dinv[2, q]))
            vq += times(h, times(a1, Dinv[1, q]) + times(a2, Dinv[3, q]))
            hq += times(a1, times(Dinv[0, q], u) + times(Dinv[1, q], v))
            hq += times(a2, times(Dinv[2, q], u) + times(Dinv[3, q], v))
        if wp.static(ADV):  # ½|v|²
            uq += times(e, u)
            vq += times(e, v)
        if wp.static(PG):  # g h
            hq += g * e
        if wp.static(ADV):  # the covariant wind: v₁ = D₀u + D₂v, v₂ = D₁u + D₃v
            uq += times(D[1, q], w2) - times(D[0, q], w1)
            vq += times(D[3, q], w2) - times(D[2, q], w1)
        return uq, vq, hq

    gather_row.__qualname__ = gather_row.__name__ = f"tendency_adjoint_gather_row_np{int(np_)}__" + "__".join(terms)
    return wp.func(gather_row, inline=True)


@functools.cache
def element(terms: tuple, np_: int, nk: int):
    """``point`` and ``gather`` fused, one thread per element on GLL rows (``operators.row_vectors``
    views, as ``tendencies.tendency_element``), k̄ = Σ c[t]·kt over the first ``nk`` (1–3) of
    k0, k1, k2. Arguments: x (3, N/np) state, D, Dinv (4, N/np), metdet, fcor, spheremp
    (N/np), g, dvv (``operators.dvv_matrix``), c (vec3d), k0, k1, k2 (3, N/np), xbar (3, N/np)
    out (overwritten: the element-local adjoint, before the unweighted DSS), fbar (2, N/np)
    (+= λ's wind rows with topography), offset (in elements). Dim nelem."""
    CONT, ADV, COR, PG, TOPO = term_flags(terms)
    GRAD = ADV or PG
    NP, NK = int(np_), int(nk)
    if not 1 <= NK <= 3:
        raise ValueError(f"k̄ is a combination of one to three arrays (got {nk})")
    vec, mat, along, _ = row_derivatives(NP)  # (M F)[j] as along(M[j], F) at every np: no frozen bits here
    # a row at a time through Warp functions (the project's 80 lines a function), forced inline,
    # the element matrices kept in the kernel: two passes as functions passing the matrices
    # between them copied them (1.05–1.15× the time at np 6 and 8). The same sums as in one body,
    # but clang contracts other products into FMAs: x̄ and f̄ changed in the last bits (at np 3, 6
    # and 8, as with every split tried; the generic target's bits the same)
    point_row, gather_row = _point_row(terms, NP, NK), _gather_row(terms, NP)

    def kernel(
        x: wp.array2d(dtype=vec),
        D: wp.array2d(dtype=vec),
        Dinv: wp.array2d(dtype=vec),
        metdet: wp.array(dtype=vec),
        fcor: wp.array(dtype=vec),
        spheremp: wp.array(dtype=vec),
        g: f64,
        dvv: mat,
        c: wp.vec3d,
        k0: wp.array2d(dtype=vec),
        k1: wp.array2d(dtype=vec),
        k2: wp.array2d(dtype=vec),
        xbar: wp.array2d(dtype=vec),
        fbar: wp.array2d(dtype=vec),
        offset: int,
    ):
        base = (wp.tid() + offset) * NP
        dvvT = wp.transpose(dvv)
        v1 = mat()  # the covariant wind (vorticity)
        v2 = mat()
        sd = mat()  # the adjoints of div, bx, by and of cx (cy's is −rb)
        sx = mat()
        sy = mat()
        rb = mat()
        ub = mat()  # x̄'s pointwise part
        vb = mat()
        if wp.static(ADV):
            for j in range(NP):
                c1, c2 = covariant(D, x, base + j)
                v1[j] = c1
                v2[j] = c2
        for j in range(NP):
            cx = vec()
            cy = vec()
            if wp.static(ADV):
                cx = along(v2[j], dvvT)
                cy = along(dvv[j], v1)
            a, b, d, r, u, v = point_row(x, Dinv, metdet, fcor, spheremp, c, k0, k1, k2, fbar, base + j, cx, cy)
            sd[j] = a
            sx[j] = b
            sy[j] = d
            rb[j] = r
            ub[j] = u
            vb[j] = v
        for q in range(base, base + NP):  # the transposed derivatives: along(s[j], dvv), along(dvvᵀ[j], s)
            j = q - base
            a1 = vec()
            a2 = vec()
            e = vec()
            w1 = vec()
            w2 = vec()
            if wp.static(CONT):
                a1 = times(metdet[q], along(sd[j], dvv))
                a2 = times(metdet[q], along(dvvT[j], sd))
            if wp.static(GRAD):
                e = along(sx[j], dvv) + along(dvvT[j], sy)
            if wp.static(ADV):
                w1 = along(dvvT[j], rb)
                w2 = along(rb[j], dvv)
            uq, vq, hq = gather_row(x, D, Dinv, metdet, g, q, ub[j], vb[j], a1, a2, e, w1, w2)
            xbar[0, q] = uq
            xbar[1, q] = vq
            xbar[2, q] = hq

    kernel.__qualname__ = kernel.__name__ = f"tendency_adjoint_element_np{NP}_k{NK}__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
