"""Recorded launches: record a kernel launch once, replay it every step (no allocation, no
argument packing in the time loop), and linear combinations of arrays as such launches.

``LaunchRecorder`` is what the model, its ∇⁴ (``hyperviscosity``), its bad-node check
(``bad_nodes``), the gravity-wave operator (``gravity_wave``) and the Helmholtz CG
(``model.helmholtz``) launch through: the launches split over the CPU threads
(``core.parallel.record``), cached under a key with the arrays they were recorded on.
``Update`` names one linear combination written by an operator's DSS.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import warp as wp

from ..core.backend import Backend
from ..core.graphs import GraphGuard
from ..core.parallel import record
from ..kernels import blas, operators

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
    shape and strides, the rows; not the coefficients (``coefficients``: launch arguments
    set in place, ``LaunchRecorder.replay_updates``)."""
    return tuple(
        (
            None if u.rows is None else (u.rows.start, u.rows.stop),
            (u.out.ptr, u.out.shape, u.out.strides),
            tuple(None if src is None else (src.ptr, src.shape, src.strides) for _, src in u.terms),
        )
        for u in updates
    )


def coefficients(updates) -> tuple:
    """The coefficients a of ``updates``' terms (a, src), in order (floats)."""
    return tuple(float(a) for u in updates for a, _ in u.terms)


def with_coefficients(updates, values) -> tuple:
    """``updates`` with their coefficients, in ``coefficients``' order, replaced by ``values``."""
    values, out = iter(values), []
    for u in updates:
        out.append(Update(u.out, tuple((next(values), src) for _, src in u.terms), u.rows))
    return tuple(out)


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
        The most keys kept (None: all): the oldest recorded goes first, and is recorded
        again if asked for.
    variants : int or None
        The most coefficient sets kept recorded under one key of ``replay`` with
        ``coefficients`` (None: all). Past it the least recently replayed list takes the
        new coefficients in place (its launch arguments set, nothing recorded): a run whose
        Δt changes step to step (``integrator.control``) sets it, so that a new Δt costs
        the arguments' setting, not a recording.
    """

    limit: int | None = None
    variants: int | None = None

    def __init__(self, device, threads: int, points: int, nnodes: int, nunique: int, per_element: bool):
        self.backend = device if isinstance(device, Backend) else Backend.of(device)
        self.device, self.threads, self.block = self.backend.device, int(threads), points * points
        self.nnodes, self.nunique, self.per_element = nnodes, nunique, bool(per_element)
        self._recorded: dict[tuple, tuple] = {}
        self._pointwise: dict[tuple, object] = {}
        # whether what launches through it may capture graphs (the solvers' loops, whole steps:
        # ``core.graphs``); off for good on a failure
        self.guard = GraphGuard()

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
        ``blas.axpby``/``axpbypcz``/``axpbypczpdw`` (one term: c·x + 0·x); of a float32 state's
        arrays (out not float64) one or two terms, ``blas.combined_state`` (ValueError for more)."""
        terms = tuple(terms)
        if out.dtype is not f64:
            if not 1 <= len(terms) <= 2:
                raise ValueError(f"a float32 state's combination is of one or two arrays (got {len(terms)})")
            c = wp.vec3d(*(c for c, _ in terms), *[0.0] * (3 - len(terms)))
            arrays = [x for _, x in terms]
            kernel = blas.combined_state(len(terms), out.dtype)
            return self.pointwise(kernel, out.shape[0], [c, arrays[0], arrays[-1], out])
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

    def lanes(self, a: wp.array) -> wp.array:
        """``a`` ((rows, N) or (N,) of nodes) as lanes (``kernels.departure``'s): vectors of an
        element's np² nodes on the per-element layout (a CPU thread's vector loop), of one node on
        the per-node one (``kernels.operators.row_vectors``, zero-copy)."""
        return operators.row_vectors(a, self.block if self.per_element else 1)

    def lanes_launch(self, kernel, *inputs):
        """The launch (not kept) of a kernel over lanes, as ``run_lanes`` records it."""
        args = [self.lanes(a) if isinstance(a, wp.array) and a.shape[-1] == self.nnodes else a for a in inputs]
        dim = next(a for a in args if isinstance(a, wp.array)).shape
        W = self.block if self.per_element else 1
        return self.record(kernel, dim if len(dim) > 1 else dim[0], args, nodes_per_index=W)

    def run_lanes(self, kernel, *inputs) -> None:
        """Run a kernel over lanes (``lanes``; a trailing ``offset`` in lanes, not in ``inputs``):
        each array of the nodes among ``inputs`` taken as lanes, the launch's dim the first one's
        ((rows, N/W) or N/W); recorded on the first call with these arrays, later calls only set
        its scalar arguments."""
        key = ("lanes", kernel.key, *(a.ptr if isinstance(a, wp.array) else None for a in inputs))
        launch = self._pointwise.get(key)
        if launch is None:
            launch = self._pointwise[key] = self.lanes_launch(kernel, *inputs)
        else:
            for arg, value in zip(kernel.adj.args, inputs):
                if not isinstance(value, wp.array):
                    launch.set_param_by_name(arg.label, value)
        launch.launch()

    def replay(self, key, arrays, build, coefficients=None) -> None:
        """Replay the launches recorded under ``key``, recording them first (``build()``,
        a list of launches) if new. The cache holds ``arrays`` so that their addresses
        (part of the key) stay theirs. With ``coefficients`` (a tuple of floats), ``build``
        takes them (``build(coefficients)``) and each must reach the launches only as a
        float64 argument or a component of a float64 vector argument: a list recorded under
        ``key`` with other coefficients is replayed with these set as its arguments
        (``variants``), the same bits as a list recorded with them. ValueError for a
        coefficient that reaches no argument."""
        entry = self._recorded.get(key)
        if entry is None:
            entry = self._recorded[key] = (build() if coefficients is None else _Variants(), arrays)
            if self.limit is not None and len(self._recorded) > self.limit:
                del self._recorded[next(iter(self._recorded))]
        launches = entry[0] if coefficients is None else entry[0].launches(build, coefficients, self.variants)
        for launch in launches:
            launch.launch()

    def replay_updates(self, key, arrays, updates, build) -> None:
        """``replay`` of the launches ``build(updates)`` makes of ``Update``s (an operator's
        element pass and its DSS into ``updates``' combinations) under ``key`` and the
        updates' arrays (``update_key``), their coefficients launch arguments."""
        self.replay(
            (*key, update_key(updates)),
            (*arrays, *update_arrays(updates)),
            lambda values: build(with_coefficients(updates, values)),
            coefficients(updates),
        )

    def recorded(self, key) -> list | None:
        """The launches recorded under ``key`` (None if none)."""
        entry = self._recorded.get(key)
        if entry is None:
            return None
        return entry[0].latest() if isinstance(entry[0], _Variants) else entry[0]

    def lists(self) -> int:
        """How many launch lists are recorded (each coefficient set's of a key its own)."""
        return sum(len(e[0].lists) if isinstance(e[0], _Variants) else 1 for e in self._recorded.values())

    def keys(self) -> list:
        """The keys of the recorded launches, in recording order."""
        return list(self._recorded)


# what a list with coefficients is first recorded with, to find the arguments each reaches:
# values no coefficient or other argument takes (negative, of order 1e-271)
def _stand_ins(n: int) -> tuple:
    return tuple(-math.pi * 2.0**-900 * (k + 1) for k in range(n))


class _Slot(NamedTuple):
    """A launch argument that holds coefficients: ``components`` (component or None for a
    scalar, coefficient index) over the vector ``template`` (None for a scalar)."""

    launch: object
    name: str
    template: object
    components: tuple

    def set(self, values) -> None:
        if self.template is None:
            self.launch.set_param_by_name(self.name, f64(values[self.components[0][1]]))
            return
        v = list(self.template)
        for component, k in self.components:
            v[component] = values[k]
        self.launch.set_param_by_name(self.name, type(self.template)(*v))


def _slots(launches, stand_ins) -> list:
    """The arguments of ``launches`` (``wp.Launch`` or ``SplitLaunch``) that hold ``stand_ins``.
    ValueError for a stand-in none holds."""
    index, slots = {v: k for k, v in enumerate(stand_ins)}, []
    for launch in launches:
        whole = getattr(launch, "whole", launch)
        kernel, args = getattr(whole, "kernel", None), getattr(whole, "fwd_args", None)
        if kernel is None or args is None:  # a halo exchange: no arguments
            continue
        for arg, value in zip(kernel.adj.args, args):
            if wp.types.type_is_vector(arg.type) and arg.type._wp_scalar_type_ is f64:
                found = tuple((c, index[float(v)]) for c, v in enumerate(value) if float(v) in index)
                template = value
            elif arg.type is f64:
                v = float(getattr(value, "value", value))
                found, template = (((None, index[v]),) if v in index else ()), None
            else:
                continue
            if found:
                slots.append(_Slot(launch, arg.label, template, found))
    reached = {k for slot in slots for _, k in slot.components}
    if len(reached) != len(stand_ins):
        missing = sorted(set(range(len(stand_ins))) - reached)
        raise ValueError(f"coefficients {missing} reach no launch argument (used otherwise by the build)")
    return slots


class _Variants:
    """The lists recorded under one key with coefficients: [coefficients, launches, slots],
    the most recently replayed last."""

    def __init__(self):
        self.lists: list[list] = []

    def latest(self) -> list:
        return self.lists[-1][1]

    def launches(self, build, values: tuple, most: int | None) -> list:
        """The launches with the coefficients ``values``: a list recorded with them, a new one
        (fewer than ``most`` kept), or the least recently replayed one set to them."""
        lists = self.lists
        for k in range(len(lists) - 1, -1, -1):
            if lists[k][0] == values:
                if k != len(lists) - 1:
                    lists.append(lists.pop(k))
                return lists[-1][1]
        if most is None or len(lists) < most:
            stand_ins = _stand_ins(len(values))
            launches = build(stand_ins)
            lists.append([None, launches, _slots(launches, stand_ins)])
        else:
            lists.append(lists.pop(0))
        entry = lists[-1]
        for slot in entry[2]:
            slot.set(values)
        entry[0] = values
        return entry[1]
