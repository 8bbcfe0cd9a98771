"""The model's DSS'd spectral-element operators and the device geometry they read.

``ElementOperators`` is what a stepper, a solver or the adjoint applies to a state besides the
tendency (``ShallowWater.rhs``): the gradient G = DSS∘grad and the divergence D = DSS∘div of the
gravity-wave operator and the Helmholtz solves (``model.gravity_wave``, ``model.helmholtz``),
written into updates as their DSS makes them; the unique-node assembly and scatter; the
vorticity and divergence the diagnostics report; and the arrays the element kernels take: the
metric terms D, D⁻¹ and metdet (HOMME's ``D``, ``Dinv``, ``metdet``), ``fcor`` and ``hs``, the derivative matrix
``dvv`` (and as the per-element kernels' rows, ``dvv_rows``), the unit vectors ``east``,
``north`` and positions ``xyz`` at the nodes, and work arrays. Every launch is recorded once a
pair of arrays in the model's ``LaunchRecorder`` and replayed (HOMME's ``derivative_mod``
operators, ``gradient_sphere``, ``divergence_sphere``, ``vorticity_sphere``, with its
``bndry_exchange`` DSS).
"""

from __future__ import annotations

import contextlib

import numpy as np
import warp as wp

from ..core.parallel import array_key
from ..kernels import operators
from .launches import check_updates
from .transposes import TendencyTranspose

f64 = wp.float64


class ElementOperators:
    """The DSS'd operators of ``grid`` (a ``CubedSphere``) assembled by ``topology`` on
    ``device``, their launches recorded in ``launches`` (the model's ``LaunchRecorder``);
    ``per_element``: the kernels' layout (an element a thread, else a node a thread); ``static_np``
    the np the per-node tendency and ∇⁴ kernels are compiled for (the grid's; 0, the per-element
    layout's, whose kernels take it otherwise). Compiled for np, their loops along an element's rows
    unroll and a node's indices divide by a constant: a step's graph 8 % faster for galewsky, 4 % for
    TC5 ne30 and as fast at ne120 on an H100, the same bits (issue 83 item 5; benchmarks/gpu/GPU.md).

    Arrays (device, element-local, N the grid's nodes): ``D``, ``Dinv`` (N, 2, 2; m and m⁻¹ per
    reference unit), ``metdet`` (N,), ``dvv`` (np, np), ``dvv_rows`` (the per-element kernels'
    ``dvv`` argument), ``xyz``, ``east``, ``north`` (N, 3; unit sphere), the case's Coriolis
    parameter ``fcor`` (N,; s⁻¹) and surface height ``hs`` (N,; m), and the work arrays
    ``scalar`` (1, N), ``scalar_dss`` (1, N) and ``vec_work`` (2, N)."""

    def __init__(self, grid, topology, launches, per_element: bool, device: str, fcor, hs):
        def up(a):
            return wp.array(np.ascontiguousarray(a), dtype=f64, device=device)

        self.grid, self.topology, self.launches, self.per_element = grid, topology, launches, bool(per_element)
        self.static_np = 0 if self.per_element else grid.np
        self.N = N = grid.nnodes
        self.D, self.Dinv, self.metdet, self.dvv = up(grid.D), up(grid.Dinv), up(grid.metdet), up(grid.rule.dvv)
        self.dvv_rows = operators.dvv_matrix(grid.rule.dvv)
        self.xyz, self.east, self.north = up(grid.xyz), up(grid.east), up(grid.north)
        self.fcor, self.hs = up(fcor), up(hs)
        self.scalar = wp.zeros((1, N), dtype=f64, device=device)
        self.scalar_dss = wp.zeros((1, N), dtype=f64, device=device)
        self.scalar_flat = self.scalar.flatten()
        self.vec_work = wp.zeros((2, N), dtype=f64, device=device)

    @contextlib.contextmanager
    def hs_as(self, hs: wp.array):
        """``hs`` (N,; m) standing for the surface height inside the block (zeros: the ∇⁴ operator
        without its hs offset, as ``Hyperviscosity.biharmonic_radius`` and the adjoint's substeps
        record it), the case's put back after, however the block ends."""
        saved, self.hs = self.hs, hs
        try:
            yield
        finally:
            self.hs = saved

    def tendency_transpose(self, terms: tuple, g: float) -> TendencyTranspose:
        """A transpose of the tendency of ``terms`` at gravity ``g`` (m s⁻²) on these operators'
        arrays, with work arrays of its own (``model.transposes``): an adjoint's."""
        return TendencyTranspose(self, terms, g)

    def as_rows(self, a: wp.array) -> wp.array:
        """``a`` as the GLL rows the per-element kernels read and write (``kernels.operators.row_vectors``)."""
        return operators.row_vectors(a, self.grid.np)

    def _element_grad(self, x, row):
        """The launch of the element-local ∇ x[row] into ``vec_work``."""
        if self.per_element:
            return self.launches.elements(
                operators.gradient_element(self.grid.np),
                [self.as_rows(x), row, self.as_rows(self.Dinv), self.dvv_rows, self.as_rows(self.vec_work)],
            )
        return self.launches.nodes(
            operators.gradient_sphere, self.N, [x, row, self.Dinv, self.dvv, self.grid.np, self.vec_work]
        )

    def _element_div(self, x):
        """The launch of the element-local ∇·v of x's rows 0, 1 into ``scalar``."""
        if self.per_element:
            return self.launches.elements(
                operators.divergence_element(self.grid.np),
                [*map(self.as_rows, (x, self.Dinv, self.metdet)), self.dvv_rows, self.as_rows(self.scalar_flat)],
            )
        return self.launches.nodes(
            operators.divergence_sphere, self.N, [x, self.Dinv, self.metdet, self.dvv, self.grid.np, self.scalar_flat]
        )

    def _build_grad(self, x, row, out):
        return [self._element_grad(x, row), *self.topology.dss(self.vec_work, 1, out)]

    def divergence_launches(self, x: wp.array2d, out: wp.array2d) -> list:
        """The launches (unrecorded by the model) of ``divergence(x, out)``: the element pass into
        ``scalar`` and its DSS (the ∇⁴'s δ when ν_div ≠ ν)."""
        return [self._element_div(x), *self.topology.dss(self.scalar, 1, out)]

    def gradient(self, x: wp.array2d, row: int, out: wp.array2d) -> None:
        """out (2, N) = G f = DSS(∇ x[row]) (units of x per m)."""
        self.launches.replay(
            ("grad", array_key(x), row, array_key(out)), (x, out), lambda: self._build_grad(x, row, out)
        )

    def divergence(self, x: wp.array2d, out: wp.array2d) -> None:
        """out (1, N) = D v = DSS(∇·v) of the wind in rows 0, 1 of x (s⁻¹ × units)."""
        self.launches.replay(("div", array_key(x), array_key(out)), (x, out), lambda: self.divergence_launches(x, out))

    def dss_update(self, x: wp.array2d, updates) -> list:
        """The launches (unrecorded) of the weighted DSS of the element-local x (rows, N)
        written into one or two ``Update``s of all rows (``Topology.dss_update``; src None
        standing for the DSS'd x): what an operator's ``*_update`` ends with."""
        return self.topology.dss_update(x, [(u.out, u.terms) for u in updates])

    def gradient_update(self, x: wp.array2d, row: int, updates) -> None:
        """G x[row] = DSS(∇ x[row]) as ``gradient`` computes it, not stored but written,
        as its DSS makes it, into one or two ``Update(out, terms)`` of (2, N) arrays
        (row views such as ``z[0:2]``): out = Σ a·src over terms (a, src), src None
        standing for G x[row] (``Topology.dss_update``: one to three terms, at most two
        arrays). Outputs may alias x and the terms. Recorded once per arrays, the coefficients
        launch arguments (``LaunchRecorder.replay_updates``)."""
        self.launches.replay_updates(
            ("grad_update", array_key(x), row),
            (x,),
            check_updates(updates),
            lambda u: [self._element_grad(x, row), *self.dss_update(self.vec_work, u)],
        )

    def divergence_update(self, x: wp.array2d, updates) -> None:
        """D v = DSS(∇·v) of x's rows 0, 1 as ``divergence`` computes it, written into
        one or two ``Update(out, terms)`` of (1, N) arrays as ``gradient_update``'s."""
        self.launches.replay_updates(
            ("div_update", array_key(x)),
            (x,),
            check_updates(updates),
            lambda u: [self._element_div(x), *self.dss_update(self.scalar, u)],
        )

    def assemble(self, x: wp.array2d, row: int, out: wp.array) -> None:
        """Unique-node out (nunique,) = M x[row]: assembled mass times a continuous field."""
        self.launches.replay(
            ("assemble", array_key(x), row, array_key(out)), (x, out), lambda: self.topology.assemble(x, row, out)
        )

    def scatter(self, y: wp.array, out: wp.array2d, row: int, rows: int = 1) -> None:
        """Element-local out[row : row + rows] from a unique-node vector y of ``rows`` rows."""
        self.launches.replay(
            ("scatter", array_key(y), array_key(out), row, rows),
            (y, out),
            lambda: self.topology.scatter(y, out, row, rows),
        )

    def vorticity(self, x: wp.array2d) -> np.ndarray:
        """Relative vorticity ζ (s⁻¹), (N,) numpy, with the model's operator and a DSS."""
        self.launches.replay(
            ("vort", array_key(x)),
            (x,),
            lambda: [
                self.launches.elements(
                    operators.vorticity_element(self.grid.np),
                    [*map(self.as_rows, (x, self.D, self.metdet)), self.dvv_rows, self.as_rows(self.scalar_flat)],
                )
                if self.per_element
                else self.launches.nodes(
                    operators.vorticity_sphere,
                    self.N,
                    [x, self.D, self.metdet, self.dvv, self.grid.np, self.scalar_flat],
                ),
                *self.topology.dss(self.scalar, 1, self.scalar_dss),
            ],
        )
        return self.scalar_dss.numpy()[0].copy()

    def wind_divergence(self, x: wp.array2d) -> np.ndarray:
        """Divergence δ = ∇·v (s⁻¹) of the wind in rows 0, 1 of x, (N,) numpy: the
        operator the model steps with (``divergence``), DSS'd."""
        self.divergence(x, self.scalar_dss)
        return self.scalar_dss.numpy()[0].copy()
