"""The float32 state's global mass fixer (``precision = "float32_state"``, ``[numerics]
mass_fixer``): a step's float32 stages round h − H₀ where no flux cancels the rounding, so ∫h
drifts (0.8–3.1e-9 relative over the scenes' runs without it: docs/explanation/precision.md);
the fixer puts back at the step's end the mass its start held, spread over the sphere by weight
spheremp (a uniform depth), a global correction computed in float64 as the IFS's mass fixers
restore what its non-conserving transport loses (Diamantakis & Flemming 2014, Geosci. Model Dev.
7, 965).

The two masses are float64 sums in the whole grid's element order: each element's Σ spheremp·h
(``kernels.departure.element_mass``), then the elements one after another (``blas.row_totals``
on the device with one rank; gathered and added in the same order on the host with several), so
that a run has the same bits on any rank count."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import blas, departure

f64 = wp.float64


class MassFixer:
    """The mass of a state (3, N float64) taken at a step's start (``measure``) put back at its
    end (``restore``), on ``model``'s topology through its launches."""

    def __init__(self, model):
        topo = self.topology = model.topology
        self.launches, self.block = model.launches, model.grid.np**2
        nelem = topo.N // self.block
        self.masses = wp.zeros((2, nelem), dtype=f64, device=topo.device)  # the start's and the end's, by element
        self.totals = wp.zeros(2, dtype=f64, device=topo.device)
        # Σ spheremp over the sphere (m²) in the masses' order: the same bits on any rank count
        self.area = float(self.whole_totals(topo.grid.spheremp.reshape(1, nelem, self.block).sum(axis=2))[0])
        self._recorded: dict = {}
        self.taken = False  # whether ``measure`` took the mass to keep (a kept float32 state's, once)

    def whole_totals(self, by_element: np.ndarray) -> np.ndarray:
        """(rows,) sums of (rows, nelem) per-element values of this rank's elements over the
        whole grid, element after element in the grid's order (the device's ``row_totals``
        bits: a running sum from 0), every rank getting them."""
        topo = self.topology
        if topo.distributed:
            whole = np.empty((len(by_element), topo.nnodes_total // self.block))
            pieces = topo.comm.allgather(by_element)
            for part, piece in zip(topo.parts, pieces, strict=True):
                whole[:, part] = piece
            by_element = whole
        return np.cumsum(by_element, axis=1)[:, -1]

    def _launch(self, x, slot: int) -> None:
        key = (x.ptr, slot)
        if key not in self._recorded:
            lanes, topo = self.launches.lanes, self.topology
            per = self.block // (self.block if self.launches.per_element else 1)  # an element's lanes
            inputs = [lanes(x[2]), lanes(topo.spheremp[: topo.N]), per, slot, self.masses]
            self._recorded[key] = self.launches.elements(departure.element_mass, inputs)
        self._recorded[key].launch()

    def measure(self, x: wp.array2d) -> None:
        """Take x's mass ∫h (m³; of a float32 state's h − H₀, less H₀·area) as the one to keep:
        a step's start, or where the run keeps the float32 state its first step's (``taken``)."""
        self._launch(x, 0)
        self._total(0)
        self.taken = True

    @property
    def target(self) -> float:
        """The mass ``measure`` took (m³, the float64 sum; collective where ``restore`` is): a
        restart file keeps a kept float32 state's (``members``), which a continuation sets back."""
        return float(self.totals.numpy()[0])

    @target.setter
    def target(self, mass: float) -> None:
        self.totals.assign(np.array([mass, 0.0]))
        self.taken = True

    def restore(self, x: wp.array2d) -> None:
        """Move x's depth by the uniform amount that gives it the mass ``measure`` took (each
        node's move rounded to x's float type: below a float32 state's spacing it is lost, and
        the mass left out stays a deficit that the next step's fixer puts back with its own)."""
        self._launch(x, 1)
        self._total(1)
        self.launches.run_lanes(departure.restore_mass, x[2], self.totals, f64(self.area))

    def _total(self, slot: int) -> None:
        """totals[slot] = the whole grid's sum of masses[slot] (``whole_totals``' bits)."""
        if self.topology.distributed:  # a host read: a step over several ranks is never a graph
            totals = self.totals.numpy()
            totals[slot] = self.whole_totals(self.masses.numpy()[slot : slot + 1])[0]
            self.totals.assign(totals)
        else:
            wp.launch(
                blas.row_totals, 1, [self.masses[slot : slot + 1], self.totals[slot : slot + 1]],
                device=self.topology.device,
            )  # fmt: skip
