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
that a run has the same bits on any rank count. On an ensemble's copies of the grid (a grid with
``members``: ``members.grid.MemberGrid``) each member's mass is its own, summed and put back as
its single run's.

Where the run keeps the float32 state (``model.held``) the mass to keep is taken once, when the
held state is set (``measure``: the run's start, a state set from outside), or set from a restart
file (``targets``), never inside a step: a step is then the same launches every time, as a
captured graph replays it."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.parallel import record_one
from ..kernels import blas, departure

f64 = wp.float64


class MassFixer:
    """The mass of a state (rows, N) taken at a step's start (``measure``) put back at its end
    (``restore``), each member's its own (``members``: 1, or an ensemble's copies of the grid),
    on ``model``'s topology through its launches."""

    def __init__(self, model):
        topo = self.topology = model.topology
        self.launches, self.block = model.launches, model.grid.np**2
        self.members = int(getattr(topo.grid, "members", 1))  # a MemberGrid's copies, member after member
        nelem = topo.N // self.block
        self.masses = wp.zeros((2, nelem), dtype=f64, device=topo.device)  # the start's and the end's, by element
        self.totals = wp.zeros((2, self.members), dtype=f64, device=topo.device)  # by member
        # Σ spheremp over one member's sphere (m²) in the masses' order: the same bits on any rank count
        one = topo.grid.spheremp.reshape(1, nelem, self.block).sum(axis=2)[:, : nelem // self.members]
        self.area = float(self.whole_totals(one)[0])
        self._recorded: dict = {}

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

    def _recorded_for(self, key, build) -> list:
        """The launches recorded under ``key`` (``build()`` on first use): replayed each step
        with no argument set again."""
        launches = self._recorded.get(key)
        if launches is None:
            launches = self._recorded[key] = build()
        return launches

    def _sum(self, x, slot: int) -> None:
        """masses[slot] = x's mass by element, totals[slot] = each member's sum of them over the
        whole grid (``whole_totals``' bits)."""
        topo = self.topology

        def build():
            lanes = self.launches.lanes
            per = self.block // (self.block if self.launches.per_element else 1)  # an element's lanes
            inputs = [lanes(x[2]), lanes(topo.spheremp[: topo.N]), per, slot, self.masses]
            launches = [self.launches.elements(departure.element_mass, inputs)]
            if not topo.distributed:
                rows = self.masses[slot].reshape((self.members, -1))  # a member's elements a row
                launches.append(record_one(blas.row_totals, 1, [rows, self.totals[slot]], device=topo.backend))
            return launches

        for launch in self._recorded_for((x.ptr, slot), build):
            launch.launch()
        if topo.distributed:  # a host read: a step over several ranks is never a graph (one member)
            totals = self.totals.numpy()
            totals[slot] = self.whole_totals(self.masses.numpy()[slot : slot + 1])
            self.totals.assign(totals)

    def measure(self, x: wp.array2d) -> None:
        """Take x's mass ∫h (m³ a member; of a float32 state's h − H₀, less H₀·area) as the one
        to keep: a step's start, or the state a run keeps in float32 as it is set
        (``model.held.HeldState``)."""
        self._sum(x, 0)

    @property
    def targets(self) -> list[float]:
        """The masses ``measure`` took, a member each (m³, the float64 sums; collective where
        ``restore`` is): a restart file keeps a kept float32 state's (``members``), which a
        continuation sets back."""
        return [float(m) for m in self.totals.numpy()[0]]

    @targets.setter
    def targets(self, masses) -> None:
        totals = self.totals.numpy()
        totals[0] = masses
        self.totals.assign(totals)

    def restore(self, x: wp.array2d) -> None:
        """Move each member's depth by the uniform amount that gives it the mass ``measure``
        took (each node's move rounded to x's float type: below a float32 state's spacing it is
        lost, and the mass left out stays a deficit that the next step's fixer puts back with its
        own)."""
        self._sum(x, 1)
        self._recorded_for((x.ptr, "restore"), lambda: [self._restore_launch(x)])[0].launch()

    def _restore_launch(self, x):
        lanes = self.topology.N // self.members // (self.block if self.launches.per_element else 1)  # a member's
        return self.launches.lanes_launch(departure.restore_mass, x[2], self.totals, f64(self.area), lanes)
