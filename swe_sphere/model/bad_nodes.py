"""The bad-node check of a ``ShallowWater`` model's states (a non-finite value or a dry node),
at once (one host read) or flagged on the device over a block of steps and read once."""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..kernels import blas


class BadNodes:
    """The bad-node check of ``model``'s states (3, N; float64, or the float32 state the run keeps,
    ``model.held``): a node is bad where u, v or h
    is not finite or (when the scene has a pressure gradient, so h is a depth) h ≤ 0
    (``kernels.blas.first_bad_node``, launched through the model's recorder).
    Holds two int32 arrays of a slot per CPU thread: ``bad`` (``first``'s) and
    ``watched`` (``watch``'s)."""

    def __init__(self, model):
        self.model = m = model
        self.bad = wp.zeros(max(1, m.threads), dtype=wp.int32, device=m.device)
        self.watched = wp.full(max(1, m.threads), m.N, dtype=wp.int32, device=m.device)
        self.depth = "pressure_gradient" in m.terms  # h a depth: h <= 0 is bad

    def mask(self, x: np.ndarray) -> np.ndarray:
        """(..., N) bool: the nodes of host states x (..., 3, N) that ``first`` and ``watch`` find
        bad, by the same rule (an ensemble's members named in a blow-up's line)."""
        bad = ~np.isfinite(x).all(axis=-2)
        return bad | (x[..., 2, :] <= 0) if self.depth else bad

    def first(self, x: wp.array2d) -> int | None:
        """Whole-grid element-local index of the first bad node of x over all ranks;
        None if all are good. Reads the device (a host synchronisation)."""
        N = self.model.N
        self.bad.fill_(N)
        self._check(x, self.bad, "guard")
        first = int(self.bad.numpy().min())
        return self.model.topology.first_node(None if first == N else first)

    def describe(self, x: wp.array2d, node: int) -> str:
        """What is bad at the whole-grid node ``node`` of x (``first``'s index) and where: "non-finite
        value" or "depth h = … m <= 0", at lat, lon (degrees); the same line on every rank (call on
        all: gathers x and the grid)."""
        topo = self.model.topology
        values, grid = topo.gather(self.model.held.values(x)[:3]), topo.whole_grid()
        if values is None:
            return topo.bcast(None)
        u, v, h = values[:, node]
        lat, lon = np.degrees(grid.lat[node]), np.degrees(grid.lon[node])
        what = "non-finite value" if not all(map(math.isfinite, (u, v, h))) else f"depth h = {h:.4g} m <= 0"
        return topo.bcast(f"{what} at lat {lat:.2f}, lon {lon:.2f} degrees")

    def watch(self, x: wp.array2d) -> None:
        """Flag on the device whether x has a bad node, without reading it back: the
        flag (the smallest bad index seen) holds every state watched since the last
        ``watched_bad``, so a block of steps needs one read."""
        self._check(x, self.watched, "watch")

    def watched_bad(self) -> bool:
        """Whether any state given to ``watch`` since the last call had a bad node on
        any rank (the same answer on every rank; call on all); resets the flag.
        One host read."""
        N = self.model.N
        bad = int(self.watched.numpy().min()) < N
        self.watched.fill_(N)
        return self.model.topology.max(float(bad)) > 0.0

    def _check(self, x, first, name):
        """Launch ``blas.first_bad_node`` on x into the per-thread slots of ``first``
        (an atomic minimum: the same index whatever order the threads run in)."""
        m = self.model
        check_depth = 1 if self.depth else 0
        h0 = wp.float64(m.held.depth if x.dtype is not wp.float64 else 0.0)  # a float32 state's h is h − H₀
        slots = [first[k : k + 1] for k in range(first.shape[0])]  # one per thread: CPU atomics are plain
        m.launches.replay(
            (name, x.ptr),
            (x,),
            lambda: [
                m.launches.pointwise(blas.first_bad_node, None, [x, check_depth, h0, first], per_part={"first": slots})
            ],
        )
