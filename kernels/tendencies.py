"""The shallow-water tendency, compiled for the terms a scene names
(Williamson et al. 1992, eqs. 2–3 in vector-invariant form; HOMME
``sweq_mod``/``compute_and_apply_rhs``):

    ∂v/∂t = −(ζ + f) k×v − ∇(½|v|² + g(h + hs)),    ∂h/∂t = −∇·(h v).

``tendency(terms)`` builds one kernel per set of terms: each term's code sits
under ``wp.static`` so a term the scene does not name is not compiled at all
(its kernel key, ``tendency__<term>__<term>...``, lists the terms it holds). One thread per
node writes the element-local tendency (rows du/dt, dv/dt, dh/dt; k×v =
(−v, u)); the model then applies the DSS. Dim N.
"""

import functools

import warp as wp

from .operators import element_node

f64 = wp.float64

TENDENCY_TERMS = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography")


@functools.cache
def tendency(terms: tuple):
    """The tendency kernel for ``terms`` (a tuple in ``TENDENCY_TERMS`` order). Arguments:
    x (3, N) state, D, Dinv (4, N), metdet, fcor (N), forcing (2, N) topographic −g∇hs,
    dvv (np, np), np, g, tend (3, N) output, offset."""
    unknown = set(terms) - set(TENDENCY_TERMS)
    if unknown:
        raise ValueError(f"unknown tendency terms {sorted(unknown)}")
    CONT, ADV, COR, PG, TOPO = (t in terms for t in TENDENCY_TERMS)
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

    kernel.__qualname__ = kernel.__name__ = "tendency__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=False, module="unique")
