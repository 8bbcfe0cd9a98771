"""Recorded launches: record a kernel launch once, replay it every step (no allocation, no
argument packing in the time loop), and linear combinations of arrays as such launches.

``LaunchRecorder`` is what the model, its ∇⁴ (``hyperviscosity``), its bad-node check
(``bad_nodes``), the gravity-wave operator (``gravity_wave``) and the Helmholtz CG
(``solvers.helmholtz``) launch through: the launches split over the CPU threads
(``core.parallel.record``), cached under a key with the arrays they were recorded on.
``Update`` names one linear combination written by an operator's DSS.
"""

from __future__ import annotations

from typing import NamedTuple

import warp as wp

from ..core.backend import Backend
from ..core.parallel import record
from ..kernels import blas

f64 = wp.float64


class Update(NamedTuple):
    """One linear combination an operator's DSS writes: out[rows] = Σ a·src[rows] over
    ``terms`` (a, src), src a (rows, N) array of out's shape or None standing for the
    operator's result (which is not stored). ``rows``: a slice of the rows, or None for
    all (``ShallowWater.rhs_update``; the other operators take None only)."""

    out: wp.array
    terms: tuple
    rows: slice | None = None


def update_key(updates) -> tuple:
    """What a recorded combination fixes of ``updates``: each out's and src's address,
    shape and strides, the coefficients, the rows."""
    return tuple(
        (
            None if u.rows is None else (u.rows.start, u.rows.stop),
            (u.out.ptr, u.out.shape, u.out.strides),
            tuple((a, None if src is None else (src.ptr, src.shape, src.strides)) for a, src in u.terms),
        )
        for u in updates
    )


def update_arrays(updates) -> tuple:
    """The arrays of ``updates`` (outs and sources), held with their recorded launches."""
    return tuple(a for u in updates for a in (u.out, *(src for _, src in u.terms if src is not None)))


def check_updates(updates) -> tuple:
    """``updates`` as a tuple; TypeError unless each is an ``Update``."""
    updates = tuple(updates)
    for u in updates:
        if not isinstance(u, Update):
            raise TypeError(f"an update must be an Update(out, terms, rows) (got {type(u).__name__})")
    return updates


class LaunchRecorder:
    """Records and replays the launches of one grid's element-local arrays.

    Parameters
    ----------
    device : the run's ``core.backend.Backend`` (or a Warp device name, looked up once).
    threads : CPU threads a launch is split over (``core.parallel.record``; 1 on CUDA).
    points : GLL points per element direction, np (a block of np² nodes is one element).
    nnodes : element-local nodes held, N = nelem·np².
    nunique : unique nodes held (the length of a unique-node vector).
    per_element : the pointwise kernels' layout: np² nodes a thread (True) or one.

    Attributes
    ----------
    limit : int or None
        The most launch lists kept (None: all). A run whose Δt changes step to step
        (``simulation.adaptive``) sets it: keys that fold Δt into their coefficients (the
        stages' combinations, the ∇⁴ step) would else add lists every step; the oldest
        recorded goes first, and is recorded again if asked for.
    """

    limit: int | None = None

    def __init__(self, device, threads: int, points: int, nnodes: int, nunique: int, per_element: bool):
        self.backend = device if isinstance(device, Backend) else Backend.of(device)
        self.device, self.threads, self.block = self.backend.device, int(threads), points * points
        self.nnodes, self.nunique, self.per_element = nnodes, nunique, bool(per_element)
        self._recorded: dict[tuple, tuple] = {}
        self._pointwise: dict[tuple, object] = {}

    def record(self, kernel, dim, inputs, **kw):
        """``core.parallel.record`` on this device and threads (``block``, ``per_part``,
        ``nodes_per_index`` as there)."""
        return record(kernel, dim, inputs, device=self.backend, threads=self.threads, **kw)

    def nodes(self, kernel, dim, inputs, per_part=None, elements=None):
        """Record a per-node kernel with a trailing ``offset`` argument (not in ``inputs``)
        over dim N or (rows, N): split over the CPU threads at element boundaries.
        ``elements`` (start, stop): over those elements' nodes only (dim N)."""
        if elements is not None:
            start, stop = elements
            dim, first = (stop - start) * self.block, start * self.block
            return self.record(kernel, dim, inputs, block=self.block, per_part=per_part, start=first)
        return self.record(kernel, dim, inputs, block=self.block, per_part=per_part)

    def elements(self, kernel, inputs, elements=None):
        """Record a per-element kernel (dim nelem, trailing element ``offset``); ``elements``
        (start, stop): over those elements only."""
        start, stop = (0, self.nnodes // self.block) if elements is None else elements
        return self.record(kernel, stop - start, inputs, nodes_per_index=self.block, start=start)

    def pointwise(self, kernel, rows, inputs, elements=None, per_part=None):
        """Record a pointwise kernel with trailing ``block`` and ``offset`` arguments
        (``kernels.blas``) over (rows, N), or N if ``rows`` is None: np² nodes a thread
        with the per-element layout, one on CUDA. ``elements`` (start, stop): over
        those elements' nodes only; ``per_part`` as ``core.parallel.record``'s."""
        block = self.block if self.per_element else 1
        start, stop = (0, self.nnodes // self.block) if elements is None else elements
        first, n = start * self.block // block, (stop - start) * self.block // block
        return self.record(
            kernel,
            n if rows is None else (rows, n),
            [*inputs, block],
            nodes_per_index=block,
            start=first,
            per_part=per_part,
        )

    def lincomb(self, out, terms):
        """The recorded launch of out = Σ c·x over one to four (c, x) terms of (rows, N)
        arrays (row views such as ``x[2:3]`` included; out may alias any x),
        ``blas.axpby``/``axpbypcz``/``axpbypczpdw`` (one term: c·x + 0·x)."""
        terms = tuple(terms)
        if len(terms) == 1:
            terms += ((0.0, terms[0][1]),)
        args = [a for c, x in terms for a in (f64(c), x)]
        kernel = {2: blas.axpby, 3: blas.axpbypcz, 4: blas.axpbypczpdw}[len(terms)]
        return self.pointwise(kernel, out.shape[0], [*args, out])

    def lincomb_at(self, out, terms, nodes):
        """The recorded launch of out = Σ c·x over four (c, x) terms of states (3, N) at the
        element-local ``nodes`` only (a non-empty int32 device array; out's other nodes
        keep their values), ``blas.axpbypczpdw_at``: at each of them the bits of
        ``lincomb``'s. np² listed nodes a thread with the per-element layout, one on CUDA.
        ValueError for another number of terms, rows, or no nodes."""
        terms = tuple(terms)
        if len(terms) != 4 or out.shape[0] != 3 or nodes.shape[0] == 0:
            raise ValueError(
                f"lincomb_at takes four terms, three rows and some nodes (got {len(terms)}, {out.shape[0]}, "
                f"{nodes.shape[0]})"
            )
        block = self.block if self.per_element else 1
        args = [a for c, x in terms for a in (f64(c), x)]
        n = -(-nodes.shape[0] // block)
        return self.record(blas.axpbypczpdw_at, n, [*args, out, nodes, block], nodes_per_index=block)

    def run_pointwise(self, kernel, *inputs, unique=False) -> None:
        """Run a pointwise kernel (``kernels.blas`` convention: trailing ``block``,
        ``offset``) on ``inputs`` over (3, N), or over (3, nunique) if ``unique``
        (trailing ``offset`` only): recorded on the first call with these arrays,
        later calls only set its scalar arguments."""
        key = (kernel.key, *(a.ptr if isinstance(a, wp.array) else None for a in inputs))
        launch = self._pointwise.get(key)
        if launch is None:
            build = (
                self.nodes(kernel, (3, self.nunique), list(inputs))
                if unique
                else self.pointwise(kernel, 3, list(inputs))
            )
            launch = self._pointwise[key] = build
        else:
            for arg, value in zip(kernel.adj.args, inputs):
                if not isinstance(value, wp.array):
                    launch.set_param_by_name(arg.label, value)
        launch.launch()

    def replay(self, key, arrays, build) -> None:
        """Replay the launches recorded under ``key``, recording them first (``build()``,
        a list of launches) if new. The cache holds ``arrays`` so that their addresses
        (part of the key) stay theirs."""
        entry = self._recorded.get(key)
        if entry is None:
            entry = self._recorded[key] = (build(), arrays)
            if self.limit is not None and len(self._recorded) > self.limit:
                del self._recorded[next(iter(self._recorded))]
        for launch in entry[0]:
            launch.launch()

    def recorded(self, key) -> list | None:
        """The launches recorded under ``key`` (None if none)."""
        entry = self._recorded.get(key)
        return None if entry is None else entry[0]

    def keys(self) -> list:
        """The keys of the recorded launches, in recording order."""
        return list(self._recorded)
