"""The element filter of a ``ShallowWater`` model: a scene's ``[filter]`` (HOMME's ``filter_nl``).

A Boyd–Vandeven modal filter (``grid.gll.boyd_vandeven``) applied to every element's fields, then
the weighted DSS that makes them continuous again (HOMME ``filter_P`` and its ``bndry_exchangev``;
Fischer & Mullen 2001, C. R. Acad. Sci. Paris 332, 265, the filter as a stabiliser of spectral
elements). Beside or in place of the ∇⁴: where the ∇⁴ damps by degree on the sphere, the filter
damps the highest Legendre modes of each element by a fixed fraction ``mu`` an application,
whatever Δt. Kernel: ``kernels.filter``.
"""

from __future__ import annotations

import warp as wp

from ..grid.gll import boyd_vandeven
from ..kernels import filter as kernels
from ..kernels import operators

f64 = wp.float64


class ElementFilter:
    """The filter (``mu``, ``p``, ``s``: ``grid.gll.boyd_vandeven``'s) of ``model``: ``apply``
    x ← DSS(F ⊗ F x). Holds its matrix (np, np), allocates two work arrays (3 and 4 rows of N) once; records its
    launches (the element pass, the weighted DSS) per state array."""

    def __init__(self, model, mu: float, p: float, s: float):
        self.model = m = model
        self.mu, self.p, self.s = float(mu), float(p), float(s)
        self.matrix = operators.dvv_matrix(boyd_vandeven(m.grid.np, self.mu, self.p, self.s))
        self._filtered = wp.zeros((3, m.N), dtype=f64, device=m.device)
        self._cartesian = wp.zeros((4, m.N), dtype=f64, device=m.device)  # the kernel's filtered fields

    def apply(self, x: wp.array2d) -> None:
        """x (3, N) ← the weighted DSS of the filter of x, element by element (rows u, v in
        m s⁻¹ and h in m; ``kernels.filter``): the mass Σ spheremp·h kept to round-off, a
        constant state kept."""
        self.model.launches.replay(("filter", x.ptr), (x,), lambda: self.build(x))

    def build(self, x: wp.array2d) -> list:
        """The launches of ``apply`` on x."""
        m, ops = self.model, self.model.operators
        rows = [ops.as_rows(a) for a in (x, ops.hs, m.spheremp[: m.N], ops.east, ops.north)]
        args = [*rows, self.matrix, ops.as_rows(self._cartesian), ops.as_rows(self._filtered)]
        return [m.launches.elements(kernels.element_filter(m.grid.np), args), *m.topology.dss(self._filtered, True, x)]
