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
  into local vectors and differentiated from there, with ``dvv`` compiled in
  as constants and FMA contraction on (2.9× the per-node kernel on one core at
  ne30 np4).
"""

import functools

import warp as wp

from .operators import CPU_FAST, dvv_constant, element_node

f64 = wp.float64

TENDENCY_TERMS = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography")


def _flags(terms):
    """Which of ``TENDENCY_TERMS`` are in ``terms``; ValueError for an unknown one."""
    unknown = set(terms) - set(TENDENCY_TERMS)
    if unknown:
        raise ValueError(f"unknown tendency terms {sorted(unknown)}")
    return tuple(t in terms for t in TENDENCY_TERMS)


@functools.cache
def finish(terms: tuple):
    """The pointwise end of the tendency at node p, shared by both layouts: from
    the reference derivatives div = Σ∂(metdet h c), (bx, by) = ∂(Bernoulli), and
    cx − cy = ∂ξ v₂ − ∂η v₁ (covariant wind), write tend[:, p]."""
    CONT, ADV, COR, PG, TOPO = _flags(terms)
    GRAD = ADV or PG

    def finish_terms(
        p: int, div: f64, bx: f64, by: f64, cx: f64, cy: f64,
        x: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64),
        fcor: wp.array(dtype=f64), forcing: wp.array2d(dtype=f64), tend: wp.array2d(dtype=f64),
    ):
        du = f64(0.0)
        dv = f64(0.0)
        dh = f64(0.0)
        if wp.static(CONT):
            dh = -div / metdet[p]
        if wp.static(GRAD):
            du = -(Dinv[0, p] * bx + Dinv[2, p] * by)
            dv = -(Dinv[1, p] * bx + Dinv[3, p] * by)
        rot = f64(0.0)  # ζ + f, the absolute vorticity's named parts
        if wp.static(ADV):
            rot += (cx - cy) / metdet[p]
        if wp.static(COR):
            rot += fcor[p]
        if wp.static(ADV or COR):  # −(ζ + f) k×v
            du += rot * x[1, p]
            dv -= rot * x[0, p]
        if wp.static(TOPO):
            du += forcing[0, p]
            dv += forcing[1, p]
        tend[0, p] = du
        tend[1, p] = dv
        tend[2, p] = dh

    finish_terms.__qualname__ = finish_terms.__name__ = "finish__" + "__".join(terms)
    return wp.func(finish_terms)


@functools.cache
def tendency(terms: tuple):
    """The tendency kernel for ``terms`` (a tuple in ``TENDENCY_TERMS`` order). Arguments:
    x (3, N) state, D, Dinv (4, N), metdet, fcor (N), forcing (2, N) topographic −g∇hs,
    dvv (np, np), np, g, tend (3, N) output, offset."""
    CONT, ADV, _, PG, _ = _flags(terms)
    GRAD = ADV or PG  # ∇ of the Bernoulli function ½|v|² + g h

    def kernel(
        x: wp.array2d(dtype=f64),
        D: wp.array2d(dtype=f64),
        Dinv: wp.array2d(dtype=f64),
        metdet: wp.array(dtype=f64),
        fcor: wp.array(dtype=f64),
        forcing: wp.array2d(dtype=f64),
        dvv: wp.array2d(dtype=f64),
        np: int,
        g: f64,
        tend: wp.array2d(dtype=f64),
        offset: int,
    ):
        p = wp.tid() + offset
        base, i, j = element_node(p, np)
        div = f64(0.0)  # Σ ∂(metdet c)        (continuity)
        bx = f64(0.0)  # ∂ξ, ∂η of the Bernoulli function
        by = f64(0.0)
        cx = f64(0.0)  # ∂ξ v₂, ∂η v₁ of the covariant wind (vorticity)
        cy = f64(0.0)
        for m in range(np):
            q = base + j * np + m  # along ξ through (i, j)
            r = base + m * np + i  # along η
            if wp.static(CONT):
                div += dvv[i, m] * metdet[q] * x[2, q] * (Dinv[0, q] * x[0, q] + Dinv[1, q] * x[1, q])
                div += dvv[j, m] * metdet[r] * x[2, r] * (Dinv[2, r] * x[0, r] + Dinv[3, r] * x[1, r])
            if wp.static(GRAD):
                eq = f64(0.0)
                er = f64(0.0)
                if wp.static(ADV):
                    eq += f64(0.5) * (x[0, q] * x[0, q] + x[1, q] * x[1, q])
                    er += f64(0.5) * (x[0, r] * x[0, r] + x[1, r] * x[1, r])
                if wp.static(PG):
                    eq += g * x[2, q]
                    er += g * x[2, r]
                bx += dvv[i, m] * eq
                by += dvv[j, m] * er
            if wp.static(ADV):
                cx += dvv[i, m] * (D[1, q] * x[0, q] + D[3, q] * x[1, q])
                cy += dvv[j, m] * (D[0, r] * x[0, r] + D[2, r] * x[1, r])
        wp.static(finish(terms))(p, div, bx, by, cx, cy, x, Dinv, metdet, fcor, forcing, tend)

    kernel.__qualname__ = kernel.__name__ = "tendency__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=False, module="unique")


@functools.cache
def tendency_element(terms: tuple, dvv: tuple):
    """The tendency kernel for ``terms``, one thread per element, for the
    derivative matrix ``dvv`` (np rows of np values, compiled in). Arguments:
    x (3, N) state, D, Dinv (4, N), metdet, fcor (N), forcing (2, N)
    topographic −g∇hs, g, tend (3, N) output, offset (in elements). Dim nelem."""
    CONT, ADV, _, PG, _ = _flags(terms)
    GRAD = ADV or PG
    NP = len(dvv)
    NPP = NP * NP
    vec = wp.types.vector(length=NPP, dtype=f64)
    DVV = dvv_constant(dvv)

    def kernel(
        x: wp.array2d(dtype=f64),
        D: wp.array2d(dtype=f64),
        Dinv: wp.array2d(dtype=f64),
        metdet: wp.array(dtype=f64),
        fcor: wp.array(dtype=f64),
        forcing: wp.array2d(dtype=f64),
        g: f64,
        tend: wp.array2d(dtype=f64),
        offset: int,
    ):
        base = (wp.tid() + offset) * NPP
        f1 = vec()  # metdet h c¹, metdet h c²: the mass flux (continuity)
        f2 = vec()
        E = vec()  # the Bernoulli function
        v1 = vec()  # covariant wind (vorticity)
        v2 = vec()
        for k in range(NPP):
            q = base + k
            u = x[0, q]
            v = x[1, q]
            h = x[2, q]
            if wp.static(CONT):
                Jh = metdet[q] * h
                f1[k] = Jh * (Dinv[0, q] * u + Dinv[1, q] * v)
                f2[k] = Jh * (Dinv[2, q] * u + Dinv[3, q] * v)
            if wp.static(ADV):
                E[k] = f64(0.5) * (u * u + v * v)
                v1[k] = D[0, q] * u + D[2, q] * v
                v2[k] = D[1, q] * u + D[3, q] * v
            if wp.static(PG):
                E[k] = E[k] + g * h
        for j in range(NP):
            for i in range(NP):
                div = f64(0.0)
                bx = f64(0.0)
                by = f64(0.0)
                cx = f64(0.0)
                cy = f64(0.0)
                for m in range(NP):
                    a = DVV[i, m]  # along ξ through (i, j): node j*NP + m
                    b = DVV[j, m]  # along η: node m*NP + i
                    if wp.static(CONT):
                        div += a * f1[j * NP + m] + b * f2[m * NP + i]
                    if wp.static(GRAD):
                        bx += a * E[j * NP + m]
                        by += b * E[m * NP + i]
                    if wp.static(ADV):
                        cx += a * v2[j * NP + m]
                        cy += b * v1[m * NP + i]
                wp.static(finish(terms))(base + j * NP + i, div, bx, by, cx, cy, x, Dinv, metdet, fcor, forcing, tend)

    kernel.__qualname__ = kernel.__name__ = "tendency__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=False, module="unique", module_options=CPU_FAST)
