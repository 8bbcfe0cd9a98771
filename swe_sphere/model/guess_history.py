"""The start of a sequence of Helmholtz solves with one coefficient: the projection onto the
past solutions (``GuessHistory``, Fischer 1998) that ``helmholtz.HelmholtzSolver`` starts its
CG from with ``guess_history`` k > 0, and the work arrays its histories share."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import warp as wp

from ..kernels import helmholtz_cg as cgk

f64 = wp.float64


class HistoryWork(NamedTuple):
    """The work arrays a solver's ``GuessHistory``s share: the solve's start y0 and its
    product w0 (nunique,), the partial sums (k + 4, chunks), the projection's coefficients
    (k,) and the increment's sums (k + 4,)."""

    y0: wp.array
    w0: wp.array
    partial: wp.array
    alpha: wp.array
    sums: wp.array


class GuessHistory:
    """The start of a sequence of solves (M + cK) y = b with one c (``HelmholtzSolver``'s with
    ``history`` k): projection onto the past solutions (Fischer 1998, Comput. Methods Appl.
    Mech. Engrg. 163, 193, "method 2"; PETSc's ``KSPFischerGuess``). X (k, nunique) is an
    A-orthonormal basis of up to k vectors, AX their products; the start is y0 = Σ (Xⱼ·b) Xⱼ,
    the A-norm's best in their span, with A y0 = Σ (Xⱼ·b) AXⱼ and so no product (one fewer
    than a warm start). After the solve the increment y − y0 (A-orthogonal to X in exact
    arithmetic), A-orthonormalised against X, is appended, its product from the CG's residual
    (A y = b − r); with k vectors the basis restarts from the solution and its start
    (``kernels.helmholtz_cg.history_coefficients``; Fischer's from the solution alone). The inner
    products are summed on the device in index order and over ranks by ``Topology``
    (``HelmholtzCG.totals``' way): the same bits on any threads, to round-off on any ranks.

    ``guess()``: y, w (and the copies y0, w0) of ``HelmholtzSolver``'s CG set to the start;
    ``store()``: the solution into the basis (launches, nothing read back); ``fresh``: no
    vector stored yet (known on the host: the solver starts such a solve from its last
    solution instead, and ``store(fresh=True)`` keeps the solution itself). ``count()``:
    the vectors in use (a host read); ``whole()``/``set(count, arrays, what)``: X and AX
    as ``arrays`` whole-grid (3, nnodes_total) arrays, three vectors each (rows past 2k zero),
    for ``HelmholtzSolver.state``/``restore`` (ValueError naming ``what`` for a misshapen one);
    ``spare()``: arrays to hold a basis (any history's of the solver); ``snapshot(spare)``/
    ``put_back(snap)``: the basis copied into them on the device and back, for a rejected
    step's rollback (``HelmholtzSolver.checkpoint``)."""

    def __init__(self, gw):
        """gw: the ``HelmholtzSolver`` whose CG (``cg``, ``y``, ``b``) and ``history_work`` it uses."""
        cg, topo, dev, k = gw.cg, gw.model.topology, gw.model.topology.device, gw.history
        self.topology, self.k = topo, k
        self.X = wp.zeros((k, topo.nunique), dtype=f64, device=dev)
        self.AX = wp.zeros((k, topo.nunique), dtype=f64, device=dev)
        self.hic = wp.zeros(3, dtype=wp.int32, device=dev)  # kernels.helmholtz_cg COUNT, MODE, SLOT
        self.hcs = wp.zeros(max(k + 1, 3), dtype=f64, device=dev)  # 1/‖·‖_A, the βⱼ
        self.arrays = (2 * k + 2) // 3
        self.fresh = True
        rec, nchunks, chunk, nu = gw.model.launches.record, cg.partial.shape[1], cg.chunk, topo.nunique
        y, (y0, w0, partial, alpha, sums) = gw.y, gw.history_work
        self._y0, self._w0 = y0, w0
        self._guess = [
            rec(cgk.history_dots, nchunks, [self.X, gw.b, self.hic, partial, chunk], nodes_per_index=chunk),
            *topo.device_sums(partial, k, alpha),
            alpha,
            rec(cgk.history_guess, nu, [self.X, self.AX, alpha, self.hic, y, cg.w, y0, w0]),
        ]
        self._store = [
            rec(
                cgk.history_increment_dots,
                nchunks,
                [self.X, y, y0, gw.b, cg.r, w0, self.hic, partial, chunk],
                nodes_per_index=chunk,
            ),
            *topo.device_sums(partial, k + 4, sums),
            sums,
            wp.launch(cgk.history_coefficients, 1, [sums, k, self.hic, self.hcs], device=dev, record_cmd=True),
            rec(cgk.history_store, nu, [self.X, self.AX, y, y0, gw.b, cg.r, w0, self.hic, self.hcs]),
        ]

    def _play(self, launches) -> None:
        for launch in launches:
            if isinstance(launch, wp.array):  # the totals summed over ranks between the launches
                self.topology.allreduce(launch)
            else:
                launch.launch()

    def guess(self) -> None:
        self._play(self._guess)

    def store(self, fresh: bool = False) -> None:
        if fresh:  # the solve did not start from ``guess``: the increment from zero, the solution itself
            self._y0.zero_()
            self._w0.zero_()
        self._play(self._store)
        self.fresh = False

    def _basis(self) -> tuple:
        return self.X, self.AX, self.hic, self.hcs

    def spare(self) -> tuple:
        return tuple(wp.empty_like(a) for a in self._basis())

    def snapshot(self, spare: tuple) -> tuple:
        for saved, a in zip(spare, self._basis()):
            wp.copy(saved, a)
        return self.fresh, spare

    def put_back(self, snap: tuple) -> None:
        """In place: the solves' graphs hold the basis's arrays."""
        self.fresh, spare = snap
        for a, saved in zip(self._basis(), spare):
            wp.copy(a, saved)

    def count(self) -> int:
        return int(self.hic.numpy()[cgk.COUNT])

    def _rows(self):
        return [self.X[j] for j in range(self.k)] + [self.AX[j] for j in range(self.k)]

    def whole(self) -> list:
        """X's and AX's rows scattered to element-local (3, N) arrays, gathered on rank 0 (call on all ranks)."""
        topo, rows, out = self.topology, self._rows(), []
        for m in range(self.arrays):
            a = wp.zeros((3, topo.N), dtype=f64, device=self.X.device)
            for row, v in enumerate(rows[3 * m : 3 * m + 3]):
                for launch in topo.scatter(v, a, row):
                    launch.launch()
            out.append(topo.gather(a.numpy()))
        return out

    def set(self, count: int, arrays: list, what: str) -> None:
        topo, rows = self.topology, self._rows()
        first = topo.first.numpy()
        for m, whole in enumerate(arrays):
            part = topo.distribute(whole, 3, what)
            for row, v in enumerate(rows[3 * m : 3 * m + 3]):
                v.assign(part[row][first])
        self.hic.assign(np.array([count, 0, 0], dtype=np.int32))
        self.fresh = count == 0
