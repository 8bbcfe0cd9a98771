"""The Jacobian-vector product of the model's RHS by a forward difference, on
unique-node vectors: the JFNK stepper's (``implicit``) and the exponential
steppers' (``exponential``).

Krylov vectors live on unique nodes (3·nunique, row r of unique node g at
r·nunique + g: the state is continuous, so one copy per node carries it all;
0.56× the element-local length at np = 4); ``gather`` and ``scatter`` move
between them and element-local (3, N) states (``kernels.implicit``).

    J w ≈ (F(x + εw) − F(x)) / ε,   ε = sqrt(ε_mach) (1 + ‖x‖) / ‖w‖

(one of the choices of Knoll & Keyes 2004, J. Comput. Phys. 193, 357; ‖·‖ the
Euclidean norm of the unique-node vectors over all processes). Every term of F is
at most quadratic in the state, so the difference's error is ε‖F''‖: ~1e-8
relative (``tests/test_implicit.py``).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..kernels import blas
from ..kernels import implicit as ik

f64 = wp.float64
_SQRT_EPS = math.sqrt(np.finfo(float).eps)


class FiniteDifferenceJacobian:
    """J w of ``model``'s RHS about a point x, with ``F(x, out)`` the caller's RHS
    evaluation (it counts them). ``apply(x, Fx, xnorm, w, out, shift, scale)``:
    out = shift·w + scale·J w for unique-node vectors w, out (3·nunique,), with
    F(x) in Fx (3, N) and xnorm = ‖x‖ on unique nodes; one F evaluation (none
    for w = 0, out = 0). x and Fx are left alone."""

    def __init__(self, model, F):
        self.model, self.F = model, F
        self.topology = model.topology
        self.nu = self.topology.nunique
        self.xp = wp.zeros((3, model.N), dtype=f64, device=model.device)  # x + εw
        self.Fp = wp.zeros((3, model.N), dtype=f64, device=model.device)  # F(x + εw)

    def norm(self, a) -> float:
        """Euclidean norm of an array (3, N) or (3·nunique,) over all processes."""
        return self.topology.norm(a)

    def gather(self, a: float, v, out) -> None:
        """Unique-node out = a·v from a continuous (3, N) v."""
        self.model.pointwise(ik.gather, f64(a), v, self.topology.first, self.nu, out, unique=True)

    def scatter(self, u, out) -> None:
        """Element-local out (3, N) from the unique-node vector u."""
        self.model.scatter(u, out, 0, rows=3)

    def apply(self, x, Fx, xnorm: float, w, out, shift: float = 0.0, scale: float = 1.0) -> None:
        wnorm = self.norm(w)
        if wnorm == 0.0:
            out.zero_()
            return
        eps = _SQRT_EPS * (1.0 + xnorm) / wnorm
        self.scatter(w, self.xp)
        self.model.pointwise(blas.axpby, f64(1.0), x, f64(eps), self.xp, self.xp)  # x + ε w
        self.F(self.xp, self.Fp)
        self.model.pointwise(ik.jacobian_vector, w, Fx, self.Fp, self.topology.first, self.nu, f64(shift), f64(-scale / eps), out, unique=True)
