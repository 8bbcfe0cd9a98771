"""The linear gravity-wave operator of the shallow-water equations about a mean depth H,

    L x = (L_v, L_h) = (−g G h, −H D v),

with G = DSS∘grad and D = DSS∘div the model's own strong operators (so the split
F = (F − L) + L of the model's RHS is exact). It is the implicit part of the
semi-implicit, IMEX and JFNK steppers (inverted by ``model.helmholtz.HelmholtzSolver``)
and the fast part of the multirate split (``steppers.multirate.GravitySplit``): one
element pass of both halves (``kernels.gravity_wave.linear``, ``linear_element``) and
one DSS of its three rows into the combinations that use it. HOMME's
``advance_si_nonstag`` linearises about the same reference depth.
"""

from __future__ import annotations

import warp as wp

from ..kernels import gravity_wave
from .launches import Update, check_updates
from .transposes import GravityTranspose

f64 = wp.float64


def check_mean_depth(mean_depth) -> None:
    """ValueError 'mean_depth must be ...' unless ≥ 0 (0: the initial mean)."""
    if not mean_depth >= 0:
        raise ValueError(f"mean_depth must be >= 0 (got {mean_depth})")


def reference_depth(mean: float) -> float:
    """H (m) from the area-mean depth (m), rounded to 6 significant digits: any depth near
    the mean serves the linearisation, and a rounded one is the same on any number of
    ranks (whose sums of the mean differ in their last bits)."""
    return float(f"{mean:.6g}")


class GravityWaveOperator:
    """L x = (−g G h, −H D v) of ``model`` (a ``ShallowWater``) about the depth H (m).

    Parameters
    ----------
    model : ShallowWater, with the continuity and pressure-gradient terms.
    mean_depth : H (m); 0: ``reference_depth`` of the area-mean depth of the first state
        given to ``set_depth``.

    States are (3, N) element-local arrays of rows u, v (m s⁻¹) and h (m); L x is in
    m s⁻² (wind rows) and m s⁻¹ (depth row). Raises ``ValueError`` for a model without
    the continuity or pressure-gradient term, or a negative ``mean_depth``.
    """

    def __init__(self, model, mean_depth: float = 0.0):
        for term in ("continuity", "pressure_gradient"):
            if term not in model.terms:
                raise ValueError(f"the gravity-wave operator needs the {term} term")
        check_mean_depth(mean_depth)
        self.model, self.H = model, float(mean_depth)

    def set_depth(self, x: wp.array2d) -> None:
        """Fix H from the state x (its full depth in row 2) unless given or fixed before:
        ``reference_depth`` of its area mean over all ranks (a host read)."""
        if self.H == 0.0:
            self.H = reference_depth(self.model.topology.mean(x.numpy()[2]))

    def apply(self, x: wp.array2d, out: wp.array2d, forcing: wp.array2d | None = None) -> None:
        """out (3, N) = L x (+ ``forcing``, a (3, N) array)."""
        terms = ((1.0, None),) if forcing is None else ((1.0, None), (1.0, forcing))
        self.update(x, [Update(out, terms)])

    def update(self, x: wp.array2d, updates) -> None:
        """L x, not stored but written, as its DSS makes it, into one or two
        ``Update(out, terms)`` of (3, N) arrays: out = Σ a·src over terms (a, src), src None
        standing for L x (``Topology.dss_update``: one to three terms, at most two arrays).
        Outputs may alias x and the terms (the element pass reads x first). Recorded once per arrays and H, the coefficients launch arguments
        (``LaunchRecorder.replay_updates``)."""
        m, updates = self.model, check_updates(updates)
        tape = m.recorder  # a gradient's tape (``SteppingModel.recorder``): L written on it
        if tape is not None and not tape.linear(self, x, updates):
            return
        H = self.H

        def build(updates):
            if m.operators.per_element:
                element = m.launches.elements(
                    gravity_wave.linear_element(m.grid.np),
                    [
                        *map(m.operators.as_rows, (x, m.operators.Dinv, m.operators.metdet)),
                        m.g,
                        f64(H),
                        m.operators.dvv_rows,
                        m.operators.as_rows(m.tend),
                    ],
                )
            else:
                element = m.launches.nodes(
                    gravity_wave.linear,
                    m.N,
                    [x, m.operators.Dinv, m.operators.metdet, m.operators.dvv, m.grid.np, m.g, f64(H), m.tend],
                )
            return [element, *m.operators.dss_update(m.tend, updates)]

        m.launches.replay_updates(("linear_update", (x.ptr, x.shape, x.strides), H), (x,), updates, build)

    def transpose(self, solver) -> GravityTranspose:
        """The transposes of L and of its implicit solve A_a⁻¹ = (I − aL)⁻¹ in the mass form, for
        an adjoint (``model.transposes.GravityTranspose``): ``solver`` the ``model.helmholtz.
        HelmholtzSolver`` about this operator that the transposed solve solves with (the
        adjoint's own, the stepper's guesses untouched)."""
        return GravityTranspose(self, solver)
