"""The tendency kernel that Warp can differentiate (``wp.Tape``), for the gradients of a run
(``swe_sphere.adjoint``).

``tendencies.tendency`` loops over an element's GLL points to a bound read at run time
(``np_``), accumulating into scalars as it goes; Warp's generated adjoint of such a dynamic
loop with loop-carried sums is wrong (measured: a dot-product against central differences off
by 23 % on TC5 ne2), and the DSS's vector sums (``dss.gather``) likewise. Here the bound is the
compile-time np (``wp.static``), so Warp unrolls the loop into single assignments and its
adjoint is exact; the forward arithmetic is the per-node kernel's, in the same order (the
same bits: ``tests/adjoint``). The pointwise end is the shared ``tendencies.finish``.
Compiled with ``enable_backward`` in a module of its own, only when a gradient is asked:
the default path's kernels and compile time are not touched.
"""

import functools

import warp as wp

from .operators import element_node
from .tendencies import TENDENCY_TERMS, finish

f64 = wp.float64


@functools.cache
def tendency(terms: tuple, np_: int):
    """The differentiable ``tendencies.tendency`` for ``terms`` at np = ``np_``. Arguments:
    x (3, N) state, D, Dinv (4, N), metdet, fcor (N), forcing (2, N), dvv (np, np), g, tend
    (3, N) output. Dim N; no offset (one launch over every node, as the tape records it)."""
    unknown = set(terms) - set(TENDENCY_TERMS)
    if unknown:
        raise ValueError(f"unknown tendency terms {sorted(unknown)}")
    CONT, ADV, PG = ("continuity" in terms, "momentum_advection" in terms, "pressure_gradient" in terms)
    GRAD = ADV or PG
    NP = int(np_)

    def kernel(
        x: wp.array2d(dtype=f64),
        D: wp.array2d(dtype=f64),
        Dinv: wp.array2d(dtype=f64),
        metdet: wp.array(dtype=f64),
        fcor: wp.array(dtype=f64),
        forcing: wp.array2d(dtype=f64),
        dvv: wp.array2d(dtype=f64),
        g: f64,
        tend: wp.array2d(dtype=f64),
    ):
        p = wp.tid()
        base, i, j = element_node(p, NP)
        div = f64(0.0)
        bx = f64(0.0)
        by = f64(0.0)
        cx = f64(0.0)
        cy = f64(0.0)
        for m in range(wp.static(NP)):
            q = base + j * NP + m
            r = base + m * NP + i
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

    kernel.__qualname__ = kernel.__name__ = f"tendency_taped_np{NP}__" + "__".join(terms)
    return wp.kernel(kernel, enable_backward=True, module="unique")


@wp.kernel(enable_backward=False, module="unique")
def weigh(w: wp.array(dtype=f64), x: wp.array2d(dtype=f64), out: wp.array2d(dtype=f64)):
    """out[r, p] = w[p]·x[r, p] (out may alias x): a DSS's transpose, spheremp times the
    continuous adjoint (``swe_sphere.adjoint.explicit``). Dim (rows, N)."""
    r, p = wp.tid()
    out[r, p] = w[p] * x[r, p]
